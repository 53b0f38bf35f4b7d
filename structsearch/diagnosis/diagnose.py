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

from ..discovery import effects as fx
from . import floor as fl
from ..data.coefficients import COEFFICIENTS
from ..data.flightdata import FlightData
from ..data.errors import DataError, DeclarationError
from ..discovery.adoption import TEST_NAME
from ..discovery.explore import Status, explore
from ..discovery.final_choice import stopped_text
from ..discovery.moves import structure_key
from ..discovery.search_setting import DIAGNOSE, SearchSetting
from ..discovery.search_start import start_search
from ..fitting.comparison import MIN_MANEUVERS, relative_excess, within_noise as one_se_rule
from ..fitting.candidates import Candidate
from ..fitting.candidate_result import CandidateResult
from ..fitting.fitter import Fitter
from ..fitting.models import predict_candidate
from ..engine.scores import maneuver_mse, sizes_of, weighted_mean_se
from ..engine.ties import first_of_lowest, sort_by
from .fitted import Fitted, fit as _fit, state_for_phases
from .equivalence import equivalences
from .results import Diagnosis, EffectRow, Round, StateLevel, TrainValidation
from .state_level import state_level
from .unexplained import unexplained as _unexplained
from .where import overlap as _overlap, where, where_bins

__all__ = ["DIAGNOSE", "SearchSetting", "diagnose", "diagnose_search", "saturated", "wald_p_value", "within_noise", "where", "spectral_floor", "state_level",
           "Diagnosis"]

SPECTRAL_SPLIT_HZ = 3.0
# A model is at the floor when its per-maneuver relative excess over the floor model is within one standard
# error or below this (the ranking's practical tolerance); the error needs this many maneuvers.


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
    """Mean and standard error of the per-maneuver relative MSE excess over the floor model (paired; the
    ranking's statistic, :func:`structsearch.fitting.comparison.relative_excess`)."""
    slices = data.segment_slices()
    return relative_excess(maneuver_mse(residual, slices), maneuver_mse(floor_residual, slices), sizes_of(slices))


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
    return summary.wald_test([n for n in names if n in summary.estimates.params]).p_value


def within_noise(residual: np.ndarray, floor_residual: np.ndarray, data: FlightData) -> tuple[bool, float, float]:
    """Whether a model's validation residual is at the floor within its uncertainty: the per-maneuver relative
    MSE excess over the floor model is on average within one standard error of zero or below 1 %. Returns
    (at floor, mean excess, its standard error); the error is NaN with fewer than three maneuvers."""
    mean, se = _relative_excess(residual, floor_residual, data)
    return one_se_rule(mean, se), float(mean), float(se)


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
    residual: np.ndarray | None    # None: a structure of the search, whose residual is computed when needed
    source: str
    library_free: bool = False
    node: object = None


def _flexible(fit: Fitted, model: Candidate, lift, train: FlightData, val: FlightData, seed: int):
    """The library-free floor of one model's residual, with the signals and the validation phase state."""
    x_train = state_for_phases(model, fit.summary, lift, train)
    x_val = state_for_phases(model, fit.summary, lift, val)
    sig_train, sig_val = fl.signals(train, x_train), fl.signals(val, x_val)
    flex = fl.flexible_fit(fit.train_residual, train, sig_train, fit.residual, sig_val, seed)
    return flex, sig_train, sig_val, x_val


VERDICT_ORDER = (Status.IMPROVES, Status.SIMPLIFIES, Status.REPAIRS, Status.LOOK_AHEAD, Status.REJECTED, Status.FAILED)


def _row_key(n):
    """Adopted and passing moves first, then by the held-out MSE; failed fits last."""
    return (VERDICT_ORDER.index(n.status) if n.status in VERDICT_ORDER else len(VERDICT_ORDER), n.mse)


@dataclass
class _Context:
    """What every round of one diagnosis shares."""

    train: FlightData
    val: FlightData
    lifts: dict
    seed: int

    def lift_of(self, c: Candidate):
        return self.lifts.get(c.lift) if c.lift else None

    def fitted(self, node) -> Fitted:
        """A node of the structure search as a :class:`Fitted` (its residuals on both splits)."""
        c, r = node.candidate, node.result
        lift = self.lift_of(c)
        return Fitted(c, r, self.val[c.coefficient] - predict_candidate(c, r.estimates.params, self.val, lift),
                      self.train[c.coefficient] - predict_candidate(c, r.estimates.params, self.train, lift))


