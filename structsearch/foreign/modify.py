"""``--modify FILE``: a modification of a JSBSim aircraft, read as data (TOML, never run)::

    [[scale]]
    function = "aero/coefficient/CLq"   # an axis function of the aircraft
    factor = 2.0                        # a finite number: the function is multiplied by it

    [[lag]]
    function = "aero/coefficient/CLwbh" # an axis function of the aircraft
    input = "aero/alpha-rad"            # a property it reads: it reads it lagged instead
    time_constant = 0.3                 # s, positive and finite: tau dy/dt + y = input

    [[replace]]
    function = "aero/coefficient/CLwbh" # an axis function holding one table
    rows = [-0.09, 0.0, 0.09, 0.36]     # its row breakpoints, increasing
    columns = [0.0, 1.0]                # its column breakpoints (a table of two inputs only)
    values = [[-0.22, -0.22], [0.25, 0.25], [0.73, 0.73], [1.15, 1.15]]   # a row of values per row breakpoint
                                                                            # (one number per row without columns)

    [[state]]
    system = "systems/structsearch_states.xml"  # a separation-state system `export --format jsbsim` wrote,
                                                # a path inside this file's directory
    state = "structsearch/X_ss"                 # the state it computes (1 attached, 0 separated)
    function = "aero/coefficient/CLwbh"         # an axis function of the aircraft
    input = "aero/stall-hyst-norm"              # a property it reads: it reads the state instead
    complement = true                           # read 1 - state (a property that is 1 when separated)

    [[wing_drop]]                               # an asymmetric stall: a separation state per wing
    a_star = 0.30                               # (structsearch.foreign.wing_drop says what each key is)
    a1 = 30.0
    tau1 = 0.1
    eta = 0.5
    asymmetry = 0.01
    roll = 0.05
    yaw = 0.01

A lag is a first-order separation lag on what the function reads (its table's alpha, say): the function follows
the input with the time constant, as a separation that takes time to follow alpha does. A state is a separation
state the project identified and exported, flown inside the aircraft: its system is copied into the aircraft and
the function reads the state where it read ``input`` (c172p's stall latch, say, which picks the lift table's
column). A replaced table keeps the inputs it reads and takes the given breakpoints and values. A lag and a state
act over time, as a wing drop does, so they modify an aircraft that is flown (``simulate --jsbsim``), not one evaluated at recorded
states. At least one entry; each error names the file and the entry.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

from ..data.errors import DataError, DeclarationError
from ..data.reading import parse_toml, read_text, shown
from .aircraft_xml import parse_bytes
from .wing_drop import OPTIONAL as WING_DROP_OPTIONAL, REQUIRED as WING_DROP_KEYS, WingDrop

KEYS = ("scale", "lag", "replace", "state", "wing_drop")
SCALE_KEYS = ("function", "factor")
LAG_KEYS = ("function", "input", "time_constant")
REPLACE_KEYS = ("function", "rows", "values")
REPLACE_OPTIONAL = ("columns",)
STATE_KEYS = ("system", "state", "function", "input")
STATE_OPTIONAL = ("complement",)
# the properties a lag's flight writes and its function reads (foreign.private_copy, foreign.fly)
LAG_ACTIVE = "structsearch/lag-active"


@dataclass(frozen=True)
class Lag:
    """``function`` reads ``input`` lagged by ``time_constant`` [s]; ``number`` (1, 2, ...) names its properties."""

    function: str
    input: str
    time_constant: float
    number: int = 1

    @property
    def lagged(self) -> str:
        """The lagged input of the frame before, which the flight writes after each frame."""
        return f"structsearch/lag-{self.number}/lagged"

    @property
    def read(self) -> str:
        """The property the function reads in place of its input: the input until the lag is active (trim), the
        lagged input after."""
        return f"structsearch/lag-{self.number}/input"

    def retained(self, frame_s: float) -> float:
        """The share of the lagged value one frame of ``frame_s`` seconds keeps: exp(-frame/tau)."""
        return math.exp(-frame_s / self.time_constant)


@dataclass(frozen=True)
class Table:
    """``function``'s only table replaced: breakpoints ``rows`` (and ``columns``, for a table of two inputs) and
    ``values`` (one per row; a row of one per column for two inputs)."""

    function: str
    rows: tuple[float, ...]
    values: tuple
    columns: tuple[float, ...] = ()
    entry: str = field(default="[[replace]]", compare=False)   # the file and entry that declared it, for errors

    def table_data(self) -> str:
        """The values as JSBSim's ``<tableData>`` reads them: the column breakpoints first, then a line per row."""
        lines = ["\t".join(repr(c) for c in self.columns)] if self.columns else []
        for row, value in zip(self.rows, self.values):
            lines.append("\t".join(repr(v) for v in (row, *(value if self.columns else (value,)))))
        return "\n" + "\n".join(lines) + "\n"

    def key(self) -> str:
        return f"{self.function}={self.rows!r}x{self.columns!r}:{self.values!r}"


