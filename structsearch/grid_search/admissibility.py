"""Admissibility: the conditions under which a flight-test engineer would accept a candidate's estimates.

A candidate is admissible when its fit converged (a fit that did not reports no statistics to judge), the data
identify every parameter, no nonlinear parameter sits at a bound (within 1e-3 of its box or within its own standard
deviation of the bound: ``ParameterEstimates.at_bound``), every t-test rejects zero (but those of a static curve's break angle
and steepness: :data:`structsearch.engine.static_forms.CURVE_SHAPE_PARAMETERS` says why), no two parameters
correlate
beyond ``max_correlation``, every alpha* lies inside the angle-of-attack range flown, and the
physics is plausible: positive Kirchhoff (K_L) and lift-slope (alpha) terms in a lift model, and,
for a pitch model on a campaign that gives a cg envelope, the centre of pressure of the attached
flow aft of the cg wherever the cg sits in that envelope (a statically stable aircraft). The ranking puts admissible
candidates first and keeps the others with these reasons.

Correlations are judged with every data column centred that can be centred without changing
the model (its span): x_cg in ``C_L`` and ``x_cg/cbar*C_L``, for one. A correlation that moving
a column's datum removes (Marquardt 1980: "non-essential ill-conditioning") says nothing about
what the data can separate; the thesis' C_m,K0 / C_m,cg pair (-1.00 in its Table 16) is one.
"""
from __future__ import annotations

import re
from enum import StrEnum

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import sympy

from ..engine.regressors import parse, symbol_names
from ..engine.separation import SeparationState, vortex_symbols
from ..engine.static_forms import CURVE_SHAPE_PARAMETERS
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate

MAX_CORRELATION = 0.95


@dataclass(frozen=True)
class AdmissibilityRules:
    """The thresholds and what the campaign says about the aircraft."""

    max_correlation: float = MAX_CORRELATION
    alpha_range: tuple[float, float] | None = None   # flown in the training maneuvers [rad]
    cg_range: tuple[float, float] | None = None      # cg envelope [m], the datum of the x_cg column
    cbar: float | None = None                        # [m]


class Reason(StrEnum):
    """The kinds of reasons against admissibility; a reason's message is plain words (ranking.csv,
    diagnosis.json), and :meth:`of` tells its kind from them, so that rules about kinds of reasons (a refinement
    can remove some, some reject a move outright) are written once, here."""

    FIT_FAILED = "fit failed"
    NOT_CONVERGED = "optimizer did not converge"
    NOT_IDENTIFIABLE = "not identifiable"
    AT_BOUND = "at a bound"
    INSIGNIFICANT = "t-test accepts 0"
    CORRELATED = "correlated"
    ALPHA_STAR_OUTSIDE = "alpha* outside the alpha range flown"
    NOT_POSITIVE = "not positive"
    CENTRE_OF_PRESSURE = "centre of pressure not aft of the cg"

    @classmethod
    def of(cls, message: str) -> "Reason | None":
        """The kind of the reason ``message`` as :func:`reasons` words it (None: a reason of another judge, of
        no kind these rules know)."""
        return next((kind for kind, pattern in _REASON_PATTERNS if pattern.search(message)), None)


_REASON_PATTERNS = tuple((kind, re.compile(pattern)) for kind, pattern in (
    (Reason.FIT_FAILED, r"^fit failed"), (Reason.NOT_CONVERGED, r"^optimizer did not converge"),
    (Reason.NOT_IDENTIFIABLE, r"^not identifiable"), (Reason.INSIGNIFICANT, r"^t-test accepts 0"),
    (Reason.CORRELATED, r"^\|rho\("), (Reason.AT_BOUND, r" at its \w+ bound$"),
    (Reason.ALPHA_STAR_OUTSIDE, r" deg outside the alpha range flown"), (Reason.NOT_POSITIVE, r" is not positive$"),
    (Reason.CENTRE_OF_PRESSURE, r"^centre of pressure at ")))
# reasons a move may not add (the data cannot identify the structure, or its fit did not converge)
HARD_REASONS = frozenset({Reason.FIT_FAILED, Reason.NOT_CONVERGED, Reason.NOT_IDENTIFIABLE})
# reasons a refinement may remove: by dropping terms (the constant included), or a separation state the data do
# not place (a parameter at a bound, alpha* outside the range flown) by dropping it or, a time constant at zero,
# by the simpler state it nests (:mod:`.refinement`)
FIXABLE_REASONS = frozenset({Reason.INSIGNIFICANT, Reason.CORRELATED, Reason.AT_BOUND, Reason.ALPHA_STAR_OUTSIDE})


def _fmt(names) -> str:
    return ", ".join(names)


def reasons(result: CandidateResult, candidate: Candidate | None, rules: AdmissibilityRules) -> tuple[str, ...]:
    """Why ``result`` is not admissible (empty when it is)."""
    if result.failed:
        return (f"fit failed: {result.error}",)
    out = []
    e = result.estimates
    if result.optimizer.converged is False or e.withheld:
        out.append(f"optimizer did not converge ({result.optimizer.message}): no standard deviations")
    if e.not_identifiable and not e.withheld:   # withheld: every parameter, for the reason just given
        out.append(f"not identifiable: {_fmt(e.not_identifiable)}")
    for name, side in (e.at_bound or {}).items():
        out.append(f"{name} at its {side} bound")
    unidentified = set(e.not_identifiable or {})
    accepts = [n for n, p in (e.p_values or {}).items()
               if n not in unidentified and not (p < e.significance) and not _is_curve_shape(n)]
    if accepts:
        out.append(f"t-test accepts 0 at {e.significance:.0%}: {_fmt(accepts)}")
    out += _correlation_reasons(result, rules.max_correlation)
    if candidate is not None:
        out += _alpha_star_reasons(result, candidate, rules.alpha_range)
        out += _physics_reasons(result, candidate, rules)
    return tuple(out)


