"""Diagnosis benchmark: withheld library effects, out-of-library effects, and the null case, each scored
against the truth itself, never against the diagnosis' own fits.

* Withheld effects: for every effect of the final model that the candidate system can express, the
  baseline is the final model of its coefficient without it, on the default campaign (whose truth
  contains every effect). Is the effect ranked first, does it close at least half of the gap, and is
  the gap where the truth says the effect acts?
* Out-of-library effects (:mod:`structsearch.flight.anomalies`): campaigns whose truth contains
  something no library effect expresses; the baseline is the final model of the coefficient it affects.
  Is the gap located where the truth differs, is it not claimed explained by a library effect that
  closes less than half of it, and is the responsible signal ranked first among what remains? An anomaly
  that library terms reproduce to first order (a vane lag: an alpha_dot term) may end explained: that is
  right only when the diagnosis also names the equivalence (:mod:`.equivalence`); explained without it
  is not counted right, since the reader is not told what else the fit means.
* Null case: the final models themselves on several seeds. A false alarm by the Wald test alone (the
  saturated model's additions significant at 1 %) and by the combined rule (not at the floor).

"Where the truth differs" is the phase and alpha band holding the largest share of the squared
difference between the truth with and without the effect, evaluated on the flown validation states
(:func:`structsearch.flight.anomalies.truth_difference`), with the phases from the truth's own stall-strip
state.
"""
from __future__ import annotations

import dataclasses

import time
from dataclasses import dataclass, fields
from typing import Callable, Mapping

import numpy as np

from .diagnose import DIAGNOSE, diagnose
from .results import Diagnosis
from .story import unexplained_sentence
from .where import bins, shares, top_bins
from ..engine.separation import static_separation
from ..flight.reference import FINAL_LIFT
from ..flight.anomalies import ANOMALIES, truth_difference
from ..flight.flighttest import build_campaign
from ..flight.reference import FINAL_MODEL_NAMES
from ..fitting.candidates import Candidate
from ..fitting.fitter import temporary_fitter
from ..fitting.options import FitOptions, command_options
from ..fitting.specs import find_candidate

# effect -> (coefficient, regressors to drop, state kind changes)
WITHHELD = {
    "unsteady_lag": ("CL", (), {"ss": "Q"}),
    "second_separation_state": ("CL", ("CL_KL_w",), {"w": None}),
    "pitch_rate": ("CL", ("CL_qstar",), {}),
    "elevator": ("CL", ("CL_de",), {}),
    "thrust": ("CD", ("CD_CT",), {}),
    "induced_drag": ("CD", ("CD_CL2",), {}),
    "separation_drag": ("CD", ("CD_1mX_ss", "CD_1mX_w"), {}),
    "elevator_effectiveness_loss": ("Cm", ("Cm_Xde_ss",), {}),
    "cp_shift": ("Cm", ("Cm_1mX_ssCL", "Cm_1mX_wCL"), {}),
}
NOT_EXPRESSIBLE = {"separation_delay": "the final X_ss is unsteady (tau1 and tau2); a lag without delay is not one "
                                       "of the S/Q/U kinds, so 'final model minus tau2' has no candidate"}
# A library effect "explains" a gap only when it closes at least this share of it.
HALF = 0.5


def baseline_without(effect: str) -> Candidate:
    coefficient, drop, kinds = WITHHELD[effect]
    final = find_candidate(FINAL_MODEL_NAMES[coefficient])
    states = tuple((n, kinds.get(n, k)) for n, k in final.states if kinds.get(n, k) is not None)
    regs = tuple(r for r in final.regressors if r[0] not in drop)
    bounds = tuple(b for b in final.bounds if not (effect == "second_separation_state" and b[0].endswith("_w")))
    return dataclasses.replace(final, name=f"{final.name} - {effect}", regressors=regs, states=states,
                               note=f"{final.name} without {effect}", bounds=bounds)