def _row(child, base: Fitted, floor: _Floor, explained_now: bool, where_rows, ctx: _Context, x_val) -> EffectRow:
    """One move tried from a round's structure: its shrink of the gap, test and (fitted in full) where it acts."""
    move = child.move
    extra = dict(kind=move.kind, effect=move.effect, verdict=child.status,
                 test=child.test.to_dict() if child.test is not None else None)
    if child.result.failed:
        return EffectRow(move.name, error=child.result.error, **extra)
    mse_base = float(np.mean(base.residual ** 2))
    mse_after = child.result.validation.mse
    shrink = None if explained_now else _shrink(mse_base, mse_after, floor.mse)
    p = overlap = acts_in = at_floor = None
    if not child.screened:   # statistics and residuals of the structures fitted in full
        p = wald_p_value(child.result, move.new_parameters) if move.new_parameters else float("nan")
        after = ctx.fitted(child)
        overlap, acts_in = _overlap(where_rows, base.residual, after.residual, ctx.val, x_val)
        at_floor = within_noise(after.residual, floor.residual, ctx.val)[0]
    return EffectRow(move.name, None if shrink is None else min(shrink, 1.0), mse_after, child.result.mse_train,
                     p if p is not None and np.isfinite(p) else None, overlap, acts_in, at_floor,
                     child.candidate.name, **extra)


def diagnose(fitter: Fitter, baseline: Candidate, setting: SearchSetting = DIAGNOSE, **inputs) -> Diagnosis:
    """Diagnose one coefficient (:func:`diagnose_search`, its diagnosis alone)."""
    return diagnose_search(fitter, baseline, setting, **inputs)[0]


def diagnose_search(fitter: Fitter, baseline: Candidate, setting: SearchSetting = DIAGNOSE, *, seed: int = 0,
                    terms: str | None = None, simulator_terms=()):
    """Diagnose one coefficient, and the structure search it ran: a search over moves
    (:mod:`structsearch.discovery`) from ``baseline`` until no move passes the adoption test; each adopted move
    is a round, and the final structure is judged against the floor. ``setting`` is what the search does
    (:class:`~structsearch.discovery.search_setting.SearchSetting`: :data:`DIAGNOSE`, or ``discover``'s
    :data:`~structsearch.discovery.search_setting.DISCOVER`). ``to_dict()`` of the result is the JSON document
    of docs/interfaces.md sections 3 and 5.4. ``fitter``'s lift models are lift models a drag or pitch structure
    may be fed besides its own (the story: the lift structure found for C_L); ``terms`` a user's term file;
    ``simulator_terms`` the terms of a simulator baseline (:class:`~structsearch.discovery.terms.SimulatorTerm`:
    a grey box whose terms the moves rescale, drop or replace)."""
    t0 = time.perf_counter()
    start = start_search(fitter, baseline, terms, setting.kinds, simulator_terms)
    fitter = start.fitter
    train, val = fitter.splits()
    ctx = _Context(train, val, dict(fitter.lifts), seed)
    warnings = []
    if len(val.names) < MIN_MANEUVERS:
        warnings.append(f"only {len(val.names)} validation maneuvers: no spread of the per-maneuver excess, so "
                        "'at the floor' uses the 1 % tolerance alone and standard errors are n/a")
    if start.reasons:
        warnings.append(f"the baseline {baseline.name} as fitted here is not admissible: " + "; ".join(start.reasons))
    base_fit = Fitted(baseline, start.result, *_residuals(ctx, baseline, start.result))
    first = _first_floors(fitter, base_fit, ctx, warnings)
    # the floor is no stopping rule: an estimate of it from the baseline's residual can lie above what a better
    # structure reaches (pitch on Van Ingen's single state: the flexible model lacks the lift model's two states),
    # and the search would stop early; it stops when no move passes, and the verdict is taken at the end
    fitter.say(f"structure search from {baseline.name}: {len(start.library.terms)} term templates, "
               f"beam {setting.beam}")
    ex = explore(baseline, fitter, start.library, beam=setting.beam, alpha=setting.alpha,
                 max_steps=setting.max_rounds, judge=start.judge, kinds=setting.kinds, simplify=setting.simplify,
                 at_floor=_own_floor_gate(ctx))
    path = ex.final.path()
    fits = [base_fit] + [ctx.fitted(n) for n in path[1:]]
    floors, flexible, x_val_final = _final_floors(first, path, fits[-1], ctx, fitter.say)
    floor = _lowest(floors, ctx)
    rounds = _rounds(path, fits, ex, floor, ctx, first.p_gap)
    final_fit = fits[-1]
    explained, final_excess, final_excess_se = within_noise(final_fit.residual, floor.residual, val)
    library_free = min(f.mse for f in floors if f.library_free)
    block = _unexplained(rounds[0].mse.validation, final_fit, flexible[0], library_free, val, flexible[1],
                         flexible[2], x_val_final, explained, seed, first.base)
    # the state-level replay flies the longitudinal simulator: a lateral structure has no place in it
    replay = setting.state_level and len(fits) > 1 and not COEFFICIENTS[baseline.coefficient].lateral
    sl = _state_level(fitter, fits, ctx) if replay else None
    # the stop reason is worded now that the floor is known: "at the floor" only where the final structure is
    ex = dataclasses.replace(ex, stopped=stopped_text(ex.stop, explained, " and ".join(ex.stopped_at),
                                                       setting.max_rounds))
    search_doc = {"stopped": ex.stopped, "structures_fitted": ex.n_fitted, "steps": len(ex.steps),
                  "beam": setting.beam, "alpha": setting.alpha, "test": TEST_NAME, "terms": start.library.to_dict(),
                  "lift_models": sorted(ctx.lifts), "final_rule": ex.final_rule,
                  "set_aside": [a.to_dict() for a in ex.set_aside]}
    return Diagnosis(coefficient=baseline.coefficient, baseline=baseline.name, noise_floor=floor.mse,
                     floor_source=floor.source,
                     noise_floor_library=min(f.mse for f in floors if not f.library_free), explained=explained,
                     final_excess_over_floor=final_excess, final_excess_se=final_excess_se, rounds=tuple(rounds),
                     final_model=final_fit.candidate.name, final_mse=float(np.mean(final_fit.residual ** 2)),
                     unexplained=block, warnings=tuple(warnings), state_level=sl, seconds=time.perf_counter() - t0,
                     final_structure=final_fit.candidate.to_dict(), search=search_doc, baseline_reasons=start.reasons,
                     equivalences=_equivalences(baseline, path[-1], ctx)), ex


