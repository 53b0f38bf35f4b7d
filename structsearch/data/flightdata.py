"""In-memory flight data: named sample columns split into maneuvers (segments).

The numeric core sees a :class:`FlightData`: one float array per column over all
samples, a strictly increasing time per maneuver and the sample index where each
maneuver starts. Separation states and residual autocorrelations never cross
those boundaries.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .errors import DataError

TIME = "t"


@dataclass(frozen=True, eq=False)
class FlightData:
    """Samples of several maneuvers stacked end to end.

    ``columns`` maps a column name to a float array of length ``n_samples``;
    ``starts`` holds the first sample index of every maneuver (``starts[0] == 0``).
    ``flights``, when the campaign records them, names each maneuver's flight (None: a maneuver whose flight
    is not recorded, a flight of its own); None when no maneuver's flight is recorded.
    ``periods``: each maneuver's period [s] where it is periodic (its separation states start at their periodic
    solution: docs/interfaces.md 7.5), :data:`STEADY` (infinite) where its samples are steady points, None where it
    is neither; None when no maneuver is periodic or steady.
    """

    columns: Mapping[str, np.ndarray]
    starts: np.ndarray
    names: tuple[str, ...]
    source: str = "<memory>"
    constants: Mapping[str, float] = field(default_factory=dict)
    flights: tuple[str | None, ...] | None = None
    periods: tuple[float | None, ...] | None = None

    @property
    def period_array(self) -> np.ndarray | None:
        """The periods as floats, NaN where a maneuver is not periodic, infinite where it is steady (None when no
        maneuver is either): what the separation states read (:func:`structsearch.engine.separation.first_order_lag`)."""
        if self.periods is None:
            return None
        return np.array([np.nan if p is None else p for p in self.periods], dtype=float)

    @property
    def n_samples(self) -> int:
        return len(self.columns[TIME])

    @property
    def n_segments(self) -> int:
        return len(self.starts)

    def memo(self, kind: str) -> dict:
        """A dict of derived arrays kept with this data (what every model bound to it would recompute
        alike: the separation states for fixed parameters). Never pickled; gone with the data."""
        return self.__dict__.setdefault("_memo", {}).setdefault(kind, {})  # frozen dataclass: not a field

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_memo", None)
        return state

    @property
    def bounds(self) -> np.ndarray:
        """Segment boundaries ``[s0, s1, ..., n]`` (length ``n_segments + 1``)."""
        return np.append(self.starts, self.n_samples)

    def segment_slices(self) -> list[slice]:
        b = self.bounds
        return [slice(int(b[i]), int(b[i + 1])) for i in range(len(b) - 1)]

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise DataError(f"required column is missing (have: {', '.join(sorted(self.columns))})",
                            source=self.source, column=name) from None

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def select(self, segment_indices: Sequence[int]) -> "FlightData":
        """A new FlightData holding only the given maneuvers, in the given order."""
        slices = self.segment_slices()
        idx = np.concatenate([np.arange(slices[i].start, slices[i].stop) for i in segment_indices])
        lengths = [slices[i].stop - slices[i].start for i in segment_indices]
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        return FlightData({k: v[idx] for k, v in self.columns.items()}, starts,
                          tuple(self.names[i] for i in segment_indices), self.source,
                          dict(self.constants),
                          _recorded(None if self.flights is None else [self.flights[i] for i in segment_indices]),
                          _periodic(None if self.periods is None else [self.periods[i] for i in segment_indices]))

    def with_columns(self, columns: Mapping[str, np.ndarray]) -> "FlightData":
        """The same maneuvers (boundaries, names, constants, flights, periods) with these columns."""
        return FlightData(columns, self.starts, self.names, self.source, dict(self.constants), self.flights,
                          self.periods)


def _recorded(flights) -> tuple[str | None, ...] | None:
    """Each maneuver's flight as stored: None when no maneuver's flight is recorded."""
    if flights is None or all(f is None for f in flights):
        return None
    return tuple(None if f is None else str(f) for f in flights)


def _periodic(periods) -> tuple[float | None, ...] | None:
    """Each maneuver's period as stored: None when no maneuver is periodic."""
    if periods is None or all(p is None for p in periods):
        return None
    return tuple(None if p is None else float(p) for p in periods)


def _check_column(name: str, values: np.ndarray, source: str, offset: int) -> None:
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise DataError("value is NaN or infinite", source=source, column=name,
                        row=int(bad[0]) + offset)