def truth_location(campaign, effect: str) -> dict:
    """Where the truth with and without ``effect`` differ most on the validation maneuvers: the phase and
    alpha band holding the largest share of the squared difference, and its mean square."""
    delta = truth_difference(campaign, effect)
    mask = np.concatenate([np.full(sl.stop - sl.start, m.split == "validation")
                           for m, sl in zip(campaign.maneuvers, campaign.data.segment_slices())])
    val = campaign.split("validation")
    # phases as the diagnosis defines them (a static stall-strip curve), from the truth's parameters
    labels = bins(val, static_separation(val["alpha"], FINAL_LIFT["a1_ss"], FINAL_LIFT["a_star_ss"]))
    out = {"truth_mse": float(np.mean(delta[mask] ** 2))}
    for dim in ("phase", "alpha_band"):
        keys, share = shares(delta[mask] ** 2, labels[dim])
        top = None if np.all(np.isnan(share)) else int(np.nanargmax(share))
        out[dim] = None if top is None else str(keys[top])
        out[f"{dim}_share"] = None if top is None else float(share[top])
    return out


class _Row:
    """A benchmark row: its ``to_dict()`` is its fields in declaration order (the JSON's key order)."""

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class WithheldRow(_Row):
    """A final model without one library effect, diagnosed: is the effect found, does it close the gap, and is
    the gap where the truth says the effect acts?"""

    effect: str
    coefficient: str
    baseline: str
    ranked_first: bool
    first: str
    shrink: float | None
    closes_half: bool
    # the truth's own measure of the effect against the baseline's gap: an upper bound of what adding it can
    # close (the baseline's refit absorbs part of the effect through its other terms)
    truth_share: float | None
    top_phase: str | None
    top_alpha_band: str | None
    truth_phase: str | None
    truth_alpha_band: str | None
    truth_mse: float
    located: bool
    gap_p_value: float | None
    explained: bool
    state_alpha_rms: float | None
    state_alpha_rms_after: float | None
    seconds: float


@dataclass(frozen=True)
class AnomalyRow(_Row):
    """A campaign whose truth holds an effect outside the library, diagnosed from the final model."""

    anomaly: str
    coefficient: str
    baseline: str
    description: str
    signal: str
    detected: bool
    top_phase: str | None
    top_alpha_band: str | None
    truth_phase: str | None
    truth_alpha_band: str | None
    truth_mse: float
    located: bool
    adopted: str                 # the model after the adopted effects
    closed_by_library: float     # NaN: no gap
    explained: bool
    false_claim: bool
    unexplained_share: float | None
    first_signal: str | None
    says: str
    first_signal_remaining: str | None
    signal_first: bool
    gap_p_value: float | None
    # "explained by library terms, equivalence named": what the diagnosis says the added terms are also the
    # signature of for this anomaly, the parameter it converts to and the one injected (None: none named)
    equivalence: str | None
    equivalent_value: float | None
    injected_value: float | None
    right: bool
    seconds: float


@dataclass(frozen=True)
class NullRow(_Row):
    """A final model diagnosed on a campaign of its own truth: any alarm is false."""

    seed: int
    model: str
    explained: bool
    gap_p_value: float | None
    alarm_test: bool | None      # None: the Wald test is not estimable
    alarm_combined: bool
    seconds: float
    adopted: str | None = None   # the first move the structure search adopted: a false adoption (None: none)


@dataclass(frozen=True)
class BenchmarkResult:
    """The whole benchmark; ``to_dict()`` is ``withheld_benchmark.json``."""

    seed: int
    scale: float
    rows: tuple[WithheldRow, ...]
    outside: tuple[AnomalyRow, ...]
    null: tuple[NullRow, ...]
    not_expressible: Mapping[str, str]
    seconds: float

    def to_dict(self) -> dict:
        return {"seed": self.seed, "scale": self.scale, "rows": [r.to_dict() for r in self.rows],
                "outside": [r.to_dict() for r in self.outside], "null": [r.to_dict() for r in self.null],
                "not_expressible": dict(self.not_expressible), "seconds": self.seconds}

    @property
    def ranked_first(self) -> int:
        return sum(r.ranked_first for r in self.rows)

    @property
    def outside_scored(self) -> int:
        """Out-of-library effects diagnosed right (:func:`outside_right`)."""
        return sum(r.right for r in self.outside)

    @property
    def false_alarms(self) -> int:
        return sum(r.alarm_combined for r in self.null)

    @property
    def false_alarms_test(self) -> int:
        return sum(bool(r.alarm_test) for r in self.null)

    @property
    def false_adoptions(self) -> int:
        """Null diagnoses in which the structure search adopted a move (the truth is the baseline)."""
        return sum(r.adopted is not None for r in self.null)


