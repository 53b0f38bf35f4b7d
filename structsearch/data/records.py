"""Short and periodic records: the shortest maneuver worth fitting, and a periodic record cut into cycles.

**How long a maneuver must be.** A separation state's dynamics are set by the convective time cbar/V: its
time constants scale with it (a pitching airfoil in a wind tunnel, cbar/V = 0.013 s, and the Citation II,
cbar/V = 0.02-0.04 s, have the same dynamics in these units, not in seconds). A maneuver is therefore too short
when it lasts fewer than :data:`MIN_CONVECTIVE_TIMES` convective times cbar/V, with V its mean airspeed and
cbar from ``[aircraft]``, or holds fewer than :data:`MIN_SAMPLES` samples (the filters, the derivative of alpha
and the fit need some). 30 convective times is twice the slowest separation lag on record (the Citation stall
strip's tau1 = 0.42 s = 15 cbar/V in the thesis' final model): a shorter record cannot tell that lag from an
offset, and every state restarts in equilibrium at a maneuver's first sample, so its warm-up must be a small
part of the maneuver. The rule passes every maneuver of a Citation campaign (tens of seconds, > 1000 convective
times) and a wind-tunnel cycle up to a reduced frequency k = omega cbar / (2 V) = pi / 30 = 0.10 (0.83 s at
cbar/V = 0.013 s: 64 convective times); ``campaign.toml`` may change it, for all kinds or per kind
(``min_convective_times``, :class:`LengthRules`).

**Cycles.** A long periodic record (a pitching airfoil, one run of several cycles) may be cut into its cycles,
each a maneuver of its own (ids ``m07.c1``, ``m07.c2``, ...; same kind, split and flight as the record). The
cycles are named by a ``cycle`` column of the maneuver file (each run of equal whole numbers one cycle), else
found from alpha: a cycle runs from one minimum of alpha to the next (a minimum: the lowest point, on alpha
smoothed over an eighth of the stretch, between a downward crossing of alpha's mean and the next upward one,
each crossing counted once alpha has been :data:`HYSTERESIS` standard deviations on the other side, so that
noise never counts twice). A stub at either end shorter than :data:`FRAGMENT_SHARE` of the period joins its
neighbour, so no sample is dropped. Alpha must look periodic (minima and crossings evenly spaced, alpha alike
one period later), else the record is an error, not cut.

Why minima: states never run across a maneuver boundary, so each cycle's separation states restart in
equilibrium with its first sample. At a minimum of alpha the airfoil has spent half a cycle at low angles (the
flow has reattached) and alpha is momentarily still, so the lagged state is at its equilibrium value and the
restart costs next to nothing: on a four-cycle record of CL-II (tau1 = 4.6 cbar/V) the training MSE of the cut
record is within 0.5 % of the whole record's (cut at upward mean crossings instead, where the state moves
fastest, it was 28 % higher). The first cycle starts where the record does, as without cutting. A cycle too
short for the rule above is an error naming the record and the cycle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .errors import DataError
from .flightdata import STEADY, TIME, check_period
from .tables import LINE_KEY
from .reading import shown

# the rule (module docstring): at least this many convective times cbar/V and this many samples per maneuver
MIN_CONVECTIVE_TIMES = 30.0
MIN_SAMPLES = 20
# what ``--segment`` / a [[maneuver]] ``segment`` key may ask: cut into cycles, or keep every record whole
SEGMENT_CHOICES = ("cycles", "none")
CYCLE_COLUMN = "cycle"
# a crossing of alpha's mean counts once alpha has been this many standard deviations on its other side
HYSTERESIS = 0.25
# a stub at either end of a record is a cycle of its own from this share of the median period on
FRAGMENT_SHARE = 0.5
# alpha is periodic when its minima and mean crossings are spaced within this factor of their median spacing
PERIOD_TOLERANCE = 1.5
# and alpha correlates with itself one period later at least this much
PERIODIC_CORRELATION = 0.9


def convective_time(cbar: float, airspeed: np.ndarray) -> float:
    """cbar / V with V the mean airspeed of the record [s]."""
    return float(cbar) / float(np.mean(airspeed))


@dataclass(frozen=True)
class LengthRule:
    """The shortest maneuver worth fitting: ``min_convective_times`` convective times cbar/V and ``min_samples``."""

    min_convective_times: float = MIN_CONVECTIVE_TIMES
    min_samples: int = MIN_SAMPLES

    def problem(self, t: np.ndarray, airspeed: np.ndarray, cbar: float) -> str | None:
        """Why a record with these time stamps and airspeeds is too short (None when it is long enough);
        airspeeds must be positive."""
        n = len(t)
        duration = float(t[-1] - t[0]) if n else 0.0
        unit = convective_time(cbar, airspeed) if n else math.nan
        times = duration / unit if n else 0.0
        if n >= self.min_samples and times >= self.min_convective_times:
            return None
        return (f"{n} samples over {duration:.3g} s = {times:.3g} convective times cbar/V (cbar/V = {unit:.3g} s "
                f"at its mean airspeed {cbar / unit:.4g} m/s); the rule asks for at least {self.min_samples} samples "
                f"and {self.min_convective_times:g} convective times ({self.min_convective_times * unit:.3g} s here; "
                "campaign.toml's min_convective_times sets the number, for every kind or per kind)")


@dataclass(frozen=True)
class LengthRules:
    """The rule for every maneuver kind: ``default``, and ``by_kind`` overrides (campaign.toml
    ``min_convective_times = 20`` or ``[min_convective_times]`` with ``default`` and kind keys)."""

    default: float = MIN_CONVECTIVE_TIMES
    by_kind: Mapping[str, float] = field(default_factory=dict)

    def for_kind(self, kind: str) -> LengthRule:
        return LengthRule(float(self.by_kind.get(kind, self.default)))

    @property
    def is_default(self) -> bool:
        return self.default == MIN_CONVECTIVE_TIMES and not self.by_kind

    def as_table(self) -> dict[str, float]:
        """The ``[min_convective_times]`` table that reads back as these rules."""
        return {"default": self.default, **self.by_kind}

    @classmethod
    def parse(cls, value, kinds: Sequence[str], source: str) -> "LengthRules":
        """campaign.toml's ``min_convective_times``: absent, a number >= 0 or a table of numbers by kind."""
        if value is None:
            return cls()
        if _count(value):
            return cls(float(value))
        if not isinstance(value, dict):
            raise DataError(f"min_convective_times must be a number >= 0 or a table of them by kind, not {shown(value)}",
                            source=source, column="min_convective_times")
        for key, v in value.items():
            if key != "default" and key not in kinds:
                raise DataError(f"[min_convective_times] has an unknown kind {shown(key)}; keys: default, "
                                f"{', '.join(kinds)}", source=source, column=key)
            if not _count(v):
                raise DataError(f"[min_convective_times] {key} must be a number >= 0, not {shown(v)}", source=source,
                                column=key)
        return cls(float(value.get("default", MIN_CONVECTIVE_TIMES)),
                   {k: float(v) for k, v in value.items() if k != "default"})


