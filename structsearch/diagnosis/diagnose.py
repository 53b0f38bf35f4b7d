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
after the adopted effects is at the floor. What it leaves is the ``unexplained`` block: its share of
the gap and the signals it follows.

Per sample, the excess is r_baseline^2 - r_floor^2; ``where`` gives each bin's share of the summed
excess (shares of one dimension sum to 1), with a bootstrap over validation maneuvers for uncertainty.
"""
from __future__ import annotations

import dataclasses

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import stats

from . import effects as fx
from . import floor as fl
from ..data.campaign import Campaign
from ..data.flightdata import FlightData
from ..data.errors import DataError, DeclarationError
from ..fitting.models import build_model, predict_candidate
from ..fitting.options import FitOptions
from ..fitting.candidate_fit import fit_candidate, fit_lift_model
from ..fitting.lift_fit import LiftFit
from ..engine.regressors import declare, symbol_names
from ..engine.separation import static_separation
from ..fitting.candidates import Candidate
from ..fitting.specs import find_candidate
from ..fitting.candidate_result import CandidateResult
from ..engine.scores import maneuver_mse, sizes_of, weighted_mean_se
from ..flight.reference import FINAL_LIFT, FINAL_MODEL_NAMES

ALPHA_BAND = 0.04          # rad
FREQ_BANDS = (0.0, 0.5, 1.0, 2.0, 5.0, np.inf)  # Hz
SPECTRAL_SPLIT_HZ = 3.0
N_BOOTSTRAP = 200
# A model is at the floor when its per-maneuver relative excess over the floor model is within one standard
# error or below this (the ranking's practical tolerance); the error needs this many maneuvers.
PRACTICAL_TOLERANCE = 0.01
MIN_MANEUVERS = 3


@dataclass
class Fitted:
    candidate: Candidate
    summary: CandidateResult
    residual: np.ndarray        # validation residual
    train_residual: np.ndarray  # training residual


def _fit(c: Candidate, train: FlightData, val: FlightData, lift, options, start=None) -> Fitted:
    summary = fit_candidate(c, train, val, lift, options, start=start)
    if summary.failed:
        raise DeclarationError(f"fitting {c.name} failed: {summary.error}")
    pred = predict_candidate(c, summary.params, val, lift)
    pred_train = predict_candidate(c, summary.params, train, lift)
    return Fitted(c, summary, val[c.coefficient] - pred, train[c.coefficient] - pred_train)


def _fit_or_error(c: Candidate, train, val, lift, options, start) -> Fitted | str:
    try:
        return _fit(c, train, val, lift, options, start=start)
    except DeclarationError as exc:
        return str(exc)


def _fit_all(models, train, val, lift, options, start, n_jobs: int) -> list[Fitted | str]:
    """:func:`_fit` of every model (the error text where one fails), in order, on ``n_jobs`` processes."""
    if n_jobs == 1 or len(models) < 2:
        return [_fit_or_error(c, train, val, lift, options, start) for c in models]
    from joblib import Parallel, delayed
    return Parallel(n_jobs=n_jobs)(delayed(_fit_or_error)(c, train, val, lift, options, start)
                                   for c in models)


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


def _bins(data: FlightData, x: np.ndarray):
    """Per sample: the bin label of each dimension."""
    alpha, alpha_dot = data["alpha"], data["alpha_dot"]
    labels = {"maneuver": np.concatenate([[name] * (sl.stop - sl.start) for name, sl in
                                          zip(data.names, data.segment_slices())]).astype(object)}
    lo = np.floor(alpha / ALPHA_BAND) * ALPHA_BAND
    labels["alpha_band"] = np.array([f"{a:.2f}-{a + ALPHA_BAND:.2f}" for a in lo], dtype=object)
    x_dot = np.concatenate([np.gradient(x[sl], data["t"][sl]) for sl in data.segment_slices()])
    phase = np.where(x > 0.9, "attached", np.where(x < 0.1, "stalled",
                                                   np.where(x_dot < 0, "separating", "reattaching")))
    labels["phase"] = phase.astype(object)
    labels["alpha_dot_sign"] = np.where(alpha_dot >= 0, "alpha increasing", "alpha decreasing").astype(object)
    return labels


def _shares(excess: np.ndarray, labels: np.ndarray):
    """Each bin's share of the positive summed excess; NaN everywhere when there is no excess to share."""
    keys = sorted(set(labels))
    sums = np.array([excess[labels == k].sum() for k in keys])
    pos = np.clip(sums, 0, None)
    total = pos.sum()
    return keys, (pos / total if total > 0 else np.full(len(keys), np.nan))


