"""A fit's summary, rendered one way as text, Markdown, HTML, LaTeX or CSV (building a string is not I/O).

:class:`FitSummary` is what ``summary()`` of a :class:`~.results.FitResult`, of a search's candidate
result and of :class:`~.estimates.ParameterEstimates` returns; ``report.fit_report`` and the parameter
tables of ``report.tables`` are built on the same functions, so every table of a fit looks alike.
A *fit* here is anything that reads like one: ``names``, ``nonlinear_names``, ``params``, ``stderr``,
``p_values``, ``significant``, ``at_bound``, ``high_correlations``, ``not_identifiable``.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .estimates import HIGH_CORRELATION

FORMATS = ("text", "markdown", "latex", "html", "csv")
TABLEFMT = {"text": "simple", "markdown": "github", "md": "github", "latex": "latex_booktabs",
            "tex": "latex_booktabs", "html": "html"}
# CSV numbers carry 10 significant digits: what the estimates support, and no churn in the 15th digit
# between machines.
CSV_DIGITS = 10


def csv_value(v):
    """A CSV cell: floats with CSV_DIGITS significant digits, NaN as empty, the rest as is."""
    if isinstance(v, (float, np.floating)):
        return "" if not math.isfinite(v) else f"{float(v):.{CSV_DIGITS}g}"
    return v


def render_table(rows, headers, fmt: str, floatfmt: str = ".6g", numparse: bool = True) -> str:
    """One table as text, Markdown ("markdown"/"md"), LaTeX ("latex"/"tex"), HTML or CSV."""
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(headers)
        writer.writerows([[csv_value(v) for v in row] for row in rows])
        return buf.getvalue()
    if fmt not in TABLEFMT:
        raise ValueError(f"format must be one of {FORMATS}, not {fmt!r}")
    from tabulate import tabulate
    return tabulate(rows, headers=headers, tablefmt=TABLEFMT[fmt], floatfmt=floatfmt,
                    disable_numparse=not numparse)


def with_newline(text: str, fmt: str) -> str:
    return text if fmt == "csv" else text + "\n"


# ----- the parameters of one fit -----------------------------------------------------------------
PARAMETER_HEADERS = ["parameter", "unit", "kind", "estimate", "std. dev.", "ref. dof", "t", "p (two-sided)",
                     "flags"]
# A parameter whose t reference has fewer degrees of freedom than this rests on few maneuvers: its interval is
# wide by the t quantile (t_0.975(4) = 2.78 against 1.96), and its standard deviation itself, a per-maneuver sum
# over few terms, is uncertain and on the simulated campaigns tends to be too small (bench --calibration: reported
# over Monte Carlo down to 0.5). The table says so next to the number (issue 30) rather than letting the quantile
# alone carry the interval's coverage.
FEW_DOF = 5.0


def parameter_flags(fit, name: str) -> list[str]:
    flags = []
    dof = _reference_dof(fit, name)
    if math.isfinite(dof) and dof < FEW_DOF:
        flags.append(f"few maneuvers (t dof {dof:.1f})")
    if name in fit.at_bound:
        flags.append(f"at {fit.at_bound[name]} bound")
    if getattr(fit, "withheld", None):
        flags.append("no statistics: not converged")
    elif name in (fit.not_identifiable or {}):
        flags.append("not identifiable")
    elif not fit.significant[name]:
        flags.append("t-test accepts 0")
    if any(name in pair[:2] for pair in fit.high_correlations):
        flags.append(f"|rho| > {HIGH_CORRELATION}")
    return flags


def parameter_rows(fit) -> list[list]:
    rows = []
    for name in fit.names:
        value, se = fit.params[name], fit.stderr[name]
        t = value / se if se > 0 else math.nan  # no standard deviation, no t
        kind = "nonlinear" if name in fit.nonlinear_names else "linear"
        rows.append([name, parameter_unit(fit, name), kind, value, se, _reference_dof(fit, name), t,
                     fit.p_values[name], "; ".join(parameter_flags(fit, name))])
    return rows


def parameter_unit(fit, name: str) -> str:
    """The parameter's unit as the fit records it ("unknown" when it does not); an angle in rad also in deg, the
    way flight-test engineers read a_star."""
    unit = (getattr(fit, "units", None) or {}).get(name, "unknown")
    value = fit.params[name]
    if unit == "rad" and math.isfinite(value):
        return f"rad ({math.degrees(value):.2f} deg)"
    return unit


def _reference_dof(fit, name: str) -> float:
    """The degrees of freedom of the parameter's t reference (inf: the normal one; NaN: none, or a fit that does
    not say)."""
    dof = (getattr(fit, "reference_dof", None) or {}).get(name)
    return float(dof) if dof is not None else math.nan


def parameter_table(fit, fmt: str = "text", floatfmt: str = ".4g") -> str:
    """Estimates, standard deviations, each t reference's degrees of freedom, t-tests and flags (thesis Tables 11,
    13, 15; a flag where the reference has fewer than FEW_DOF degrees of freedom)."""
    return with_newline(render_table(parameter_rows(fit), PARAMETER_HEADERS, fmt, floatfmt=floatfmt), fmt)


def covariance_head(estimates) -> list[tuple[str, str]]:
    """The head lines every summary shows of a fit's covariance and identifiability."""
    head = [("scaled condition number", f"{estimates.condition_number:.3g}")]
    if estimates.withheld:   # whether the data identify the parameters is not known where the optimizer stopped
        head.append(("standard deviations", f"NONE: {estimates.withheld}"))
    else:
        head.append(("identifiable", "yes" if estimates.identifiable else
                     f"NO ({len(estimates.not_identifiable)} parameters)"))
    if not estimates.covariance_psd:
        head.append(("covariance", "INDEFINITE: some standard deviations or correlations are not estimable"))
    return head