def _equivalences(baseline: Candidate, node, ctx: _Context):
    """What the terms the search added are also the signature of, read on the training maneuvers (the samples
    the coefficients were fitted to)."""
    if node.result.failed or node.candidate is baseline:
        return ()
    return equivalences(baseline, node.candidate, node.result.estimates.params, ctx.train,
                        ctx.lift_of(node.candidate))


@dataclass(frozen=True)
class _FirstFloors:
    """The floor estimates before the search: the baseline's library-free floor (with its signals, what the
    unexplained block compares with), the baseline itself and the saturated library model."""

    floors: tuple[_Floor, ...]
    base: tuple                 # (baseline fit, flexible fit, training signals, validation signals)
    x_val: np.ndarray           # the baseline's validation phase state
    p_gap: float | None         # the Wald test of the saturated model's added parameters


def _first_floors(fitter: Fitter, base_fit: Fitted, ctx: _Context, warnings: list[str]) -> _FirstFloors:
    baseline = base_fit.candidate
    lift = ctx.lift_of(baseline)
    fitter.say(f"library-free floor of {baseline.name}'s residual; the saturated library model")
    flexible, sig_train, sig_val, x_val = _flexible(base_fit, baseline, lift, ctx.train, ctx.val, ctx.seed)
    floors = [_Floor(flexible.mse, flexible.residual, "library-free flexible model of the residual", True),
              _Floor(float(np.mean(base_fit.residual ** 2)), base_fit.residual, baseline.name)]
    p_gap = None
    if fx.applicable(baseline):
        saturated_c, added = saturated(baseline, fx.applicable(baseline))
        try:
            sat_fit = _fit(saturated_c, ctx.train, ctx.val, lift, fitter.options, start=base_fit.summary.estimates.params)
            floors.append(_Floor(float(np.mean(sat_fit.residual ** 2)), sat_fit.residual, "saturated library model"))
            p = wald_p_value(sat_fit.summary, [q for ps in added.values() for q in ps])
            p_gap = p if np.isfinite(p) else None
        except DeclarationError as exc:
            warnings.append(f"the saturated library model could not be fitted: {exc}")
    return _FirstFloors(tuple(floors), (base_fit, flexible, sig_train, sig_val), x_val, p_gap)


