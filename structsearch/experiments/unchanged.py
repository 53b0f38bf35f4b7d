"""A run written over earlier results keeps the files whose answers did not change.

Run again, on another machine or after a change that moves nothing, the demo finds the same answers with other
last digits (docs/reproducibility.md): rewriting every table would change a checkout's committed files for
nothing. So before a run the files already in its output directory are copied aside; after it, each file the run
wrote is compared with its earlier version as :mod:`.reproducibility` compares two runs (decisions equal, numbers
within its tolerances; a Markdown or LaTeX table as text whose words are equal and whose numbers agree); a file
with the same answers is put back byte for byte, one with other answers stays as the run wrote it. The manifests
of the file sets are then recomputed from the files as they are.
"""
from __future__ import annotations

import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..data.manifest import finish_set, listed_files
from .reproducibility import (SKIPPED_DIRECTORIES, Difference, Tolerances, _compare_csv, _compare_json,
                              _compare_text_or_number)

TEXT_SUFFIXES = (".md", ".tex", ".toml", ".txt", ".html", ".svg")
MANIFEST_SUFFIX = "_manifest.json"


@dataclass(frozen=True)
class Unchanged:
    """What :func:`keep_unchanged` did: the files put back as they were, those whose answers differ (with their
    first difference), and the files the run wrote that were not there before."""

    kept: tuple[str, ...]
    changed: tuple[Difference, ...]
    new: tuple[str, ...]
    put_back: tuple[str, ...] = ()   # kept files the run had rewritten with other digits

    def line(self, out: Path) -> str:
        if not self.changed:
            back = f" ({len(self.put_back)} rewritten with other last digits and put back)" if self.put_back else ""
            return (f"{out}: the same answers as the results already there (in a checkout, the committed ones): "
                    f"{len(self.kept)} files kept as they were{back}" + (f", {len(self.new)} new" if self.new else ""))
        return (f"{out}: {len(self.changed)} files hold other answers than the results that were there and were "
                f"rewritten (first: {self.changed[0].line()}); {len(self.kept)} files with the same answers kept "
                "as they were")


def _files(root: Path) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*")
                  if p.is_file() and not set(p.relative_to(root).parts[:-1]) & set(SKIPPED_DIRECTORIES))


def snapshot(out: Path) -> Path | None:
    """A copy of the files in ``out`` (not its cache or campaign) in a temporary directory; None when ``out`` holds
    no earlier results."""
    out = Path(out)
    names = _files(out) if out.is_dir() else []
    if not names:
        return None
    # named as every run's temporary folder, so that the next run sweeps it when this one is killed with -9
    aside = Path(tempfile.mkdtemp(prefix=f"structsearch-{os.getpid()}-earlier-results-"))
    for name in names:
        (aside / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(out / name, aside / name)
    return aside


def restore(out: Path, aside: Path) -> None:
    """Put every file of ``aside`` (:func:`snapshot`) back into ``out`` as it was, each written atomically, and
    remove the files it did not hold: an interrupted run leaves the results it found, not half of its own."""
    from ..data.atomic import write_bytes
    earlier = set(_files(aside))
    for name in _files(Path(out)):   # what the interrupted run added (an unfinished manifest, say) goes
        if name not in earlier:
            (Path(out) / name).unlink(missing_ok=True)
    for name in sorted(earlier):
        write_bytes(Path(out) / name, (aside / name).read_bytes())


def differences(name: str, earlier: Path, now: Path, tol: Tolerances = Tolerances()) -> list[Difference]:
    """How ``now`` differs from ``earlier`` in its answers (empty: the same answers)."""
    if earlier.read_bytes() == now.read_bytes():
        return []
    suffix = Path(name).suffix
    if suffix not in (".csv", ".json") + TEXT_SUFFIXES:
        return [Difference(name, "bytes", "earlier", "now", "decision")]
    a, b = earlier.read_text(encoding="utf-8"), now.read_text(encoding="utf-8")
    if suffix == ".csv":
        return _compare_csv(name, a, b, tol)
    if suffix == ".json":
        return _compare_json(name, a, b, tol)
    return _compare_text(name, a, b, tol)


# a wall time in a sentence ("(10.3 s)", "in 4.8 s"): how the run went, not what it found
_SECONDS = re.compile(r"\b\d+(?:\.\d+)? s\b")


def _squeezed(text: str) -> list[str]:
    """A text's lines without a table's padding (a number printed one digit longer widens its column) and with
    wall times masked."""
    return [_SECONDS.sub("# s", re.sub(r"-{3,}", "---", re.sub(r"[ \t]+", " ", line))).strip()
            for line in text.splitlines()]


def _compare_text(name: str, a: str, b: str, tol: Tolerances) -> list[Difference]:
    """Line by line: words equal, numbers within tolerance; the first line that differs is named."""
    lines_a, lines_b = _squeezed(a), _squeezed(b)
    if len(lines_a) != len(lines_b):
        return [Difference(name, "lines", str(len(lines_a)), str(len(lines_b)), "decision")]
    for i, (x, y) in enumerate(zip(lines_a, lines_b)):
        found = _compare_text_or_number(name, f"line {i + 1}", x, y, 0.0, tol)
        if found:
            return [Difference(name, found[0].where, _short(x), _short(y), found[0].kind)]
    return []


def _short(line: str, width: int = 120) -> str:
    return line if len(line) <= width else line[:width - 4] + " ..."


def keep_unchanged(out: Path, aside: Path, tol: Tolerances = Tolerances()) -> Unchanged:
    """Put back from ``aside`` (:func:`snapshot`) every file of ``out`` whose answers are the same; recompute the
    manifests; remove ``aside``."""
    out = Path(out)
    kept, changed, new, put_back = [], [], [], []
    try:
        for name in _files(out):
            if name.endswith(MANIFEST_SUFFIX):
                continue
            if not (aside / name).is_file():
                new.append(name)
                continue
            found = differences(name, aside / name, out / name, tol)
            if found:
                changed.append(found[0])
            else:
                if (aside / name).read_bytes() != (out / name).read_bytes():
                    shutil.copy2(aside / name, out / name)
                    put_back.append(name)
                kept.append(name)
        _refinish_manifests(out)
    finally:
        shutil.rmtree(aside, ignore_errors=True)
    return Unchanged(tuple(kept), tuple(changed), tuple(new), tuple(put_back))


def _refinish_manifests(out: Path) -> None:
    """Each complete manifest in ``out`` recomputed from its files as they now are (the same bytes as before when
    every file was put back)."""
    for path in sorted(out.glob(f"*{MANIFEST_SUFFIX}")):
        name = path.name[:-len(MANIFEST_SUFFIX)]
        listed = listed_files(out, name)
        if listed and all((out / f).is_file() for f in listed):
            finish_set(out, name, [out / f for f in sorted(listed)])
