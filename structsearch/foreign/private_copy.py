"""The private copy of a JSBSim aircraft that JSBSim loads to be evaluated at recorded states.

JSBSim computes some of what an aircraft's aerodynamics read from its own history, not from the state it is given:
``aero/alphadot-rad_sec`` is the change of alpha since the previous frame, ``aero/stall-hyst-norm`` a latch set by
the frames before, a propeller's induced velocity the engine's. Evaluated sample by sample, such values would
depend on the order of evaluation. The copy (the aircraft directory copied into a temporary JSBSim root beside
links to the original root's ``engine/`` and ``systems/``) rewrites every such read in its ``<aerodynamics>`` to a
property of the ``structsearch/`` namespace that the evaluation writes from the recording:

* ``aero/alphadot-rad_sec`` (``-deg_sec``) -> ``structsearch/alphadot-rad_sec`` (``-deg_sec``);
* ``aero/stall-hyst-norm`` -> ``structsearch/stall-hyst-norm``;
* every other property that is neither derived by JSBSim from the written state (:func:`derived`) nor the
  elevator -> ``structsearch/input/<property>``: an input the campaign or ``--simulator-input`` supplies.

The copy's top-level ``<output>`` directives are removed (JSBSim would write files), each function a
modification scales (``--modify``) is wrapped in a product with its factor, each input a modification lags is
read by its function through a property of its own (:func:`_lag`; the flight writes the lagged value), a replaced
table takes its new breakpoints and values, and a separation state's system is copied into the aircraft, its
function reading the state in place of the input it replaces (:func:`_state`).
"""
from __future__ import annotations

import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Mapping, Sequence

from ..data.errors import DeclarationError
from .aircraft_xml import READ_TAGS, AircraftFile, parse_bytes, parse_file
from .modify import LAG_ACTIVE, Lag, State, Table
from .wing_drop import SEPARATED as WING_SEPARATED, WingDrop, insert as insert_wing_drop, separated as wing_separated

NAMESPACE = "structsearch/"
ALPHADOT = {"aero/alphadot-rad_sec": "structsearch/alphadot-rad_sec",
            "aero/alphadot-deg_sec": "structsearch/alphadot-deg_sec"}
HYSTERESIS = "aero/stall-hyst-norm"
HYSTERESIS_INPUT = "structsearch/stall-hyst-norm"
INPUT_PREFIX = "structsearch/input/"
# the elevator position the campaign's de gives (JSBSim's convention: positive trailing edge down, as de's), and
# what JSBSim's flight-control system derives from it when it is written
ELEVATOR = "fcs/elevator-pos-rad"
ELEVATOR_DERIVED = ("fcs/elevator-pos-deg", "fcs/mag-elevator-pos-rad")
# what JSBSim derives from the state written through ic/... and run_ic(): the flight condition, the geometry
_DERIVED_PREFIXES = ("velocities/", "atmosphere/", "attitude/", "position/", "metrics/", "inertia/",
                     "aero/alpha-", "aero/beta-", "aero/mag-beta-", "aero/qbar-psf", "aero/qbarUW", "aero/qbarUV",
                     "aero/ci2vel", "aero/bi2vel", "aero/h_b-", "aero/Re", "aero/vt-")


def derived(prop: str) -> bool:
    """Whether JSBSim derives ``prop`` from the state the evaluation writes (or from the elevator)."""
    return prop == ELEVATOR or prop in ELEVATOR_DERIVED or prop.startswith(_DERIVED_PREFIXES)


def rewritten(prop: str) -> str:
    """The property the private copy reads in place of ``prop``."""
    if prop in ALPHADOT:
        return ALPHADOT[prop]
    if prop == HYSTERESIS:
        return HYSTERESIS_INPUT
    if derived(prop) or prop.startswith(NAMESPACE):
        return prop
    return INPUT_PREFIX + prop


