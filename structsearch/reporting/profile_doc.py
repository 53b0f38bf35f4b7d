"""The profile intervals of a fit's nonlinear parameters as a Markdown section (``fit.md``)."""
from __future__ import annotations

import math


def _bound(value: float, is_open: bool) -> str:
    if not math.isfinite(value):
        return "NaN"
    return f"{value:.5g}" + (" (box edge, open)" if is_open else "")


def _interval(i) -> str:
    return f"{_bound(i.low, i.open_low)} .. {_bound(i.high, i.open_high)}"


def _wald(i) -> str:
    return "NaN" if not (math.isfinite(i.wald_low) and math.isfinite(i.wald_high)) else \
        f"{i.wald_low:.5g} .. {i.wald_high:.5g}"


def profile_table(profiles) -> str:
    """``profiles`` (:class:`structsearch.engine.profile.Profiles`) as a Markdown section: per nonlinear
    parameter and level its profile interval beside its Wald interval, the variance ratio c_j and the t dof."""
    from tabulate import tabulate
    head = "## Profile intervals of the nonlinear parameters\n\n"
    if not profiles.parameters:
        return head + ("This model has no nonlinear parameter of its own (its separation states, if any, are its "
                       "lift model's, held at that fit's estimates): no profile.\n")
    levels = profiles.levels
    rows = []
    for p in profiles.parameters:
        row = [p.name, f"{p.estimate:.5g}"]
        for level in levels:
            i = p.interval(level)
            row += [_interval(i), _wald(i)]
        row += [f"{p.variance_ratio:.3g}" if math.isfinite(p.variance_ratio) else "NaN",
                f"{p.dof:.1f}" if math.isfinite(p.dof) else "NaN", p.refits]
        rows.append(row)
    headers = ["parameter", "estimate"]
    for level in levels:
        headers += [f"{level:.0%} profile", f"{level:.0%} Wald"]
    headers += ["c_j", "t dof", "refits"]
    why = []
    for p in profiles.parameters:
        if p.reason:
            why.append(f"{p.name}: no interval: {p.reason}")
            continue
        for i in p.intervals:
            for side, reason, is_open in (("lower", i.reason_low, i.open_low), ("upper", i.reason_high, i.open_high)):
                if reason and not is_open:
                    why.append(f"{p.name} ({i.level:.0%}, {side}): {reason}")
        why += [f"{p.name}: {n}" for n in p.notes]
    return (head + "Each parameter held at values on either side of its estimate, every other parameter refitted "
            "(nonlinear ones by the variable-projection solve, warm-started; linear ones by projection): the "
            "interval is where the statistic (S(theta_j) - S_min) / (sigma^2 c_j) reaches the square of the Wald "
            f"interval's t quantile (same dof). c_j = reported ({profiles.covariance_kind}) / white variance of the "
            "parameter: the plain likelihood-ratio statistic (c_j = 1) would give intervals as narrow as the white "
            "covariance's on these coloured, heteroscedastic residuals. For a model linear in the parameter the "
            "profile interval is the Wald interval; where they differ the model is nonlinear over the interval "
            "(an asymmetric profile interval follows the skew of the estimator). A side marked \"box edge, open\" "
            "reached the parameter's box before the statistic crossed: the data do not bound it there.\n\n"
            + tabulate(rows, headers=headers, tablefmt="github") + "\n"
            + ("\n" + "\n".join(f"- {w}" for w in why) + "\n" if why else ""))