def _top(doc: Diagnosis):
    top = top_bins(doc.where)
    return (None, None) if top is None else (top.phase, top.alpha_band)


def _closed_by_library(doc: Diagnosis) -> float:
    """Fraction of the first round's gap the adopted library effects close together (NaN: no gap)."""
    gap = doc.mse.validation - doc.noise_floor
    return float((doc.mse.validation - doc.final_mse) / gap) if gap > 0 else float("nan")


def withheld_row(campaign, effect: str, options: FitOptions, n_jobs: int) -> WithheldRow:
    base = baseline_without(effect)
    with temporary_fitter(campaign, options, n_jobs=n_jobs) as fitter:
        doc = diagnose(fitter, base, DIAGNOSE.but(max_rounds=1))
    first = doc.effects[0]
    # a move carries the effect's name when it equals the effect, or is the effect at one state (row.effect)
    reported = next((e for e in doc.effects if e.name == effect or e.effect == effect), None)
    truth = truth_location(campaign, effect)
    top_phase, top_band = _top(doc)
    mse, floor = doc.mse.validation, doc.noise_floor
    sl = doc.state_level if doc.state_level is not None and not doc.state_level.failed else None
    return WithheldRow(effect, base.coefficient, base.name, first.name == effect or first.effect == effect, first.name,
                       reported.shrink if reported else None,
                       bool(reported and reported.shrink is not None and reported.shrink >= HALF),
                       min(truth["truth_mse"] / (mse - floor), 1.0) if mse > floor else None,
                       top_phase, top_band, truth["phase"], truth["alpha_band"], truth["truth_mse"],
                       top_phase is not None and top_phase == truth["phase"], doc.rounds[0].gap_p_value,
                       doc.explained, None if sl is None else sl.before.alpha, None if sl is None else sl.after.alpha,
                       doc.seconds)


def outside_right(explained_by_library: bool, equivalence_named: bool, located: bool, false_claim: bool,
                  signal_first: bool) -> bool:
    """The scoring rule of an out-of-library effect. Explained by library terms (adopted moves close the gap to
    the floor): right only with the equivalence named and at least half of the gap closed; else: located, not
    falsely explained and the responsible signal first."""
    if explained_by_library:
        return equivalence_named and not false_claim
    return located and not false_claim and signal_first


def _injected(anomaly) -> float | None:
    """The anomaly's own size in the parameter its declared equivalents convert to (a vane lag: seconds)."""
    return anomaly.vane_lag_s if anomaly.vane_lag_s else None


def anomaly_row(name: str, seed: int, scale: float, options: FitOptions, n_jobs: int) -> AnomalyRow:
    anomaly = ANOMALIES[name]
    campaign = build_campaign(seed=seed, scale=scale, anomaly=name)
    base = find_candidate(FINAL_MODEL_NAMES[anomaly.coefficient])
    with temporary_fitter(campaign, options, n_jobs=n_jobs) as fitter:
        doc = diagnose(fitter, base, DIAGNOSE.but(max_rounds=2, state_level=False))
    truth = truth_location(campaign, name)
    top_phase, top_band = _top(doc)
    closed = _closed_by_library(doc)
    # the signal the whole gap followed before any library effect: an adopted effect may absorb part of the
    # anomaly and leave a remainder that follows something else (flight-to-flight offsets)
    signals, remaining = doc.unexplained.gap_signals, doc.unexplained.signals
    detected = not doc.gap_explained_by_baseline
    by_library = bool(doc.explained and doc.final_model != base.name)
    false_claim = bool(by_library and not closed >= HALF)
    named = next((e for e in doc.equivalences if e.anomaly == name), None)
    located = bool(detected and top_phase is not None and top_phase == truth["phase"])
    signal_first = bool(signals and signals[0].name == anomaly.signal)
    return AnomalyRow(name, anomaly.coefficient, base.name, anomaly.description, anomaly.signal, detected,
                      top_phase, top_band, truth["phase"], truth["alpha_band"], truth["truth_mse"],
                      located, doc.final_model, closed, doc.explained, false_claim, doc.unexplained.share,
                      signals[0].name if signals else None, unexplained_sentence(doc),
                      remaining[0].name if remaining else None, signal_first, doc.rounds[0].gap_p_value,
                      None if named is None else named.words(), None if named is None else named.value,
                      _injected(anomaly), outside_right(by_library, named is not None, located, false_claim,
                                                                signal_first), doc.seconds)


