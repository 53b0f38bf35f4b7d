"""Flight-test campaigns on disk (docs/interfaces.md section 1): ``campaign.toml`` plus one file per maneuver.

Maneuver files are CSV, Parquet (optional ``pyarrow``) or MATLAB ``.mat``
(variables or one struct whose fields are the columns). Reading validates
everything once and raises one :class:`~structsearch.errors.DataError` naming the
file, the column and the row (0-based data row; for CSV also the line).
"""
from __future__ import annotations

import difflib
import math
import os
import shutil
import tempfile
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .atomic import exchange_directories, sync_path, umask
from .flightdata import FlightData, from_segments
from .errors import DataError
from . import records
from .tables import LINE_KEY, read_mat, read_table as _read_table  # noqa: F401  (read_mat: the reader of .mat files)

KINDS = ("quasi-steady", "dynamic", "deep-dynamic", "pullup", "pushover", "phugoid", "other")
SPLITS = ("train", "validation")
REQUIRED = ("t", "alpha", "q", "V", "de")
ANGLES = ("alpha", "de", "theta")
# Raw flight-test campaigns (docs/interfaces.md 5.2, ``format = "raw"``): the channels as recorded.
RAW_REQUIRED = ("t", "ax", "ay", "az", "p", "q", "r", "phi", "theta", "V", "alpha", "h", "de", "thrust")
RAW_ANGLES = ("alpha", "de", "theta", "phi", "beta", "da", "dr")
FORMATS = ("standard", "raw")
# Largest plausible magnitude of an angle in radians; more looks like degrees.
MAX_ANGLE_RAD = 1.2
# The shortest maneuver worth fitting is measured in convective times cbar/V (structsearch.data.records)
MIN_CONVECTIVE_TIMES = records.MIN_CONVECTIVE_TIMES
MIN_SAMPLES = records.MIN_SAMPLES
AIRCRAFT_KEYS = ("S", "cbar", "b")
# optional aircraft data (docs/interfaces.md 5.1): positive scalars, signed scalars, and vectors of a length
OPTIONAL_POSITIVE = ("mass", "Ixx", "Iyy", "Izz")
OPTIONAL_SIGNED = ("Ixz", "thrust_line_z")
OPTIONAL_VECTORS = {"x_cg_range": 2, "accelerometer": 3}


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
            raise DataError(f"unknown split {which!r}; expected one of {SPLITS}")
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

    def _where(self) -> str:
        return str(self.directory / "campaign.toml") if self.directory else self.name


# ----- reading -----------------------------------------------------------------------------
def _manifest(path: Path) -> dict:
    toml = path / "campaign.toml"
    if not toml.is_file():
        raise DataError("campaign.toml not found", source=str(toml))
    try:
        return tomllib.loads(toml.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"not valid TOML: {exc}", source=str(toml)) from None


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
            raise DataError(f"unknown key {unknown[0]!r}{_close_match(unknown[0], MANEUVER_KEYS)}", source=where,
                            column=unknown[0])
        for key in ("id", "file", "kind", "split"):
            if not isinstance(e.get(key), str) or not e[key]:
                raise DataError(f"missing or empty {key!r}", source=where, column=key)
        if e["id"] in seen:
            raise DataError(f"maneuver id {e['id']!r} appears twice", source=where, column="id")
        seen.add(e["id"])
        if e["kind"] not in KINDS:
            raise DataError(f"unknown kind {e['kind']!r}; expected one of {', '.join(KINDS)}",
                            source=where, column="kind")
        if e["split"] not in SPLITS:
            raise DataError(f"unknown split {e['split']!r}; expected one of {', '.join(SPLITS)}",
                            source=where, column="split")
        maneuvers.append(Maneuver(e["id"], e["file"], e["kind"], e["split"], _flight(e, where)))
    return str(doc.get("name", "")), parsed, maneuvers


# The keys a [[maneuver]] entry may hold (docs/interfaces.md 1, 6.4, 6.9): any other is a typo, refused.
MANEUVER_KEYS = ("id", "file", "kind", "split", "flight", "record", "segment")


def _close_match(key: str, known) -> str:
    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else f" (known: {', '.join(known)})"