def covariance_line(kind: str, max_lag, bandwidth) -> str:
    return (kind + (f" (lags <= {max_lag})" if max_lag is not None else "")
            + (f" (bandwidth {bandwidth:.1f} samples)" if bandwidth is not None else ""))


@dataclass(frozen=True, eq=False)
class FitSummary:
    """One summary of a fit: the model as equations (where the fit knows its model), a head of (label, value)
    lines, the parameters with tests and flags, the strong correlations and why a parameter is not identifiable. ``str()`` is the text; notebooks show the HTML."""

    fit: Any
    head: tuple[tuple[str, str], ...] = ()  # (label, value) lines; a label may repeat
    equations: Any = None                   # the model's equations.Equations (None: a fit without a model)

    def render(self, fmt: str = "text") -> str:
        if fmt not in FORMATS:
            raise ValueError(f"format must be one of {FORMATS}, not {fmt!r}")
        if fmt == "csv":
            return parameter_table(self.fit, "csv", floatfmt=".6g")
        from tabulate import tabulate
        tablefmt = TABLEFMT.get(fmt, "simple")
        parts = [self.equations.render(fmt)] if self.equations is not None and self.equations.text else []
        if self.head:
            parts.append(tabulate([list(line) for line in self.head], tablefmt=tablefmt))
        parts.append(parameter_table(self.fit, fmt, floatfmt=".6g").rstrip("\n"))
        if self.fit.high_correlations:
            corr = [[a, b, f"{c:+.3f}"] for a, b, c in self.fit.high_correlations]
            parts.append(tabulate(corr, headers=["parameter", "parameter", "correlation"], tablefmt=tablefmt))
        withheld = getattr(self.fit, "withheld", None)
        if withheld:
            parts.append(tabulate([[withheld]], headers=["no standard deviation, p-value, interval or correlation"],
                                  tablefmt=tablefmt))
        elif self.fit.not_identifiable:
            why = [[name, reason] for name, reason in self.fit.not_identifiable.items()]
            parts.append(tabulate(why, headers=["not identifiable", "why"], tablefmt=tablefmt))
        sep = "\n\n" if fmt != "html" else "\n"
        return sep.join(parts) + "\n"

    def as_text(self) -> str:
        return self.render("text")

    def as_markdown(self) -> str:
        return self.render("markdown")

    def as_html(self) -> str:
        return self.render("html")

    def as_latex(self) -> str:
        return self.render("latex")

    def as_csv(self) -> str:
        return self.render("csv")

    def __str__(self) -> str:
        return self.as_text()

    def _repr_html_(self) -> str:
        return self.as_html()