def _frequency_excess(r_base, r_sat, data):
    """Excess power per frequency band, summed over maneuvers (same normalisation as squared residuals)."""
    out = np.zeros(len(FREQ_BANDS) - 1)
    for sl in data.segment_slices():
        f = np.fft.rfftfreq(sl.stop - sl.start, float(np.median(np.diff(data["t"][sl]))))
        for r, sign in ((r_base[sl], 1.0), (r_sat[sl], -1.0)):
            spec = np.abs(np.fft.rfft(r)) ** 2 / len(r) * 2
            spec[0] /= 2
            for i in range(len(out)):
                out[i] += sign * spec[(f >= FREQ_BANDS[i]) & (f < FREQ_BANDS[i + 1])].sum()
    return out


def where(r_base, r_sat, data: FlightData, x: np.ndarray, seed: int = 0) -> list[dict]:
    """Shares of the excess squared residual by bin, with bootstrap standard deviations over maneuvers."""
    excess = r_base ** 2 - r_sat ** 2
    labels = _bins(data, x)
    rng = np.random.default_rng(seed)
    slices = data.segment_slices()
    out = []
    maneuver_of = np.concatenate([np.full(sl.stop - sl.start, i) for i, sl in enumerate(slices)])
    for dim, lab in labels.items():
        keys, shares = _shares(excess, lab)
        # excess summed per (maneuver, bin): a bootstrap over maneuvers adds rows of this table
        code = np.searchsorted(np.array(keys, dtype=object), lab)
        table = np.zeros((len(slices), len(keys)))
        np.add.at(table, (maneuver_of, code), excess)
        boot = []
        for _ in range(N_BOOTSTRAP if dim != "maneuver" else 0):
            pos = np.clip(table[rng.integers(0, len(slices), len(slices))].sum(axis=0), 0, None)
            boot.append(pos / pos.sum() if pos.sum() > 0 else np.zeros(len(keys)))
        spread = np.std(boot, axis=0) if boot else np.full(len(keys), np.nan)
        for k, s, sd in zip(keys, shares, spread):
            mask = lab == k
            out.append({"dimension": dim, "bin": str(k), "share": float(s), "share_std": float(sd),
                        "mse": float(np.mean(r_base[mask] ** 2)), "samples": int(mask.sum())})
    fx_ = _frequency_excess(r_base, r_sat, data)
    pos = np.clip(fx_, 0, None)
    for i, s in enumerate(pos / pos.sum() if pos.sum() > 0 else pos):
        hi = FREQ_BANDS[i + 1]
        label = f"{FREQ_BANDS[i]:g}-{hi:g} Hz" if np.isfinite(hi) else f">{FREQ_BANDS[i]:g} Hz"
        out.append({"dimension": "frequency_band", "bin": label, "share": float(s), "share_std": float("nan"),
                    "mse": float("nan"), "samples": 0})
    return out


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
    names = [n for n in names if n in summary.params]
    if not names:
        return float("nan")
    idx = [summary.names.index(n) for n in names]
    corr = summary.correlation_matrix[np.ix_(idx, idx)]
    sd = np.array([summary.stderr[n] for n in names])
    cov = corr * np.outer(sd, sd)
    b = np.array([summary.params[n] for n in names])
    try:
        w = float(b @ np.linalg.solve(cov, b))
    except np.linalg.LinAlgError:
        return float("nan")
    # F(q, dof): the small-sample version of chi2(q)/q (equal to it for m - p dof), the usual reference
    # for a clustered sandwich (Cameron & Miller 2015); dof: the fewest among the tested parameters
    finite = [d for d in ((summary.reference_dof or {}).get(n, np.nan) for n in names) if np.isfinite(d)]
    dof = min(finite) if finite else np.nan
    if not np.isfinite(dof):
        return float(stats.chi2.sf(w, len(names)))
    return float(stats.f.sf(w / len(names), len(names), dof))


def _overlap(gap_rows, r_base, r_new, data, x):
    """Histogram intersection of gap shares and improvement shares over alpha bands and phases, and the
    bins where the effect improves the fit most (where it acts); NaN and no bins where it improves nothing
    or there is no gap."""
    labels = _bins(data, x)
    improvement = r_base ** 2 - r_new ** 2
    scores, acts = [], {}
    for dim in ("alpha_band", "phase"):
        keys, imp = _shares(improvement, labels[dim])
        gap = {row["bin"]: row["share"] for row in gap_rows if row["dimension"] == dim}
        scores.append(float(sum(min(gap.get(k, 0.0), s) for k, s in zip(keys, imp))))
        if np.all(np.isnan(imp)):
            return float("nan"), {}
        acts[dim] = str(keys[int(np.nanargmax(imp))])
    return float(np.mean(scores)), acts


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
    x_train = _state_for_phases(model, fit.summary, lift, train)
    x_val = _state_for_phases(model, fit.summary, lift, val)
    sig_train, sig_val = fl.signals(train, x_train), fl.signals(val, x_val)
    flex = fl.flexible_fit(fit.train_residual, train, sig_train, fit.residual, sig_val, seed)
    return flex, sig_train, sig_val, x_val


