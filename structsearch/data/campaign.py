"""Flight-test campaigns on disk (docs/interfaces.md section 1): ``campaign.toml`` plus one file per maneuver.

Maneuver files are CSV, Parquet (optional ``pyarrow``) or MATLAB ``.mat``
(variables or one struct whose fields are the columns). Reading validates
everything once and raises one :class:`~structsearch.errors.DataError` naming the
file, the column and the row (0-based data row; for CSV also the line).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .flightdata import FlightData, from_segments
from .errors import DataError
from .reading import inside, load_toml
from . import records
from .tables import LINE_KEY, read_mat, read_table as _read_table  # noqa: F401  (read_mat: the reader of .mat files)
from .moment_transfer import REFERENCE_KEY, check_reference_point, check_transfer_datum
from .campaign_checks import (ANGLES, MANEUVER_KEYS, RAW_ANGLES, RAW_REQUIRED, REQUIRED,
                              RESERVED_KEYS, _check_top_level, _close_match, _flight, _parse_aircraft, _parse_cutoffs,
                              _number, _periodic, _steady, validate_maneuver)
from . import units
from .reading import shown

# the lateral kinds are those ``simulate --jsbsim NAME --lateral`` flies (structsearch.foreign.lateral_plan)
LATERAL_KINDS = ("aileron-doublet", "rudder-doublet", "sideslip", "wind-up-turn", "lateral-stall")
KINDS = ("quasi-steady", "dynamic", "deep-dynamic", "pullup", "pushover", "phugoid", "other", "nominal") + LATERAL_KINDS
# Nominal maneuvers (docs/interfaces.md 7.5) fly attached flow across the envelope; every other kind (and a
# campaign written before nominal maneuvers existed) is a stall maneuver: the two regimes a global model is
# validated on separately (structsearch.api.by_kind)
NOMINAL = "nominal"
REGIMES = ("nominal", "stall")


def regime(kind: str) -> str:
    """The flow regime of a maneuver kind: "nominal" for ``nominal``, else "stall"."""
    return NOMINAL if kind == NOMINAL else "stall"
SPLITS = ("train", "validation")
FORMATS = ("standard", "raw")


@dataclass(frozen=True)
class Maneuver:
    id: str
    file: str
    kind: str
    split: str
    # the flight the maneuver was flown on (docs/interfaces.md 6.4): maneuvers of one flight share its mass,
    # engine-model and vane-calibration errors; None: not recorded
    flight: str | None = None
    # the record (maneuver file) a cycle was cut from (structsearch.data.records); "" for a whole record
    record: str = ""
    # a periodic maneuver (docs/interfaces.md 7.5): its separation states start at their periodic solution; the
    # period is 1/frequency [Hz], else the record is one cycle (records.period)
    periodic: bool = False
    frequency: float | None = None
    # steady points (docs/interfaces.md 8): each sample an equilibrium of the separation states (a static polar,
    # trim points), no rate, no time constant acting (flightdata.STEADY)
    steady: bool = False


@dataclass(frozen=True, eq=False)
class Campaign:
    """A campaign: its manifest and all samples (maneuvers in manifest order)."""

    name: str
    aircraft: Mapping[str, object]     # S, cbar, b and the optional data of docs/interfaces.md 5.1
    maneuvers: tuple[Maneuver, ...]
    data: FlightData
    directory: Path | None = None
    extra: Mapping[str, object] = field(default_factory=dict)
    cutoffs_hz: Mapping[str, float] = field(default_factory=dict)   # [cutoffs] of a raw campaign: overrides
    # the shortest maneuver worth fitting, per kind (campaign.toml min_convective_times; structsearch.data.records)
    length_rules: records.LengthRules = field(default_factory=records.LengthRules)

    def split(self, which: str) -> FlightData:
        """The maneuvers of one split ("train" or "validation") as FlightData."""
        if which not in SPLITS:
            raise DataError(f"unknown split {shown(which)}; expected one of {SPLITS}")
        # computed once per campaign (a search splits it for every grid and refinement step); the frozen
        # dataclass keeps the cache in its __dict__, and the sample arrays are read-only so that a caller
        # that writes into one fails instead of changing what the next caller reads
        cache = self.__dict__.setdefault("_split_cache", {})
        if which not in cache:
            idx = [i for i, m in enumerate(self.maneuvers) if m.split == which]
            if not idx:
                raise DataError(f"the campaign has no {which} maneuvers", source=self._where())
            data = self.data.select(idx)
            for values in data.columns.values():
                values.flags.writeable = False
            cache[which] = data
        return cache[which]

    def of_kind(self, *kinds: str) -> FlightData:
        idx = [i for i, m in enumerate(self.maneuvers) if m.kind in kinds]
        if not idx:
            raise DataError(f"the campaign has no maneuvers of kind {', '.join(kinds)}", source=self._where())
        return self.data.select(idx)

    def keeping(self, keep) -> "Campaign":
        """The campaign of the maneuvers for which ``keep(maneuver)`` is true (manifest order kept)."""
        idx = [i for i, m in enumerate(self.maneuvers) if keep(m)]
        if not idx:
            raise DataError("no maneuver of the campaign is left", source=self._where())
        return replace(self, maneuvers=tuple(self.maneuvers[i] for i in idx), data=self.data.select(idx))

    def _where(self) -> str:
        return str(self.directory / "campaign.toml") if self.directory else self.name


# ----- reading -----------------------------------------------------------------------------
def _manifest(path: Path) -> dict:
    toml = path / "campaign.toml"
    if not toml.exists() and not toml.is_symlink():
        raise DataError("campaign.toml not found", source=str(toml))
    return load_toml(inside(path, "campaign.toml", str(toml)))


def _parse_manifest(doc: dict, toml: str) -> tuple[str, dict, list[Maneuver]]:
    aircraft = doc.get("aircraft")
    if not isinstance(aircraft, dict):
        raise DataError("missing [aircraft] table", source=toml)
    parsed = _parse_aircraft(aircraft, toml)
    entries = doc.get("maneuver")
    if not isinstance(entries, list) or not entries:
        raise DataError("no [[maneuver]] entries", source=toml)
    _check_top_level(doc, toml)
    maneuvers, seen = [], set()
    for i, e in enumerate(entries):
        where = f"{toml} [[maneuver]] #{i + 1}"
        if not isinstance(e, dict):
            raise DataError("a [[maneuver]] entry must be a table", source=where)
        unknown = [k for k in e if k not in MANEUVER_KEYS]
        if unknown:
            raise DataError(f"unknown key {shown(unknown[0])}{_close_match(unknown[0], MANEUVER_KEYS)}", source=where,
                            column=unknown[0])
        for key in ("id", "file", "kind", "split"):
            if not isinstance(e.get(key), str) or not e[key]:
                raise DataError(f"missing or empty {shown(key)}", source=where, column=key)
        if e["id"] in seen:
            raise DataError(f"maneuver id {shown(e['id'])} appears twice", source=where, column="id")
        seen.add(e["id"])
        if e["kind"] not in KINDS:
            raise DataError(f"unknown kind {shown(e['kind'])}; expected one of {', '.join(KINDS)}",
                            source=where, column="kind")
        if e["split"] not in SPLITS:
            raise DataError(f"unknown split {shown(e['split'])}; expected one of {', '.join(SPLITS)}",
                            source=where, column="split")
        periodic, frequency = _periodic(e, where)
        maneuvers.append(Maneuver(e["id"], e["file"], e["kind"], e["split"], _flight(e, where), "", periodic,
                                  frequency, _steady(e, where, periodic)))
    return str(doc.get("name", "")), parsed, maneuvers


def _sample_rate(doc: dict, toml: str) -> float | None:
    """The optional top-level ``sample_rate`` [Hz]: every maneuver file's time step is checked against it."""
    if "sample_rate" not in doc:
        return None
    value = doc["sample_rate"]
    if not (_number(value) and value > 0):
        raise DataError(f"sample_rate must be a positive number of samples per second (Hz), not {value!r}",
                        source=toml, column="sample_rate")
    return float(value)