def run(seed: int = 0, scale: float = 1.0, null_seeds=(0, 1, 2), effects=None, anomalies=None,
        progress: Callable[[str], None] | None = None, options: FitOptions = command_options("diagnose"),
        n_jobs: int = 1) -> BenchmarkResult:
    say = progress or (lambda m: None)
    t0 = time.perf_counter()
    campaign = build_campaign(seed=seed, scale=scale)
    rows = []
    for effect in WITHHELD if effects is None else effects:
        say(f"withheld {effect}")
        rows.append(withheld_row(campaign, effect, options, n_jobs))
    outside = []
    for name in ANOMALIES if anomalies is None else anomalies:
        say(f"out of the library: {name}")
        outside.append(anomaly_row(name, seed, scale, options, n_jobs))
    null = []
    for s in null_seeds:
        camp = campaign if s == seed else build_campaign(seed=s, scale=scale)
        for coef, name in FINAL_MODEL_NAMES.items():
            say(f"null case seed {s} {name}")
            with temporary_fitter(camp, options, n_jobs=n_jobs) as fitter:
                doc = diagnose(fitter, find_candidate(name), DIAGNOSE.but(max_rounds=1, state_level=False))
            p = doc.rounds[0].gap_p_value
            null.append(NullRow(s, name, doc.explained, p, None if p is None else bool(p < 0.01), not doc.explained,
                                doc.seconds, doc.rounds[0].adopted))
    return BenchmarkResult(seed, scale, tuple(rows), tuple(outside), tuple(null), NOT_EXPRESSIBLE,
                           time.perf_counter() - t0)


def _yes(flag) -> str:
    return "yes" if flag else "NO"


