"""Human-readable summaries of a FitResult, kept apart from the numerics (like lmfit's fit_report)."""
from __future__ import annotations

from tabulate import tabulate

from ..engine.results import FitResult
from .tables import TABLEFMT, FORMATS, correlation_table, parameter_table

__all__ = ["fit_report", "parameter_table", "correlation_table", "FORMATS"]


def fit_report(result: FitResult, fmt: str = "text") -> str:
    """One summary of a fit: goodness of fit, parameters with tests and flags, strong correlations."""
    r2 = result.r2_summary
    head = [
        ["model", result.model],
        ["coefficient", result.coefficient or "-"],
        ["samples / maneuvers", f"{result.n_samples} / {len(result.segment_names)}"],
        ["parameters (nonlinear + linear)", f"{len(result.nonlinear_names)} + {len(result.linear_names)}"],
        ["RSS", f"{result.rss:.6g}"],
        ["MSE", f"{result.mse:.6g}"],
        ["R^2 (all samples)", f"{result.r2:.6f}"],
        ["R^2 per maneuver mean / min / max", f"{r2['mean']:.4f} / {r2['min']:.4f} / {r2['max']:.4f}"],
        ["covariance", result.covariance_kind
         + (f" (lags <= {result.max_lag})" if result.max_lag is not None else "")
         + (f" (bandwidth {result.bandwidth:.1f} samples)" if result.bandwidth is not None else "")],
        ["optimizer", f"{'converged' if result.success else 'NOT CONVERGED'}: {result.message} "
                      f"({result.nfev} evaluations)"],
        ["starts reaching the best cost", f"{result.n_reached_best} of {result.n_starts}"],
        ["scaled condition number", f"{result.condition_number:.3g}"],
        ["identifiable", "yes" if result.identifiable else f"NO ({len(result.not_identifiable)} parameters)"],
    ]
    if not result.covariance_psd:
        head.append(["covariance", "INDEFINITE: some standard deviations or correlations are not estimable"])
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, not {fmt!r}")
    if fmt == "csv":
        return parameter_table(result, "csv", floatfmt=".6g")
    tablefmt = TABLEFMT.get(fmt, "simple")
    parts = [tabulate(head, tablefmt=tablefmt), parameter_table(result, fmt, floatfmt=".6g").rstrip("\n")]
    if result.high_correlations:
        corr = [[a, b, f"{c:+.3f}"] for a, b, c in result.high_correlations]
        parts.append(tabulate(corr, headers=["parameter", "parameter", "correlation"], tablefmt=tablefmt))
    if result.not_identifiable:
        why = [[name, reason] for name, reason in result.not_identifiable.items()]
        parts.append(tabulate(why, headers=["not identifiable", "why"], tablefmt=tablefmt))
    sep = "\n\n" if fmt != "html" else "\n"
    return sep.join(parts) + "\n"
