"""JSON documents the commands write: ``fit.json`` (docs/interfaces.md section 2, plus ``converged``, ``identifiable``,
``not_identifiable`` and ``condition_number`` of 5.4)."""
from __future__ import annotations

import numpy as np

from ..fitting.candidate_result import CandidateResult
from ..fitting.lift_fit import LiftFit


def fit_document(fit: CandidateResult, lift: LiftFit | None, bands=None) -> dict:
    """``fit.json`` of one fitted candidate (and the lift model whose states it uses, and its static curve's
    ``bands``: :class:`structsearch.fitting.bands.StaticBands`); written with
    :func:`structsearch.data.atomic.write_json`, which turns what could not be estimated into null."""
    e = fit.estimates
    doc = {
        "model": fit.name, "coefficient": fit.coefficient, "params": e.params, "stderr": e.stderr,
        "mse": {"train": fit.mse_train, "validation": fit.mse_validation,
                **({"cv": fit.cv.mse, "cv_folds": fit.cv_folds} if fit.cv is not None else {})},
        "reference_dof": e.reference_dof,
        "p_values": e.p_values, "at_bound": e.at_bound,
        "bounds": {n: [float(lo), float(hi)] for n, lo, hi in zip(e.nonlinear_names, e.lower, e.upper)},
        "high_correlations": [list(p) for p in e.high_correlations], "insignificant": list(fit.insignificant),
        "r2": {"train": fit.train.r2.as_dict(), "validation": fit.validation.r2.as_dict()},
        "n_starts": fit.optimizer.n_starts, "n_reached_best": fit.optimizer.n_reached_best,
        "converged": fit.optimizer.converged, "message": fit.optimizer.message, "nfev": fit.optimizer.nfev,
        "identifiable": fit.identifiable, "not_identifiable": e.not_identifiable,
        "statistics_withheld": e.withheld,
        "condition_number": e.condition_number,
        "lift": lift and {"model": lift.name, "params": lift.params},
        "covariance": covariance_document(fit.estimates.covariance_record()),
        "cross_validation": {"scheme": fit.cv_scheme or None, "folds": fit.cv_folds,
                             "mse": fit.cv.mse if fit.cv is not None else None, "note": fit.cv_note},
    }
    if fit.equations is not None:   # the structure as equations: what each parameter multiplies
        doc["equations"] = {"text": list(fit.equations.text), "latex": list(fit.equations.latex)}
    if bands is not None:
        doc["bands"] = bands.to_dict()
    # per-flight offsets, apart from the parameters above (docs/interfaces.md 7.5); null: none estimated
    doc["flight_effects"] = None if fit.flight_effects is None else fit.flight_effects.to_dict()
    doc["warnings"] = list(fit.warnings)
    return doc


def parameter_covariance(estimates) -> dict:
    """Every parameter's covariance as fit.json's ``parameter_covariance``: ``names`` and the ``matrix`` in their
    order (what could not be estimated is null)."""
    return {"names": list(estimates.names), "matrix": np.asarray(estimates.covariance, float).tolist()}
def moment_reference_document(candidate, reference_point: float | None) -> dict:
    """Where a pitch fit takes C_m about (docs/interfaces.md 7.5): ``about`` "cg" (the recorded cg) or "fixed";
    a fixed one's ``reference_point`` [m] and the ``transfer`` that moves its C_m to the recorded cg."""
    if candidate.moment_reference != "fixed":
        return {"about": "cg"}
    from ..data.moment_transfer import TRANSFER_EXPRESSION, TRANSFER_NAME
    return {"about": "fixed", "reference_point": reference_point,
            "transfer": f"Cm = {TRANSFER_NAME} + (the model about the reference point), "
                        f"{TRANSFER_NAME} = {TRANSFER_EXPRESSION}"}


def bands_table(bands, every: int = 6) -> str:
    """The static curve's bands at every ``every``-th grid point, as Markdown (``fit.md``)."""
    from tabulate import tabulate
    b = bands.band
    rows = [[f"{a:.4f}", f"{np.degrees(a):.1f}", f"{b.estimate[i]:.5g}",
             f"{b.confidence_low[i]:.5g} .. {b.confidence_high[i]:.5g}",
             f"{b.prediction_low[i]:.5g} .. {b.prediction_high[i]:.5g}", f"{b.dof[i]:.1f}"]
            for i, a in enumerate(bands.alpha) if i % every == 0 or i == len(bands.alpha) - 1]
    pct = f"{bands.level:.0%}"
    table = tabulate(rows, headers=["alpha [rad]", "alpha [deg]", bands.coefficient, f"{pct} confidence",
                                    f"{pct} prediction", "t dof"], tablefmt="github")
    from ..fitting.bands import CONDITIONS_TEXT
    held = ", ".join(f"{k} = {v:.4g}" for k, v in bands.held.items())
    reasons = ("\n\nNot estimable where these act: " + "; ".join(bands.reasons)) if bands.reasons else ""
    return (f"## Static curve of {bands.coefficient} and its bands\n\nConditions: {CONDITIONS_TEXT}"
            + (f" ({held})" if held else "")
            + ". Confidence: where the true static curve lies (the delta method on the parameters' covariance); "
            "prediction: where a new measurement at that alpha lies (plus the training residual's variance in "
            "that alpha band). Each point's t quantile has its own degrees of freedom (its effective number of "
            f"maneuvers minus one).\n\n{table}{reasons}\n" + sampled_sentence(bands))