def _own_floor_gate(ctx: _Context) -> Callable:
    """Whether a structure's own residual is at its library-free floor. It gates the look-ahead: from a structure
    whose own residual a library-free model cannot improve out of sample, no pair of moves can pay, and the
    look-ahead (the most expensive step) is not taken."""
    own_floor: dict[str, bool] = {}

    def at_own_floor(node) -> bool:
        key = structure_key(node.candidate)
        if key not in own_floor:
            fit_n = ctx.fitted(node)
            flex = _flexible(fit_n, node.candidate, ctx.lift_of(node.candidate), ctx.train, ctx.val, ctx.seed)[0]
            own_floor[key] = within_noise(fit_n.residual, flex.residual, ctx.val)[0]
        return own_floor[key]
    return at_own_floor


def _final_floors(first: _FirstFloors, path, final_fit: Fitted, ctx: _Context, say):
    """Every floor estimate, the structure reached and its library-free floor among them (the many structures a
    search tries and leaves are not: the lowest validation MSE of dozens of structures is biased low by the choice
    itself, and would call a true model unexplained; a move's shrink is capped at 1 instead); the last flexible
    fit with its signals, and the final model's validation phase state."""
    floors = list(first.floors)
    _, flexible, sig_train, sig_val = first.base
    x_val_final = first.x_val
    if len(path) > 1:
        floors.append(_Floor(path[-1].result.validation.mse, None, path[-1].candidate.name, node=path[-1]))
        say("library-free floor of the final model's residual")
        flexible, sig_train, sig_val, x_val_final = _flexible(final_fit, final_fit.candidate, ctx.lift_of(
            final_fit.candidate), ctx.train, ctx.val, ctx.seed)
        floors.append(_Floor(flexible.mse, flexible.residual, "library-free flexible model of the residual", True))
    return floors, (flexible, sig_train, sig_val), x_val_final


def _rounds(path, fits, ex, floor: _Floor, ctx: _Context, p_gap_first) -> list[Round]:
    """One round per structure of the path: its gap to the floor, where it lies and every move tried from it."""
    rounds = []
    val = ctx.val
    for i, (node, fit_i) in enumerate(zip(path, fits)):
        x_i = state_for_phases(node.candidate, node.result, ctx.lift_of(node.candidate), val)
        explained_now, excess, excess_se = within_noise(fit_i.residual, floor.residual, val)
        where_rows = where_bins(fit_i.residual, floor.residual, val, x_i, seed=ctx.seed)
        # the adopted move first (the one the round's verdict is about), then the others by verdict and MSE
        adopted_node = path[i + 1] if i + 1 < len(path) else None
        children = sort_by(ex.tried_from(node), lambda c: c.mse, lambda c: c.candidate.name,
                           lambda c: (c is not adopted_node, *_row_key(c)[:1]))
        rows = tuple(_row(c, fit_i, floor, explained_now, where_rows, ctx, x_i) for c in children)
        mse_i, se_i = _mse_se(fit_i.residual, val)
        adopted = path[i + 1].move.name if i + 1 < len(path) else None
        rounds.append(Round(node.candidate.name, TrainValidation(node.result.mse_train, mse_i), floor.mse,
                            floor.source, spectral_floor(fit_i.residual, val), se_i, where_rows, rows, explained_now,
                            excess, excess_se, p_gap_first if i == 0 else None, adopted, floor.mse,
                            mse_i - floor.mse))
    return rounds


def _state_level(fitter: Fitter, fits, ctx: _Context) -> StateLevel:
    """The validation maneuvers replayed before and after the first adopted move."""
    fitter.say("state level: replaying the validation maneuvers before and after")
    base_fit = fits[0]
    lift = ctx.lift_of(base_fit.candidate)
    try:
        return state_level(fitter.campaign, base_fit, fits[1], lift, fitter.options,
                           lift_after=ctx.lift_of(fits[1].candidate) or lift)
    except (DeclarationError, DataError) as exc:
        return StateLevel(error=str(exc))


def _residuals(ctx: _Context, c: Candidate, r) -> tuple[np.ndarray, np.ndarray]:
    lift = ctx.lift_of(c)
    return (ctx.val[c.coefficient] - predict_candidate(c, r.estimates.params, ctx.val, lift),
            ctx.train[c.coefficient] - predict_candidate(c, r.estimates.params, ctx.train, lift))


def _lowest(floors: list[_Floor], ctx: _Context) -> _Floor:
    """The lowest floor estimate, with its validation residual (that of a structure of the search computed now)."""
    # a flexible correction that changes nothing (no boosting iteration generalises) equals its structure's MSE
    # up to rounding: the structure, a named model, is the floor on every machine
    floor = first_of_lowest(sorted(floors, key=lambda f: f.library_free), lambda f: f.mse)
    if floor.residual is None:
        floor = dataclasses.replace(floor, residual=_residuals(ctx, floor.node.candidate, floor.node.result)[0])
    return floor
