"""A JSBSim aircraft file read as data: where it is, its aerodynamic axes and their functions, what each axis reads.

The file is user input: it is parsed by the standard library's ElementTree after refusing any document type
declaration (no entity is ever expanded: a ``<!DOCTYPE`` or ``<!ENTITY`` is one error naming the file), and
nothing in it is run. An axis function (``<axis name="LIFT"><function name="aero/coefficient/CLq">``) is a force
(lbs) or a moment (lbs ft) JSBSim sums into that axis; the properties it reads are collected through the helper
functions the aerodynamics define (``aero/function/...``), down to the properties JSBSim or the caller provides.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

from ..data.coefficients import COEFFICIENTS, FORCES, coefficient as coefficient_record
from ..data.errors import DeclarationError

# the axis that carries each coefficient (wind axes for the forces, the body pitch axis for the moment)
# the elements of a JSBSim function that name a property it reads
READ_TAGS = ("property", "p", "independentVar")
MAX_BYTES = 20_000_000


@dataclass(frozen=True)
class AircraftFile:
    """One aircraft: its name, its directory, the JSBSim root whose ``engine/`` and ``systems/`` it uses, and its
    parsed aerodynamics (``axes``: axis -> its function names in file order; ``reads``: function name -> the
    properties it reads directly; ``hysteresis``: the stall latch's (min, max) angle of attack in rad, or None)."""

    name: str
    directory: Path
    root: Path
    bundled: bool
    axes: Mapping[str, tuple[str, ...]] = field(repr=False)
    reads: Mapping[str, frozenset[str]] = field(repr=False)
    hysteresis: tuple[float, float] | None = None

    @property
    def file(self) -> Path:
        return self.directory / f"{self.name}.xml"

    def functions(self, axis: str) -> tuple[str, ...]:
        return self.axes.get(axis, ())

    def leaves(self, names) -> set[str]:
        """The properties the functions ``names`` read, through the helper functions the aerodynamics define."""
        out, seen, todo = set(), set(), list(names)
        while todo:
            name = todo.pop()
            if name in seen:
                continue
            seen.add(name)
            for p in self.reads.get(name, ()):
                if p in self.reads:
                    todo.append(p)
                else:
                    out.add(p)
        return out


def jsbsim_root() -> Path:
    """JSBSim's own root directory (its bundled aircraft, engines and systems)."""
    import jsbsim
    getter = getattr(jsbsim, "get_default_root_dir", None)
    return Path(getter()) if getter is not None else Path(jsbsim.__file__).parent


def locate(target: str) -> tuple[str, Path, Path, bool]:
    """(name, aircraft directory, root, bundled) of ``jsbsim:TARGET``: an aircraft directory (``<name>/<name>.xml``),
    a JSBSim root holding one aircraft under ``aircraft/``, or the name of one of JSBSim's own aircraft."""
    path = Path(target)
    if path.is_dir():
        path = path.resolve()
        if (path / f"{path.name}.xml").is_file():
            root = path.parent.parent if path.parent.name == "aircraft" else path.parent
            return path.name, path, root, False
        found = sorted(d.name for d in (path / "aircraft").glob("*") if (d / f"{d.name}.xml").is_file())
        if len(found) == 1:
            return found[0], path / "aircraft" / found[0], path, False
        raise DeclarationError(f"--simulator jsbsim:{target}: " + (
            f"the directory holds the aircraft {', '.join(found)}: name one (jsbsim:{path / 'aircraft' / found[0]})"
            if found else "no JSBSim aircraft here (neither <name>.xml in it nor aircraft/<name>/<name>.xml)"))
    if "/" in target or "\\" in target or target in ("", ".", ".."):
        raise DeclarationError(f"--simulator jsbsim:{target}: no such directory")
    root = jsbsim_root()
    directory = root / "aircraft" / target
    if not (directory / f"{target}.xml").is_file():
        known = sorted(d.name for d in (root / "aircraft").glob("*") if (d / f"{d.name}.xml").is_file())
        close = [k for k in known if k.lower().startswith(target.lower()[:3])][:5]
        raise DeclarationError(f"--simulator jsbsim:{target}: JSBSim has no aircraft {target!r} (in {root / 'aircraft'}"
                               + (f"; close: {', '.join(close)}" if close else "") + ")")
    return target, directory, root, True


def parse_file(path: Path) -> ET.Element:
    """The XML document at ``path``, refusing document type declarations (no entity expansion)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DeclarationError(f"{path}: cannot read the aircraft file ({exc.strerror})") from None
    return parse_bytes(raw, str(path), "the aircraft file")


def parse_bytes(raw: bytes, source: str, what: str) -> ET.Element:
    """The XML document ``raw`` (``source`` names it in an error), refusing document type declarations."""
    if len(raw) > MAX_BYTES:
        raise DeclarationError(f"{source}: {len(raw)} bytes is not {what} (more than {MAX_BYTES})")
    if b"<!DOCTYPE" in raw or b"<!ENTITY" in raw:
        raise DeclarationError(f"{source}: {what} declares a document type or an entity, which is not "
                               "read (entities are never expanded): remove the <!DOCTYPE ...> declaration")
    try:
        return ET.fromstring(raw)
    except ET.ParseError as exc:
        raise DeclarationError(f"{source}: not well-formed XML ({exc})") from None


def _reads(element: ET.Element) -> frozenset[str]:
    out = set()
    for tag in READ_TAGS:
        for e in element.iter(tag):
            text = (e.text or "").strip()
            if text:
                out.add(text.lstrip("-"))
    return frozenset(out)


def _angle(element: ET.Element, tag: str, path: Path) -> float:
    e = element.find(tag)
    try:
        value = float((e.text or "").strip())
    except (AttributeError, ValueError):
        raise DeclarationError(f"{path}: <hysteresis_limits> needs a numeric <{tag}>") from None
    unit = (element.get("unit") or "RAD").upper()
    return value * (3.141592653589793 / 180.0) if unit == "DEG" else value


def read_aircraft(target: str) -> AircraftFile:
    """The aircraft of ``jsbsim:TARGET`` with its aerodynamics parsed (module docstring)."""
    name, directory, root, bundled = locate(target)
    path = directory / f"{name}.xml"
    doc = parse_file(path)
    aero = doc.find("aerodynamics")
    if aero is None:
        raise DeclarationError(f"{path}: the aircraft has no <aerodynamics> section")
    if aero.get("file"):
        raise DeclarationError(f"{path}: the aerodynamics are in another file ({aero.get('file')}), which is not "
                               "read: copy them into the aircraft file")
    reads: dict[str, frozenset[str]] = {}
    for f in aero.iter("function"):
        if f.get("name"):
            reads[f.get("name")] = _reads(f)
    axes = {}
    for axis in aero.findall("axis"):
        names = tuple(f.get("name") for f in axis.findall("function") if f.get("name"))
        axes[(axis.get("name") or "").upper()] = axes.get((axis.get("name") or "").upper(), ()) + names
    hyst = aero.find("hysteresis_limits")
    limits = (_angle(hyst, "min", path), _angle(hyst, "max", path)) if hyst is not None else None
    return AircraftFile(name, directory, root, bundled, axes, reads, limits)


def check_axes(aircraft: AircraftFile, coefficient: str) -> tuple[str, ...]:
    """The functions of the axis that carries ``coefficient`` (for a moment also the force axes, whose forces the
    moment transfer to the cg reads; for C_Y the drag's); one error when the aircraft lacks them."""
    need = axes_read(coefficient)
    missing = [a for a in need if not aircraft.functions(a)]
    if missing:
        have = ", ".join(sorted(aircraft.axes)) or "none"
        raise DeclarationError(f"{aircraft.file}: no function in the aerodynamic axis {' and '.join(missing)} (the "
                               f"axes it has: {have}); {coefficient} is read from the {', '.join(need)} axes, not "
                               "from body-axis (X, Y, Z) forces")
    return aircraft.functions(coefficient_record(coefficient).jsbsim_axis)


def axes_read(coefficient: str) -> list[str]:
    """The aerodynamic axes ``coefficient`` is evaluated from: its own, and for a moment the force axes too
    (the transfer of the moment to the cg reads the forces)."""
    record = coefficient_record(coefficient)
    if not record.lateral:
        return [record.jsbsim_axis] + ([f.jsbsim_axis for f in FORCES] if record.moment else [])
    # the body-axis side force holds the drag turned by the sideslip; a lateral moment about the cg reads every
    # aerodynamic force (its arm)
    if not record.moment:
        return [record.jsbsim_axis, COEFFICIENTS["CD"].jsbsim_axis]
    return [record.jsbsim_axis] + [c.jsbsim_axis for c in COEFFICIENTS.values() if not c.moment]
