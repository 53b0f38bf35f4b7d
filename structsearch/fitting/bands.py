"""Uncertainty bands of a fitted candidate's static curve: C_L, C_D or C_m against alpha with the separation
states at their steady values (:mod:`structsearch.engine.bands` does the arithmetic).

The curve is evaluated on a grid over the flown angle-of-attack range of the training maneuvers, under fixed
conditions: q* = 0, delta_e = 0, C_T = 0, alpha_dot = 0 (so that every separation state sits at its steady
value X0(alpha)), every other column the model reads (V, x_cg, mass, ...) at its training mean. Each grid point
is a maneuver of its own whose state starts, and stays, at X0(alpha), so the model's own Jacobian (through the
states, the Golub-Pereyra one's model part) gives the delta method's. A drag or pitch candidate is evaluated
on its lift model's steady states and C_L at the lift model's estimate: its covariance (the two-step one)
carries the lift model's estimation error into its own parameters, the curve's band does not add the lift
model's direct effect on X and C_L (a joint fit shares those parameters and carries it).

The quantile of each point is Student's t with the point's own reference degrees of freedom (its effective
number of maneuvers minus one with a per-maneuver covariance, :func:`structsearch.engine.bands.point_effective_maneuvers`).

The prediction band adds the residual noise variance of the training maneuvers in the alpha band of each
grid point (equal-count bins: the noise is heteroscedastic, larger in the stall); the residual's colour does
not change a single point's variance.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ..data.flightdata import FlightData
from ..engine.bands import (Band, band, output_variance, parameter_draws, point_effective_maneuvers, quantile,
                            sampled_limits)
from ..engine.statistics import covariance_kind
from .candidate_result import CandidateResult
from .candidates import Candidate
from .lift_fit import LiftFit
from .models import build_model, with_lift_prediction

LEVEL = 0.95
GRID_POINTS = 61
NOISE_BINS = 12
# columns a static curve holds at zero: rates, controls and thrust (the "static" in static curve)
ZERO_COLUMNS = ("alpha_dot", "qstar", "q", "de", "CT")
CONDITIONS_TEXT = ("q* = 0, delta_e = 0, C_T = 0, alpha_dot = 0 (separation states at their steady values "
                   "X0(alpha)); every other column the model reads at its training mean; drag and pitch on "
                   "their lift model's steady states and C_L at its estimate")


@dataclass(frozen=True)
class SampledBand:
    """A confidence band by parameter sampling: the outputs of ``draws`` parameter vectors drawn from the
    estimate's normal distribution, and their pointwise equal-tailed interval. It needs no linearisation (the
    separation states are nonlinear in a*, a1, tau), so where it departs from the delta method's band the
    curve is not linear in its parameters over their uncertainty."""

    low: np.ndarray
    high: np.ndarray
    draws: int
    seed: int
    held: tuple[str, ...] = ()     # parameters held at their estimate (their variance cannot be estimated)
    # sampled half width / the delta method's at the normal quantile, per point: 1 where the curve is linear in
    # its parameters over their uncertainty. (The delta band itself uses each point's t quantile: a point resting
    # on few maneuvers is wider by t/z, which sampling from a normal does not know.)
    ratio_to_delta: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict:
        r = self.ratio_to_delta[np.isfinite(self.ratio_to_delta)] if self.ratio_to_delta.size else np.zeros(0)
        return {"confidence_low": self.low.tolist(), "confidence_high": self.high.tolist(), "draws": self.draws,
                "seed": self.seed, "held_at_estimate": list(self.held),
                "half_width_ratio_to_delta_normal": ({"median": float(np.median(r)), "min": float(r.min()),
                                                      "max": float(r.max())} if r.size else None)}


@dataclass(frozen=True)
class StaticBands:
    """A fitted model's static curve with its bands on an alpha grid (rad)."""

    coefficient: str
    alpha: np.ndarray
    band: Band
    held: Mapping[str, float]            # the other columns the model reads, at their training means
    reasons: tuple[str, ...] = ()        # why a band is NaN somewhere (a parameter the data cannot identify)
    noise_bins: tuple[tuple[float, float, float], ...] = field(default=(), repr=False)  # (lo, hi, variance)
    sampled: "SampledBand | None" = None  # the parameter-sampling cross-check of the confidence band

    @property
    def level(self) -> float:
        return self.band.level

    def to_dict(self) -> dict:
        """``fit.json``'s ``bands`` (docs/interfaces.md 6.3 and 6.7) of this one curve."""
        return bands_document([self])