@dataclass(frozen=True)
class State:
    """A separation state's system (its XML text, from ``source``) flown in the aircraft; ``function`` reads
    ``state`` (or 1 - state, ``complement``) where it read ``input``."""

    source: str
    system: str = field(repr=False)
    state: str
    function: str
    input: str
    complement: bool = False
    entry: str = field(default="[[state]]", compare=False)     # the file and entry that declared it, for errors

    def key(self) -> str:
        text = hashlib.sha256(self.system.encode()).hexdigest()[:16]
        return f"{self.function}<{self.input}={'1-' if self.complement else ''}{self.state}@{text}"


@dataclass(frozen=True)
class Modification:
    """What ``--modify`` changes: functions scaled (function -> factor), inputs lagged, tables replaced,
    separation states flown in place of inputs and an asymmetric stall (:mod:`.wing_drop`)."""

    scales: Mapping[str, float] = field(default_factory=dict)
    lags: tuple[Lag, ...] = ()
    tables: tuple[Table, ...] = ()
    states: tuple[State, ...] = ()
    wing_drops: tuple[WingDrop, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.scales or self.lags or self.tables or self.states or self.wing_drops)

    @property
    def acts_over_time(self) -> bool:
        """Whether it modifies only an aircraft that is flown (a lag, a state, a wing drop), not one evaluated at
        states."""
        return bool(self.lags or self.states or self.wing_drops)

    @property
    def functions(self) -> tuple[str, ...]:
        """Every function the modification names (each must be one of the aircraft's axis functions)."""
        return tuple(dict.fromkeys([*self.scales, *(lag.function for lag in self.lags),
                                    *(t.function for t in self.tables), *(s.function for s in self.states),
                                    *(w.function for w in self.wing_drops if w.function)]))

    def digest(self) -> str:
        """A short digest of the modification, "none" without one (a campaign's ``source.modify``). A modification
        of scales alone keeps the digest it has always had."""
        if not self:
            return "none"
        text = ";".join(f"{k}={float(v)!r}" for k, v in sorted(self.scales.items()))
        if self.lags:
            text += "|" + ";".join(f"{g.function}<{g.input}~{g.time_constant!r}" for g in self.lags)
        if self.tables or self.states:
            text += "|" + ";".join(t.key() for t in self.tables) + "|" + ";".join(s.key() for s in self.states)
        if self.wing_drops:
            text += "|" + ";".join(w.key() for w in self.wing_drops)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _refused(source: str, message: str) -> DeclarationError:
    return DeclarationError(f"{source}: {' '.join(message.split())}")


def _not_toml(source: str, message: str) -> DeclarationError:
    return DeclarationError(f"{source}: not a TOML file ({' '.join(message.removeprefix('not valid TOML: ').split())})")


def _name(value, where: str, what: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise DeclarationError(f"{where}: {what}")
    return value.strip()


def _number(value, where: str, what: str, positive: bool = False) -> float:
    try:       # an integer of hundreds of digits has no float: the same error as any other bad number
        number = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan
    except OverflowError:
        number = math.nan
    if not math.isfinite(number) or (positive and number <= 0):
        raise DeclarationError(f"{where}: {what}, not {shown(value)}")
    return number


def _entries(doc: dict, key: str, path: Path) -> list:
    entries = doc.get(key, [])
    if not isinstance(entries, list):
        raise DeclarationError(f"{path}: {key} must be a list of [[{key}]] entries")
    return entries


def _scales(entries: list, path: Path) -> dict[str, float]:
    out: dict[str, float] = {}
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[scale]] entry {i}"
        _keys(e, SCALE_KEYS, (), where, "exactly function = \"...\" and factor = NUMBER")
        function = _name(e["function"], where, "function must be the name of an axis function")
        if function in out:
            raise DeclarationError(f"{where}: {function} is scaled twice")
        out[function] = _number(e["factor"], where, "factor must be a finite number")
    return out