def namespace_reads(aircraft: AircraftFile) -> set[str]:
    """Every ``structsearch/`` property the private copy's aerodynamics read (each must exist before JSBSim loads
    the copy, whichever axis reads it)."""
    reads = {p for ps in aircraft.reads.values() for p in ps if p not in aircraft.reads}
    return {rewritten(p) for p in reads if rewritten(p).startswith(NAMESPACE)}


def _rewrite_reads(aero: ET.Element, defined: set[str]) -> None:
    for tag in READ_TAGS:
        for e in aero.iter(tag):
            text = (e.text or "").strip()
            if not text:
                continue
            sign, prop = ("-", text[1:]) if text.startswith("-") else ("", text)
            if prop not in defined:
                e.text = sign + rewritten(prop)


def _scale(aero: ET.Element, scales: Mapping[str, float]) -> None:
    """Each function named in ``scales`` multiplied by its factor: its operation wrapped in a product."""
    for f in aero.iter("function"):
        factor = scales.get(f.get("name") or "")
        if factor is None:
            continue
        body = [c for c in f if c.tag != "description"]
        product = ET.Element("product")
        value = ET.SubElement(product, "value")
        value.text = repr(float(factor))
        for c in body:
            f.remove(c)
            product.append(c)
        f.append(product)


def _lag(aero: ET.Element, lag: Lag, aircraft: str, frame_s: float) -> None:
    """``lag.function`` reads ``lag.read`` where it read ``lag.input``; that property is a function ahead of the
    axes, evaluated in the frame after JSBSim has computed the frame's input: the exact step of tau dy/dt + y = u
    from the value of the frame before (``lag.lagged``, which the flight writes back after each frame),
    y = u + A (y_before - u) with A = exp(-frame/tau) while :data:`~.modify.LAG_ACTIVE` is 1, and the input itself
    while it is 0 (JSBSim trims the aircraft so: in equilibrium a lagged input is the input)."""
    _read_instead(aero, lag.function, lag.input, lag.read, aircraft, "[[lag]]")
    switched = ET.Element("function", name=lag.read)
    total = ET.SubElement(switched, "sum")
    ET.SubElement(total, "property").text = lag.input
    product = ET.SubElement(total, "product")
    ET.SubElement(product, "property").text = LAG_ACTIVE
    ET.SubElement(product, "value").text = repr(lag.retained(frame_s))
    difference = ET.SubElement(product, "difference")
    ET.SubElement(difference, "property").text = lag.lagged
    ET.SubElement(difference, "property").text = lag.input
    _insert_ahead(aero, switched)


def _read_instead(aero: ET.Element, function: str, prop: str, read: str, aircraft: str, entry: str) -> None:
    """``function`` reads ``read`` where it read ``prop`` (``entry``: what asks, "[[lag]]" or the file and entry of
    a state)."""
    reads = [e for f in aero.iter("function") if f.get("name") == function
             for tag in READ_TAGS for e in f.iter(tag) if (e.text or "").strip().lstrip("-") == prop]
    if not reads:
        raise DeclarationError(f"--modify: {entry}: the function {function} of {aircraft} does not read {prop}; "
                               "it replaces a property its function reads")
    for e in reads:
        e.text = ("-" if e.text.strip().startswith("-") else "") + read


def _insert_ahead(aero: ET.Element, function: ET.Element) -> None:
    """``function`` ahead of every function and axis of the aerodynamics: computed before anything reads it."""
    aero.insert(next((i for i, c in enumerate(aero) if c.tag in ("function", "axis")), len(aero)), function)


def _replace_table(aero: ET.Element, table: Table, aircraft: str) -> None:
    """``table.function``'s only table takes ``table``'s breakpoints and values; it reads the inputs it read."""
    found = [t for f in aero.iter("function") if f.get("name") == table.function for t in f.iter("table")]
    if len(found) != 1:
        raise DeclarationError(f"--modify: {table.entry}: the function {table.function} of {aircraft} holds "
                               f"{len(found)} tables; a [[replace]] replaces a function's only table")
    inputs = [(v.text or "").strip() for v in found[0].findall("independentVar")]
    if len(inputs) != (2 if table.columns else 1):
        raise DeclarationError(f"--modify: {table.entry}: the table of {table.function} reads {len(inputs)} inputs "
                               f"({', '.join(inputs)}): give columns = [...] for a table of two inputs, none for one")
    found[0].find("tableData").text = table.table_data()


