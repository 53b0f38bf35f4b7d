"""``structsearch report``: PNG figures and one self-contained HTML page for a campaign.

The models are the winners of the user's search (:mod:`.choice`); the Van
Ingen structures (CL-I, CD-I, Cm-I) are fitted beside them for comparison.
The page opens with the answer (:mod:`.answer`); :mod:`.page_html` writes it.
This module only draws: :func:`structsearch.api.report`
fits (through the runner's cache, so after ``structsearch demo`` it refits
nothing already fitted) and hands the fits to :func:`build`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..data.coefficients import COEFFICIENTS, LONGITUDINAL
from . import figures as fg
from . import figure_data as rd
from ..data.campaign import Campaign
from ..data.errors import DataError
from ..data.atomic import write_text
from .numbers import share
from .page_html import render_html
from .diagnosis_doc import unexplained_sentence
from ..flight.reference import VAN_INGEN_MODEL_NAMES
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.bands import static_bands
from ..fitting.options import FitOptions
from ..thesis_study.model_set import ModelSet

# What draws a figure onto the page: emit(figure, file, title, caption) saves it and lists it.
Emit = Callable[[Any, str, str, str], None]


@dataclass(frozen=True)
class Figure:
    file: str
    title: str
    caption: str


def best_effect(diagnosis) -> str | None:
    """The name of the diagnosis' best effect that was fitted (None if none was)."""
    best = diagnosis.best_effect
    return None if best is None else best.name


@dataclass(frozen=True)
class ReportFits:
    """Everything the page shows that had to be fitted (by :func:`structsearch.api.report`; the report layer
    fits nothing): the models chosen and the notes on how, the identified and the Van Ingen model sets, the
    diagnosis of one coefficient and its best effect's fit."""

    names: Mapping[str, str]
    notes: tuple[str, ...]
    identified: ModelSet | None                # None: no lift, drag and pitch set to draw (the first screen only)
    van_ingen: ModelSet | None                 # None: the Van Ingen structures could not be fitted (a note says why)
    diagnosis_coefficient: str | None = None
    diagnosis: Any = None                      # the diagnosis (dict or typed) of diagnosis_coefficient's model
    effect: tuple[str, Candidate, CandidateResult] | None = None  # (best effect, model with it, its fit)
    # per coefficient the structure the page answers with: (candidate, its fit, the LiftFit whose states it reads)
    answers: Mapping[str, tuple] = field(default_factory=dict)
    source: str = ""                           # where the answers come from, in words
    verdicts: Mapping[str, dict] = field(default_factory=dict)   # per coefficient the search's answer (8.1)


def require_figures() -> None:
    """Raise unless matplotlib is installed (before anything is fitted for a page that cannot be drawn)."""
    fg.require()


def build(campaign: Campaign, out: Path, fits: ReportFits, *, options: FitOptions = FitOptions(),
          story: list[str] | None = None, gaps=None) -> dict:
    """Write ``out/figures/*.png`` and ``out/report.html`` from ``fits``; returns what was written and the notes."""
    fg.require()
    t0 = time.perf_counter()
    fig_dir = out / "figures"
    names, notes = dict(fits.names), list(fits.notes)
    ms, vi = fits.identified, fits.van_ingen
    train, val = campaign.split("train"), campaign.split("validation")
    ref = rd.reference(train)
    alpha = np.linspace(min(0.0, float(campaign.data["alpha"].min())), float(campaign.data["alpha"].max()), 400)
    written: list[Figure] = []

    def emit(fig, file, title, caption):
        fg.save(fig, fig_dir / file)
        written.append(Figure(file, title, caption))

    diagnosis = None
    if ms is not None:   # the figures draw one lift, drag and pitch set
        curves = _static_figures(emit, campaign, names, ms, vi, train, alpha, ref)
        _derived_pitch_figures(emit, campaign, names, ms, vi, alpha, ref, curves, notes)
        hyst = _dynamic_figures(emit, campaign, names, ms, train, val, ref, options)
        diagnosis = _diagnosis_figures(emit, campaign, fits, ms)
        _replay_figure(emit, campaign, ms, hyst, notes)
    fits = fits if fits.answers else _with_answers(fits)
    page = render_html(campaign, out, fits, ms, vi, written, notes, diagnosis, story, gaps)
    write_text(out / "report.html", page)
    return {"html": out / "report.html", "figures": [fig_dir / f.file for f in written], "notes": notes,
            "seconds": time.perf_counter() - t0}