def scalar_constants(aircraft: Mapping[str, object]) -> dict[str, float]:
    """The aircraft data a regressor may name (numbers, not the envelope or positions)."""
    return {k: float(v) for k, v in aircraft.items() if not isinstance(v, (tuple, list))}



def read_campaign(directory: Path | str, fmt: str = "standard", segment: str | None = None) -> Campaign:
    """Read and validate a campaign directory: a standard one (docs/interfaces.md section 1), or with ``fmt="raw"``
    a raw flight-test campaign (section 5.2). Top-level keys other than the name and format are kept in
    ``Campaign.extra``. ``segment``: "cycles" cuts every record into its cycles, "none" none (and joins cycles a
    campaign was written as back into their records); None (default) as
    each [[maneuver]]'s ``segment`` key says, else the records whose file has a ``cycle`` column
    (:mod:`structsearch.data.records`)."""
    directory = Path(directory)
    toml = str(directory / "campaign.toml")
    doc = _manifest(directory)
    found = doc.get("format", "standard")
    if found not in FORMATS:
        raise DataError(f"unknown format {shown(found)}; expected one of {', '.join(FORMATS)}", source=toml,
                        column="format")
    if found != fmt:
        hint = (" (recorded channels: turn them into coefficients with `structsearch preprocess --raw DIR "
                "--out DIR2`)" if found == "raw" else "")
        raise DataError(f"a {found} campaign where a {fmt} one is needed{hint}", source=toml, column="format")
    name, aircraft, maneuvers = _parse_manifest(doc, toml)
    cutoffs = _parse_cutoffs(doc.get("cutoffs", {}), toml)
    extra = {k: v for k, v in doc.items() if k not in RESERVED_KEYS and not isinstance(v, (dict, list))}
    if isinstance(doc.get("source"), dict):   # where a simulated campaign comes from (a simulator, its aircraft)
        extra["source"] = dict(doc["source"])
    if segment is not None and segment not in records.SEGMENT_CHOICES:
        raise DataError(f"segment must be one of {', '.join(records.SEGMENT_CHOICES)}, not {shown(segment)}")
    rules = records.LengthRules.parse(doc.get("min_convective_times"), KINDS, toml)
    pieces, segments = _read_maneuvers(directory, doc, maneuvers, aircraft, fmt, segment, rules)
    ids = [m.id for m in pieces]
    if len(set(ids)) != len(ids):
        twice = next(x for x in ids if ids.count(x) > 1)
        raise DataError(f"maneuver id {shown(twice)} appears twice once the records are cut into cycles", source=toml,
                        column="id")
    maneuvers = pieces
    if segment == "none":
        maneuvers, segments = _join_written_cycles(maneuvers, segments, toml)
    # keep only the columns every maneuver has: optional columns must be all-or-nothing
    common = set.intersection(*(set(s) for s in segments))
    _same_columns_everywhere(maneuvers, segments, common, directory)
    periods = [records.period(m.periodic, m.frequency, s["t"], str(directory / m.file), m.id, m.steady)
               for m, s in zip(maneuvers, segments)]
    data = from_segments([{k: s[k] for k in sorted(common)} for s in segments],
                         names=[m.id for m in maneuvers], source=str(directory),
                         constants=scalar_constants(aircraft), derive_alpha_dot=fmt != "raw",
                         flights=[m.flight for m in maneuvers], periods=periods)
    if fmt == "raw":
        extra["format"] = "raw"
    check_transfer_datum(data.columns.get("x_cg"), aircraft, toml)
    return Campaign(name, aircraft, tuple(maneuvers), data, directory, extra, cutoffs, rules)