def from_segments(segments: Sequence[Mapping[str, np.ndarray]], *, names: Sequence[str] | None = None,
                  source: str = "<memory>", constants: Mapping[str, float] | None = None,
                  derive_alpha_dot: bool = True, flights: Sequence[str | None] | None = None,
                  periods: Sequence[float | None] | None = None) -> FlightData:
    """Stack maneuvers (each a mapping column -> array) into one :class:`FlightData`.

    Every maneuver must carry the same columns and a strictly increasing ``t``.
    ``alpha_dot`` is derived from ``alpha`` per maneuver (second-order accurate,
    non-uniform steps allowed) when it is absent. ``flights``: each maneuver's flight (None where not
    recorded); all None or absent: no flights recorded. ``periods``: each maneuver's period [s] where it is
    periodic (None where not): positive, and at most one sample step more than the maneuver lasts when it
    is shorter (a record of one cycle).
    """
    if not segments:
        raise DataError("no maneuvers given", source=source)
    names = tuple(names) if names is not None else tuple(f"segment{i}" for i in range(len(segments)))
    if len(names) != len(segments):
        raise DataError(f"{len(names)} names for {len(segments)} maneuvers", source=source)
    if flights is not None and len(flights) != len(segments):
        raise DataError(f"{len(flights)} flights for {len(segments)} maneuvers", source=source)
    flights = _recorded(flights)
    if periods is not None and len(periods) != len(segments):
        raise DataError(f"{len(periods)} periods for {len(segments)} maneuvers", source=source)
    periods = _periodic(periods)
    keys = set(segments[0])
    if TIME not in keys:
        raise DataError("required column is missing", source=f"{source}:{names[0]}", column=TIME)
    stacked: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for i, (name, seg) in enumerate(zip(names, segments)):
        where = f"{source}:{name}" if source != "<memory>" else name
        if set(seg) != keys:
            missing = sorted(keys.symmetric_difference(seg))
            raise DataError("maneuvers carry different columns", source=where, column=missing[0])
        n = len(seg[TIME])
        for k in keys:
            arr = np.asarray(seg[k], dtype=float)
            if arr.shape != (n,):
                raise DataError(f"has shape {arr.shape}, expected ({n},)", source=where, column=k)
            _check_column(k, arr, where, 0)
            stacked[k].append(arr)
        t = np.asarray(seg[TIME], dtype=float)
        if n < 3:
            raise DataError(f"maneuver has {n} samples; at least 3 are needed", source=where, column=TIME)
        step = np.diff(t)
        bad = np.flatnonzero(step <= 0)
        if bad.size:
            raise DataError("time is not strictly increasing", source=where, column=TIME,
                            row=int(bad[0]) + 1)
        if periods is not None and periods[i] is not None:
            check_period(t, periods[i], where)
    lengths = [len(s[TIME]) for s in segments]
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    columns = {k: np.concatenate(v) for k, v in stacked.items()}
    if derive_alpha_dot and "alpha_dot" not in columns and "alpha" in columns:
        columns["alpha_dot"] = np.concatenate([
            derivative(np.asarray(s["alpha"], float), np.asarray(s[TIME], float),
                       None if periods is None else periods[i])
            for i, s in enumerate(segments)])
    return FlightData(columns, starts, names, source, dict(constants or {}), flights, periods)


def derivative(values: np.ndarray, t: np.ndarray, period: float | None = None) -> np.ndarray:
    """d(values)/dt, second-order accurate on any grid; a record of one cycle (shorter than its ``period``) is
    differentiated across its ends as the periodic signal it is, else one-sided differences end it. Steady points
    (``period`` :data:`STEADY`) are each an equilibrium: their rates are zero, whatever order they are listed in."""
    if period is not None and math.isinf(period):
        return np.zeros_like(np.asarray(values, float))
    if period is None or t[-1] - t[0] >= period:
        return np.gradient(values, t, edge_order=2)
    wrapped_t = np.concatenate([[t[-1] - period], t, [t[0] + period]])
    wrapped = np.concatenate([[values[-1]], values, [values[0]]])
    return np.gradient(wrapped, wrapped_t)[1:-1]


# The period of a maneuver of steady points (a static polar, trim points): each sample is an equilibrium of the
# separation states, the zero-frequency limit of a cycle. Its states equal their static value X0(alpha) and have no
# rate, so alpha_dot is zero and neither time constant acts on them (docs/interfaces.md section 8).
STEADY = math.inf

# a periodic record shorter than its period may miss this many sample steps at its end (one: the step from the
# last sample back to the first, one period on; a little more for a record whose steps vary)
PERIOD_GAP_STEPS = 1.5
# and a period spans at least this many sample steps
MIN_PERIOD_STEPS = 4


def check_period(t: np.ndarray, period: float, source: str, column: str = TIME) -> None:
    """A DataError unless ``period`` [s] fits a periodic record with time stamps ``t``: positive and finite, at
    least :data:`MIN_PERIOD_STEPS` median sample steps, and,
    where the record is shorter than one period, covering it but for the step back to its first sample (at most
    :data:`PERIOD_GAP_STEPS` median steps). A record longer than its period is several cycles: the states start
    at the state one period later, on the record's own samples. :data:`STEADY` fits any record of steady points."""
    if period == STEADY:
        return
    if not (np.isfinite(period) and period > 0):
        raise DataError(f"the period of a periodic maneuver must be a positive number of seconds, not {period!r}",
                        source=source, column=column)
    t = np.asarray(t, float)
    step = float(np.median(np.diff(t)))
    if period < MIN_PERIOD_STEPS * step:
        raise DataError(f"the period of a periodic maneuver, {period:.4g} s, is shorter than {MIN_PERIOD_STEPS} of "
                        f"its sample steps ({step:.4g} s): its samples cannot follow a cycle (a frequency in Hz, not "
                        "rad/s or rpm?)", source=source, column=column)
    gap = float(t[0] + period - t[-1])
    if gap > PERIOD_GAP_STEPS * step:
        raise DataError(f"a periodic maneuver must cover its period: its samples span {t[-1] - t[0]:.6g} s of the "
                        f"{period:.6g} s period, leaving {gap:.4g} s from the last sample to one period after the "
                        f"first (at most {PERIOD_GAP_STEPS:g} sample steps, {PERIOD_GAP_STEPS * step:.4g} s): give "
                        "a whole cycle, or the frequency of the cycle it is", source=source, column=column)


def single_segment(columns: Mapping[str, np.ndarray], *, source: str = "<memory>",
                   constants: Mapping[str, float] | None = None) -> FlightData:
    """One maneuver; adds a sample-index time column when ``t`` is absent."""
    cols = dict(columns)
    if TIME not in cols:
        n = len(next(iter(cols.values())))
        cols[TIME] = np.arange(n, dtype=float)
    return from_segments([cols], names=["all"], source=source, constants=constants)
