"""Sim-to-real gap diagnosis: where the model misses the data, which unmodelled effect causes it,
how far the gap shrinks once the effect is added, and what the effect library cannot explain.

Noise floor. Two estimates, and the floor is the lower of them (and of every model fitted here, so
that every reported shrink lies in [0, 1]):

* the *saturated* model: the baseline with every applicable effect of the library added at once, the
  lowest error the library can reach;
* a *library-free* floor (:mod:`.floor`): a flexible model of the residual as a function of the
  measured signals, fitted on the training maneuvers and judged on the validation maneuvers. A gap
  caused by something the library lacks shows here and not in the saturated model.

The high-frequency estimate (residual power above 3 Hz, with the same density assumed below) is
reported beside them for comparison.

"At the floor": the per-maneuver relative MSE excess over the floor model is on average within one
standard error (or below 1 %). The diagnosis adopts the best effect while it is significant (Wald test,
the options' covariance, 1 %) and closes part of the gap; ``explained`` is true only when the model
after the adopted effects is at the floor. What it leaves is the ``unexplained`` block (:mod:`.unexplained`):
its share of the gap and the signals it follows.

Where the gap lies is :mod:`.where`; the state-level comparison :mod:`.state_level`; the result the typed
:class:`.results.Diagnosis`, whose ``to_dict()`` is ``diagnosis.json``.
"""
from __future__ import annotations

import dataclasses

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import effects as fx
from . import floor as fl
from ..data.campaign import Campaign
from ..data.flightdata import FlightData
from ..data.errors import DataError, DeclarationError
from ..fitting.options import FitOptions
from ..fitting.candidate_fit import fit_lift_model
from ..fitting.candidates import Candidate
from ..fitting.candidate_result import CandidateResult
from ..engine.scores import maneuver_mse, sizes_of, weighted_mean_se
from .fitted import Fitted, fit as _fit, fit_all as _fit_all, state_for_phases
from .results import Diagnosis, EffectRow, Round, StateLevel, TrainValidation
from .state_level import state_level
from .unexplained import unexplained as _unexplained
from .where import overlap as _overlap, where, where_bins

__all__ = ["diagnose", "saturated", "wald_p_value", "within_noise", "where", "spectral_floor", "state_level",
           "Diagnosis"]

SPECTRAL_SPLIT_HZ = 3.0
# A model is at the floor when its per-maneuver relative excess over the floor model is within one standard
# error or below this (the ranking's practical tolerance); the error needs this many maneuvers.
PRACTICAL_TOLERANCE = 0.01
MIN_MANEUVERS = 3


def spectral_floor(residual: np.ndarray, data: FlightData) -> float:
    """Spectral noise estimate: residual power above 3 Hz, and the same density below."""
    total, n = 0.0, 0
    for sl in data.segment_slices():
        r = residual[sl] - residual[sl].mean()
        dt = float(np.median(np.diff(data["t"][sl])))
        spec = np.abs(np.fft.rfft(r)) ** 2 / len(r) ** 2 * 2
        f = np.fft.rfftfreq(len(r), dt)
        high = f >= SPECTRAL_SPLIT_HZ
        density = spec[high].sum() / max(f[-1] - SPECTRAL_SPLIT_HZ, 1e-9)
        total += (spec[high].sum() + density * SPECTRAL_SPLIT_HZ) * len(r)
        n += len(r)
    return total / n


def _mse_se(residual: np.ndarray, data: FlightData) -> tuple[float, float]:
    """Validation MSE over all samples and the standard error of the maneuver-weighted mean MSE."""
    per = maneuver_mse(residual, data.segment_slices())
    return float(np.mean(residual ** 2)), weighted_mean_se(per, sizes_of(data.segment_slices()))[1]


def _relative_excess(residual: np.ndarray, floor_residual: np.ndarray, data: FlightData) -> tuple[float, float]:
    """Mean and standard error of the per-maneuver relative MSE excess over the floor model (paired)."""
    slices = data.segment_slices()
    d = maneuver_mse(residual, slices) / maneuver_mse(floor_residual, slices) - 1.0
    return weighted_mean_se(d, sizes_of(slices))


def saturated(current: Candidate, library) -> tuple[Candidate, dict[str, tuple[str, ...]]]:
    """``current`` with every effect of ``library`` added, and the parameters each effect adds."""
    saturated_c, added = current, {}
    for e in library:
        nxt = e.apply(saturated_c)
        added[e.name] = e.new_parameters(saturated_c, nxt)
        saturated_c = nxt
    return saturated_c, added


def wald_p_value(summary: CandidateResult, names) -> float:
    """p-value of the Wald test that the parameters ``names`` are all zero (NaN if not estimable)."""
    if summary.failed:
        return float("nan")
    # on the covariance the fit kept (engine.estimates.ParameterEstimates.wald_test: F(q, fewest dof))
    return summary.wald_test([n for n in names if n in summary.params]).p_value