def with_reference_point(campaign: Campaign, reference_point: float) -> Campaign:
    """``campaign`` with ``[aircraft] reference_point`` set to ``reference_point`` (``--reference-point``: it
    replaces the manifest's), checked as the manifest's would be; the data's constants (which a pitch model about
    the fixed point reads) follow."""
    source = f"{campaign._where()} (--reference-point)"
    aircraft = {**campaign.aircraft, REFERENCE_KEY: check_reference_point(reference_point, campaign.aircraft, source)}
    check_transfer_datum(campaign.data.columns.get("x_cg"), aircraft, source)
    data = campaign.data
    data = FlightData(data.columns, data.starts, data.names, data.source, scalar_constants(aircraft), data.flights)
    return replace(campaign, aircraft=aircraft, data=data)


def _same_columns_everywhere(maneuvers, segments, common: set, directory: Path) -> None:
    """An optional column is in every maneuver file or in none. The error names the file that differs: the
    one that has a column most files lack, or the one that lacks a column most files have."""
    for column in sorted(set.union(*(set(s) for s in segments)) - common):
        holders = [m for m, s in zip(maneuvers, segments) if column in s]
        if 2 * len(holders) <= len(maneuvers):
            raise DataError(f"column appears in {len(holders)} of {len(maneuvers)} maneuver files only (this one "
                            "first): an optional column must be in every maneuver file or in none",
                            source=str(directory / holders[0].file), column=column)
        lacking = next(m for m, s in zip(maneuvers, segments) if column not in s)
        raise DataError(f"column missing here but present in {len(holders)} of {len(maneuvers)} maneuver files: "
                        "an optional column must be in every maneuver file or in none",
                        source=str(directory / lacking.file), column=column)