def bands_document(bands: "Sequence[StaticBands]") -> dict:
    """``fit.json``'s ``bands`` for one or several coefficients on the same grid (a joint fit): the level, the
    alpha grid, the conditions, and per coefficient its band with each point's dof and the reasons it is null
    somewhere."""
    held: dict[str, float] = {}
    for b in bands:
        held.update(b.held)
    static = {"alpha": bands[0].alpha.tolist(),
              "conditions": {"text": CONDITIONS_TEXT, **{c: 0.0 for c in ZERO_COLUMNS},
                             "held_at_training_mean": held}}
    for b in bands:
        static[b.coefficient] = {**b.band.to_dict(), "dof": b.band.dof.tolist(), "reasons": list(b.reasons),
                                 **({"sampled": b.sampled.to_dict()} if b.sampled is not None else {})}
    return {"level": bands[0].level, "static": static}


def static_grid(model_columns, train: FlightData, alpha: np.ndarray) -> tuple[FlightData, dict[str, float]]:
    """The grid as FlightData: one two-sample maneuver per alpha (a state starts at, and keeps, X0(alpha))."""
    n = len(alpha)
    cols = {"t": np.tile([0.0, 0.01], n), "alpha": np.repeat(alpha, 2)}
    held = {}
    for c in model_columns:
        if c in cols or c in train.constants:
            continue
        if c in ZERO_COLUMNS:
            cols[c] = np.zeros(2 * n)
        elif c in train:
            held[c] = float(np.mean(train[c]))
            cols[c] = np.full(2 * n, held[c])
    for c in ZERO_COLUMNS:
        cols.setdefault(c, np.zeros(2 * n))
    data = FlightData(cols, np.arange(0, 2 * n, 2), tuple(f"alpha {a:.4f}" for a in alpha), "static grid",
                      dict(train.constants))
    return data, held


def noise_variance(alpha_train: np.ndarray, residual: np.ndarray, alpha: np.ndarray, bins: int = NOISE_BINS):
    """The residual variance in equal-count alpha bins of the training data, at each grid alpha."""
    edges = np.quantile(alpha_train, np.linspace(0.0, 1.0, bins + 1))
    edges[0], edges[-1] = -np.inf, np.inf
    which = np.clip(np.searchsorted(edges, alpha_train, side="right") - 1, 0, bins - 1)
    var = np.array([np.mean(residual[which == b] ** 2) if np.any(which == b) else np.nan for b in range(bins)])
    at = np.clip(np.searchsorted(edges, alpha, side="right") - 1, 0, bins - 1)
    table = tuple((float(edges[b]), float(edges[b + 1]), float(var[b])) for b in range(bins))
    return var[at], table


def static_evaluation(c: Candidate, params: Mapping[str, float], train: FlightData, lift: LiftFit | None = None,
                      points: int = GRID_POINTS, jacobian: bool = True, model=None):
    """The static curve of ``c`` with ``params`` on the alpha grid of ``train``: (alpha, output, Jacobian in the
    model's parameters or None, their names, the columns held at their training mean). ``lift`` gives a drag or
    pitch candidate its lift model's states and C_L (its ``params`` may be another estimate's, the truth's);
    ``model`` replaces ``c``'s own (a joint fit's drag model, whose states are free)."""
    model = model if model is not None else build_model(c, lift)
    alpha = np.linspace(float(np.min(train["alpha"])), float(np.max(train["alpha"])), points)
    columns = set(model.required_columns)
    if c.lift and lift is not None:   # the lift model's C_L on the grid reads its own columns (and replaces CL)
        columns |= set(build_model(lift.candidate).required_columns) | {"CL"}
    grid, held = static_grid(sorted(columns), train, alpha)
    if c.lift and lift is not None:
        grid = with_lift_prediction(grid, lift.params, lift.candidate)
        held.pop("CL", None)   # the lift model's C_L on the grid, not a mean
    names = model.nonlinear_names + model.linear_names
    if not jacobian:
        return alpha, model.predict(grid, params)[::2], None, names, held
    jac, out = model.jacobian(grid, params)
    return alpha, out[::2], jac[::2], names, held


def _training_view(c: Candidate, train: FlightData, lift: LiftFit | None) -> FlightData:
    """The training data as the fit saw it (a drag or pitch candidate: C_L from its lift model)."""
    return with_lift_prediction(train, lift.params, lift.candidate) if c.lift and lift is not None else train


def static_bands(c: Candidate, result: CandidateResult, train: FlightData, lift: LiftFit | None = None,
                 level: float = LEVEL, points: int = GRID_POINTS, samples: int = 0, seed: int = 0) -> StaticBands:
    """The static curve of a fitted candidate with its confidence and prediction bands (module docstring);
    ``samples`` > 0: with the parameter-sampling cross-check."""
    if result.failed or result.estimates is None:
        raise ValueError(f"{c.name}: a failed fit has no bands")
    return curve_bands(c, result.estimates, train, lift, build_model(c, lift), level, points, samples, seed)