def _count(v) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v) and v >= 0
    except OverflowError:
        return False


def segment_request(entry: Mapping, source: str) -> str | None:
    """A [[maneuver]] entry's ``segment`` key ("cycles" or "none"; None when absent)."""
    value = entry.get("segment")
    if value is not None and value not in SEGMENT_CHOICES:
        raise DataError(f"segment must be one of {', '.join(SEGMENT_CHOICES)}, not {shown(value)}", source=source,
                        column="segment")
    return value


def wants_cycles(asked: str | None, entry_key: str | None, has_column: bool) -> bool:
    """Whether a record is cut into cycles: ``asked`` (the command's ``--segment``) decides for every record;
    else its [[maneuver]] ``segment`` key; else whether its file names the cycles (a ``cycle`` column)."""
    choice = asked or entry_key
    return choice == "cycles" if choice is not None else has_column


# ----- periodic records (docs/interfaces.md 7.5) ----------------------------------------------------------
def with_cycle_time(columns: dict[str, np.ndarray], maneuver: str, frequency: float | None,
                    source: str) -> dict[str, np.ndarray]:
    """A maneuver file's columns with a time column: its own, or, for a phase-averaged cycle that has none and
    whose [[maneuver]] gives its ``frequency``, t = k / (n f) for sample k of n (uniform over one period, the
    first sample at t = 0). Without either, the columns as they are (the check of required columns names t)."""
    if TIME in columns or frequency is None:
        return columns
    n = len(next((v for k, v in columns.items() if k != LINE_KEY), ()))
    if n == 0:
        raise DataError(f"maneuver {shown(maneuver)}: the file has no samples", source=source)
    return {TIME: np.arange(n, dtype=float) / (n * frequency), **columns}


