"""How a candidate's cross-validation folds are formed from its training maneuvers: a :class:`FoldPlan`.

Three schemes, chosen by :func:`plan_folds` from the training data alone:

``maneuvers`` (maneuver-grouped folds, round robin in campaign order): with at least
:data:`~.options.CV_MIN_MANEUVERS` training maneuvers and room for two folds of ``fold_size`` maneuvers.
``fold_size`` is :data:`~.options.CV_MIN_MANEUVERS` (3) on a flight-test campaign, so that every fold keeps
maneuvers of every kind, and 1 when every training maneuver is a cycle of a periodic record with other cycles
(:func:`fold_size_for`): cycles of one record are repetitions of one maneuver, and leaving one out removes no
kind. Four cycles give four folds (leave one cycle out).

``blocks`` (blocked folds of contiguous time): with one or two training maneuvers (one or two long records,
not cut into cycles) there is no maneuver to leave out. Each record is cut into K contiguous blocks of equal
length, K = min(:data:`~.options.CV_FOLDS`, the most blocks that each last the shortest maneuver worth fitting:
the campaign's ``min_convective_times`` convective times cbar/V (:data:`structsearch.data.records.MIN_CONVECTIVE_TIMES`
unless campaign.toml sets it; the least over the training maneuvers' kinds, :func:`block_convective_times`) and
:data:`~structsearch.data.records.MIN_SAMPLES` samples); fold j holds out the j-th block of every record. Five,
as for maneuvers: each fold's fit keeps 80 % of the record; blocks of at least a maneuver's length hold whole
separation transients, and the residual correlation that leaks across a block's two edges (a few time constants)
is a small part of it, which is why blocked cross-validation is sound for such records (Bergmeir & Benitez 2012,
"On the use of cross-validation for time series predictor evaluation"). A fold holds out a block's outputs, not
its inputs: its least squares leave the block's samples out while its separation states are flown over the
whole record (no state restarts at a block's edge, so a model with lagged states is not penalised by warm-ups),
and the block is predicted by the same flight with the fold's estimates. Its per-unit scores are per block.

``none``, with the reason in :attr:`FoldPlan.note`: no folds asked (``cv_folds=0``); three to five training
maneuvers of a flight-test campaign (fewer than two folds that keep every kind: the candidates are compared on
the validation maneuvers, as before); or records too short for two blocks.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from ..data.flightdata import FlightData
from ..data.records import MIN_CONVECTIVE_TIMES, MIN_SAMPLES
from .options import CV_FOLDS, CV_MIN_MANEUVERS

SCHEMES = ("maneuvers", "blocks", "none")


@dataclass(frozen=True)
class FoldPlan:
    """The folds of a cross-validation: ``units`` (row ranges, in order, covering the training data: its
    maneuvers, or the blocks of its records), ``folds`` (the units each fold holds out) and ``note`` (how they
    were formed, or why there are none)."""

    scheme: str
    folds: tuple[tuple[int, ...], ...]
    units: tuple[tuple[int, int], ...]
    note: str

    @property
    def n_folds(self) -> int:
        return len(self.folds)

    @property
    def bounds(self) -> np.ndarray:
        """The units' boundaries ``[0, ..., m]``."""
        return np.asarray([a for a, _ in self.units] + [self.units[-1][1]] if self.units else [0], np.int64)

    def slices(self) -> list[slice]:
        return [slice(a, b) for a, b in self.units]

    def maneuver_folds(self) -> list[list[int]]:
        """The folds as lists of maneuver indices (the ``maneuvers`` scheme; [] otherwise)."""
        return [list(f) for f in self.folds] if self.scheme == "maneuvers" else []


def _units_of(train: FlightData) -> tuple[tuple[int, int], ...]:
    return tuple((s.start, s.stop) for s in train.segment_slices())


def maneuver_plan(train: FlightData, folds: Iterable[Iterable[int]]) -> FoldPlan:
    """Given maneuver folds as a plan (a caller that formed its own)."""
    folds = tuple(tuple(int(i) for i in f) for f in folds)
    return FoldPlan("maneuvers" if folds else "none", folds, _units_of(train),
                    f"{len(folds)} folds of the training maneuvers" if folds else "no folds given")


