"""When a move is adopted: the test of a child structure against its parent.

A nested move (an effect, a term, a state or a state's lag added: the parent is the child with the new
parameters at zero) is tested by the Wald test of those parameters on the covariance the fit kept (the
options' kind: maneuver-aware, coloured residuals), the most powerful test the fit offers. Every other move
(a replacement, a lift model, a removal) is tested out of sample.

The out-of-sample statistic is the ranking's: the per-maneuver relative MSE out of sample, paired maneuver by maneuver
and weighted by samples, over every maneuver that has one: the training maneuvers held out by the
maneuver-grouped cross-validation and the validation maneuvers (only these when a fit has no folds, or when the
two were cross-validated by different methods: a structure with another static separation form has refitted folds,
:func:`structsearch.discovery.explore.refits_folds`, and a form move is tested against its parent refitted alike).
Pooling both doubles the pairs the test has; each error is still a prediction of data the fit did not see. A split
of fewer than :data:`~structsearch.fitting.folds.UNITS_BELOW_MANEUVERS` held-out units (a few long records) is
paired by units smaller than a maneuver instead: the cycles of a periodic record, or contiguous blocks as long as
the shortest maneuver worth fitting (:func:`structsearch.fitting.folds.score_units`); the test's ``basis`` says
so ("cv+validation, paired by blocks") and ``n_maneuvers`` counts the pairs. A
non-nested move *improves* when the one-sided paired t-test of ``1 - child/parent`` > 0 rejects at ``alpha / m``;
a nested move when its Wald test rejects at ``alpha / m`` and the pooled held-out MSE (the samples' mean, what the
search compares) falls. The relative gain weighs every maneuver alike, so it can be negative for a term that a
few large-residual maneuvers need and the rest do not notice (the first terms of a pitch model fitted from the
intercept alone); the Wald test already judges the parameters, and the pooled gain only asks that the fit does
not predict worse. ``m``: Bonferroni over the moves a step tries from
that parent, so that the step's family-wise false-adoption rate stays below ``alpha`` whatever the number
of moves (the rate measured on null campaigns, the final models on their own truth, is in
``results/null_benchmark/withheld_benchmark.md``, made by ``structsearch diagnose --benchmark --parts null
--null-seeds 20 --scale 0.1``). A move *simplifies* (fewer parameters) when its relative
excess over the parent is within one standard error (or 1 %): the ranking's one-standard-error rule.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.special import stdtr

from ..engine.scores import weighted_mean_se
from ..engine.ties import TIE_RTOL
from ..fitting.candidate_result import CandidateResult
from ..fitting.comparison import MIN_MANEUVERS, within_noise

# The family-wise rate of one step's improvement test (Bonferroni over its moves).
DEFAULT_ALPHA = 0.10
TEST_NAME = ("paired one-sided t-test of the out-of-sample per-maneuver relative MSE (held-out training and "
             "validation maneuvers), Bonferroni over the step's moves")
WALD_TEST_NAME = "Wald test of the parameters the move adds (the fit's covariance), Bonferroni over the step's moves"


@dataclass(frozen=True)
class MoveTest:
    """The adoption test of one child against its parent: the mean relative gain (1 - child/parent per maneuver)
    and its standard error, the one-sided p-value and the threshold (alpha / moves tried); NaN p-value with
    ``reason`` when it cannot be computed (fewer than three maneuvers, a failed fit)."""

    basis: str                  # "cv+validation" or "validation"
    gain: float
    gain_se: float
    n_maneuvers: int
    p_value: float              # the paired out-of-sample test
    threshold: float
    reason: str = ""
    # a nested move (it only adds parameters, whose zero gives back the parent): the Wald test of them on the
    # covariance the fit kept; None for another move, or for a fit screened without statistics
    wald_p_value: float | None = None
    # 1 - child/parent of the pooled held-out MSE (the samples' mean over the same maneuvers)
    pooled_gain: float = float("nan")
    # adopted in place of this move (within one standard error of it; the step's best, whose test passed)
    stands_for: str = ""

    @property
    def kind(self) -> str:
        return "wald" if self.wald_p_value is not None else "paired"

    @property
    def decisive_p_value(self) -> float:
        """The p-value the adoption decides on: Wald for a nested move, the paired test otherwise."""
        return self.wald_p_value if self.wald_p_value is not None else self.p_value

    @property
    def improves(self) -> bool:
        p = self.decisive_p_value
        gain = self.pooled_gain if self.kind == "wald" else self.gain
        return bool(np.isfinite(p) and p < self.threshold and gain > 0)

    @property
    def within_one_se(self) -> bool:
        """Not worse than the parent beyond one standard error (or 1 %): a simplification may be adopted (the
        ranking's rule, :func:`structsearch.fitting.comparison.within_noise`, on the child's excess -gain)."""
        return within_noise(-self.gain, self.gain_se)

    def to_dict(self) -> dict:
        def num(x):
            return float(x) if np.isfinite(x) else None
        return {"test": WALD_TEST_NAME if self.kind == "wald" else TEST_NAME, "kind": self.kind,
                "p_value": num(self.decisive_p_value), "threshold": self.threshold, "basis": self.basis,
                "gain": num(self.gain), "gain_se": num(self.gain_se), "n_maneuvers": self.n_maneuvers,
                "paired_p_value": num(self.p_value), "pooled_gain": num(self.pooled_gain),
                "stands_for": self.stands_for or None, "reason": self.reason or None}


def _paired_units(scores) -> tuple[np.ndarray, np.ndarray, str]:
    """A split's out-of-sample MSE and samples per unit the test pairs: per unit smaller than a maneuver (cycles,
    blocks) where the split has too few maneuvers and kept them (``SplitScores.units``), else per maneuver."""
    if scores.units:
        return np.array(scores.mse_units, float), np.array(scores.n_units, float), scores.units
    return np.array(scores.mse_maneuvers, float), np.array(scores.n_maneuvers, float), ""


def _labelled(basis: str, units: list[str]) -> str:
    """The basis with the smaller units it pairs, if any ("cv+validation, paired by blocks")."""
    used = sorted({u for u in units if u})
    return f"{basis}, paired by {' and '.join(used)}" if used else basis


def _per_maneuver(result: CandidateResult) -> tuple[str, np.ndarray, np.ndarray]:
    """Out-of-sample MSE and samples of every unit: the training maneuvers held out by the folds, then the
    validation maneuvers (fitted on all training maneuvers); the validation ones alone without folds. A split of
    few maneuvers is paired by its smaller units (:func:`_paired_units`), and the basis says so."""
    parts = [("cv", result.cv)] if result.cv is not None else []
    parts.append(("validation", result.validation))
    units = [_paired_units(s) for _, s in parts]
    return (_labelled("+".join(n for n, _ in parts), [u[2] for u in units]),
            np.concatenate([u[0] for u in units]), np.concatenate([u[1] for u in units]))


def move_test(parent: CandidateResult, child: CandidateResult, alpha: float, n_moves: int,
              new_parameters: tuple[str, ...] = (), statistics: bool = True) -> MoveTest:
    """The child against the parent (module docstring); ``new_parameters`` are those a nested move adds (their
    Wald test decides, when the child has ``statistics``)."""
    test = _paired(parent, child, alpha, n_moves)
    if new_parameters and statistics and not child.failed:
        wald = child.wald_test([n for n in new_parameters if n in child.estimates.params]).p_value
        test = dataclasses.replace(test, wald_p_value=float(wald) if np.isfinite(wald) else float("nan"))
    return test


# Relative changes of an MSE below this are rounding (fits converge to 1e-10 of their cost; two kernels'
# rounding differs by 1e-13): ties, resolved the same way on every machine (structsearch.engine.ties).
ROUNDING_GAIN = TIE_RTOL


def _methods_differ(a: CandidateResult, b: CandidateResult) -> bool:
    """Whether ``a`` and ``b`` were cross-validated by different methods (a linear fit's folds are exact either
    way, as the ranking has it)."""
    methods = {r.cv_method for r in (a, b) if r.cv is not None and r.estimates is not None
               and r.estimates.nonlinear_names}
    return len(methods) > 1


def _paired(parent: CandidateResult, child: CandidateResult, alpha: float, n_moves: int) -> MoveTest:
    threshold = alpha / max(n_moves, 1)
    if parent.failed or child.failed:
        return MoveTest("", float("nan"), float("nan"), 0, float("nan"), threshold, "a fit failed")
    basis, before, _ = _per_maneuver(parent)
    child_basis, after, samples = _per_maneuver(child)
    if child_basis != basis or len(after) != len(before) or _methods_differ(parent, child):
        # one of them without folds, or folds of another method (one-step and refitted: a structure with another
        # static form is cross-validated by refitted folds): compare what both have alike
        (before, _, unit), (after, samples, other) = _paired_units(parent.validation), _paired_units(child.validation)
        if unit != other:   # one kept its smaller units and the other not: both per maneuver
            before, after = np.array(parent.validation.mse_maneuvers), np.array(child.validation.mse_maneuvers)
            samples, unit = np.array(child.validation.n_maneuvers, float), ""
        basis = _labelled("validation", [unit])
    gain_each = 1.0 - after / before
    # a move that leaves the structure's fit as it was (a term it already has) changes each MSE by rounding
    # only: those gains are zero, so that no test or sign follows the processor's rounding
    gain_each = np.where(np.abs(gain_each) <= ROUNDING_GAIN, 0.0, gain_each)
    gain, se = weighted_mean_se(gain_each, samples)
    pooled = float(1.0 - np.dot(after, samples) / np.dot(before, samples))
    pooled = 0.0 if abs(pooled) <= ROUNDING_GAIN else pooled
    n = len(gain_each)
    if n < MIN_MANEUVERS or not np.isfinite(se) or se <= 0:
        return MoveTest(basis, float(gain), float("nan"), n, float("nan"), threshold,
                        f"{n} maneuvers: no spread of the per-maneuver gain" if n < MIN_MANEUVERS else
                        "no spread of the per-maneuver gain", pooled_gain=pooled)
    p_value = float(stdtr(n - 1, -gain / se))   # P(T >= t): the child better than the parent
    return MoveTest(basis, float(gain), float(se), n, p_value, threshold, pooled_gain=pooled)