def _systems(doc: ET.Element, aero: ET.Element, states: Sequence[State]) -> None:
    """Each distinct system of ``states`` flown once in the aircraft: a system inserted twice would step its states
    twice a frame (two different systems computing one property are refused when the modification is read)."""
    for state in {s.system: s for s in states}.values():
        doc.insert(list(doc).index(aero), parse_bytes(state.system.encode(), state.source, "a system file"))


def _state(aero: ET.Element, state: State, number: int, aircraft: str) -> None:
    """The state's function reads the state (or 1 - state) in place of ``state.input`` (its system: :func:`_systems`)."""
    read = state.state
    if state.complement:
        read = f"structsearch/state-{number}/complement"
        complement = ET.Element("function", name=read)
        difference = ET.SubElement(complement, "difference")
        ET.SubElement(difference, "value").text = "1.0"
        ET.SubElement(difference, "property").text = state.state
        _insert_ahead(aero, complement)
    _read_instead(aero, state.function, state.input, read, aircraft, state.entry)


def _link(source: Path, target: Path) -> None:
    if not source.is_dir():
        return
    try:
        os.symlink(source, target, target_is_directory=True)
    except OSError:
        shutil.copytree(source, target)


def make_copy(aircraft: AircraftFile, scales: Mapping[str, float] | None = None,
              rewrite: bool = True, lags: Sequence[Lag] = (), frame_s: float = 0.01, tables: Sequence[Table] = (),
              states: Sequence[State] = (), wing_drops: Sequence[WingDrop] = ()) -> tempfile.TemporaryDirectory:
    """A temporary JSBSim root holding the private copy of ``aircraft`` (module docstring); the caller keeps the
    returned directory object alive while JSBSim reads from it. Without ``rewrite`` (an aircraft to fly, not to
    evaluate at given states) the aerodynamics keep reading JSBSim's own properties; only such an aircraft may
    carry ``lags`` and ``states`` (they act over time), stepped in frames of ``frame_s`` seconds."""
    if (lags or states or wing_drops) and rewrite:
        raise DeclarationError("--modify: a [[lag]], a [[state]] or a [[wing_drop]] acts over time: it modifies an "
                               "aircraft that is flown (simulate --jsbsim), not one evaluated at recorded states")
    holder = tempfile.TemporaryDirectory(prefix="structsearch-jsbsim-")
    root = Path(holder.name)
    # the name is an existing aircraft directory's own name (aircraft_xml.locate refuses '/', '\\' and '..'), never
    # a name read from a file: the copy stays under root
    target = root / "aircraft" / aircraft.name
    shutil.copytree(aircraft.directory, target, symlinks=False)
    for sub in ("engine", "systems"):
        _link(aircraft.root / sub, root / sub)
    doc = parse_file(aircraft.file)
    for out in doc.findall("output"):
        doc.remove(out)
    aero = doc.find("aerodynamics")
    if rewrite:
        _rewrite_reads(aero, set(aircraft.reads))
    for table in tables:
        _replace_table(aero, table, aircraft.name)
    _scale(aero, dict(scales or {}))
    for lag in lags:
        _lag(aero, lag, aircraft.name, frame_s)
    _systems(doc, aero, states)
    for number, state in enumerate(states, 1):
        _state(aero, state, number, aircraft.name)
    for drop in wing_drops:
        insert_wing_drop(doc, aero, drop, aircraft.name)
        if drop.function:   # the lift stalls with the wings
            _insert_ahead(aero, wing_separated())
            _read_instead(aero, drop.function, drop.input, WING_SEPARATED, aircraft.name, drop.entry)
    ET.ElementTree(doc).write(target / f"{aircraft.name}.xml", encoding="utf-8", xml_declaration=True)
    return holder