def _rank_key(r: dict):
    """Significant effects first (Wald test, 1 %; an untestable one counts as not significant), then by shrink."""
    p = r["p_value"]
    return (not (p is not None and p < 0.01), -(r["shrink"] or 0.0), p if p is not None else np.inf)


def diagnose(campaign: Campaign, baseline: Candidate, *, options: FitOptions = FitOptions(n_starts=2, cv_folds=0),
             max_rounds: int = 3, progress: Callable[[str], None] | None = None, seed: int = 0,
             states: bool = True, n_jobs: int = 1) -> dict:
    """Diagnose one coefficient; returns the JSON document of docs/interfaces.md sections 3 and 5.4. The fits of
    each round's effects run on ``n_jobs`` processes."""
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
    rounds, current = [], baseline
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

        def remaining_p(skip: str | None) -> float:
            """Wald p-value of what the saturated model adds beyond the baseline (and effect ``skip``)."""
            names = [p for name, ps in added.items() if name != skip for p in ps]
            return wald_p_value(sat_fit.summary, names)
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
        where_rows = where(base_fit.residual, floor.residual, val, x_val, seed=seed)
        ranked = []
        for e, changed, f in candidates:
            if isinstance(f, str):
                ranked.append({"name": e.name, "error": f})
                continue
            p = wald_p_value(f.summary, e.new_parameters(current, changed))
            ranked.append({
                "name": e.name, "shrink": None if explained_now else _shrink(mse_base, float(np.mean(f.residual ** 2)),
                                                                           floor.mse),
                "mse_validation_after": float(np.mean(f.residual ** 2)), "mse_train_after": f.summary.mse_train,
                "p_value": p if np.isfinite(p) else None,
                **dict(zip(("overlap", "acts_in"), _overlap(where_rows, base_fit.residual, f.residual, val, x_val))),
                "at_floor": within_noise(f.residual, floor.residual, val)[0],
                "model": changed.name, "_fit": f})
        ok = sorted((r for r in ranked if "error" not in r), key=_rank_key)
        ranked = ok + [r for r in ranked if "error" in r]
        best = ok[0] if ok else None
        p_gap = remaining_p(None)
        rounds.append({"baseline": current.name, "mse": {"train": base_fit.summary.mse_train,
                                                         "validation": mse_base},
                       "noise_floor_round": floor.mse, "floor_source": floor.source,
                       "noise_floor_spectral": spectral_floor(base_fit.residual, val),
                       "gap_se": se_base, "where": where_rows,
                       "effects": [{k: v for k, v in r.items() if not k.startswith("_")} for r in ranked],
                       "explained_before": explained_now, "excess_over_floor": excess, "excess_se": excess_se,
                       "gap_p_value": p_gap if np.isfinite(p_gap) else None, "adopted": None})
        significant = best is not None and best["p_value"] is not None and best["p_value"] < 0.01
        if explained_now or not significant or not (best["shrink"] or 0.0) > 0:
            break
        rounds[-1]["adopted"] = best["name"]
        if first_best is None:
            first_best = best["_fit"]
        current, base_fit = best["_fit"].candidate, best["_fit"]
    final_fit = base_fit
    if rounds[-1]["adopted"] is not None or flexible is None:  # the final model's own library-free floor
        say("library-free floor of the final model's residual")
        flexible, sig_train, sig_val, x_val = _flexible(final_fit, current, lift, train, val, seed)
        floors.append(_Floor(flexible.mse, flexible.residual, "library-free flexible model of the residual", True))
    floor = min(floors, key=lambda f: f.mse)
    explained, final_excess, final_excess_se = within_noise(final_fit.residual, floor.residual, val)
    for r in rounds:  # one floor for every reported shrink and verdict: the lowest of everything fitted
        r["noise_floor"], r["gap"] = floor.mse, r["mse"]["validation"] - floor.mse
        for e in r["effects"]:
            if "error" not in e and e["shrink"] is not None:
                e["shrink"] = _shrink(r["mse"]["validation"], e["mse_validation_after"], floor.mse)
    last = rounds[-1]
    if last["adopted"] is None:  # the final model is the last round's baseline: one verdict for both
        last["explained_before"], last["excess_over_floor"], last["excess_se"] = \
            explained, final_excess, final_excess_se
    first = rounds[0]
    library_free = min(f.mse for f in floors if f.library_free)
    unexplained = _unexplained(first["mse"]["validation"], final_fit, flexible, library_free, val, sig_train,
                               sig_val, x_val, explained, seed, first_floor)
    doc = {"coefficient": baseline.coefficient, "baseline": baseline.name,
           "mse": first["mse"], "noise_floor": floor.mse, "floor_source": floor.source,
           "noise_floor_library": min(f.mse for f in floors if not f.library_free),
           "noise_floor_spectral": first["noise_floor_spectral"], "where": first["where"],
           "effects": first["effects"], "explained": explained,
           "gap_explained_by_baseline": first["explained_before"],
           "final_excess_over_floor": final_excess, "final_excess_se": final_excess_se,
           "rounds": rounds, "final_model": current.name, "final_mse": float(np.mean(final_fit.residual ** 2)),
           "unexplained": unexplained, "warnings": warnings}
    if states and first_best is not None:
        say("state level: replaying the validation maneuvers before and after")
        try:
            doc["state_level"] = state_level(campaign, baseline_fit, first_best, lift, options)
        except (DeclarationError, DataError) as exc:
            doc["state_level"] = {"error": str(exc)}
    doc["seconds"] = time.perf_counter() - t0
    return doc


