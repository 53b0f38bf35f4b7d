"""Two fits compared out of sample: one rule for the ranking, the structure search and the diagnosis.

The statistic is the per-maneuver relative MSE excess of one fit over another, on the same held-out maneuvers
(cross-validation folds or the validation maneuvers): relative, because maneuvers differ in difficulty by
orders of magnitude (a deep stall against a pull-up) and a missing effect shows as a consistent relative
excess; its mean and standard error are sample-weighted. The one-standard-error rule: an excess within one
standard error, or within the practical tolerance of 1 %, is noise; with fewer than three maneuvers there is no
spread to estimate and the practical tolerance alone decides.
"""
from __future__ import annotations

import numpy as np

from ..engine.scores import weighted_mean_se

# A relative excess below this is never a reason to prefer a larger model.
PRACTICAL_TOLERANCE = 0.01
# How far above the best fit an admissible structure may fit and still be the answer (search, discover and
# diagnose alike): a held-out MSE 25 % above the best is an RMS error 12 % above it, less than a wind tunnel's
# runs of one airfoil differ from each other at another frequency or Reynolds number, and far below the factor
# of 2 and more that a missing effect costs. Beyond it the outputs say that no admissible structure is near.
ANSWER_TOLERANCE = 0.25
# Fewer maneuvers than this give no standard error of an excess ("n/a"): only the practical tolerance.
MIN_MANEUVERS = 3


def relative_excess(mse: np.ndarray, reference_mse: np.ndarray, samples: np.ndarray) -> tuple[float, float]:
    """Mean and standard error of ``mse / reference_mse - 1`` over maneuvers, weighted by their ``samples``;
    the standard error is NaN with fewer than :data:`MIN_MANEUVERS` maneuvers."""
    excess = np.asarray(mse, float) / np.asarray(reference_mse, float) - 1.0
    mean, se = weighted_mean_se(excess, np.asarray(samples, float))
    return float(mean), (float(se) if len(excess) >= MIN_MANEUVERS else float("nan"))


def noise_bar(se: float) -> float:
    """How large an excess the data cannot tell from zero: one standard error, at least the practical
    tolerance (the tolerance alone when there is no standard error)."""
    return max(se, PRACTICAL_TOLERANCE) if np.isfinite(se) else PRACTICAL_TOLERANCE


def answer_bar(se: float) -> float:
    """How far (relative excess of held-out MSE) an admissible structure may fit above the best fit and still be
    the answer: the noise bar, at least :data:`ANSWER_TOLERANCE`."""
    return max(noise_bar(se), ANSWER_TOLERANCE)


def within_noise(excess: float, se: float) -> bool:
    """The one-standard-error rule: ``excess`` (relative, of one fit over another) is within noise."""
    return bool(np.isfinite(excess) and excess <= noise_bar(se))
