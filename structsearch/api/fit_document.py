"""A ``fit.json`` read back (``structsearch export --fit DIR``): every field an export reads, checked for its type.

The file may come from anyone: a parameter that is a string, a covariance that is not a square of numbers or a
structure whose regressor is code would otherwise reach the export as it is (into ``model.json``, unparsed) or end
in a traceback. Each is one :class:`DataError` naming the file and the key (``params.CL0``); the structure's
regressors are parsed again by the expression grammar, never copied.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import numpy as np

from ..data.coefficients import COEFFICIENTS
from ..data.errors import DataError, DeclarationError
from ..data.reading import excerpt, load_json, shown
from ..fitting.candidates import Candidate
from ..fitting.spec_types import ENTRY_TYPES, grid_name_problem


class Fields:
    """Typed access to one JSON document's fields; an error names the file and the key."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, key: str, message: str):
        raise DataError(message, source=str(self.path), column=key)

    def table(self, doc, key: str, where: str = "") -> dict:
        value = doc.get(key) if isinstance(doc, dict) else None
        if not isinstance(value, dict):
            self.fail(where + key, f"must be a table (a JSON object), not {shown(value)}")
        return value

    def string(self, doc, key: str, where: str = "") -> str:
        value = doc.get(key)
        if not isinstance(value, str) or not value:
            self.fail(where + key, f"must be a non-empty string, not {shown(value)}")
        return value

    def number(self, value, key: str) -> float:
        """A number (null: not estimated, NaN)."""
        if value is None:
            return math.nan
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            self.fail(key, f"must be a number, not {shown(value)}")
        return float(value)

    def numbers(self, doc, key: str, where: str = "") -> dict[str, float]:
        return {k: self.number(v, f"{where}{key}.{k}") for k, v in self.table(doc, key, where).items()}

    def optional_numbers(self, doc, key: str, where: str = "") -> dict[str, float | None]:
        if doc.get(key) is None:
            return {}
        return {k: (None if math.isnan(v) else v) for k, v in self.numbers(doc, key, where).items()}

    def covariance(self, doc, where: str = "") -> tuple[tuple[str, ...], np.ndarray | None]:
        """``parameter_covariance``: its names and a square matrix of numbers of their size (absent: none)."""
        cov = doc.get("parameter_covariance")
        if not cov:
            return (), None
        key = where + "parameter_covariance"
        table = self.table(doc, "parameter_covariance", where)
        names = table.get("names")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            self.fail(f"{key}.names", f"must be a list of parameter names, not {shown(names)}")
        rows = table.get("matrix")
        if not isinstance(rows, list) or len(rows) != len(names) or not all(
                isinstance(r, list) and len(r) == len(names) for r in rows):
            self.fail(f"{key}.matrix", f"must be a {len(names)} x {len(names)} list of lists of numbers")
        matrix = np.array([[self.number(v, f"{key}.matrix[{i}][{j}]") for j, v in enumerate(r)]
                           for i, r in enumerate(rows)], float).reshape(len(names), len(names))
        return tuple(names), matrix

    def structure(self, entry, where: str) -> Candidate:
        """A structure as fit.json records it (:meth:`Candidate.to_dict`), its fields typed and its regressors
        parsed (a grammar, never code)."""
        key = where + "structure"
        d = self.table(entry, "structure", where)
        for field in ("name", "coefficient"):
            self.string(d, field, key + ".")
        if d["coefficient"] not in COEFFICIENTS:
            self.fail(f"{key}.coefficient", f"must be one of {', '.join(COEFFICIENTS)}, not {shown(d['coefficient'])}")
        if grid_name_problem(d.get("grid")):
            self.fail(f"{key}.grid", grid_name_problem(d.get("grid")))
        for field in ("regressors", "states", "lift", "note", "bounds", "x0"):
            test, wanted = ENTRY_TYPES.get("states" if field == "x0" else field)
            if field in d and d[field] is not None and not test(d[field]):
                self.fail(f"{key}.{field}", f"must be {wanted}, not {shown(d[field])}")
        for name, box in (d.get("bounds") or {}).items():
            if not (isinstance(box, list) and len(box) == 2):
                self.fail(f"{key}.bounds.{name}", f"must be [lo, hi], not {shown(box)}")
            for v in box:
                self.number(v, f"{key}.bounds.{name}")
        self._expressions(d.get("regressors") or {}, key)
        try:
            return Candidate.from_dict({**d, "regressors": {k: str(v) for k, v in (d.get("regressors") or {}).items()},
                                        "states": d.get("states") or {}, "lift": d.get("lift")})
        except (KeyError, TypeError, ValueError) as exc:
            self.fail(key, f"not a structure: {excerpt(exc)}")

    def _expressions(self, regressors: Mapping, key: str) -> None:
        from ..engine.regressors import parse
        for name, text in regressors.items():
            try:
                parse(str(text), known=())
            except DeclarationError as exc:
                self.fail(f"{key}.regressors.{name}", str(exc))


def read_fit_json(path: Path):
    """The document of a ``fit.json``: a regular UTF-8 JSON file of bounded size and nesting."""
    return load_json(path)