def _top_bins(rows: list[dict]) -> dict | None:
    """The phase and alpha band holding the largest share of an excess; None when there is no excess."""
    out = {}
    for dim in ("phase", "alpha_band"):
        shares = [r for r in rows if r["dimension"] == dim and np.isfinite(r["share"])]
        if not shares:
            return None
        out[dim] = max(shares, key=lambda r: r["share"])["bin"]
    return out


def _signal_ranking(train_residual: np.ndarray, residual: np.ndarray, flex: fl.FlexibleFit, sig_train: dict,
                    sig_val: dict, gap: float, seed: int) -> tuple[list[dict], dict]:
    """The signals a gap of size ``gap`` follows, best first by their permutation importance in the flexible
    model on the validation maneuvers (it sees the signals jointly, so V counts for a dependence on V times
    delta_e even where V alone explains little, and a signal that only travels with the responsible one, such
    as the time in a maneuver that bleeds off speed, does not), ties by a one-signal fit; each with the share
    of the gap a function of it alone, fitted on the training maneuvers, removes on the validation maneuvers
    (docs/interfaces.md 5.4)."""
    fits = {f.name: f for f in fl.ranked_signals(train_residual, sig_train, residual, sig_val)}
    importance = fl.permutation_importance(flex, residual, sig_val, seed)
    mse = float(np.mean(residual ** 2))
    # without importances (the flexible model removed nothing) the one-signal fits alone order the signals
    order = sorted(fits, key=lambda n: (-importance.get(n, -np.inf), fits[n].mse))
    return [{"name": n, "share": float(min(max((mse - fits[n].mse) / gap, 0.0), 1.0)),
             "importance": importance.get(n)} for n in order], fits


def _unexplained(mse_base: float, final: Fitted, flexible: fl.FlexibleFit, library_free: float,
                 val: FlightData, sig_train: dict, sig_val: dict, x_val: np.ndarray, explained: bool,
                 seed: int, first=None) -> dict:
    """The docs/interfaces.md 5.4 ``unexplained`` block: the share of the gap (baseline validation MSE minus the
    library-free floor) left after the adopted library effects, the signals the rest follows, where it sits.
    ``flexible`` is the library-free model of the final model's residual. ``first`` (the baseline's fit, its
    flexible model and signals) adds ``gap_signals``: the signals the whole gap followed before any effect."""
    mse_final = float(np.mean(final.residual ** 2))
    gap, remaining = mse_base - library_free, mse_final - library_free
    out = {"noise_floor": library_free, "flexible_iterations": flexible.n_iter,
           "share": float(min(max(remaining / gap, 0.0), 1.0)) if gap > 0 else None,
           "signals": [], "gap_signals": [], "where": None, "partial_dependence": []}
    if gap <= 0:
        out["note"] = "no gap above the library-free floor"
    elif first is not None:
        base_fit, base_flex, base_train, base_val = first
        out["gap_signals"] = _signal_ranking(base_fit.train_residual, base_fit.residual, base_flex, base_train,
                                             base_val, gap, seed)[0]
    if explained:
        return out
    if not remaining > 0:
        out["note"] = ("the final model is at the library-free floor but not at the floor the library sets with "
                       "several effects together (the saturated model); no single effect was significant")
        return out
    out["signals"], fits = _signal_ranking(final.train_residual, final.residual, flexible, sig_train, sig_val,
                                           remaining, seed)
    out["where"] = _top_bins(where(final.residual, flexible.residual, val, x_val, seed=seed))
    for entry in out["signals"][:3]:
        f = fits[entry["name"]]
        x, mean = fl.binned_means(sig_val[f.name], final.residual)
        out["partial_dependence"].append({"name": f.name, "x": f.centres.tolist(), "fitted": f.values.tolist(),
                                          "validation_x": x.tolist(), "validation_mean": mean.tolist()})
    return out


