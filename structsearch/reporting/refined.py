"""The structures a search reached by refinement ("-auto" names), written beside its ranking so that a reader of
``ranking.csv`` (the report) can resolve them: one grid file per grid, ``refined_<grid>.toml``, in the
``model_specs/`` format (``search --grid FILE`` and ``fit --model`` read it too).

The files are part of the search's set (:mod:`structsearch.data.manifest`): a file the last search did not write,
or one changed since, is refused with an error naming it. They are read as any grid file is (parsed, never
evaluated), so a tampered file that still parses declares nothing beyond the regressor language either.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable, Mapping

from ..data.atomic import write_text
from ..data.errors import DataError, DeclarationError
from ..data.manifest import check_set, listed_files
from ..discovery.spec_file import grid_text
from ..fitting.candidates import Candidate

PATTERN = "refined_*.toml"


def refined_path(out: Path, grid: str) -> Path:
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in grid)
    return Path(out) / f"refined_{safe}.toml"


def write_refined(out: Path, reached: Mapping[str, Iterable[Candidate]]) -> list[Path]:
    """``refined_<grid>.toml`` for each grid with refined structures (grid -> candidates); a previous run's file
    of a grid without any is removed (it would otherwise pass for this run's). Returns the files written."""
    out = Path(out)
    written = []
    keep = set()
    for grid, candidates in reached.items():
        candidates = list(candidates)
        if not candidates:
            continue
        path = refined_path(out, grid)
        keep.add(path.name)
        note = (f"structures the search reached by refining the {grid} grid's best candidates "
                "(structsearch search; read back by structsearch report)")
        written.append(write_text(path, grid_text(candidates, note)))
    for stale in out.glob(PATTERN):
        if stale.name not in keep:
            stale.unlink()
    return written


def load_refined(out: Path) -> dict[str, Candidate]:
    """Every refined structure the search in ``out`` wrote, by name (none without such files). A file that is not
    the one the last search wrote, or that does not parse as a grid, raises an error naming it."""
    from ..fitting.specs import load_grid
    out = Path(out)
    listed = listed_files(out, "search")
    found: dict[str, Candidate] = {}
    for path in sorted(out.glob(PATTERN)):
        if listed is not None and path.name not in listed:
            raise DataError("not written by the last search (its manifest does not list it): run the search "
                            "again", source=str(path))
        check_set(out, "search", path.name)
        try:
            grid = load_grid(str(path))
        except DeclarationError as exc:
            text = str(exc)
            raise DeclarationError(text if str(path) in text else f"{path}: {text}") from None
        for c in grid.candidates:
            if not c.name.endswith("-auto"):
                raise DeclarationError(f"{path}: {c.name!r} is not a refined structure's name (they end in "
                                       "'-auto'): a shipped structure cannot be redeclared here")
            found[c.name] = c
    return found