def _check_top_level(doc: dict, toml: str) -> None:
    """Top-level scalars are free metadata (the simulator's seed and truth, a preprocessing record), kept in
    ``Campaign.extra``; a table or list that is not one of campaign.toml's, or a scalar whose name is one
    letter or two from a reserved key (``fromat``), is a typo: refused with the close match."""
    for key, value in doc.items():
        if key in RESERVED_KEYS:
            continue
        close = difflib.get_close_matches(key, RESERVED_KEYS, n=1, cutoff=0.75)
        if isinstance(value, (dict, list)) or close:
            hint = f" (did you mean {close[0]!r}?)" if close else f" (tables: {', '.join(RESERVED_KEYS[2:])})"
            raise DataError(f"unknown key {key!r}{hint}", source=toml, column=key)


def _flight(entry: dict, where: str) -> str | None:
    """A maneuver's optional ``flight``: a non-empty string naming the flight it was flown on."""
    if "flight" not in entry:
        return None
    value = entry["flight"]
    if not isinstance(value, str) or not value.strip() or not value.isprintable():
        hint = f' (quote it: flight = "{value}")' if _number(value) else ""
        raise DataError(f"maneuver {entry['id']!r}: flight must be a non-empty string of printable characters "
                        f"naming the flight it was flown on, not {value!r}{hint}", source=where, column="flight")
    return value