def _join_written_cycles(maneuvers: list, segments: list, toml: str) -> tuple[list, list]:
    """``segment="none"`` on a campaign written as cycles (each carries ``record``): the consecutive cycles of one
    record joined back into one maneuver named after the record, as if it had never been cut. The cycles cover the
    record from its first cut to its last, contiguously; cycles that do not follow one another in time (one was
    removed, or two records share a name) are one error naming the record."""
    out_m, out_s = [], []
    i = 0
    while i < len(maneuvers):
        m = maneuvers[i]
        j = i + 1
        while m.record and j < len(maneuvers) and maneuvers[j].record == m.record:
            j += 1
        if j - i == 1 or not m.record:
            out_m.append(maneuvers[i])
            out_s.append(segments[i])
            i = j
            continue
        parts = segments[i:j]
        for a, b, name in zip(parts, parts[1:], [x.id for x in maneuvers[i + 1:j]]):
            dt = float(np.median(np.diff(a["t"]))) if len(a["t"]) > 1 else float("nan")
            gap = float(b["t"][0] - a["t"][-1])
            if not (np.isfinite(dt) and 0.5 * dt < gap < 1.5 * dt):
                raise DataError(f"--segment none: the cycles of record {shown(m.record)} do not follow one another in "
                                f"time ({name} starts {gap:.4g} s after the cycle before it, the sample time is "
                                f"{dt:.4g} s): they cannot be joined into one record", source=toml, column="record")
        keys = set.intersection(*(set(p) for p in parts))
        out_m.append(replace(m, id=m.record, record=""))
        out_s.append({k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in keys})
        i = j
    return out_m, out_s


def _read_maneuvers(directory: Path, doc: dict, maneuvers: list[Maneuver], aircraft: Mapping[str, object], fmt: str,
                    segment: str | None, rules: records.LengthRules) -> tuple[list[Maneuver], list[dict]]:
    """Each maneuver's file read, checked (:func:`validate_maneuver`, and its time step against the others') and cut
    into the maneuvers it gives (itself, or its cycles), in the manifest's order."""
    toml = str(directory / "campaign.toml")
    required, angles = (RAW_REQUIRED, RAW_ANGLES) if fmt == "raw" else (REQUIRED, ANGLES)
    sample_rate = _sample_rate(doc, toml)
    segments, pieces, steps = [], [], []
    for i, m in enumerate(maneuvers):
        where = f"{toml} [[maneuver]] #{i + 1}"
        path = inside(directory, m.file, where, "file")
        columns = _with_time(_read_table(path), m, str(path), fmt, where)
        validate_maneuver(columns, path, required, angles, cbar=aircraft["cbar"], rule=rules.for_kind(m.kind),
                          sample_rate=sample_rate, v_range=aircraft.get("V_range"), steady=m.steady)
        steps.append(float("nan") if m.steady else units.median_step(columns["t"]))
        for piece, cut in _pieces(m, columns, path, doc["maneuver"][i], segment, rules, aircraft["cbar"], where,
                                  derive_alpha_dot=fmt != "raw"):
            pieces.append(piece)
            segments.append(cut)
    units.check_steps_across(steps, [str(directory / m.file) for m in maneuvers])
    return pieces, segments