def _with_answers(fits: ReportFits) -> ReportFits:
    """``fits`` answering with the figures' set (a caller that fitted no separate answers)."""
    import dataclasses
    ms = fits.identified
    answers = {coef: (ms.candidates[coef], ms.summaries[coef], None if COEFFICIENTS[coef].owns_states else ms.lift)
               for coef in LONGITUDINAL}
    return dataclasses.replace(fits, answers=answers, source=fits.source or "shown in the figures")


def _static_figures(emit: Emit, campaign: Campaign, names: Mapping[str, str], ms: ModelSet, vi: ModelSet | None,
                    train: Campaign, alpha: np.ndarray, ref) -> Any:
    """The static separation, lift, drag and pitch figures (thesis Figs. 6-8, 11); returns the separation curves."""
    static = rd.static_coefficients(ms, alpha, ref)
    static_vi = rd.static_coefficients(vi, alpha, ref) if vi else None
    points = rd.partial_points(ms, campaign.data, ref)
    curves = rd.separation_curves(ms, alpha)
    pair = (names["CL"], VAN_INGEN_MODEL_NAMES["CL"])
    cond = (f"static condition: separation states at equilibrium, q = 0, delta_e = 0, C_T = 0, V = {ref.V:.1f} m/s"
            + (f", x_cg = {ref.x_cg:.3f} m" if ref.x_cg is not None else ""))
    corrected = ("Grey points: every maneuver's measurements (a seeded subsample of 5000) corrected to the static "
                 "condition, i.e. the static model at the sample's alpha plus the sample's residual.")
    emit(fg.separation(curves, alpha), "separation_static.png", "Static flow separation",
         f"X_0(alpha) of each separation state of {names['CL']} with the stall stages marked: flow starts to "
         "separate (X_0 = 0.9), half separated (alpha*, X_0 = 0.5), fully stalled (X_0 = 0.1) (thesis Fig. 6).")
    bands = {coef: static_bands(ms.candidates[coef], ms.summaries[coef], train, ms.lift if coef != "CL" else None)
             for coef in ("CL", "Cm")}
    band_text = ("Shaded: the fitted curve's 95 % confidence band (where the true static curve lies: the delta "
                 "method on the parameters' covariance, each point's t quantile with its own effective maneuvers) "
                 "and, lighter, its 95 % prediction band (where a new measurement at that alpha lies: plus the "
                 "training residual's variance in its alpha band), over the flown alpha range.")
    emit(fg.static_curve("CL", alpha, static, static_vi, points, pair, bands["CL"]), "lift_static.png",
         "Static lift curve",
         f"C_L(alpha) of {names['CL']} and of the Van Ingen structure {pair[1]} in the {cond}. {band_text} "
         f"{corrected} (thesis Fig. 7)")
    emit(fg.drag_polar(static, static_vi, points, (names["CD"], VAN_INGEN_MODEL_NAMES["CD"])), "drag_polar.png",
         "Static drag polar",
         f"C_L against C_D of {names['CD']} (with {names['CL']}) and of {VAN_INGEN_MODEL_NAMES['CD']} (with "
         f"{VAN_INGEN_MODEL_NAMES['CL']}) in the {cond}. {corrected} (thesis Fig. 8)")
    emit(fg.static_curve("Cm", alpha, static, static_vi, points, (names["Cm"], VAN_INGEN_MODEL_NAMES["Cm"]),
                         bands["Cm"], offset_note("Cm", alpha, static_vi, points, names["Cm"],
                                                  VAN_INGEN_MODEL_NAMES["Cm"])),
         "pitch_static.png", "Static pitch moment",
         f"C_m(alpha) of {names['Cm']} and {VAN_INGEN_MODEL_NAMES['Cm']} in the {cond}; C_L from the lift model. "
         f"{band_text} "
         f"{corrected} Both curves hold delta_e = 0: a structure whose elevator term cannot be told apart from "
         "alpha in trimmed flight (the elevator follows alpha) carries part of the alpha slope in that term. "
         "(thesis Fig. 11)")
    return curves


