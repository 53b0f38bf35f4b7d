"""Model specs: TOML files declaring regressor blocks and candidate grids (``model_specs/``).

A grid file has ``name``, ``coefficient``, ``prefix`` (for numbered names), an
optional default ``lift`` model (drag and pitch candidates take their separation
states, with parameters held fixed, from it), ``[blocks]`` of named regressors,
optional ``[sets]`` of block combinations, and an ordered list of ``[[entry]]``
tables, each one of:

* an explicit candidate: ``name`` plus ``blocks`` and/or ``regressors``;
* a series: ``always`` blocks plus each of ``combinations`` (a list, or the name
  of a set), one candidate per combination, numbered on in Roman numerals;
* a product over separation-state kinds: ``kinds = {ss = ["S", "Q", "U"], ...}``;
* a derived candidate: ``from`` another candidate, ``drop`` some regressors.

Any entry may set ``states`` (name -> kind) and ``bounds`` (parameter -> [lo, hi]).

Unnamed candidates take the next number (prefix + Roman numeral); named ones
whose name is prefix + Roman numeral also advance the count.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .errors import DeclarationError

SPEC_DIR = Path(__file__).resolve().parent.parent / "model_specs"
BUILTIN_GRIDS = ("separation", "lift", "drag", "pitch")


@dataclass(frozen=True)
class Candidate:
    """One model structure of a grid."""

    name: str
    grid: str
    coefficient: str
    regressors: tuple[tuple[str, str], ...]
    states: tuple[tuple[str, str], ...] = ()
    lift: str | None = None
    note: str = ""
    bounds: tuple[tuple[str, tuple[float, float]], ...] = ()

    @property
    def n_linear(self) -> int:
        return len(self.regressors)

    def to_dict(self) -> dict:
        return {"name": self.name, "grid": self.grid, "coefficient": self.coefficient,
                "regressors": dict(self.regressors), "states": dict(self.states), "lift": self.lift,
                "note": self.note, "bounds": {k: list(v) for k, v in self.bounds}}


@dataclass(frozen=True)
class Grid:
    name: str
    coefficient: str
    candidates: tuple[Candidate, ...]
    source: str = ""
    lift_grid: "Grid | None" = field(default=None, repr=False)

    def __getitem__(self, name: str) -> Candidate:
        for c in self.candidates:
            if c.name == name:
                return c
        raise DeclarationError(f"grid {self.name!r} has no candidate {name!r}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.candidates)


_ROMAN = [(1000, "M"), (900, "CM"), (500, "D"), (400, "CD"), (100, "C"), (90, "XC"), (50, "L"),
          (40, "XL"), (10, "X"), (9, "IX"), (5, "V"), (4, "IV"), (1, "I")]


def roman(n: int) -> str:
    out = ""
    for value, letters in _ROMAN:
        while n >= value:
            out += letters
            n -= value
    return out


def from_roman(text: str) -> int | None:
    values = {"I": 1, "V": 5, "X": 10, "L": 50, "C": 100, "D": 500, "M": 1000}
    if not text or any(ch not in values for ch in text):
        return None
    total = 0
    for a, b in zip(text, text[1:] + " "):
        v = values[a]
        total += -v if b != " " and values.get(b, 0) > v else v
    return total if roman(total) == text else None


def read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DeclarationError(f"model spec file {path} not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise DeclarationError(f"{path}: not valid TOML: {exc}") from None


def grid_path(name_or_path: str) -> Path:
    if name_or_path in BUILTIN_GRIDS:
        return SPEC_DIR / f"{name_or_path}.toml"
    return Path(name_or_path)


def load_grid(name_or_path: str, lift_grid: Grid | None = None) -> Grid:
    """Load and expand a grid; drag and pitch grids resolve their lift models in ``lift_grid``."""
    from .enumeration import expand
    path = grid_path(name_or_path)
    doc = read_toml(path)
    grid = expand(doc, str(path))
    if any(c.lift for c in grid.candidates):
        if lift_grid is None:
            lift_grid = load_grid("lift") if grid.name != "lift" else grid
        grid = Grid(grid.name, grid.coefficient, tuple(_with_lift_states(c, lift_grid) for c in grid.candidates),
                    grid.source, lift_grid)
    return grid


def _with_lift_states(c: Candidate, lift_grid: Grid) -> Candidate:
    if not c.lift:
        return c
    lift = lift_grid[c.lift]
    return Candidate(c.name, c.grid, c.coefficient, c.regressors, lift.states, c.lift, c.note, lift.bounds)


def find_candidate(name: str) -> Candidate:
    """A candidate of the shipped grids by name (``CL-VI``, ``CD-IXr``, ``Cm-XXXIII``, ``U/S``)."""
    lift = load_grid("lift")
    for grid_name in BUILTIN_GRIDS:
        grid = lift if grid_name == "lift" else load_grid(grid_name, lift)
        for c in grid.candidates:
            if c.name == name or c.name.split(" ")[-1] == name:
                return c
    raise DeclarationError(f"no candidate named {name!r} in the shipped grids ({', '.join(BUILTIN_GRIDS)})")


def resolve_candidate(name_or_path: str, coefficient: str | None = None) -> Candidate:
    """A candidate by catalogue name, or the single candidate of a model spec file."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        grid = load_grid(str(path))
        if len(grid.candidates) != 1:
            raise DeclarationError(f"{path}: a model spec file must declare exactly one candidate (it declares "
                                   f"{len(grid.candidates)}; use it as a grid with 'search --grid')")
        c = grid.candidates[0]
    else:
        c = find_candidate(name_or_path)
    if coefficient is not None and c.coefficient != coefficient:
        raise DeclarationError(f"{c.name} models {c.coefficient}, not {coefficient}")
    return c
