"""The TOML types of a grid file's keys and of its entries' keys, checked before the grid is expanded.

A grid file comes from anyone: ``regressors = "CL0"`` (a string where a table is due), ``blocks = [1]`` or
``bounds = [0, 1]`` would otherwise reach the expansion as the wrong type and end in a traceback far from the
key. Each is one :class:`DeclarationError` naming the file, the entry and the key.
"""
from __future__ import annotations

import math
from typing import Callable, Mapping

from ..data.errors import DeclarationError
from ..data.reading import shown

# Characters a grid's name may not hold: it names the grid's folder of the cache and its tables' files.
_PATH_CHARACTERS = ("/", "\\", "\0", ":")
MAX_NAME = 100


def _string(v) -> bool:
    return isinstance(v, str)


def grid_name_problem(name) -> str | None:
    """Why ``name`` cannot name a grid (a folder and files are named after it), or None."""
    if not isinstance(name, str) or not name.strip():
        return "a grid's name is a non-empty string"
    if len(name) > MAX_NAME:
        return f"a grid's name has at most {MAX_NAME} characters"
    if name.startswith(".") or any(ch in name for ch in _PATH_CHARACTERS) or not name.isprintable():
        return ("a grid's name names a folder of the cache and files of the tables: it may not start with '.' "
                "nor hold '/', '\\', ':' or a control character")
    return None


def _grid_name(v) -> bool:
    return grid_name_problem(v) is None


def _expression(v) -> bool:   # a quoted expression (a bare finite number reads as one)
    return isinstance(v, str) or (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v))


def _name(v) -> bool:
    return isinstance(v, str) and bool(v.strip())


def _names(v) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


def _table_of(test: Callable) -> Callable:
    return lambda v: isinstance(v, dict) and all(test(x) for x in v.values())


def _table(v) -> bool:
    return isinstance(v, dict)


def _combinations(v) -> bool:
    return isinstance(v, str) or (isinstance(v, list) and all(_names(x) for x in v))


# key -> (test, what the key must be, in words)
GRID_TYPES: Mapping[str, tuple[Callable, str]] = {
    "name": (_grid_name, "a grid's name (a string without '/', '\\' or ':', not starting with '.')"),
    "coefficient": (_string, "a string (CL, CD, Cm, ...)"),
    "prefix": (_string, "a string"),
    "lift": (_string, "the name of a lift candidate"),
    "sets": (_table_of(lambda v: isinstance(v, list) and all(_names(x) for x in v)),
             "a table of sets, each a list of lists of block names"),
    "blocks": (_table_of(_table_of(_expression)),
               "a table of blocks, each a table of regressor names to quoted expressions"),
    "bounds": (_table, "a table of parameter = [lo, hi]"),
}
ENTRY_TYPES: Mapping[str, tuple[Callable, str]] = {
    "name": (_name, "a non-empty string"),
    "lift": (_string, "the name of a lift candidate"),
    "states": (lambda v: _table_of(_string)(v) or (isinstance(v, list) and all(_string(x) for x in v)),
               "a table of state names to kinds, such as { ss = \"S\" }, or (with drive) a list of wing states, "
               "such as [\"X_left\", \"X_right\"]"),
    "drive": (_table_of(_string), "a table of wing states to the angle of attack each reads, such as "
                                  "{ X_left = \"alpha - 0.5*pstar\" }"),
    "note": (_string, "a string"),
    "bounds": (_table, "a table of parameter = [lo, hi]"),
    "from": (_string, "the name of a candidate declared before"),
    "drop": (_names, "a list of regressor names"),
    "kinds": (_table_of(lambda v: _names(v) and bool(v)),
              "a table of state names to lists of kinds, such as { ss = [\"S\", \"Q\"] }"),
    "prefix": (_string, "a string"),
    "blocks": (_names, "a list of block names"),
    "always": (_names, "a list of block names"),
    "combinations": (_combinations, "a list of lists of block names, or the name of a set"),
    "regressors": (_table_of(_expression), "a table of regressor names to quoted expressions, "
                                           "such as { CL0 = \"1\" }"),
}


def check_types(table: dict, types: Mapping[str, tuple[Callable, str]], where: str) -> None:
    """Refuse the first key of ``table`` whose value is not of its type, naming it and what it must be."""
    for key, value in table.items():
        if key in types and not types[key][0](value):
            raise DeclarationError(f"{where}: {key!r} must be {types[key][1]}, not {shown(value)}")
