"""Which parameters the data cannot identify at a solution, and why.

Two sources of reasons, merged by the fit:

- *domain rules* a problem may supply (``problem.identifiability(theta)``):
  a stall model names the parameters of a separation state that stays saturated
  (X above 0.999 or below 0.001 on every sample) and the coefficients whose
  regressors become collinear with the others once that state is a constant;
- *the Jacobian's rank*: singular values of the column-scaled model Jacobian below
  ``RANK_RTOL`` times the largest span a null space; every parameter with a
  non-negligible loading on it is named, grouped with the parameters it is
  collinear with.

The covariance is then computed on the identifiable parameters plus one member of
each collinear group of regressors (:func:`covariance_basis`), and every named
parameter gets a NaN standard deviation.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy.linalg import qr
from ..data.errors import DeclarationError

# 1/RANK_RTOL bounds the scaled condition number of an identifiable fit. 1e8 ~ 1/sqrt(eps): beyond it
# the normal equations behind every covariance lose all digits. The NIST StRD problems reach 6e4
# (Bennett5) and the default campaign's candidates 1e3, so the limit flags only real singularities.
RANK_RTOL = 1e-8
# A parameter whose unit vector has a component this large in the numerical null space is named.
NULL_LOADING = 0.05
# A separation state above 1 - SATURATION (or below SATURATION) on every sample is saturated.
SATURATION = 1e-3
# A regressor whose column (state held at its saturated value) is this close to the span of the
# others, relative to its norm, is collinear with them.
COLLINEAR_RTOL = 1e-6


def join_names(names: Sequence[str]) -> str:
    names = list(names)
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def rank_reasons(jac: np.ndarray, names: Sequence[str], skip: Sequence[str] = (),
                 factor: np.ndarray | None = None) -> dict[str, str]:
    """Parameters in the numerical null space of the column-scaled Jacobian (``skip``: already named);
    ``factor``: the R of the thin QR of the whole column-scaled Jacobian, when the caller has it."""
    keep = [i for i, n in enumerate(names) if n not in set(skip)]
    if not keep:
        return {}
    # no copy of the m x p Jacobian (and no m x p temporary for the norms) when every column is kept
    sub = jac if len(keep) == jac.shape[1] else jac[:, keep]
    norms = np.sqrt(np.einsum("ij,ij->j", sub, sub))
    out = {}
    zero = norms == 0
    for i in np.flatnonzero(zero | ~np.isfinite(norms)):
        out[names[keep[i]]] = ("the model output does not depend on it at the solution (its Jacobian "
                               "column is zero or not finite)")
    live = np.flatnonzero(~zero & np.isfinite(norms))
    if live.size == 0:
        return out
    # the triangular factor has the Jacobian's singular values and right singular vectors: SVD p x p, not m x p
    if factor is not None and live.size == len(names):
        r = factor   # every column is in: the caller's factor is this one
    else:
        r = qr(sub[:, live] / norms[live], mode="r", check_finite=False)[0][:live.size]
    _, s, vt = np.linalg.svd(r)
    # fewer samples than parameters: the singular values R lacks are zero, their vectors null directions
    s = np.concatenate([s, np.zeros(vt.shape[0] - len(s))])
    null = vt[s < RANK_RTOL * s[0]]
    if null.size == 0:
        return out
    # parameters sharing a null vector are collinear; join the groups of overlapping vectors
    groups: list[set[int]] = []
    for v in null:
        members = set(np.flatnonzero(np.abs(v) > NULL_LOADING * np.abs(v).max()))
        for g in [g for g in groups if g & members]:
            members |= g
            groups.remove(g)
        groups.append(members)
    cond = s[0] / s[-1] if s[-1] > 0 else float("inf")
    for g in groups:
        group = [names[keep[live[i]]] for i in sorted(g)]
        if len(group) == 1:
            reason = (f"its Jacobian column is numerically zero next to the others (scaled condition number "
                      f"{cond:.3g})")
        else:
            reason = (f"{join_names(group)} are collinear: the data determine only a combination of them "
                      f"(scaled condition number {cond:.3g})")
        for name in group:
            out[name] = reason
    return out


def collinear_with(column: np.ndarray, others: np.ndarray) -> np.ndarray | None:
    """Indices of the columns of ``others`` that reproduce ``column`` (None if they do not)."""
    norm = float(np.linalg.norm(column))
    if norm == 0:
        return np.zeros(0, int)
    if others.shape[1] == 0:
        return None
    coef, *_ = np.linalg.lstsq(others, column, rcond=None)
    if np.linalg.norm(column - others @ coef) > COLLINEAR_RTOL * norm:
        return None
    weight = np.abs(coef) * np.sqrt(np.sum(others * others, axis=0))
    return np.flatnonzero(weight > 1e-3 * norm)


def covariance_basis(jac: np.ndarray, names: Sequence[str], reasons: dict, n_nonlinear: int) -> np.ndarray:
    """Columns the covariance is computed on: every identifiable parameter, plus a maximal independent
    subset of the non-identifiable *linear* ones.

    Keeping one member of a collinear group of regressors in the computation means the others'
    statistics are those of the model with the group merged into that member (their marginal
    uncertainty), not conditional on an arbitrary value of the combination; the named members are
    still reported as NaN. Named nonlinear parameters carry no information and are held fixed.
    """
    keep = np.array([n not in reasons for n in names])
    if keep.all():
        return keep
    norms = np.sqrt(np.sum(jac * jac, axis=0))
    norms[norms == 0] = 1.0
    scaled = jac / norms
    q = np.linalg.qr(scaled[:, keep])[0] if keep.any() else np.zeros((len(jac), 0))
    for j in range(n_nonlinear, len(names)):
        if keep[j] or not np.all(np.isfinite(scaled[:, j])):
            continue
        rest = scaled[:, j] - q @ (q.T @ scaled[:, j])
        size = float(np.linalg.norm(rest))
        if size > COLLINEAR_RTOL:
            keep[j] = True
            q = np.column_stack([q, rest / size])
    return keep


def check_parameter_names(name: str, state_parameters, nonlinear_names, fixed, start, bounds) -> None:
    """A declared model's fixed values name its separation parameters, its starts and boxes its nonlinear ones
    (a name it does not have could never be estimated), and every box is increasing."""
    for key in fixed:
        if key not in state_parameters:
            raise DeclarationError(f"model {name!r}: fixed parameter {key!r} is not one of its separation "
                                   f"parameters ({', '.join(state_parameters) or 'none'})")
    for key in list(start) + list(bounds):
        if key not in nonlinear_names:
            raise DeclarationError(f"model {name!r}: {key!r} is not one of its nonlinear parameters "
                                   f"({', '.join(nonlinear_names) or 'none'})")
    for key, (lo, hi) in bounds.items():
        if not lo < hi:
            raise DeclarationError(f"model {name!r}: bounds of {key!r} are not increasing: ({lo}, {hi})")