def with_steady_order(columns: dict[str, np.ndarray], maneuver: str, source: str) -> dict[str, np.ndarray]:
    """A file of steady points with a time column: its own (it orders the points only), else t = 0, 1, 2 ... s
    (:data:`~.flightdata.STEADY`: no state or rate reads the time of a steady point)."""
    if TIME in columns:
        return columns
    n = len(next((v for k, v in columns.items() if k != LINE_KEY), ()))
    if n == 0:
        raise DataError(f"maneuver {shown(maneuver)}: the file has no samples", source=source)
    return {TIME: np.arange(n, dtype=float), **columns}


def period(periodic: bool, frequency: float | None, t: np.ndarray, source: str, maneuver: str,
           steady: bool = False) -> float | None:
    """A maneuver's period [s]: :data:`~.flightdata.STEADY` for steady points; None when it is not periodic;
    1/frequency when the manifest gives one; else the
    record is one cycle, its period its duration and one median sample step (from the last sample back to the
    first). An error naming the file, the maneuver and the key when a record shorter than its period does not
    cover it (:func:`~.flightdata.check_period`)."""
    if steady:
        return STEADY
    if not periodic:
        return None
    t = np.asarray(t, float)
    value = 1.0 / frequency if frequency is not None else float(t[-1] - t[0] + np.median(np.diff(t)))
    check_period(t, value, f"{source} (maneuver {shown(maneuver)})", "frequency" if frequency is not None else TIME)
    return value


# ----- cycles ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Cycle:
    """One cycle of a record: its label (``c<label>`` in the maneuver id) and its rows ``start:stop``."""

    label: int
    start: int
    stop: int


@dataclass(frozen=True)
class Cycles:
    """A record cut into cycles, and how they were found ("column": its ``cycle`` column; "alpha": upward
    crossings of alpha's mean)."""

    cycles: tuple[Cycle, ...]
    found_by: str

    def __len__(self) -> int:
        return len(self.cycles)


def mean_crossings(alpha: np.ndarray, upward: bool = True) -> np.ndarray:
    """Rows where alpha rises (``upward``) or falls through its mean, each counted once alpha has been
    HYSTERESIS standard deviations on the other side of the mean since the previous one."""
    x = np.asarray(alpha, float) - float(np.mean(alpha))
    x = x if upward else -x
    h = HYSTERESIS * float(np.std(x))
    if not h > 0:
        return np.zeros(0, int)
    state = np.where(x >= 0.0, 1, np.where(x < -h, -1, 0))
    marked = np.flatnonzero(state)
    if marked.size == 0:
        return np.zeros(0, int)
    # carry the last mark forward over the band between -h and 0
    filled = state[marked][np.searchsorted(marked, np.arange(len(x)), side="right") - 1]
    filled[: marked[0]] = 0
    return np.flatnonzero((filled[1:] == 1) & (filled[:-1] == -1)) + 1


