"""Option types and choices of the command line, importable without numpy, scipy, sympy or pandas.

``structsearch --help`` builds the parser from this module and :mod:`.parser` only, so it starts
fast; the heavy modules that own these choices are checked against the copies here by
tests/test_api.py (the engine's covariance kinds, the admissibility's correlation limit, the
cross-validation methods).
"""
from __future__ import annotations

import argparse
import math

# Copies of the owners' constants (kept equal by a test): structsearch.engine.statistics.COVARIANCE_KINDS and
# DEFAULT_COVARIANCE, structsearch.grid_search.admissibility.MAX_CORRELATION, structsearch.fitting.options.CV_METHODS,
# structsearch.experiments.calibration_profile.PROFILE_CAMPAIGNS.
COVARIANCE_KINDS = ("colored", "white", "hac", "hac-qs", "hac-maneuver", "cluster", "hac-flight")
DEFAULT_COVARIANCE = "hac-maneuver"
MAX_CORRELATION = 0.95
CV_METHODS = ("refit", "one-step")
# structsearch.data.records.SEGMENT_CHOICES (--segment)
SEGMENT_CHOICES = ("cycles", "none")
# structsearch.fitting.candidates.MOMENT_REFERENCES (--moment-reference) and structsearch.flight.aero.CG_MOMENTS
MOMENT_REFERENCES = ("cg", "fixed")
CG_MOMENTS = ("thesis", "transfer")
PROFILE_CAMPAIGNS = 20


def _cutoff(text: str) -> tuple[str, float]:
    """One --cutoff NAME=HZ."""
    name, eq, value = text.partition("=")
    try:
        hz = float(value)
    except ValueError:
        hz = math.nan
    if not (eq and name.strip() and math.isfinite(hz) and hz > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected CHANNEL=HZ with a positive frequency, e.g. q=2")
    return name.strip(), hz


def _bound(text: str) -> tuple[str, tuple[float, float]]:
    """One --bound NAME=LO:HI."""
    name, eq, box = text.partition("=")
    lo, colon, hi = box.partition(":")
    try:
        lo_v, hi_v = float(lo), float(hi)
    except ValueError:
        lo_v = hi_v = math.nan
    if not (eq and colon and name.strip().isidentifier() and math.isfinite(lo_v) and math.isfinite(hi_v)):
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=LO:HI with finite numbers, e.g. tau2_ss=0:5")
    if not lo_v < hi_v:
        raise argparse.ArgumentTypeError(f"{text!r}: LO must be below HI")
    return name.strip(), (lo_v, hi_v)


class _Parser(argparse.ArgumentParser):
    """Bad options are one line naming the option (no usage block), exit status 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _count(text: str) -> int:
    """An integer >= 1 (starts, repeats, campaigns, samples)."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {value}")
    return value


def _non_negative(text: str) -> int:
    """An integer >= 0 (seeds; --jobs, where 0 means all cores)."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, not {value}")
    return value


def _seed_range(text: str) -> list[int]:
    """"A:B": the seeds A, A+1, ..., B-1 (at least two: a Monte Carlo spread needs two campaigns)."""
    first, sep, last = text.partition(":")
    if not sep:
        raise argparse.ArgumentTypeError(f"must be A:B (seeds A to B-1), not {text!r}")
    a, b = _non_negative(first), _non_negative(last)
    if b - a < 2:
        raise argparse.ArgumentTypeError(f"must give at least two seeds (A:B with B >= A + 2), not {text!r}")
    return list(range(a, b))


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def _float_option(text: str, ok, requirement: str) -> float:
    """A number that passes ``ok``; otherwise "must <requirement>, not <text>"."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not ok(value):
        raise argparse.ArgumentTypeError(f"must {requirement}, not {text}")
    return value


def _angle_degrees(text: str) -> float:
    """A finite angle of attack in degrees, within +-90."""
    return _float_option(text, lambda v: -90.0 < v < 90.0, "be an angle of attack in degrees within +-90")


def _non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    return _float_option(text, lambda v: math.isfinite(v) and v >= 0.0, "be a finite number >= 0")


def _finite_float(text: str) -> float:
    """A finite number (a body station, which may lie ahead of the datum)."""
    return _float_option(text, math.isfinite, "be a finite number")


def _positive_float(text: str) -> float:
    """A finite number > 0."""
    return _float_option(text, lambda v: math.isfinite(v) and v > 0.0, "be a finite number > 0")


def _fraction(text: str) -> float:
    """A number in (0, 1] (scales, correlation limits)."""
    return _float_option(text, lambda v: 0.0 < v <= 1.0, "lie in (0, 1]")


def _jobs(args) -> int:
    """--jobs as a process count: 0 means every core."""
    import os
    return args.jobs or os.cpu_count() or 1


def _bounds(args) -> tuple:
    """The --bound options as ((name, (lo, hi)), ...), the last one of a name winning."""
    return tuple(sorted(dict(getattr(args, "bound", None) or []).items()))


def _covariance_kinds(text: str) -> tuple[str, ...]:
    """``--kinds hac-maneuver,hac-flight``: covariance kinds out of COVARIANCE_KINDS, each once."""
    kinds = tuple(dict.fromkeys(k.strip() for k in text.split(",") if k.strip()))
    unknown = [k for k in kinds if k not in COVARIANCE_KINDS]
    if not kinds or unknown:
        raise argparse.ArgumentTypeError(f"unknown covariance kind {unknown[0] if unknown else text!r}; known: "
                                         f"{', '.join(COVARIANCE_KINDS)}")
    return kinds


def _flight_effects(text: str) -> tuple[str, ...]:
    """``--flight-effects x_cg,intercept``: names out of structsearch.fitting.flight_effects.EFFECTS."""
    from ..data.errors import DeclarationError
    from ..fitting.flight_effects import parse_effects
    try:
        return parse_effects([t.strip() for t in text.split(",")], "--flight-effects")
    except DeclarationError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--flight-effects: ")) from None