def _state_for_phases(c: Candidate, summary: CandidateResult, lift: LiftFit | None,
                      data: FlightData) -> np.ndarray:
    """The separation state that defines flight phases: the model's first state, or a static stall-strip
    curve from the lift fit; without any, the thesis' stall-strip curve."""
    params = summary.params if not c.lift else (lift.params if lift is not None else {})
    for name, _ in (c.states or ()):
        suffix = f"_{name}" if name else ""
        if f"a1{suffix}" in params and f"a_star{suffix}" in params:
            return static_separation(data["alpha"], params[f"a1{suffix}"], params[f"a_star{suffix}"])
    return static_separation(data["alpha"], FINAL_LIFT["a1_ss"], FINAL_LIFT["a_star_ss"])


def state_level(campaign: Campaign, before: Fitted, after: Fitted, lift, options: FitOptions,
                window_s: float = 5.0) -> dict:
    """Forward-simulated state error on the validation maneuvers with the model before and after.

    The diagnosed coefficient uses the baseline (before) or improved (after) fit; the other two use
    the final structures of the thesis refitted on the training maneuvers with the same separation
    states, so that the three form one simulator.
    """
    from ..flight.aero import AeroModel
    from ..flight.replay import replay
    train, val = campaign.split("train"), campaign.split("validation")
    coef = before.candidate.coefficient

    def aero(fitted: Fitted) -> AeroModel:
        # the simulator's lift model: the diagnosed one, or the lift model the drag or pitch candidate names
        lift_fit = LiftFit(fitted.candidate, fitted.summary) if coef == "CL" else lift
        lift_cand = lift_fit.candidate
        models, params = {}, dict(lift_fit.params)
        models["CL"] = build_model(lift_cand)
        for other in ("CD", "Cm"):
            if other == coef:
                models[other] = build_model(fitted.candidate, lift)
                params.update(fitted.summary.params)
                continue
            structure = find_candidate(FINAL_MODEL_NAMES[other])
            # terms on states this lift model does not have, or on columns the campaign lacks (x_cg), are left
            # out (before and after alike)
            symbols = [f"X_{n}" if n else "X" for n, _ in lift_cand.states]
            have = set(campaign.data.columns) | set(campaign.data.constants) | set(symbols)
            kept = []
            for name, text in structure.regressors:
                try:
                    declare(name, text, states=symbols)
                except DeclarationError:
                    continue
                if set(symbol_names(text)) <= have | {"CL"}:
                    kept.append((name, text))
            structure = Candidate(structure.name, structure.grid, structure.coefficient, tuple(kept),
                                  lift_cand.states, lift_cand.name, structure.note, lift_cand.bounds)
            s = fit_candidate(structure, train, val, lift_fit, options)
            if s.failed:
                raise DeclarationError(f"state-level comparison: {s.error}")
            models[other] = build_model(structure, lift_fit)
            params.update({k: v for k, v in s.params.items() if k not in lift_fit.result.nonlinear_names})
        return AeroModel(models["CL"], models["CD"], models["Cm"], params, name=fitted.candidate.name)

    out = {}
    for label, fitted in (("before", before), ("after", after)):
        runs = replay(val, aero(fitted), window_s=window_s)
        n = sum(len(r.t) for r in runs)
        out[label] = {s: float(np.sqrt(sum(r.rms[s] ** 2 * len(r.t) for r in runs) / n))
                      for s in ("alpha", "q", "V", "theta")}
    out["window_s"] = window_s
    out["reduction"] = {s: 1 - out["after"][s] / out["before"][s] if out["before"][s] > 0 else float("nan")
                        for s in ("alpha", "q", "V", "theta")}
    return out