def _with_time(columns: dict, m: Maneuver, path: str, fmt: str, where: str) -> dict:
    """A maneuver file's columns with its time column (its own, a cycle's from its frequency, steady points'
    order); steady points are coefficients, so a raw campaign (recorded channels) has none."""
    if not m.steady:
        return records.with_cycle_time(columns, m.id, m.frequency, path)
    if fmt == "raw":
        raise DataError(f"maneuver {shown(m.id)}: steady points are given as coefficients (a standard campaign), not "
                        "as recorded channels", source=where, column="steady")
    return records.with_steady_order(columns, m.id, path)


def _pieces(m: Maneuver, columns: dict, path: Path, entry: dict, segment: str | None, rules: records.LengthRules,
            cbar: float, where: str, derive_alpha_dot: bool = True) -> list[tuple[Maneuver, dict]]:
    """A validated record as the maneuvers it gives: itself, or its cycles (:mod:`structsearch.data.records`).
    A record cut into cycles gets its alpha_dot (when derived) from the whole record first, as a campaign in
    memory cut by :func:`~.cycles.segmented` has it: derived per cycle, it would be one-sided and noisy exactly
    where the states restart, and the two ways of cutting would fit different data."""
    lines = columns.pop(LINE_KEY, None)
    if "record" in entry:   # a cycle written by write_campaign names the record it was cut from
        if not isinstance(entry["record"], str) or not entry["record"]:
            raise DataError(f"record must be a non-empty string, not {shown(entry['record'])}", source=where,
                            column="record")
        m = replace(m, record=entry["record"])
    asked = records.segment_request(entry, where)
    if m.steady:
        columns.pop(records.CYCLE_COLUMN, None)
        return [(m, columns)]
    if m.record or not records.wants_cycles(segment, asked, records.CYCLE_COLUMN in columns):
        columns.pop(records.CYCLE_COLUMN, None)
        return [(m, columns)]
    if derive_alpha_dot and "alpha_dot" not in columns and "alpha" in columns:
        columns["alpha_dot"] = np.gradient(np.asarray(columns["alpha"], float), np.asarray(columns["t"], float),
                                           edge_order=2)
    line_of = None if lines is None else (lambda row: f", line {int(lines[row])}")
    # a cycle of a periodic record is one period from its first sample to the sample after its last (records.period)
    return [(replace(m, id=piece_id, record=m.id, frequency=None), piece) for piece_id, piece in
            records.cut_record(columns, m.id, str(path), rules.for_kind(m.kind), cbar, line_of)]


# ----- writing -----------------------------------------------------------------------------
def make_campaign(name: str, aircraft: Mapping[str, float], maneuvers: Sequence[Maneuver],
                  segments: Sequence[Mapping[str, np.ndarray]], extra: Mapping[str, object] | None = None
                  ) -> Campaign:
    clash = [k for k in (extra or {}) if k in RESERVED_KEYS and not (k == "format" and extra[k] == "raw")]
    if clash:
        raise DataError(f"campaign key {shown(clash[0])} is reserved in campaign.toml ({', '.join(RESERVED_KEYS)})")
    data = from_segments(list(segments), names=[m.id for m in maneuvers], source=name,
                         constants=scalar_constants(aircraft),
                         derive_alpha_dot=(extra or {}).get("format") != "raw",  # raw: recorded channels only
                         flights=[m.flight for m in maneuvers],
                         periods=[records.period(m.periodic, m.frequency, s["t"], f"{name}:{m.id}", m.id,
                                                 m.steady) for m, s in zip(maneuvers, segments)])
    check_transfer_datum(data.columns.get("x_cg"), aircraft, name)
    return Campaign(name, dict(aircraft), tuple(maneuvers), data, None, dict(extra or {}))


# the writer lives in its own module; importing it here keeps data.campaign.write_campaign where it always was
from .campaign_write import write_campaign  # noqa: E402,F401