def plan_folds(train: FlightData, folds: int = CV_FOLDS, fold_size: int = CV_MIN_MANEUVERS,
               block_convective_times: float = MIN_CONVECTIVE_TIMES) -> FoldPlan:
    """The folds of ``train`` (module docstring): ``folds`` at most (0: none), ``fold_size`` maneuvers at least
    per fold in the maneuver-grouped scheme, blocks of ``block_convective_times`` cbar/V at least in the blocked
    one."""
    n = train.n_segments
    units = _units_of(train)
    if folds <= 0:
        return FoldPlan("none", (), units, "no cross-validation asked (0 folds)")
    if n >= CV_MIN_MANEUVERS:
        k = min(folds, n // max(fold_size, 1))
        if k >= 2:
            sizes = sorted({len(range(i, n, k)) for i in range(k)})
            what = "cycle" if fold_size == 1 else "maneuver"
            return FoldPlan("maneuvers", tuple(tuple(range(i, n, k)) for i in range(k)), units,
                            f"{k} folds of the {n} training {what}s, round robin "
                            f"({'-'.join(map(str, sizes))} {what}{'s' if sizes[-1] > 1 else ''} each)")
        return FoldPlan("none", (), units,
                        f"no cross-validation: {n} training maneuvers make fewer than two folds of {fold_size} "
                        "(a fold keeps maneuvers of every kind); compared on the validation maneuvers")
    k = min(folds, min(_most_blocks(train, s, block_convective_times) for s in train.segment_slices()))
    if k < 2:
        return FoldPlan("none", (), units,
                        f"no cross-validation: {n} training record{'s' if n > 1 else ''} too short for two blocks "
                        f"of {block_convective_times:g} convective times cbar/V and {MIN_SAMPLES} samples; compared "
                        "on the validation maneuvers")
    blocks = []
    for s in train.segment_slices():
        rows = np.array_split(np.arange(s.start, s.stop), k)
        blocks += [(int(r[0]), int(r[-1]) + 1) for r in rows]
    shortest = min(_duration(train, slice(a, b)) for a, b in blocks)
    return FoldPlan("blocks", tuple(tuple(r * k + j for r in range(n)) for j in range(k)), tuple(blocks),
                    f"{k} blocked folds: each of the {n} training record{'s' if n > 1 else ''} cut into {k} "
                    f"contiguous blocks ({shortest:.3g} s or more); fold j holds out the j-th block of every record, "
                    "fitted on the rest with its states flown over the whole record")


def _duration(data: FlightData, rows: slice) -> float:
    t = data["t"][rows]
    return float(t[-1] - t[0])


def _most_blocks(data: FlightData, rows: slice, convective_times: float = MIN_CONVECTIVE_TIMES) -> int:
    """How many blocks of the shortest maneuver worth fitting (``convective_times`` cbar/V and MIN_SAMPLES
    samples) one record holds (the sample rule alone when the data carry no cbar or airspeed, or the rule asks
    for no convective time)."""
    count = (rows.stop - rows.start) // MIN_SAMPLES
    if "cbar" in data.constants and "V" in data and convective_times > 0:
        unit = float(data.constants["cbar"]) / float(np.mean(data["V"][rows]))
        count = min(count, math.floor(_duration(data, rows) / (convective_times * unit)))
    return int(count)


def block_convective_times(campaign) -> float:
    """The shortest block of a blocked fold in convective times: the campaign's rule for the shortest maneuver
    worth fitting (campaign.toml ``min_convective_times``), the least over its training maneuvers' kinds."""
    kinds = {m.kind for m in campaign.maneuvers if m.split == "train"}
    rules = campaign.length_rules
    return min((rules.for_kind(k).min_convective_times for k in kinds), default=rules.default)


def fold_size_for(maneuvers: Sequence) -> int:
    """1 when every training maneuver is a cycle of a record with at least two training cycles (interchangeable
    repetitions: leaving one out removes no kind), else CV_MIN_MANEUVERS. ``maneuvers``: a campaign's."""
    train = [m for m in maneuvers if m.split == "train"]
    records = Counter(getattr(m, "record", "") for m in train)
    if train and "" not in records and min(records.values()) >= 2:
        return 1
    return CV_MIN_MANEUVERS


# Fewer maneuvers than this in a split: its scores are also kept per unit smaller than a maneuver
# (:func:`score_units`), so that a paired comparison of two structures has pairs enough to estimate a spread.
UNITS_BELOW_MANEUVERS = 8


def score_units(data: FlightData, convective_times: float = MIN_CONVECTIVE_TIMES) -> tuple[tuple[tuple[int, int], ...], str]:
    """Row ranges smaller than a maneuver that a paired test can compare two structures on, and what they are
    (``"cycles"``, ``"blocks"``, ``"cycles and blocks"``); ``((), "")`` when no maneuver can be cut.

    A periodic maneuver of two or more whole cycles is cut into its cycles (repetitions of one motion: the
    natural units); any other maneuver into the most contiguous blocks, up to :data:`~.options.CV_FOLDS`, that
    each last the shortest maneuver worth fitting (``convective_times`` cbar/V and MIN_SAMPLES samples), the
    blocked folds' rule: a block holds whole separation transients, and the residual correlation across its
    edges lasts a few time constants, a small part of it. The units depend on the data alone, so every structure
    fitted to the same data is scored on the same units."""
    units, kinds = [], set()
    periods = data.period_array
    t = data["t"]
    for i, rows in enumerate(data.segment_slices()):
        period = float(periods[i]) if periods is not None else float("nan")
        # whole cycles: the record's span plus its last sample's step (a cycle of n samples spans n - 1 steps)
        span = t[rows.stop - 1] - t[rows.start] + (float(np.median(np.diff(t[rows]))) if rows.stop - rows.start > 1 else 0)
        cycles = math.floor(span / period + 1e-9) if np.isfinite(period) else 0
        if np.isinf(period):   # steady points: one unit (their order is no time, so no block is a transient)
            units.append((rows.start, rows.stop))
            continue
        if cycles >= 2:
            edges = [rows.start] + [rows.start + int(np.searchsorted(t[rows], t[rows.start] + k * period))
                                    for k in range(1, cycles)] + [rows.stop]
            kinds.add("cycles")
        else:
            k = min(CV_FOLDS, _most_blocks(data, rows, convective_times))
            if k < 2:
                units.append((rows.start, rows.stop))
                continue
            split = np.array_split(np.arange(rows.start, rows.stop), k)
            edges = [int(r[0]) for r in split] + [rows.stop]
            kinds.add("blocks")
        units += list(zip(edges[:-1], edges[1:]))
    if not kinds:
        return (), ""
    return tuple((int(a), int(b)) for a, b in units), " and ".join(sorted(kinds))
