"""Stepwise regression over a pool of regressors: forward selection with backward elimination."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..data.errors import DeclarationError


@dataclass(frozen=True)
class StepwiseResult:
    selected: tuple[str, ...]
    history: tuple[tuple[str, str, float, float], ...]  # (action, regressor, F statistic, p-value)


def stepwise(columns: dict[str, np.ndarray], y: np.ndarray, *, forced: Sequence[str] = (),
             alpha_in: float = 0.01, alpha_out: float = 0.05, max_steps: int = 100) -> StepwiseResult:
    """Forward selection with backward elimination by partial F-tests (Klein & Morelli style).

    ``columns`` maps candidate regressor names to sample arrays; ``forced`` ones are
    always kept. A regressor enters when its partial F p-value is below
    ``alpha_in`` and leaves when it rises above ``alpha_out``.
    """
    from scipy import stats
    if alpha_in > alpha_out:
        raise DeclarationError("alpha_in must not exceed alpha_out (the search could cycle)")
    names = list(columns)
    for f in forced:
        if f not in columns:
            raise DeclarationError(f"forced regressor {f!r} is not in the pool")
    selected = list(forced)
    m = len(y)
    history = []

    def rss(cols):
        if not cols:
            return float(y @ y)
        X = np.column_stack([columns[c] for c in cols])
        coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        r = y - X @ coef
        return float(r @ r)

    for _ in range(max_steps):
        changed = False
        base = rss(selected)
        best = None
        for c in names:
            if c in selected:
                continue
            new = rss(selected + [c])
            dof = m - len(selected) - 1
            F = (base - new) / (new / dof) if new > 0 else np.inf
            p = float(stats.f.sf(F, 1, dof))
            if best is None or p < best[2]:
                best = (c, F, p)
        if best is not None and best[2] < alpha_in:
            selected.append(best[0])
            history.append(("add", best[0], float(best[1]), best[2]))
            changed = True
        full = rss(selected)
        dof = m - len(selected)
        worst = None
        for c in selected:
            if c in forced:
                continue
            reduced = rss([s for s in selected if s != c])
            F = (reduced - full) / (full / dof) if full > 0 else np.inf
            p = float(stats.f.sf(F, 1, dof))
            if worst is None or p > worst[2]:
                worst = (c, F, p)
        if worst is not None and worst[2] > alpha_out:
            selected.remove(worst[0])
            history.append(("remove", worst[0], float(worst[1]), worst[2]))
            changed = True
        if not changed:
            break
    return StepwiseResult(tuple(selected), tuple(history))