def few_maneuvers(record: dict) -> list[str]:
    """The parameters whose t reference (a ``covariance`` record's ``reference_dof``) has fewer than FEW_DOF
    degrees of freedom: those every parameter table flags "few maneuvers"."""
    from ..engine.summary import FEW_DOF
    return [n for n, d in (record.get("reference_dof") or {}).items() if d is not None and d < FEW_DOF]


def few_maneuvers_note(record: dict) -> str:
    """What few degrees of freedom mean and how to get more ("" when no parameter has few)."""
    from ..engine.summary import FEW_DOF
    few = few_maneuvers(record)
    if not few:
        return ""
    dof = [record["reference_dof"][n] for n in few]
    groups = record.get("groups")
    more = ("cut periodic records into their cycles (`--segment cycles`: each cycle a maneuver and a group)"
            if groups is not None and groups < 2 * FEW_DOF else "")
    return (f"{len(few)} of {len(record['reference_dof'])} t references have fewer than {FEW_DOF:g} degrees of "
            f"freedom ({_span(dof)}"
            + (f"; the covariance groups the residuals by {groups} {record.get('grouped_by', 'maneuvers')}"
               if groups is not None else "")
            + "): their intervals are wide by the t quantile (t_0.975(1) = 12.7, t_0.975(3) = 3.18) and their "
            "standard deviations themselves rest on few numbers. "
            + (f"For more: {more}; " if more else "")
            + "`--covariance hac` uses a bandwidth within each maneuver instead (reference dof m - p), which assumes "
            "the residuals decorrelate well within a maneuver and cuts slow errors off (README, calibration).")


def held_out_phrase(fit) -> str:
    """The console's words on a fit's cross-validation (its MSE and folds, or why there is none) and, when some
    parameters rest on few maneuvers, on their t references."""
    import math
    if fit.cv is not None:
        words = f", {fit.cv_folds}-fold {'blocked ' if fit.cv_scheme == 'blocks' else ''}CV {fit.cv.mse:.4g}"
    else:
        words = f", {fit.cv_note}" if fit.cv_note else ""
    few = few_maneuvers(fit.estimates.covariance_record())
    if few:
        dof = [fit.estimates.reference_dof[n] for n in few if math.isfinite(fit.estimates.reference_dof[n])]
        words += f"; {len(few)} t reference(s) on few maneuvers (dof {_span(dof)}: fit.md says what that means)"
    return words


def _span(values) -> str:
    lo, hi = min(values), max(values)
    return f"{lo:.1f}" if f"{lo:.1f}" == f"{hi:.1f}" else f"{lo:.1f}-{hi:.1f}"


def covariance_document(record: dict) -> dict:
    """fit.json's ``covariance`` (docs/interfaces.md 6.4) with ``few_maneuvers``, the parameters whose t reference
    has fewer than FEW_DOF degrees of freedom (flagged in every parameter table), and, when there are any, a
    ``note`` on what that means and how to get more."""
    out = dict(record, few_maneuvers=few_maneuvers(record))
    note = few_maneuvers_note(record)
    if note:
        out["note"] = note
    return out


def covariance_sentence(record: dict) -> str:
    """What produced a fit's standard deviations and p-values (its ``covariance`` record), in one line of
    ``fit.md``."""
    from ..engine.summary import FEW_DOF
    how = []
    if record.get("groups") is not None and record.get("grouped_by") == "flights":
        how.append(f"per maneuver and across the maneuvers of each flight, {record['groups']} flights")
    elif record.get("groups") is not None:
        how.append(f"per maneuver, {record['groups']} maneuvers")
    if record.get("bandwidth") is not None:
        how.append(f"Bartlett bandwidth {record['bandwidth']:.1f} samples")
    if record.get("max_lag") is not None:
        how.append(f"lags up to {record['max_lag']}")
    return (f"Standard deviations and p-values: the `{record['kind']}` covariance"
            + (f" ({'; '.join(how)})" if how else "")
            + f"; each parameter's t reference has the degrees of freedom in the column `ref. dof` (its effective "
            f"maneuvers minus one with a per-maneuver covariance), flagged \"few maneuvers\" below {FEW_DOF:g}. "
            "Units: the column `unit` (a linear coefficient's is the inverse of its regressor's, since the "
            "coefficient it builds is dimensionless; \"-\": dimensionless)."
            + (f" **Few maneuvers**: {few_maneuvers_note(record)}" if few_maneuvers(record) else "") + "\n")


