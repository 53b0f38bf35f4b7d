"""Numbers as a reader takes them in: an estimate rounded to its uncertainty, a fit statistic to a few
significant digits, a signed share without a "-0 %"."""
from __future__ import annotations

import math

# significant digits of a standard deviation (the estimate is rounded to the same decimal place)
SD_DIGITS = 2


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def with_uncertainty(estimate: float, sd: float | None, sep: str = " ± ") -> tuple[str, str]:
    """(estimate, std. dev.) as text: the std. dev. at SD_DIGITS significant digits and the estimate at the same
    decimal place; a very small or large value in powers of ten. Without a finite positive std. dev., the
    estimate at 4 significant digits and "n/a"."""
    if not _finite(estimate):
        return "n/a", "n/a"
    if not _finite(sd) or sd <= 0:
        return f"{estimate:.4g}", "n/a"
    place = math.floor(math.log10(sd)) - (SD_DIGITS - 1)   # the decimal place of the last digit kept
    big = max(abs(estimate), sd)
    if big >= 1e5 or big < 1e-3:   # powers of ten: one shared exponent keeps both readable
        exp = math.floor(math.log10(big))
        decimals = max(exp - place, 0)
        return f"{estimate / 10 ** exp:.{decimals}f}e{exp}", f"{sd / 10 ** exp:.{decimals}f}e{exp}"
    decimals = max(-place, 0)
    return _fixed(estimate, place, decimals), _fixed(sd, place, decimals)


def _fixed(x: float, place: int, decimals: int) -> str:
    if place > 0:   # digits left of the point are rounded too (12345 +- 120 -> 12300 +- 120)
        return f"{round(x, -place):.0f}"
    text = f"{x:.{decimals}f}"
    return "0" + text[2:] if text.startswith("-") and float(text) == 0 else text


def estimate_text(estimate: float, sd: float | None) -> str:
    """"estimate ± std. dev." rounded to the std. dev. (module docstring)."""
    e, s = with_uncertainty(estimate, sd)
    return e if s == "n/a" else f"{e} ± {s}"


def sig(x, digits: int = 4) -> str:
    """``x`` at ``digits`` significant digits ("n/a" when it is not a finite number)."""
    return f"{x:.{digits}g}" if _finite(x) else "n/a"


def share(x, signed: bool = False) -> str:
    """A fraction as a percentage without "-0%": below half a percent either way, "< 0.5%" (or "0%" when it is
    exactly zero); ``signed`` writes "+" on a gain."""
    if not _finite(x):
        return "n/a"
    pct = 100 * x
    if pct == 0:
        return "0%"
    if abs(pct) < 0.5:
        return "< 0.5%"   # a change this small has no sign worth reading
    text = f"{pct:.0f}%"
    return ("+" + text) if signed and pct > 0 else text