def _derived_pitch_figures(emit: Emit, campaign: Campaign, names: Mapping[str, str], ms: ModelSet,
                           vi: ModelSet | None, alpha: np.ndarray, ref, curves, notes: list[str]) -> None:
    """The centre of pressure (where the pitch model implies one and the cg is known) and the elevator
    effectiveness (thesis Figs. 9-10); a note for a figure left out."""
    envelope = campaign.aircraft.get("x_cg_range")
    derived = rd.derived_pitch(ms, alpha, ref)
    if derived["depends_on_CL"] and ref.x_cg is None:
        notes.append("The campaign has no x_cg column, so the centre of pressure cannot be placed; that figure is "
                     "left out.")
    elif derived["depends_on_CL"]:
        if envelope is None:
            notes.append("campaign.toml gives no cg envelope (x_cg_range): the centre-of-pressure figure shows "
                         "the mean centre of gravity only.")
        span = (f"against the centre-of-gravity envelope ({envelope[0]:.3f}-{envelope[1]:.3f} m, campaign.toml)"
                if envelope is not None else "(no cg envelope in the campaign)")
        emit(fg.centre_of_pressure(alpha, derived, curves, envelope, ref.x_cg), "centre_of_pressure.png",
             "Centre of pressure",
             f"x_cp = x_cg + l_cp * cbar with l_cp = -dC_m/dC_L of {names['Cm']} (Eq. 32) at the mean centre of "
             f"gravity, {span}; dashed: alpha* of each separation "
             "state (thesis Fig. 9). The aircraft is statically stable where x_cp lies aft of x_cg.")
    else:
        notes.append(f"{names['Cm']} has no C_L term, so it implies no centre of pressure; that figure is left out.")
    vi_de = rd.derived_pitch(vi, alpha, ref)["Cm_de"] if vi else None
    emit(fg.elevator(alpha, derived["Cm_de"], vi_de, (names["Cm"], VAN_INGEN_MODEL_NAMES["Cm"])), "elevator_effectiveness.png",
         "Elevator effectiveness",
         f"C_m_delta_e*(alpha) = dC_m/d delta_e of {names['Cm']} (Eq. 33) and of {VAN_INGEN_MODEL_NAMES['Cm']}, whose "
         "max(1/2, X) term forces a 50 % loss, with the separation states at equilibrium (thesis Fig. 10).")


def _dynamic_figures(emit: Emit, campaign: Campaign, names: Mapping[str, str], ms: ModelSet, train: Campaign,
                     val: Campaign, ref, options: FitOptions) -> dict:
    """The validation time traces, the dynamic stall hysteresis and the parameter correlations; returns the
    hysteresis figure's data (its maneuver is the one the forward simulation replays)."""
    selection = rd.trace_selection(ms, val, train)
    emit(fg.traces(selection), "time_traces.png", "Measured and modelled coefficients",
         "Validation maneuvers with the best, median and worst R^2 of each coefficient (one row per coefficient; "
         f"models {names['CL']}, {names['CD']}, {names['Cm']} fitted on the training maneuvers) (thesis Fig. 13). "
         "Shaded: the model's 95 % confidence band along the flown maneuver (the delta method through the "
         "separation states, as flown) and, lighter, its 95 % prediction band (plus the training residual's "
         "variance in each sample's alpha band); drag and pitch on the lift model's C_L at its estimate. "
         + rd.r2_sentence(ms, val))
    hyst = rd.hysteresis(ms, campaign, ref)
    emit(fg.hysteresis_loop(hyst), "hysteresis.png", "Dynamic stall hysteresis",
         f"C_L against alpha during maneuver {hyst['maneuver']} ({hyst['kind']}, {hyst['split']}): the separation "
         "lag makes lift overshoot the static curve while alpha rises and fall below it while alpha falls.")
    emit(fg.correlations(ms.summaries), "correlations.png", "Parameter correlations",
         f"Correlation matrices of the estimates ({options.covariance} covariance); '!' marks |rho| > 0.9.")
    return hyst