def sampled_sentence(bands) -> str:
    """The parameter-sampling cross-check of a static band, in one paragraph (empty without one)."""
    s = bands.sampled
    if s is None:
        return ""
    r = s.to_dict()["half_width_ratio_to_delta_normal"]
    ratio = ("no point to compare" if r is None else
             f"its half width is {r['median']:.2f} times the delta method's at the normal quantile (median over the "
             f"grid; {r['min']:.2f} to {r['max']:.2f})")
    held = f" Held at their estimates (no variance): {', '.join(s.held)}." if s.held else ""
    return (f"\nCross-check by parameter sampling ({s.draws} draws from the estimate's normal distribution, seed "
            f"{s.seed}): {ratio}. A ratio near 1 says the curve is linear in its parameters over their uncertainty; "
            "the table's t quantiles are wider than the normal one where a point rests on few maneuvers."
            f"{held}\n")


def replay_paragraph(rb) -> str:
    """A joint fit's sampled forward replay in ``fit.md``: per state the band's mean half width and the replay's
    RMS error against the measurement."""
    from tabulate import tabulate
    rows = []
    for s in ("alpha", "q", "theta", "V"):
        half = 0.5 * (rb.high[s] - rb.low[s])
        err = rb.estimate[s] - rb.measured[s]
        inside = (rb.measured[s] >= rb.low[s]) & (rb.measured[s] <= rb.high[s])
        rows.append([s, f"{np.sqrt(np.mean(err ** 2)):.4g}", f"{np.nanmean(half):.4g}", f"{np.mean(inside):.0%}"])
    return "\n".join([
        f"## Forward replay of {rb.maneuver} and its band", "",
        f"The validation maneuver replayed through the simulator in {rb.window_s:g} s windows (each started from the "
        f"measured states, driven open loop by the recorded elevator and thrust), at the joint estimate and for "
        f"{rb.draws} parameter vectors drawn from the joint covariance (seed {rb.seed}; {rb.diverged} diverged and "
        f"left out). The {rb.level:.0%} band is the spread the parameters' uncertainty alone causes: it does not hold "
        "the aircraft's unmodelled forcing (turbulence, buffet, the coefficients' coloured residual), so the "
        "measurement may lie outside it.", "",
        tabulate(rows, headers=["state", "RMS error of the replay", "mean band half width", "measured inside band"],
                 tablefmt="github"), ""])


def joint_markdown(joint) -> str:
    """``fit.md`` of a joint fit (:class:`structsearch.fitting.joint.JointFit`): the shared parameters, each
    coefficient's parameters and scores, and how the weights settled."""
    from tabulate import tabulate
    from .tables import parameter_table
    r = joint.result
    rows = [[c.coefficient, c.model, f"{c.train.mse:.5g}", f"{c.validation.mse:.5g}",
             f"{c.validation.r2.mean:.3f}", f"{c.weight:.4g}"] for c in joint.coefficients]
    settled = (f"settled after {joint.iterations} iterations" if joint.weights_settled
               else f"did NOT settle in {joint.iterations} iterations")
    lines = [f"# {joint.name} (joint fit)", "",
             f"One separable problem: the coefficients share {', '.join(joint.shared)}; each keeps its own linear "
             "coefficients. Rows weighted by 1 / (the coefficient's residual variance), re-estimated until the "
             f"weights settle ({settled}); drag and pitch read the joint lift model's C_L. Statistics with the "
             f"{r.covariance_kind} covariance of the stacked problem (a maneuver's rows of every coefficient are one "
             "record).", "",
             tabulate(rows, headers=["coefficient", "structure", "MSE train", "MSE validation",
                                     "R^2 validation (mean)", "weight"], tablefmt="github"), "",
             "## Every parameter", "", covariance_sentence(r.estimates.covariance_record()),
             parameter_table(r.estimates, "md"), ""]
    lines += [sampled_sentence(b) for b in joint.bands if b.sampled is not None]
    if joint.replay is not None:
        lines.append(replay_paragraph(joint.replay))
    if not r.converged:
        lines.insert(2, f"**The optimizer did not converge** ({r.message}).\n")
    return "\n".join(lines)
