"""JSON documents the commands write: ``fit.json`` (docs/interfaces.md section 2, plus ``converged``, ``identifiable``,
``not_identifiable`` and ``condition_number`` of 5.4)."""
from __future__ import annotations

from ..fitting.candidate_result import CandidateResult
from ..fitting.lift_fit import LiftFit


def fit_document(fit: CandidateResult, lift: LiftFit | None) -> dict:
    """``fit.json`` of one fitted candidate (and the lift model whose states it uses); written with
    :func:`structsearch.data.atomic.write_json`, which turns what could not be estimated into null."""
    return {
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
    }