def within_noise(residual: np.ndarray, floor_residual: np.ndarray, data: FlightData) -> tuple[bool, float, float]:
    """Whether a model's validation residual is at the floor within its uncertainty: the per-maneuver relative
    MSE excess over the floor model is on average within one standard error of zero or below 1 %. Returns
    (at floor, mean excess, its standard error); the error is NaN with fewer than three maneuvers."""
    mean, se = _relative_excess(residual, floor_residual, data)
    if len(data.names) < MIN_MANEUVERS:
        se = float("nan")
    bar = max(se, PRACTICAL_TOLERANCE) if np.isfinite(se) else PRACTICAL_TOLERANCE
    return bool(mean <= bar), float(mean), float(se)


def _shrink(mse_base: float, mse_after: float, floor: float) -> float | None:
    """Fraction of the gap an effect closes; None when there is no gap to close. The floor is never above
    a fitted model's MSE, so it is at most 1; an effect that makes the validation MSE worse closes 0."""
    gap = mse_base - floor
    if not gap > 0:
        return None
    return float(max((mse_base - mse_after) / gap, 0.0))


@dataclass(frozen=True)
class _Floor:
    """One estimate of the floor: its validation MSE, residual and where it comes from."""

    mse: float
    residual: np.ndarray
    source: str
    library_free: bool = False


def _flexible(fit: Fitted, model: Candidate, lift, train: FlightData, val: FlightData, seed: int):
    """The library-free floor of one model's residual, with the signals and the validation phase state."""
    x_train = state_for_phases(model, fit.summary, lift, train)
    x_val = state_for_phases(model, fit.summary, lift, val)
    sig_train, sig_val = fl.signals(train, x_train), fl.signals(val, x_val)
    flex = fl.flexible_fit(fit.train_residual, train, sig_train, fit.residual, sig_val, seed)
    return flex, sig_train, sig_val, x_val


def _rank_key(r: EffectRow):
    """Significant effects first (Wald test, 1 %; an untestable one counts as not significant), then by shrink."""
    p = r.p_value
    return (not (p is not None and p < 0.01), -(r.shrink or 0.0), p if p is not None else np.inf)


def _effect_rows(candidates, current: Candidate, base_fit: Fitted, floor: _Floor, explained_now: bool,
                 where_rows, val: FlightData, x_val: np.ndarray) -> tuple[list[EffectRow], dict[str, Fitted]]:
    """One round's effects, significant and large first, failed fits last; and the fit of each fitted one."""
    mse_base = float(np.mean(base_fit.residual ** 2))
    rows, fits = [], {}
    for e, changed, f in candidates:
        if isinstance(f, str):
            rows.append(EffectRow(e.name, error=f))
            continue
        p = wald_p_value(f.summary, e.new_parameters(current, changed))
        mse_after = float(np.mean(f.residual ** 2))
        overlap, acts_in = _overlap(where_rows, base_fit.residual, f.residual, val, x_val)
        rows.append(EffectRow(e.name, None if explained_now else _shrink(mse_base, mse_after, floor.mse), mse_after,
                              f.summary.mse_train, p if np.isfinite(p) else None, overlap, acts_in,
                              within_noise(f.residual, floor.residual, val)[0], changed.name))
        fits[e.name] = f
    ok = sorted((r for r in rows if not r.failed), key=_rank_key)
    return ok + [r for r in rows if r.failed], fits