def _lags(entries: list, path: Path) -> tuple[Lag, ...]:
    out: list[Lag] = []
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[lag]] entry {i}"
        _keys(e, LAG_KEYS, (), where, "exactly function = \"...\", input = \"...\" and time_constant = SECONDS")
        function = _name(e["function"], where, "function must be the name of an axis function")
        read = _name(e["input"], where, "input must be the name of a property the function reads")
        if any(g.function == function and g.input == read for g in out):
            raise DeclarationError(f"{where}: {function} already reads {read} lagged")
        tau = _number(e["time_constant"], where, "time_constant must be a positive finite number of seconds",
                      positive=True)
        out.append(Lag(function, read, tau, len(out) + 1))
    return tuple(out)


def _breakpoints(value, where: str, what: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) < 2:
        raise DeclarationError(f"{where}: {what} must be a list of at least two numbers")
    points = tuple(_number(v, where, f"each of {what} must be a finite number") for v in value)
    if any(b <= a for a, b in zip(points, points[1:])):
        raise DeclarationError(f"{where}: {what} must increase, not {list(points)!r}")
    return points


def _values(value, rows: int, columns: int, where: str) -> tuple:
    if not isinstance(value, list) or len(value) != rows:
        raise DeclarationError(f"{where}: values must hold one entry per row breakpoint ({rows})")
    if not columns:
        return tuple(_number(v, where, "each value must be a finite number") for v in value)
    if any(not isinstance(r, list) or len(r) != columns for r in value):
        raise DeclarationError(f"{where}: each entry of values must be a list of one number per column ({columns})")
    return tuple(tuple(_number(v, where, "each value must be a finite number") for v in r) for r in value)


def _keys(e, required: tuple[str, ...], optional: tuple[str, ...], where: str, say: str) -> None:
    if not isinstance(e, dict) or not set(required) <= set(e) or not set(e) <= set(required + optional):
        raise DeclarationError(f"{where}: give {say}")


def _tables(entries: list, path: Path) -> tuple[Table, ...]:
    out: list[Table] = []
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[replace]] entry {i}"
        _keys(e, REPLACE_KEYS, REPLACE_OPTIONAL, where,
              "function = \"...\", rows = [...], values = [...] and, for a table of two inputs, columns = [...]")
        function = _name(e["function"], where, "function must be the name of an axis function")
        if any(t.function == function for t in out):
            raise DeclarationError(f"{where}: {function}'s table is replaced twice")
        rows = _breakpoints(e["rows"], where, "rows")
        columns = _breakpoints(e["columns"], where, "columns") if "columns" in e else ()
        out.append(Table(function, rows, _values(e["values"], len(rows), len(columns), where), columns, where))
    return tuple(out)


def _system(value, path: Path, where: str) -> tuple[str, str]:
    """(the name, the text) of a state's system file: a relative path inside the modification's directory."""
    from ..data.reading import inside
    name = _name(value, where, "system must be the path of a system file beside the modification")
    try:
        file = inside(path.parent, name, source=str(path), column="system")
        return name, read_text(file, error=lambda source, message: _refused(f"{where}: the system {name!r}", message))
    except DataError as exc:
        raise DeclarationError(f"{where}: {exc}") from None
    except OSError as exc:
        raise DeclarationError(f"{where}: cannot read the system {name!r} ({exc.strerror})") from None


def _check_system(text: str, name: str, state: str, where: str) -> set[str]:
    """A system file is one ``<system>`` that reads no other file and computes ``state``; what it computes."""
    root = parse_bytes(text.encode(), f"{where}: {name}", "a system file")
    if root.tag != "system":
        raise DeclarationError(f"{where}: {name} is not a JSBSim <system> file")
    # JSBSim would load a file named by a `file` attribute from anywhere: the system must be whole
    if any("file" in e.attrib for e in root.iter()):
        raise DeclarationError(f"{where}: {name} names another file (a 'file' attribute); give the system whole")
    computed = _computed_properties(root)
    if state not in computed:
        near = sorted(p for p in computed if p.rsplit("/", 1)[-1].startswith("X"))
        raise DeclarationError(f"{where}: {name} computes no property {state!r}"
                               + (f" (its states: {', '.join(near)})" if near else ""))
    return computed


