"""``--modify FILE``: a modification of a JSBSim aircraft, read as data (TOML, never run)::

    [[scale]]
    function = "aero/coefficient/CLq"   # an axis function of the aircraft
    factor = 2.0                        # a finite number: the function is multiplied by it

    [[lag]]
    function = "aero/coefficient/CLwbh" # an axis function of the aircraft
    input = "aero/alpha-rad"            # a property it reads: it reads it lagged instead
    time_constant = 0.3                 # s, positive and finite: tau dy/dt + y = input

A lag is a first-order separation lag on what the function reads (its table's alpha, say): the function follows
the input with the time constant, as a separation that takes time to follow alpha does. A lag acts over time, so
it is a modification of an aircraft that is flown (``simulate --jsbsim``), not of one evaluated at recorded states.
At least one entry; each error names the file and the entry.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

from ..data.errors import DeclarationError
from ..data.reading import parse_toml, read_text

KEYS = ("scale", "lag")
SCALE_KEYS = ("function", "factor")
LAG_KEYS = ("function", "input", "time_constant")
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
class Modification:
    """What ``--modify`` changes: functions scaled (function -> factor) and inputs lagged."""

    scales: Mapping[str, float] = field(default_factory=dict)
    lags: tuple[Lag, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.scales or self.lags)

    @property
    def functions(self) -> tuple[str, ...]:
        """Every function the modification names (each must be one of the aircraft's axis functions)."""
        return tuple(dict.fromkeys([*self.scales, *(lag.function for lag in self.lags)]))

    def digest(self) -> str:
        """A short digest of the modification, "none" without one (a campaign's ``source.modify``). A modification
        of scales alone keeps the digest it has always had."""
        if not self:
            return "none"
        text = ";".join(f"{k}={float(v)!r}" for k, v in sorted(self.scales.items()))
        if self.lags:
            text += "|" + ";".join(f"{g.function}<{g.input}~{g.time_constant!r}" for g in self.lags)
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
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (
            positive and value <= 0):
        raise DeclarationError(f"{where}: {what}, not {value!r}")
    return float(value)


def _entries(doc: dict, key: str, path: Path) -> list:
    entries = doc.get(key, [])
    if not isinstance(entries, list):
        raise DeclarationError(f"{path}: {key} must be a list of [[{key}]] entries")
    return entries


def _scales(entries: list, path: Path) -> dict[str, float]:
    out: dict[str, float] = {}
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[scale]] entry {i}"
        if not isinstance(e, dict) or sorted(e) != sorted(SCALE_KEYS):
            raise DeclarationError(f"{where}: give exactly function = \"...\" and factor = NUMBER")
        function = _name(e["function"], where, "function must be the name of an axis function")
        if function in out:
            raise DeclarationError(f"{where}: {function} is scaled twice")
        out[function] = _number(e["factor"], where, "factor must be a finite number")
    return out


def _lags(entries: list, path: Path) -> tuple[Lag, ...]:
    out: list[Lag] = []
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[lag]] entry {i}"
        if not isinstance(e, dict) or sorted(e) != sorted(LAG_KEYS):
            raise DeclarationError(f"{where}: give exactly function = \"...\", input = \"...\" and "
                                   "time_constant = SECONDS")
        function = _name(e["function"], where, "function must be the name of an axis function")
        read = _name(e["input"], where, "input must be the name of a property the function reads")
        if any(g.function == function and g.input == read for g in out):
            raise DeclarationError(f"{where}: {function} already reads {read} lagged")
        tau = _number(e["time_constant"], where, "time_constant must be a positive finite number of seconds",
                      positive=True)
        out.append(Lag(function, read, tau, len(out) + 1))
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
        raise DeclarationError(f"{path}: unknown key {unknown[0]!r} (a modification holds [[scale]] and [[lag]] "
                               "entries)")
    modification = Modification(_scales(_entries(doc, "scale", path), path), _lags(_entries(doc, "lag", path), path))
    if not modification:
        raise DeclarationError(f"{path}: no [[scale]] or [[lag]] entry (function = \"aero/coefficient/...\", "
                               "factor = 2.0)")
    return modification