def curve_bands(c: Candidate, est, train: FlightData, lift, model, level: float = LEVEL,
                points: int = GRID_POINTS, samples: int = 0, seed: int = 0) -> StaticBands:
    """The bands of ``model``'s static curve with the estimates ``est`` (ParameterEstimates holding at least the
    model's parameters: a single fit's, or a joint fit's whose covariance also spans the shared states).
    ``samples`` > 0 adds the parameter-sampling cross-check of the confidence band (:class:`SampledBand`)."""
    alpha, out, jac, names, held = static_evaluation(c, est.params, train, lift, points, model=model)
    b, reasons, table = _band(c, est, train, lift, model, names, out, jac, alpha, level)
    sampled = None
    if samples:
        sampled = sampled_curve(c, est, train, lift, model, samples, seed, level, points)
        normal_half = np.sqrt(output_variance(jac, est.covariance[np.ix_(*[[est.names.index(n) for n in names]] * 2)])) \
            * quantile(level, np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = 0.5 * (sampled.high - sampled.low) / normal_half
        sampled = replace(sampled, ratio_to_delta=np.where(normal_half > 0, ratio, np.nan))
    return StaticBands(c.coefficient, alpha, b, held, reasons, table, sampled)


def sampled_curve(c: Candidate, est, train: FlightData, lift, model, samples: int, seed: int = 0,
                  level: float = LEVEL, points: int = GRID_POINTS) -> SampledBand:
    """The static curve of ``model`` for ``samples`` parameter vectors drawn from ``est`` (all its parameters,
    jointly), and their pointwise interval."""
    draws = parameter_draws(est.values, est.covariance, samples, seed)
    names = model.nonlinear_names + model.linear_names
    index = [est.names.index(n) for n in names]
    curves = []
    for d in draws:
        with np.errstate(all="ignore"):
            curves.append(static_evaluation(c, dict(zip(names, d[index])), train, lift, points, jacobian=False,
                                            model=model)[1])
    low, high = sampled_limits(np.array(curves), level)
    held = tuple(n for n in names if not np.isfinite(est.covariance[est.names.index(n), est.names.index(n)]))
    return SampledBand(low, high, samples, seed, held)


def trace_bands(c: Candidate, result: CandidateResult, train: FlightData, data: FlightData,
                lift: LiftFit | None = None, level: float = LEVEL) -> Band:
    """Confidence and prediction bands of a fitted candidate's output on ``data`` (a maneuver's time traces, the
    dynamic model with its states as flown): the same delta method, dof and alpha-binned noise as the static
    curve's. The residual's colour does not change one sample's variance: a band is pointwise."""
    est = result.estimates
    model = build_model(c, lift)
    view = _training_view(c, data, lift)
    jac, out = model.jacobian(view, est.params)
    names = model.nonlinear_names + model.linear_names
    return _band(c, est, train, lift, model, names, out, jac, view["alpha"], level)[0]


def _band(c, est, train, lift, model, names, out, jac, alpha, level):
    """The band of ``out`` (Jacobian ``jac`` in ``names``) at the points ``alpha``: covariance, each point's dof
    from the training maneuvers' meats, the training residual's variance in each point's alpha bin."""
    order = [est.names.index(n) for n in names]
    cov = est.covariance[np.ix_(order, order)]
    acting = np.any(jac != 0.0, axis=0)
    seen = _training_view(c, train, lift)
    jac_train, fitted = model.jacobian(seen, est.params)
    residual = seen[c.coefficient] - fitted
    kind = covariance_kind(est.covariance_kind)
    if kind.per_maneuver:
        # each point's own effective maneuvers, on the parameters the covariance could estimate
        ok = np.isfinite(np.diag(cov))
        effective = point_effective_maneuvers(jac_train[:, ok], residual, seen.bounds, est.covariance_kind,
                                              jac[:, ok], est.bandwidth, seen.flights)
        dof = np.array([kind.reference_dof(est.n_samples, est.n_params, g) for g in effective])
    else:
        dof = np.full(len(out), kind.reference_dof(est.n_samples, est.n_params, float(est.n_maneuvers)))
    noise, table = noise_variance(train["alpha"], residual, np.asarray(alpha))
    reasons = tuple(f"{n}: {est.not_identifiable[n]}" for n, a in zip(names, acting)
                    if a and n in est.not_identifiable)
    unknown_dof = int(np.sum(np.isnan(dof)))
    if unknown_dof:
        reasons += (f"{unknown_dof} point(s): no maneuver's share of their variance could be computed, so their "
                    "degrees of freedom (and band) cannot be",)
    return band(out, jac, cov, noise, level, dof), reasons, table