def markdown(res: BenchmarkResult, command: str = "structsearch diagnose --benchmark --out results") -> str:
    from tabulate import tabulate
    rows, outside, null = res.rows, res.outside, res.null
    n = len(rows)
    lines = ["# Diagnosis benchmark", "", f"Every figure on this page was made by `{command}` "
             f"(seed {res.seed}, scale {res.scale}; {res.seconds:.0f} s).", "",
             "References come from the truth itself: the truth coefficient with and without the effect, evaluated "
             "on the flown validation states, gives where the effect acts (the phase and alpha band with the "
             "largest share of the squared difference).", "",
             "## Withheld library effects", "",
             "Default campaign; baseline = final model of the effect's coefficient without it.", "",
             tabulate([[r.effect, r.coefficient, r.first, _yes(r.ranked_first),
                        "n/a" if r.shrink is None else f"{r.shrink:.2f}", _yes(r.closes_half),
                        "n/a" if r.truth_share is None else f"{r.truth_share:.2f}",
                        f"{r.top_phase} / {r.top_alpha_band}", f"{r.truth_phase} / {r.truth_alpha_band}",
                        _yes(r.located), "-" if r.state_alpha_rms is None else
                        f"{r.state_alpha_rms:.4f} -> {r.state_alpha_rms_after:.4f}", f"{r.seconds:.0f}"]
                       for r in rows],
                      headers=["withheld effect", "coef.", "ranked first", "hit", "shrink", ">= 0.5",
                               "truth's share of the gap (upper bound)",
                               "gap's top phase / alpha band", "truth's top phase / alpha band", "phase matches",
                               "replayed alpha RMS [rad] before -> after", "s"], tablefmt="github"), "",
             f"Ranked first: **{sum(r.ranked_first for r in rows)}/{n}**; closes at least half of the gap: "
             f"**{sum(r.closes_half for r in rows)}/{n}**; the gap's top phase is the truth's: "
             f"**{sum(r.located for r in rows)}/{n}**.", "",
             "Not benchmarked: " + "; ".join(f"{k}: {v}" for k, v in res.not_expressible.items()) + ".", ""]
    if outside:
        lines += _outside_lines(outside)
    lines += ["## Null case (nothing withheld)", "",
              tabulate([[r.seed, r.model, "n/a" if r.gap_p_value is None else f"{r.gap_p_value:.2g}",
                         "not testable" if r.alarm_test is None else _yes(not r.alarm_test),
                         _yes(not r.alarm_combined)] for r in null],
                       headers=["seed", "model", "gap p-value (Wald)", "no alarm by the test alone",
                                "no alarm by the combined rule (at the floor)"], tablefmt="github"), "",
              f"False alarms by the Wald test alone (1 %): **{sum(bool(r.alarm_test) for r in null)}/"
              f"{sum(r.alarm_test is not None for r in null)}** testable; "
              f"by the combined rule: **{sum(r.alarm_combined for r in null)}/{len(null)}**. "
              f"Moves adopted by the structure search (false adoptions): "
              f"**{sum(r.adopted is not None for r in null)}/{len(null)}**"
              + "".join(f"; seed {r.seed} {r.model}: {r.adopted}" for r in null if r.adopted) + ".", ""]
    return "\n".join(lines)


def _outside_lines(outside) -> list[str]:
    """The section on anomalies: the table, the scores and what the diagnosis says of each."""
    from tabulate import tabulate
    m = len(outside)
    return ["## Effects outside the library", "",
            "Campaigns whose truth contains an effect no library term expresses; baseline = the final model "
            "of the coefficient it affects (two rounds).", "",
            tabulate([[r.anomaly, r.coefficient, _yes(r.detected), f"{r.top_phase} / {r.top_alpha_band}",
                       f"{r.truth_phase} / {r.truth_alpha_band}", _yes(r.located), r.adopted,
                       "n/a" if not np.isfinite(r.closed_by_library) else f"{r.closed_by_library:.2f}",
                       "NO (false claim)" if r.false_claim else "yes",
                       "n/a" if r.unexplained_share is None else f"{r.unexplained_share:.2f}",
                       r.signal, r.first_signal or "-", r.first_signal_remaining or "-", _yes(r.signal_first),
                       _equivalence_cell(r), _yes(r.right), f"{r.seconds:.0f}"]
                      for r in outside],
                     headers=["effect", "coef.", "gap found", "gap's top phase / band", "truth's top phase / band",
                              "located", "model after adopted effects", "share the library closes",
                              "not falsely explained", "unexplained share", "responsible signal",
                              "first signal of the gap", "first signal of what remains", "signal first",
                              "equivalence named (injected)", "right", "s"],
                     tablefmt="github"), "",
            f"Located: **{sum(r.located for r in outside)}/{m}**; not falsely explained: "
            f"**{sum(not r.false_claim for r in outside)}/{m}**; responsible signal first: "
            f"**{sum(r.signal_first for r in outside)}/{m}**; right: **{sum(r.right for r in outside)}/{m}** "
            "(explained by library terms: right only with the equivalence named; otherwise located, not falsely "
            "explained and the signal first; explained without an equivalence named is not counted right).", "",
            *[f"- `{r.anomaly}`: {r.description} The diagnosis says: "
              f"{r.says or ('explained by ' + r.adopted if r.explained else '(nothing)')}"
              + (f"; {r.equivalence}" if r.equivalence else "") for r in outside], ""]


def _equivalence_cell(r: AnomalyRow) -> str:
    if r.equivalence is None:
        return "-"
    injected = "" if r.injected_value is None else f" ({r.injected_value:.2g})"
    return f"{r.equivalent_value:.2g}{injected}"
