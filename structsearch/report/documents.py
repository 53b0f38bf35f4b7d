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
    doc = {
        "model": fit.name, "coefficient": fit.coefficient, "params": fit.params, "stderr": fit.stderr,
        "mse": {"train": fit.mse_train, "validation": fit.mse_validation,
                **({"cv": fit.cv.mse, "cv_folds": fit.cv_folds} if fit.cv is not None else {})},
        "reference_dof": fit.reference_dof,
        "p_values": fit.p_values, "at_bound": fit.at_bound,
        "high_correlations": [list(p) for p in fit.high_correlations], "insignificant": list(fit.insignificant),
        "r2": {"train": fit.train.r2.as_dict(), "validation": fit.validation.r2.as_dict()},
        "n_starts": fit.n_starts, "n_reached_best": fit.n_reached_best,
        "converged": fit.converged, "message": fit.message, "nfev": fit.nfev,
        "identifiable": fit.identifiable, "not_identifiable": fit.not_identifiable,
        "condition_number": fit.condition_number,
        "lift": lift and {"model": lift.name, "params": lift.params},
        "covariance": fit.estimates.covariance_record(),
    }
    if bands is not None:
        doc["bands"] = bands.to_dict()
    return doc


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
    return (f"## Static curve and its bands\n\nConditions: {CONDITIONS_TEXT}" + (f" ({held})" if held else "")
            + ". Confidence: where the true static curve lies (the delta method on the parameters' covariance); "
            "prediction: where a new measurement at that alpha lies (plus the training residual's variance in "
            "that alpha band). Each point's t quantile has its own degrees of freedom (its effective number of "
            f"maneuvers minus one).\n\n{table}{reasons}\n")


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
             "## Every parameter", "", parameter_table(r, "md"), ""]
    if not r.converged:
        lines.insert(2, f"**The optimizer did not converge** ({r.message}).\n")
    return "\n".join(lines)
