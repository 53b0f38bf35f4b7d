"""Model specs: TOML files declaring regressor blocks and candidate grids (``model_specs/``).

A grid file has ``name``, ``coefficient``, ``prefix`` (for numbered names), an
optional default ``lift`` model (drag and pitch candidates take their separation
states, with parameters held fixed, from it), ``[blocks]`` of named regressors,
optional ``[sets]`` of block combinations, and an ordered list of ``[[entry]]``
tables, each one of:

* an explicit candidate: ``name`` plus ``blocks`` and/or ``regressors``;
* a series: ``always`` blocks plus each of ``combinations`` (a list, or the name
  of a set), one candidate per combination, numbered on in Roman numerals;
* a product over separation-state kinds: ``kinds = {ss = ["S", "Q", "U"], ...}``, named by the
  entry's own ``prefix`` (else the grid's) and the kinds joined by "/";
* a derived candidate: ``from`` another candidate, ``drop`` some regressors.

Any entry may set ``states`` (name -> kind), ``x0`` (state name -> static separation form: "tanh", the
default, "goman", "two_break" or "spline:K"; :mod:`structsearch.engine.static_forms`) and ``bounds``
(parameter -> [lo, hi]).

Unnamed candidates take the next number (prefix + Roman numeral); named ones
whose name is prefix + Roman numeral also advance the count.
"""
from __future__ import annotations

import dataclasses
import difflib
import os
from importlib import resources
from pathlib import Path
from types import MappingProxyType

from ..data.coefficients import COEFFICIENT_OF_GRID, LONGITUDINAL
from ..data.errors import DeclarationError
from ..data.reading import load_toml
from .candidates import Candidate, Grid
from .enumeration import expand

# Shipped inside the package (a link to the top-level model_specs/ in a checkout).
SPEC_DIR = resources.files("structsearch") / "model_specs"
BUILTIN_GRIDS = ("separation", "lift", "drag", "pitch", "side", "roll", "yaw")
# The global models (one grid per coefficient in one file, model_specs/global.toml): found by name like the
# candidates of the grids above, but no grid of ``search`` (they read the air-data columns Mach and qbar)
GLOBAL_SPEC = "global"
GLOBAL_TABLES = MappingProxyType({g: c for g, c in COEFFICIENT_OF_GRID.items() if c in LONGITUDINAL})


def suggestion(name: str, known) -> str:
    """" (did you mean 'lift'?)" for a close match among ``known`` (case ignored; of names alike but for their
    case, CL-VI and Cl-VI, the one spelt as ``name`` is), else ""."""
    by_lower: dict[str, list[str]] = {}
    for k in known:
        by_lower.setdefault(k.lower(), []).append(k)
    close = difflib.get_close_matches(name.lower(), list(by_lower), n=1, cutoff=0.6)
    if not close:
        return ""
    alike = by_lower[close[0]]
    best = max(alike, key=lambda k: difflib.SequenceMatcher(None, name, k).ratio())
    return f" (did you mean {best!r}?)"


def declaration_error(source: str, message: str) -> DeclarationError:
    return DeclarationError(f"{source}: {message}")


def read_toml(path) -> dict:
    """A spec or term file: a regular UTF-8 file of bounded size and nesting (:mod:`structsearch.data.reading`)."""
    if not os.path.lexists(str(path)):
        hint = suggestion(str(path), BUILTIN_GRIDS) if Path(str(path)).suffix == "" else ""
        raise DeclarationError(f"model spec file {path} not found"
                               + (hint + ": a shipped grid is named without a path" if hint else ""))
    return load_toml(path, declaration_error)


def grid_path(name_or_path: str):
    if name_or_path in BUILTIN_GRIDS:
        return SPEC_DIR / f"{name_or_path}.toml"
    return Path(name_or_path)


def load_grid(name_or_path: str, lift_grid: Grid | None = None) -> Grid:
    """Load and expand a grid; drag and pitch grids resolve their lift models in ``lift_grid``."""
    path = grid_path(name_or_path)
    doc = read_toml(path)
    grid = expand(doc, str(path))
    if any(c.lift for c in grid.candidates):
        if lift_grid is None:
            lift_grid = load_grid("lift") if grid.name != "lift" else grid
        try:
            lifted = tuple(_with_lift_states(c, lift_grid) for c in grid.candidates)
        except DeclarationError as exc:   # a lift model the lift grid lacks: named with the file that reads it
            raise DeclarationError(f"{path}: {exc}") from None
        grid = Grid(grid.name, grid.coefficient, lifted, grid.source, lift_grid)
    return grid


def load_global_grids() -> dict[str, Grid]:
    """The global models' grids of model_specs/global.toml by coefficient; drag and pitch read the global lift."""
    path = SPEC_DIR / f"{GLOBAL_SPEC}.toml"
    doc = read_toml(path)
    missing = [t for t in GLOBAL_TABLES if not isinstance(doc.get(t), dict)]
    if missing:
        raise DeclarationError(f"{path}: missing the table [{missing[0]}]")
    lift = expand(doc["lift"], f"{path} [lift]")
    grids = {"CL": lift}
    for table in ("drag", "pitch"):
        grid = expand(doc[table], f"{path} [{table}]")
        grids[GLOBAL_TABLES[table]] = Grid(grid.name, grid.coefficient,
                                           tuple(_with_lift_states(c, lift) for c in grid.candidates), grid.source,
                                           lift)
    return grids


def lift_candidate(name: str) -> Candidate:
    """The lift candidate ``name`` a drag or pitch candidate reads: of the shipped lift grid, else a global one."""
    lift = load_grid("lift")
    if name in lift.names:
        return lift[name]
    return load_global_grids()["CL"][name]


def _with_lift_states(c: Candidate, lift_grid: Grid) -> Candidate:
    if not c.lift:
        return c
    lift = lift_grid[c.lift]
    return dataclasses.replace(c, states=lift.states, bounds=lift.bounds, forms=lift.forms)


def find_candidate(name: str) -> Candidate:
    """A candidate of the shipped grids by name (``CL-VI``, ``CD-IXr``, ``Cm-XXXIII``, ``U/S``)."""
    lift = load_grid("lift")
    known = []
    for grid_name in BUILTIN_GRIDS:
        grid = lift if grid_name == "lift" else load_grid(grid_name, lift)
        for c in grid.candidates:
            if c.name == name or c.name.split(" ")[-1] == name:
                return c
            known.append(c.name.split(" ")[-1])
    for grid in load_global_grids().values():
        for c in grid.candidates:
            if c.name == name:
                return c
            known.append(c.name)
    raise DeclarationError(f"no candidate named {name!r} in the shipped grids ({', '.join(BUILTIN_GRIDS)})"
                           + suggestion(name, known))


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