def _computed_properties(root) -> set[str]:
    """The properties a system computes: its components' outputs and names, and the properties it declares."""
    out = {(e.text or "").strip() for e in root.iter("output")}
    out |= {e.get("name", "") for e in root.iter() if e.tag not in ("system", "channel")}
    out |= {(e.text or "").strip() for e in root.iter("property") if e.get("value") is not None}
    return out - {""}


def _states(entries: list, path: Path) -> tuple[State, ...]:
    """The states, each system flown once however many states it holds; two different systems may not compute
    the same property (both would write it every frame)."""
    out: list[State] = []
    systems: dict[str, tuple[str, set[str]]] = {}    # a system's text -> (the entry that named it first, computes)
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[state]] entry {i}"
        _keys(e, STATE_KEYS, STATE_OPTIONAL, where, "system = \"FILE\", state = \"PROPERTY\", function = \"...\", "
              "input = \"...\" and optionally complement = true")
        name, text = _system(e["system"], path, where)
        state = _name(e["state"], where, "state must be the property the system computes")
        computed = _check_system(text, name, state, where)
        for other, (first, theirs) in systems.items():
            if other != text and computed & theirs:
                raise DeclarationError(f"{where}: its system {name} computes {sorted(computed & theirs)[0]}, as the "
                                       f"system of {first} does")
        systems.setdefault(text, (where, computed))
        complement = e.get("complement", False)
        if not isinstance(complement, bool):
            raise DeclarationError(f"{where}: complement must be true or false, not {complement!r}")
        function = _name(e["function"], where, "function must be the name of an axis function")
        read = _name(e["input"], where, "input must be the name of a property the function reads")
        if any(s.function == function and s.input == read for s in out):
            raise DeclarationError(f"{where}: {function} already reads a state in place of {read}")
        out.append(State(name, text, state, function, read, complement, where))
    return tuple(out)


def _wing_drops(entries: list, path: Path) -> tuple[WingDrop, ...]:
    if len(entries) > 1:
        raise DeclarationError(f"{path}: [[wing_drop]] entry 2: one wing drop flies per aircraft")
    out = []
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[wing_drop]] entry {i}"
        _keys(e, WING_DROP_KEYS, WING_DROP_OPTIONAL, where, ", ".join(f"{k} = NUMBER" for k in WING_DROP_KEYS)
              + " and optionally " + " and ".join(WING_DROP_OPTIONAL))
        if ("function" in e) != ("input" in e):
            raise DeclarationError(f"{where}: function and input go together (the axis function that reads the "
                                   "wings' mean separation, and the property it reads it in place of)")
        positive = ("a1", "tau1", "eta")
        values = {k: _number(e[k], where, f"{k} must be a {'positive ' if k in positive else ''}finite number",
                             positive=k in positive) for k in e if k not in ("function", "input")}
        names = {k: _name(e[k], where, f"{k} must be a property's name") for k in ("function", "input") if k in e}
        out.append(WingDrop(**values, **names, entry=where))
    return tuple(out)


def read_modify(path: str | Path) -> Modification:
    """The modification in ``path`` (module docstring)."""
    path = Path(path)
    # a file from anyone: a regular file of bounded size, UTF-8, its nesting bounded (structsearch.data.reading)
    try:
        doc = parse_toml(read_text(path, error=_refused), path, _not_toml)
    except OSError as exc:
        raise DeclarationError(f"{path}: cannot read the modification ({exc.strerror})") from None
    unknown = [k for k in doc if k not in KEYS]
    if unknown:
        raise DeclarationError(f"{path}: unknown key {unknown[0]!r} (a modification holds [[scale]], [[lag]], "
                               "[[replace]], [[state]] and [[wing_drop]] entries)")
    modification = Modification(_scales(_entries(doc, "scale", path), path), _lags(_entries(doc, "lag", path), path),
                                _tables(_entries(doc, "replace", path), path),
                                _states(_entries(doc, "state", path), path),
                                _wing_drops(_entries(doc, "wing_drop", path), path))
    if not modification:
        raise DeclarationError(f"{path}: no [[scale]], [[lag]], [[replace]], [[state]] or [[wing_drop]] entry (function = "
                               "\"aero/coefficient/...\", factor = 2.0)")
    return modification