def diagnose(campaign: Campaign, baseline: Candidate, *, options: FitOptions = FitOptions(n_starts=2, cv_folds=0),
             max_rounds: int = 3, progress: Callable[[str], None] | None = None, seed: int = 0,
             states: bool = True, n_jobs: int = 1) -> Diagnosis:
    """Diagnose one coefficient; ``to_dict()`` of the result is the JSON document of docs/interfaces.md sections 3
    and 5.4. The fits of each round's effects run on ``n_jobs`` processes."""
    say = progress or (lambda m: None)
    t0 = time.perf_counter()
    if max_rounds < 1:
        raise DeclarationError(f"a diagnosis needs at least one round, not {max_rounds}")
    # the diagnosis compares fits on the validation maneuvers itself: no cross-validation folds
    options = dataclasses.replace(options, cv_folds=0)
    train, val = campaign.split("train"), campaign.split("validation")
    if baseline.coefficient not in val:
        raise DataError("the campaign has no column for the diagnosed coefficient", source=str(campaign.directory),
                        column=baseline.coefficient)
    if baseline.lift:
        say(f"fitting the lift model {baseline.lift}")
    lift = fit_lift_model(baseline, train, val, options)
    if not fx.applicable(baseline):
        raise DeclarationError(f"no effect of the library applies to {baseline.name} that it does not contain")
    warnings = []
    if len(val.names) < MIN_MANEUVERS:
        warnings.append(f"only {len(val.names)} validation maneuvers: no spread of the per-maneuver excess, so "
                        "'at the floor' uses the 1 % tolerance alone and standard errors are n/a")
    rounds: list[Round] = []
    current = baseline
    base_fit = _fit(current, train, val, lift, options)
    baseline_fit, first_best = base_fit, None
    floors: list[_Floor] = []   # every floor estimate of every round
    flexible = None
    for rnd in range(max_rounds):
        library = fx.applicable(current)
        if not library:
            break
        say(f"round {rnd + 1}: baseline {current.name}, {len(library)} effects; library-free floor of its residual")
        flexible, sig_train, sig_val, x_val = _flexible(base_fit, current, lift, train, val, seed)
        if rnd == 0:
            first_floor = (base_fit, flexible, sig_train, sig_val)
        saturated_c, added = saturated(current, library)
        sat_fit = _fit(saturated_c, train, val, lift, options, start=base_fit.summary.params)
        mse_base, se_base = _mse_se(base_fit.residual, val)
        changed_models = [e.apply(current) for e in library]
        fits = _fit_all(changed_models, train, val, lift, options, base_fit.summary.params, n_jobs)
        candidates = list(zip(library, changed_models, fits))
        # the floor: the lowest validation MSE of the saturated model, the library-free flexible model and
        # every model fitted here, so that no shrink leaves [0, 1]
        here = [_Floor(float(np.mean(sat_fit.residual ** 2)), sat_fit.residual, "saturated library model"),
                _Floor(flexible.mse, flexible.residual, "library-free flexible model of the residual", True),
                _Floor(mse_base, base_fit.residual, current.name)]
        here += [_Floor(float(np.mean(f.residual ** 2)), f.residual, c.name) for _, c, f in candidates
                 if not isinstance(f, str)]
        floors += here
        floor = min(here, key=lambda f: f.mse)
        explained_now, excess, excess_se = within_noise(base_fit.residual, floor.residual, val)
        where_rows = where_bins(base_fit.residual, floor.residual, val, x_val, seed=seed)
        ranked, fitted = _effect_rows(candidates, current, base_fit, floor, explained_now, where_rows, val, x_val)
        best = ranked[0] if ranked and not ranked[0].failed else None
        # the Wald p-value of everything the saturated model adds beyond the baseline
        p_gap = wald_p_value(sat_fit.summary, [p for ps in added.values() for p in ps])
        significant = best is not None and best.p_value is not None and best.p_value < 0.01
        adopt = not (explained_now or not significant or not (best.shrink or 0.0) > 0)
        # noise_floor and gap use the final floor: filled in below, once every round's floors are known
        rounds.append(Round(current.name, TrainValidation(base_fit.summary.mse_train, mse_base), floor.mse,
                            floor.source, spectral_floor(base_fit.residual, val), se_base, where_rows,
                            tuple(ranked), explained_now, excess, excess_se,
                            p_gap if np.isfinite(p_gap) else None, best.name if adopt else None,
                            float("nan"), float("nan")))
        if not adopt:
            break
        if first_best is None:
            first_best = fitted[best.name]
        current, base_fit = fitted[best.name].candidate, fitted[best.name]
    final_fit = base_fit
    if rounds[-1].adopted is not None or flexible is None:  # the final model's own library-free floor
        say("library-free floor of the final model's residual")
        flexible, sig_train, sig_val, x_val = _flexible(final_fit, current, lift, train, val, seed)
        floors.append(_Floor(flexible.mse, flexible.residual, "library-free flexible model of the residual", True))
    floor = min(floors, key=lambda f: f.mse)
    explained, final_excess, final_excess_se = within_noise(final_fit.residual, floor.residual, val)
    rounds = [_with_final_floor(r, floor.mse) for r in rounds]
    if rounds[-1].adopted is None:  # the final model is the last round's baseline: one verdict for both
        rounds[-1] = dataclasses.replace(rounds[-1], explained_before=explained, excess_over_floor=final_excess,
                                         excess_se=final_excess_se)
    library_free = min(f.mse for f in floors if f.library_free)
    block = _unexplained(rounds[0].mse.validation, final_fit, flexible, library_free, val, sig_train, sig_val,
                         x_val, explained, seed, first_floor)
    sl = None
    if states and first_best is not None:
        say("state level: replaying the validation maneuvers before and after")
        try:
            sl = state_level(campaign, baseline_fit, first_best, lift, options)
        except (DeclarationError, DataError) as exc:
            sl = StateLevel(error=str(exc))
    return Diagnosis(baseline.coefficient, baseline.name, floor.mse, floor.source,
                     min(f.mse for f in floors if not f.library_free), explained, final_excess, final_excess_se,
                     tuple(rounds), current.name, float(np.mean(final_fit.residual ** 2)), block, tuple(warnings),
                     sl, time.perf_counter() - t0)


def _with_final_floor(r: Round, floor: float) -> Round:
    """A round with the diagnosis' final floor: one floor for every reported shrink and verdict, the lowest of
    everything fitted."""
    effects = tuple(e if e.failed or e.shrink is None else
                    dataclasses.replace(e, shrink=_shrink(r.mse.validation, e.mse_validation_after, floor))
                    for e in r.effects)
    return dataclasses.replace(r, noise_floor=floor, gap=r.mse.validation - floor, effects=effects)
