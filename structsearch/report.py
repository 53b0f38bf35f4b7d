"""Human-readable summaries of a FitResult, kept apart from the numerics (like lmfit's fit_report)."""
from __future__ import annotations

import csv
import io

import numpy as np
from tabulate import tabulate

from .results import FitResult

FORMATS = ("text", "markdown", "latex", "html", "csv")
_TABLEFMT = {"text": "simple", "markdown": "github", "md": "github", "latex": "latex_booktabs",
             "tex": "latex_booktabs", "html": "html"}


def render_table(rows, headers, fmt: str, floatfmt: str = ".6g", numparse: bool = True) -> str:
    """One table as text, Markdown ("markdown"/"md"), LaTeX ("latex"/"tex"), HTML or CSV."""
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(headers)
        writer.writerows(rows)
        return buf.getvalue()
    if fmt not in _TABLEFMT:
        raise ValueError(f"format must be one of {FORMATS}, not {fmt!r}")
    return tabulate(rows, headers=headers, tablefmt=_TABLEFMT[fmt], floatfmt=floatfmt,
                    disable_numparse=not numparse)


def parameter_rows(result: FitResult) -> list[list]:
    rows = []
    for name in result.names:
        flags = []
        if name in result.at_bound:
            flags.append(f"at {result.at_bound[name]} bound")
        if not result.significant[name]:
            flags.append("not significant")
        if any(name in pair[:2] for pair in result.high_correlations):
            flags.append("|corr| > 0.9")
        kind = "nonlinear" if name in result.nonlinear_names else "linear"
        rows.append([name, kind, result.params[name], result.stderr[name], result.t_values[name],
                     result.p_values[name], "; ".join(flags)])
    return rows


HEADERS = ["parameter", "kind", "estimate", "std. dev.", "t", "p (two-sided)", "flags"]


def parameter_table(result: FitResult, fmt: str = "text") -> str:
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, not {fmt!r}")
    return render_table(parameter_rows(result), HEADERS, fmt)


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
        ["covariance", result.covariance_kind + (f" (lags <= {result.max_lag})"
                                                 if result.max_lag is not None else "")],
        ["optimizer", f"{result.message} ({result.nfev} evaluations)"],
        ["starts reaching the best cost", f"{result.n_reached_best} of {result.n_starts}"],
    ]
    if fmt == "csv":
        return parameter_table(result, "csv")
    tablefmt = _TABLEFMT.get(fmt, "simple")
    parts = [tabulate(head, tablefmt=tablefmt), parameter_table(result, fmt)]
    if result.high_correlations:
        corr = [[a, b, f"{c:+.3f}"] for a, b, c in result.high_correlations]
        parts.append(tabulate(corr, headers=["parameter", "parameter", "correlation"], tablefmt=tablefmt))
    sep = "\n\n" if fmt != "html" else "\n"
    return sep.join(parts) + "\n"


def correlation_table(result: FitResult, fmt: str = "text") -> str:
    rows = [[n] + [f"{v:+.2f}" for v in row] for n, row in zip(result.names, np.asarray(result.correlation))]
    return tabulate(rows, headers=[""] + list(result.names), tablefmt=_TABLEFMT.get(fmt, "simple"))