_CURVE_SHAPE = re.compile(rf"^({'|'.join(CURVE_SHAPE_PARAMETERS)})(_\w+)?$")


def _is_curve_shape(name: str) -> bool:
    """Whether ``name`` is where a static curve breaks or how steeply (:data:`CURVE_SHAPE_PARAMETERS`): no
    t-test against zero judges it."""
    return bool(_CURVE_SHAPE.match(name))


def _correlation_reasons(result: CandidateResult, limit: float) -> list[str]:
    names = result.estimates.names
    corr = np.asarray(result.centred_correlation or result.estimates.correlation, float)
    if corr.size == 0:
        return []
    note = " (data columns centred)" if result.centred_correlation else ""
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if np.isfinite(corr[i, j]) and abs(corr[i, j]) > limit:
                out.append(f"|rho({names[i]}, {names[j]})| = {abs(corr[i, j]):.3f} > {limit:g}{note}")
    return out


def _alpha_star_reasons(result: CandidateResult, candidate: Candidate, alpha_range) -> list[str]:
    if alpha_range is None:
        return []
    lo, hi = alpha_range
    out = []
    for state in candidate.separation_states:
        # the angle where its static curve breaks (the first break of two; a spline's first knot may lie before
        # the range flown, its knots reach into it)
        if "a_star" not in state.base_parameters and "a_k1" not in state.base_parameters:
            continue
        p = state.parameter_name("a_star" if "a_star" in state.base_parameters else "a_k1")
        v = (result.estimates.params or {}).get(p)
        if v is not None and not lo <= v <= hi:
            out.append(f"{p} = {np.degrees(v):.1f} deg outside the alpha range flown "
                       f"({np.degrees(lo):.1f} to {np.degrees(hi):.1f} deg)")
    return out


def _expr(text: str) -> sympy.Expr:
    return parse(text, known=())


def _physics_reasons(result: CandidateResult, candidate: Candidate, rules: AdmissibilityRules) -> list[str]:
    params = result.estimates.params or {}
    out = []
    if candidate.coefficient == "CL":
        vortices = vortex_symbols(candidate.states)
        for name, text in candidate.regressors:
            if ("K_L(" in text.replace(" ", "") or text.strip() == "alpha") and not params.get(name, 1.0) > 0:
                what = "Kirchhoff" if "K_L" in text else "lift-slope"
                out.append(f"{what} term {name} = {params[name]:.3g} is not positive")
            elif vortices & set(symbol_names(text)) and not params.get(name, 1.0) > 0:
                # the dynamic-stall vortex adds lift while it lies over the section; a negative one is a state
                # mimicking something else (a collapse the lag misses)
                out.append(f"vortex lift term {name} = {params[name]:.3g} is not positive")
    if candidate.coefficient == "Cm" and rules.cg_range is not None and rules.cbar:
        slope = _pitch_slopes(candidate, params, rules)
        if slope is not None:
            # lift acting at x_cp gives C_m = -(x_cp - x_cg)/cbar * C_L (x aft-positive): the centre of
            # pressure lies aft of a cg at x when dC_m/dC_L < 0 there; the slope is linear in x_cg
            for x, slope_at in zip(rules.cg_range, slope):
                if not slope_at < 0:
                    out.append(f"centre of pressure at {x - rules.cbar * slope_at:.3f} m is not aft of the cg at "
                               f"{x:.3f} m (dCm/dCL = {slope_at:.3g} at attached flow)")
    return out


def _pitch_slopes(candidate: Candidate, params: dict, rules: AdmissibilityRules) -> list[float] | None:
    """dC_m/dC_L at attached flow (every X = 1) with the cg at either end of the envelope, or None when
    the slope depends on more than x_cg and cbar (it cannot be judged from the envelope alone)."""
    attached = frozenset({SeparationState(n, k).symbol for n, k in candidate.states} | {"X", "X_ss", "X_w"})
    total = sympy.Integer(0)
    for name, text in candidate.regressors:
        if name in params:
            total += params[name] * _attached_cl_slope(text, attached, rules.cbar)
    if {sym.name for sym in total.free_symbols} - {"x_cg"}:
        return None
    x_cg = next(iter(total.free_symbols), None)
    return [float(total.subs(x_cg, x)) if x_cg is not None else float(total) for x in rules.cg_range]


@lru_cache(maxsize=1024)
def _attached_cl_slope(text: str, attached: frozenset, cbar: float) -> sympy.Expr:
    """d(regressor)/dC_L with every state in ``attached`` at 1 and cbar at its value (0 without C_L);
    cached: every pitch candidate of a grid repeats the same regressors."""
    expr = _expr(text)
    cl = next((sym for sym in expr.free_symbols if sym.name == "CL"), None)
    if cl is None:
        return sympy.Integer(0)
    slope = sympy.diff(expr, cl)
    fixed = {sym: 1 for sym in slope.free_symbols if sym.name in attached}
    fixed.update({sym: cbar for sym in slope.free_symbols if sym.name == "cbar"})
    return slope.subs(fixed)


# ----- correlations free of the data columns' datums -----------------------------------------------