def _diagnosis_figures(emit: Emit, campaign: Campaign, fits: ReportFits, ms: ModelSet) -> dict | None:
    """The gap breakdown before and after the best effect and the signals the library does not explain; returns
    the diagnosis as its document (None: no diagnosis)."""
    diagnose_coefficient = fits.diagnosis_coefficient
    # the page renders the diagnosis as its document (diagnosis.json), the form its captions quote
    diagnosis = None if fits.diagnosis is None else fits.diagnosis.to_dict()
    if diagnosis is not None:
        if fits.effect is not None:
            best, changed, fitted = fits.effect
            g = rd.with_effect(ms, diagnose_coefficient, changed, fitted, campaign)
            row = next(e for e in fits.diagnosis.effects if e.name == best)
            closes = fits.diagnosis.closes(0, row)
            verdict = ("the baseline is at the noise floor, so little changes"
                       if diagnosis["gap_explained_by_baseline"] or not np.isfinite(closes)
                       else f"the move closes {share(closes)} of the baseline's gap")
            emit(fg.gap(g["before"], g["after"], g["maneuvers"], g["bands"],
                        fg.gap_titles(g, best)),
                 "gap_breakdown.png", "Where the model misses the data",
                 f"Validation MSE of {diagnose_coefficient} per maneuver and alpha band ({rd.ALPHA_BAND} rad) before "
                 f"and after the best effect of the library, {best}, and the change (right; blue where the cell's MSE "
                 f"fell); noise floor {diagnosis['noise_floor']:.3g}; {verdict}. Empty cells: the maneuver never flew "
                 "that band.")
        curves = (diagnosis.get("unexplained") or {}).get("partial_dependence") or []
        if curves and not diagnosis["explained"]:
            emit(fg.partial_dependence(curves, diagnose_coefficient), "unexplained_signals.png",
                 "What the library does not explain",
                 f"{unexplained_sentence(diagnosis)} Residual of {diagnosis['final_model']} against the signals it "
                 "follows best: a smooth function of each signal alone, fitted on the training maneuvers (line), "
                 "and the validation maneuvers' mean residual per bin (points).")
    return diagnosis


def _replay_figure(emit: Emit, campaign: Campaign, ms: ModelSet, hyst: dict, notes: list[str]) -> None:
    """The hysteresis maneuver replayed through the simulator (a note instead when it cannot be)."""
    try:
        from ..flight.replay import replay
        runs = replay(campaign.data.select([hyst["index"]]), ms.aero, window_s=5.0)
        rms = runs[0].rms
        emit(fg.replay_traces(runs[0]), "forward_simulation.png", "Forward simulation",
             f"Maneuver {hyst['maneuver']} replayed through the simulator with the identified models: recorded "
             "elevator and thrust drive it open loop in 5 s windows, each started from the measured states. RMS "
             f"error: alpha {rms['alpha']:.4f} rad, q {rms['q']:.4f} rad/s, V {rms['V']:.2f} m/s.")
    except DataError as exc:
        notes.append(f"No forward simulation: {exc}")


# share of the corrected points on one side of a comparison curve beyond which the figure says why
OFFSET_SHARE = 0.9


def offset_note(coef: str, alpha, static_vi, points, model: str, van_ingen: str) -> str | None:
    """Why the Van Ingen curve lies above (or below) nearly every corrected point, in words for the figure; None
    when it runs through them. The points are corrected to the static condition with the identified model's own
    terms, so a structure that splits the alpha slope differently between alpha and delta_e (which follows alpha
    in trimmed flight) draws its delta_e = 0 curve offset from them although it fits the flown data."""
    if static_vi is None or len(points["alpha"]) == 0:
        return None
    curve = np.interp(points["alpha"], alpha, static_vi[coef])
    above = float(np.mean(curve > points[coef]))
    if OFFSET_SHARE > above > 1.0 - OFFSET_SHARE:
        return None
    side = "above" if above >= OFFSET_SHARE else "below"
    share = above if side == "above" else 1.0 - above
    return (f"{van_ingen} lies {side} {share:.0%} of the points: they are corrected to delta_e = 0 with "
            f"{model}'s terms. In trimmed flight delta_e follows alpha,\nso {van_ingen}'s elevator term carries "
            f"part of its alpha slope and its delta_e = 0 curve is offset:\nthe offset is in the condition "
            f"drawn, not in the fit to the flown data (its validation MSE is in the ranking).")