def troughs(alpha: np.ndarray) -> np.ndarray:
    """The rows of alpha's minima: one between each downward crossing of its mean and the next upward one (a
    record that ends before alpha rises again ends before its minimum), found on alpha smoothed by a running mean
    over an eighth of that stretch (the bottom of a cycle is flat: noise alone would move a raw minimum along it)."""
    alpha = np.asarray(alpha, float)
    ups = mean_crossings(alpha, upward=True)
    out = []
    for d in mean_crossings(alpha, upward=False):
        later = ups[ups > d]
        if not later.size:
            break
        stop = int(later[0])
        width = max(1, (stop - d) // 8)
        smooth = np.convolve(alpha[d:stop], np.full(width, 1.0 / width), mode="valid")
        out.append(int(d) + int(np.argmin(smooth)) + (width - 1) // 2)
    return np.asarray(out, int)


def cycles_from_alpha(t: np.ndarray, alpha: np.ndarray, source: str, record: str) -> Cycles:
    """The cycles of a periodic record from alpha (module docstring): from one minimum of alpha to the next. An
    error when alpha is not periodic: its minima and mean crossings spaced unequally (beyond
    :data:`PERIOD_TOLERANCE` of their median spacing, the period), or alpha unlike itself one period later
    (correlation below :data:`PERIODIC_CORRELATION`)."""
    n = len(t)
    minima = troughs(alpha)
    edges = np.unique(np.concatenate([[0], minima, [n]]).astype(int))
    pieces = [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]
    # the period: the median spacing of alpha's minima and of its upward and downward mean crossings
    spacings = np.concatenate([np.diff(t[rows]) for rows in (minima, mean_crossings(alpha, True),
                                                                 mean_crossings(alpha, False))])
    if len(pieces) < 2 or not spacings.size:
        raise DataError(f"record {shown(record)}: alpha does not fall through its mean to a minimum and rise again twice, "
                        "so it has no cycles to cut (name them with a `cycle` column, or do not segment this record)",
                        source=source, column="alpha")
    step = float(np.median(np.diff(t)))
    durations = [float((t[b] if b < n else t[-1] + step) - t[a]) for a, b in pieces]
    period = float(np.median(spacings))
    irregular = max(spacings) > PERIOD_TOLERANCE * period or min(spacings) < period / PERIOD_TOLERANCE
    likeness = _lagged_correlation(alpha, int(round(period / step)))
    if irregular or not likeness >= PERIODIC_CORRELATION:
        raise DataError(f"record {shown(record)}: alpha does not look periodic (its minima cut it into pieces of "
                        f"{', '.join(f'{d:.3g}' for d in durations)} s; alpha correlates {likeness:.2f} with itself "
                        f"one period, {period:.3g} s, later); name the cycles with a `cycle` column, or do not "
                        "segment this record", source=source, column="alpha", row=pieces[1][0])
    # stubs at either end join their neighbour
    if durations[0] < FRAGMENT_SHARE * period:
        pieces[:2] = [(pieces[0][0], pieces[1][1])]
    if len(pieces) > 1 and durations[-1] < FRAGMENT_SHARE * period:
        pieces[-2:] = [(pieces[-2][0], pieces[-1][1])]
    if len(pieces) < 2:
        raise DataError(f"record {shown(record)}: alpha completes fewer than two cycles in {float(t[-1] - t[0]):.3g} s, "
                        "so there is nothing to cut", source=source, column="alpha")
    return Cycles(tuple(Cycle(i + 1, a, b) for i, (a, b) in enumerate(pieces)), "alpha")


def _lagged_correlation(alpha: np.ndarray, lag: int) -> float:
    """The correlation of alpha with itself ``lag`` samples later (NaN when less than half a lag overlaps)."""
    if lag < 1 or len(alpha) - lag < lag // 2 or len(alpha) - lag < 3:
        return float("nan")
    a, b = alpha[:-lag], alpha[lag:]
    if np.std(a) == 0 or np.std(b) == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def cycles_from_column(labels: np.ndarray, source: str, record: str) -> Cycles:
    """The cycles a ``cycle`` column names: each run of one whole number is a cycle, and a number names one run."""
    labels = np.asarray(labels, float)
    broken = np.flatnonzero(labels != np.round(labels))
    if broken.size:
        raise DataError(f"record {shown(record)}: cycle {labels[broken[0]]:g} is not a whole number", source=source,
                        column=CYCLE_COLUMN, row=int(broken[0]))
    starts = np.concatenate([[0], np.flatnonzero(np.diff(labels) != 0) + 1]).astype(int)
    stops = np.append(starts[1:], len(labels))
    seen: dict[int, int] = {}
    out = []
    for a, b in zip(starts, stops):
        label = int(labels[a])
        if label in seen:
            raise DataError(f"record {shown(record)}: cycle {label} appears again after other cycles (first at row "
                            f"{seen[label]}); each cycle must be one run of rows", source=source,
                            column=CYCLE_COLUMN, row=int(a))
        seen[label] = int(a)
        out.append(Cycle(label, int(a), int(b)))
    return Cycles(tuple(out), "column")


def cut_record(columns: Mapping[str, np.ndarray], record: str, source: str, rule: LengthRule, cbar: float,
               line_of=None) -> list[tuple[str, dict[str, np.ndarray]]]:
    """A validated record cut into its cycles: ``(maneuver id, columns)`` for each, without the ``cycle`` column.
    A cycle shorter than ``rule`` is an error naming the file, the record, the cycle and its first row
    (``line_of(row)``: the text naming that row's file line, for CSV)."""
    if CYCLE_COLUMN in columns:
        found = cycles_from_column(columns[CYCLE_COLUMN], source, record)
    else:
        found = cycles_from_alpha(columns["t"], columns["alpha"], source, record)
    out = []
    for c in found.cycles:
        rows = slice(c.start, c.stop)
        why = rule.problem(columns["t"][rows], columns["V"][rows], cbar)
        if why is not None:
            where = line_of(c.start) if line_of is not None else ""
            raise DataError(f"cycle c{c.label} of record {shown(record)} (rows {c.start}-{c.stop - 1}{where}, found by "
                            f"{'its cycle column' if found.found_by == 'column' else 'alpha'}) is too short to fit "
                            f"separation dynamics: {why}", source=source, column="t", row=c.start)
        out.append((f"{record}.c{c.label}", {k: v[rows] for k, v in columns.items() if k != CYCLE_COLUMN}))
    return out