def _number(v) -> bool:
    """A finite int or float (TOML integers are unbounded: one beyond float range is not finite)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def _parse_aircraft(aircraft: dict, toml: str) -> dict:
    """The [aircraft] table: S, cbar, b required; the optional data of docs/interfaces.md 5.1 checked."""
    out: dict = {}
    for key in AIRCRAFT_KEYS:
        if not _number(aircraft.get(key)) or aircraft[key] <= 0:
            raise DataError(f"[aircraft] needs a positive finite number {key}", source=toml, column=key)
        out[key] = float(aircraft[key])
    known = AIRCRAFT_KEYS + OPTIONAL_POSITIVE + OPTIONAL_SIGNED + tuple(OPTIONAL_VECTORS)
    for key, value in aircraft.items():
        if key not in known:
            raise DataError(f"[aircraft] has an unknown key {key!r}; known keys: {', '.join(known)}",
                            source=toml, column=key)
        if key in OPTIONAL_POSITIVE and not (_number(value) and value > 0):
            raise DataError(f"[aircraft] {key} must be a positive finite number, not {value!r}", source=toml,
                            column=key)
        if key in OPTIONAL_SIGNED and not _number(value):
            raise DataError(f"[aircraft] {key} must be a finite number, not {value!r}", source=toml, column=key)
        if key in OPTIONAL_VECTORS:
            n = OPTIONAL_VECTORS[key]
            if not (isinstance(value, list) and len(value) == n and all(_number(v) for v in value)):
                raise DataError(f"[aircraft] {key} must be a list of {n} finite numbers, not {value!r}",
                                source=toml, column=key)
            if key == "x_cg_range" and not value[0] < value[1]:
                raise DataError(f"[aircraft] x_cg_range must be [forward, aft] with forward < aft, not {value!r}",
                                source=toml, column=key)
            out[key] = tuple(float(v) for v in value)
        elif key not in AIRCRAFT_KEYS:
            out[key] = float(value)
    return out


def scalar_constants(aircraft: Mapping[str, object]) -> dict[str, float]:
    """The aircraft data a regressor may name (numbers, not the envelope or positions)."""
    return {k: float(v) for k, v in aircraft.items() if not isinstance(v, (tuple, list))}


def _row_message(columns: Mapping[str, np.ndarray], row: int) -> str:
    lines = columns.get(LINE_KEY)
    return f" (line {int(lines[row])})" if lines is not None and row < len(lines) else ""


def validate_maneuver(columns: Mapping[str, np.ndarray], path: Path, required=REQUIRED, angles=ANGLES, *,
                      cbar: float | None = None, rule: records.LengthRule | None = None) -> None:
    """One clear error for the first problem found in a maneuver's columns (``required`` and ``angles``: those
    of the standard format, or RAW_REQUIRED and RAW_ANGLES for a raw campaign). With the aircraft's ``cbar``, a
    maneuver shorter than ``rule`` (default: :class:`structsearch.data.records.LengthRule`) in convective times
    cbar/V is an error too."""
    source = str(path)
    names = [c for c in columns if c != LINE_KEY]
    for col in required:
        if col not in columns:
            close = [c for c in names if c.lower() == col.lower()]
            spaced = [c for c in names if c.strip() == col]
            hint = (f" (found {close[0]!r}: column names are case-sensitive)" if close else
                    f" (found {spaced[0]!r}: remove the spaces around the column name)" if spaced else "")
            raise DataError(f"required column is missing{hint}", source=source, column=col)
    n = len(columns["t"])
    if n < MIN_SAMPLES:
        raise DataError(f"maneuver has {n} samples; it needs at least {MIN_SAMPLES} to fit separation dynamics",
                        source=source, column="t")
    for col in names:
        values = columns[col]
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise DataError("value is NaN or infinite" + _row_message(columns, int(bad[0])), source=source,
                            column=col, row=int(bad[0]))
    t = columns["t"]
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        raise DataError("time is not strictly increasing" + _row_message(columns, int(bad[0]) + 1),
                        source=source, column="t", row=int(bad[0]) + 1)
    slow = np.flatnonzero(columns["V"] <= 0)
    if slow.size:
        raise DataError(f"airspeed {columns['V'][slow[0]]:g} m/s is not positive"
                        + _row_message(columns, int(slow[0])), source=source, column="V", row=int(slow[0]))
    why = None if cbar is None else (rule or records.LengthRule()).problem(t, columns["V"], cbar)
    if why is not None:
        raise DataError(f"maneuver is too short to fit separation dynamics: {why}", source=source, column="t")
    for col in angles:
        if col in columns:
            big = np.flatnonzero(np.abs(columns[col]) > MAX_ANGLE_RAD)
            if big.size:
                raise DataError(f"value {columns[col][big[0]]:g} looks like degrees; angles must be in "
                                f"radians" + _row_message(columns, int(big[0])), source=source, column=col,
                                row=int(big[0]))
    _check_rates(columns, source)


# Body rates beyond a full turn per second are not flown by a fixed-wing aircraft: degrees per second.
MAX_RATE_RAD_S = 2 * math.pi
RATES = ("q", "p", "r")


def _check_rates(columns: Mapping[str, np.ndarray], source: str) -> None:
    """Rates in rad/s. A rate above a turn per second is refused; so is a pitch rate that follows the pitch
    attitude's (else the angle of attack's) derivative 57 times over, which is q in degrees per second even
    when its values are small (a gentle stall at 5 deg/s)."""
    for col in RATES:
        if col in columns:
            big = np.flatnonzero(np.abs(columns[col]) > MAX_RATE_RAD_S)
            if big.size:
                raise DataError(f"value {columns[col][big[0]]:g} looks like degrees per second; rates must be in "
                                "rad/s" + _row_message(columns, int(big[0])), source=source, column=col,
                                row=int(big[0]))
    reference = next((c for c in ("theta", "alpha") if c in columns), None)
    if "q" not in columns or reference is None or len(columns["t"]) < 3:
        return
    rate = np.gradient(columns[reference], columns["t"])
    q = columns["q"]
    if not (np.all(np.isfinite(rate)) and np.any(rate) and np.any(q)):
        return
    slope = float(q @ rate / (rate @ rate))
    correlation = float(np.corrcoef(q, rate)[0, 1])
    # rad/s: slope about 1 (q = theta_dot in wings-level flight); deg/s: 57.3. Between 20 and 150 with a clear
    # correlation is a unit, not aerodynamics.
    if correlation > 0.5 and 20.0 < slope < 150.0:
        raise DataError(f"q is {slope:.0f} times d({reference})/dt: it looks like degrees per second; rates must be "
                        "in rad/s", source=source, column="q")


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
        raise DataError(f"unknown format {found!r}; expected one of {', '.join(FORMATS)}", source=toml,
                        column="format")
    if found != fmt:
        hint = (" (recorded channels: turn them into coefficients with `structsearch preprocess --raw DIR "
                "--out DIR2`)" if found == "raw" else "")
        raise DataError(f"a {found} campaign where a {fmt} one is needed{hint}", source=toml, column="format")
    name, aircraft, maneuvers = _parse_manifest(doc, toml)
    cutoffs = _parse_cutoffs(doc.get("cutoffs", {}), toml)
    extra = {k: v for k, v in doc.items() if k not in RESERVED_KEYS and not isinstance(v, (dict, list))}
    required, angles = (RAW_REQUIRED, RAW_ANGLES) if fmt == "raw" else (REQUIRED, ANGLES)
    if segment is not None and segment not in records.SEGMENT_CHOICES:
        raise DataError(f"segment must be one of {', '.join(records.SEGMENT_CHOICES)}, not {segment!r}")
    rules = records.LengthRules.parse(doc.get("min_convective_times"), KINDS, toml)
    segments, pieces = [], []
    for i, m in enumerate(maneuvers):
        path = directory / m.file
        columns = _read_table(path)
        validate_maneuver(columns, path, required, angles, cbar=aircraft["cbar"], rule=rules.for_kind(m.kind))
        for piece, cut in _pieces(m, columns, path, doc["maneuver"][i], segment, rules, aircraft["cbar"],
                                  f"{toml} [[maneuver]] #{i + 1}", derive_alpha_dot=fmt != "raw"):
            pieces.append(piece)
            segments.append(cut)
    ids = [m.id for m in pieces]
    if len(set(ids)) != len(ids):
        twice = next(x for x in ids if ids.count(x) > 1)
        raise DataError(f"maneuver id {twice!r} appears twice once the records are cut into cycles", source=toml,
                        column="id")
    maneuvers = pieces
    if segment == "none":
        maneuvers, segments = _join_written_cycles(maneuvers, segments, toml)
    # keep only the columns every maneuver has: optional columns must be all-or-nothing
    common = set.intersection(*(set(s) for s in segments))
    _same_columns_everywhere(maneuvers, segments, common, directory)
    data = from_segments([{k: s[k] for k in sorted(common)} for s in segments],
                         names=[m.id for m in maneuvers], source=str(directory),
                         constants=scalar_constants(aircraft), derive_alpha_dot=fmt != "raw",
                         flights=[m.flight for m in maneuvers])
    if fmt == "raw":
        extra["format"] = "raw"
    return Campaign(name, aircraft, tuple(maneuvers), data, directory, extra, cutoffs, rules)


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
                raise DataError(f"--segment none: the cycles of record {m.record!r} do not follow one another in "
                                f"time ({name} starts {gap:.4g} s after the cycle before it, the sample time is "
                                f"{dt:.4g} s): they cannot be joined into one record", source=toml, column="record")
        keys = set.intersection(*(set(p) for p in parts))
        out_m.append(replace(m, id=m.record, record=""))
        out_s.append({k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in keys})
        i = j
    return out_m, out_s


def _pieces(m: Maneuver, columns: dict, path: Path, entry: dict, segment: str | None, rules: records.LengthRules,
            cbar: float, where: str, derive_alpha_dot: bool = True) -> list[tuple[Maneuver, dict]]:
    """A validated record as the maneuvers it gives: itself, or its cycles (:mod:`structsearch.data.records`).
    A record cut into cycles gets its alpha_dot (when derived) from the whole record first, as a campaign in
    memory cut by :func:`~.cycles.segmented` has it: derived per cycle, it would be one-sided and noisy exactly
    where the states restart, and the two ways of cutting would fit different data."""
    lines = columns.pop(LINE_KEY, None)
    if "record" in entry:   # a cycle written by write_campaign names the record it was cut from
        if not isinstance(entry["record"], str) or not entry["record"]:
            raise DataError(f"record must be a non-empty string, not {entry['record']!r}", source=where,
                            column="record")
        m = replace(m, record=entry["record"])
    asked = records.segment_request(entry, where)
    if m.record or not records.wants_cycles(segment, asked, records.CYCLE_COLUMN in columns):
        columns.pop(records.CYCLE_COLUMN, None)
        return [(m, columns)]
    if derive_alpha_dot and "alpha_dot" not in columns and "alpha" in columns:
        columns["alpha_dot"] = np.gradient(np.asarray(columns["alpha"], float), np.asarray(columns["t"], float),
                                           edge_order=2)
    line_of = None if lines is None else (lambda row: f", line {int(lines[row])}")
    return [(replace(m, id=piece_id, record=m.id), piece) for piece_id, piece in
            records.cut_record(columns, m.id, str(path), rules.for_kind(m.kind), cbar, line_of)]


def _parse_cutoffs(table, toml: str) -> dict[str, float]:
    """``[cutoffs]``: pre-filter cut-offs [Hz] by channel that override the defaults (docs/interfaces.md 5.2)."""
    if not isinstance(table, dict):
        raise DataError("[cutoffs] must be a table of channel = frequency in Hz", source=toml, column="cutoffs")
    for key, value in table.items():
        if not (_number(value) and value > 0):
            raise DataError(f"[cutoffs] {key} must be a positive frequency in Hz, not {value!r}", source=toml,
                            column=key)
    return {k: float(v) for k, v in table.items()}


# ----- writing -----------------------------------------------------------------------------
def _toml_value(v) -> str:
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(int(v))
    return repr(float(v))


def write_campaign(campaign: Campaign, directory: Path | str, fmt: str = "csv") -> Path:
    """Write a campaign atomically: everything goes to a temporary directory that replaces the target."""
    if fmt not in ("csv", "parquet"):
        raise DataError(f"unknown campaign file format {fmt!r} (csv or parquet)")
    import pandas as pd
    directory = Path(directory).resolve()   # a symbolic link: replace what it points to
    if directory.parent == directory:
        raise DataError("cannot write a campaign as the file-system root", source=str(directory))
    if directory.exists() and (not directory.is_dir() or (any(directory.iterdir())
                                                          and not (directory / "campaign.toml").exists())):
        raise DataError("refusing to replace it: it exists and is not a campaign directory (no campaign.toml)",
                        source=str(directory))
    directory.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{directory.name}.", dir=directory.parent))
    os.chmod(tmp, 0o777 & ~umask())
    try:
        lines = [f"name = {_toml_value(campaign.name)}", "", "[aircraft]"]
        lines += [f"{k} = {_toml_value(campaign.aircraft[k])}" for k in AIRCRAFT_KEYS]
        lines += [f"{k} = {_toml_value(v)}" for k, v in campaign.aircraft.items() if k not in AIRCRAFT_KEYS]
        for key, value in campaign.extra.items():
            lines.insert(1, f"{key} = {_toml_value(value)}")
        if not campaign.length_rules.is_default:
            lines += ["", "[min_convective_times]"] + [f"{k} = {_toml_value(v)}"
                                                       for k, v in campaign.length_rules.as_table().items()]
        if campaign.cutoffs_hz:
            lines += ["", "[cutoffs]"] + [f"{k} = {_toml_value(v)}" for k, v in campaign.cutoffs_hz.items()]
        slices = campaign.data.segment_slices()
        for m, sl in zip(campaign.maneuvers, slices):
            file = f"{m.id}.{fmt}"
            lines += ["", "[[maneuver]]", f"id = {_toml_value(m.id)}", f"file = {_toml_value(file)}",
                      f"kind = {_toml_value(m.kind)}", f"split = {_toml_value(m.split)}"]
            if m.flight is not None:
                lines.append(f"flight = {_toml_value(m.flight)}")
            if m.record:
                lines.append(f"record = {_toml_value(m.record)}")
            frame = pd.DataFrame({k: v[sl] for k, v in campaign.data.columns.items()})
            ordered = [c for c in ("t",) + REQUIRED[1:] if c in frame] + sorted(
                c for c in frame if c not in REQUIRED)
            frame = frame[ordered]
            if fmt == "csv":
                frame.to_csv(tmp / file, index=False, float_format="%.17g")
            else:
                try:
                    frame.to_parquet(tmp / file, index=False)
                except ImportError:
                    raise DataError("writing Parquet needs the optional dependency pyarrow") from None
        (tmp / "campaign.toml").write_text("\n".join(lines) + "\n", encoding="utf-8")
        for written in tmp.iterdir():   # flush the files before they become the campaign
            sync_path(written)
        sync_path(tmp)
        if directory.exists() and exchange_directories(tmp, directory):
            shutil.rmtree(tmp)          # the old campaign, now under the temporary name
        elif directory.exists():        # no atomic exchange here: a short window between two renames
            old = directory.with_name(f".{directory.name}.old")
            if old.exists():
                shutil.rmtree(old)
            os.replace(directory, old)
            os.replace(tmp, directory)
            shutil.rmtree(old)
        else:
            os.replace(tmp, directory)
        sync_path(directory.parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return directory


# Top-level names of campaign.toml that free-text keys of a campaign may not take.
RESERVED_KEYS = ("name", "format", "aircraft", "maneuver", "cutoffs", "min_convective_times")


def make_campaign(name: str, aircraft: Mapping[str, float], maneuvers: Sequence[Maneuver],
                  segments: Sequence[Mapping[str, np.ndarray]], extra: Mapping[str, object] | None = None
                  ) -> Campaign:
    clash = [k for k in (extra or {}) if k in RESERVED_KEYS and not (k == "format" and extra[k] == "raw")]
    if clash:
        raise DataError(f"campaign key {clash[0]!r} is reserved in campaign.toml ({', '.join(RESERVED_KEYS)})")
    data = from_segments(list(segments), names=[m.id for m in maneuvers], source=name,
                         constants=scalar_constants(aircraft),
                         derive_alpha_dot=(extra or {}).get("format") != "raw",  # raw: recorded channels only
                         flights=[m.flight for m in maneuvers])
    return Campaign(name, dict(aircraft), tuple(maneuvers), data, None, dict(extra or {}))
