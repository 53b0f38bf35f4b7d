"""A grid's candidates in the layout of the thesis' search tables (Tables 9, 10 and 20): the separation states'
kinds (S/Q/U), a star per linear regressor a candidate holds, the training MSE of the coefficient and, for lift
and drag, of C_X and C_Z, and the % difference of the training MSE to Van Ingen's structure."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from .comparison import percent_difference


@dataclass(frozen=True)
class ThesisTable:
    grid: str
    coefficient: str
    reference: str
    headers: tuple[str, ...]
    rows: tuple[tuple, ...]

    def to_dict(self) -> dict:
        """The table with each row as a list in the order of ``headers``; NaN where a number is missing."""
        return {"grid": self.grid, "coefficient": self.coefficient, "reference": self.reference,
                "headers": list(self.headers), "rows": [[_plain(x) for x in row] for row in self.rows]}


def thesis_table(grid: str, candidates: Sequence[Candidate], results: Sequence[CandidateResult],
                 reference: CandidateResult | None) -> ThesisTable:
    """One row per candidate in grid order; failed candidates keep their row with their reason."""
    regressors = list(dict.fromkeys(name for c in candidates for name, _ in c.regressors))
    states = list(dict.fromkeys(name for c in candidates for name, _ in c.states))
    coefficient = candidates[0].coefficient
    with_body_axes = coefficient in ("CL", "CD")
    ref_mse = reference.train.mse if reference is not None and not reference.failed else float("nan")
    headers = (["model"] + [f"X_{s}" if s else "X" for s in states] + regressors
               + [f"MSE {coefficient} train"] + (["MSE C_X train", "MSE C_Z train"] if with_body_axes else [])
               + [f"% to {reference.name if reference is not None else 'Van Ingen'}", "note"])
    rows = []
    for c, r in zip(candidates, results):
        kinds = dict(c.states)
        held = {name for name, _ in c.regressors}
        row = [c.name] + [kinds.get(s, "-") for s in states] + ["*" if name in held else "" for name in regressors]
        if r.failed:
            row += [np.nan] + ([np.nan, np.nan] if with_body_axes else []) + [np.nan, r.error]
        else:
            row += [r.train.mse] + ([_or_nan(r.train.mse_cx), _or_nan(r.train.mse_cz)] if with_body_axes else [])
            row += [percent_difference(r.train.mse, ref_mse), ""]
        rows.append(tuple(row))
    return ThesisTable(grid, coefficient, reference.name if reference is not None else "", tuple(headers),
                       tuple(rows))


def _plain(x):
    """A table cell as a JSON value (numpy scalars as Python numbers)."""
    return x.item() if isinstance(x, np.generic) else x


def _or_nan(x) -> float:
    return float("nan") if x is None else float(x)
