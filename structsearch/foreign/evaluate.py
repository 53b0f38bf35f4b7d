"""A JSBSim aircraft evaluated exactly at given states, one sample at a time.

For each sample the state is written as initial conditions, in this order: ``ic/h-sl-ft``, ``ic/vt-fps``,
``ic/alpha-rad``, ``ic/beta-rad``, ``ic/theta-rad``, ``ic/phi-rad``, ``ic/p-rad_sec``, ``ic/q-rad_sec``,
``ic/r-rad_sec`` (each initial condition is set from the ones before it), then the elevator position with the
flight-control system switched off (``simulation/models/FGFCS/enabled = 0``: a command would pass through actuator
lags that ``run_ic()`` does not reset) and the ``structsearch/`` inputs of the private copy
(:mod:`.private_copy`); ``run_ic()`` then computes every model once at that state without integrating. Each axis
function is a property holding exactly the force (lbs) or moment (lbs ft, about the aerodynamic reference point)
JSBSim sums into its axis; they are read back with the dynamic pressure and the body-axis aerodynamic forces.

The FDM is never reset (``reset_to_initial_conditions()`` disables JSBSim's stall hysteresis for good).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..data.errors import StructSearchError
from ..data.optional import need_jsbsim as need_optional_jsbsim
from .aircraft_xml import AircraftFile
from .private_copy import make_copy, namespace_reads

STATE_IC = ("ic/h-sl-ft", "ic/vt-fps", "ic/alpha-rad", "ic/beta-rad", "ic/theta-rad", "ic/phi-rad",
            "ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec")
FCS_ENABLED = "simulation/models/FGFCS/enabled"
QBAR = "aero/qbar-psf"
BODY_FORCES = ("forces/fbx-aero-lbs", "forces/fby-aero-lbs", "forces/fbz-aero-lbs")
GEOMETRY = ("metrics/Sw-sqft", "metrics/cbarw-ft", "metrics/bw-ft", "metrics/aero-rp-x-in", "metrics/aero-rp-y-in",
            "metrics/aero-rp-z-in", "inertia/cg-x-in", "inertia/cg-y-in", "inertia/cg-z-in")
NEEDS = "evaluating a JSBSim aircraft needs the jsbsim package"


def need_jsbsim():
    """The jsbsim module, or one error saying how to install it."""
    return need_optional_jsbsim(NEEDS)


@dataclass(frozen=True)
class Evaluation:
    """What JSBSim computed at every sample: each function's value (lbs or lbs ft), the dynamic pressure (psf),
    the body-axis aerodynamic forces (lbs), the geometry it was computed with, and the time spent in JSBSim."""

    functions: Mapping[str, np.ndarray] = field(repr=False)
    qbar: np.ndarray = field(repr=False)
    body: Mapping[str, np.ndarray] = field(repr=False)
    geometry: Mapping[str, float]
    seconds: float
    version: str


def load(aircraft: AircraftFile, scales: Mapping[str, float] | None = None):
    """(FDM, the private copy's directory) with ``aircraft`` loaded from its private copy, every ``structsearch/``
    property it reads created first (at 0: those of the axes not evaluated keep it) and the flight controls
    switched off."""
    jsbsim = need_jsbsim()
    holder = make_copy(aircraft, scales)
    jsbsim.FGJSBBase().debug_lvl = 0          # no banner on stdout
    fdm = jsbsim.FGFDMExec(holder.name)
    fdm.set_debug_level(0)
    manager = fdm.get_property_manager()
    for prop in sorted(namespace_reads(aircraft)):
        manager.get_node(prop, True).set_double_value(0.0)
    if not fdm.load_model(aircraft.name):
        holder.cleanup()
        raise StructSearchError(f"JSBSim could not load the aircraft {aircraft.name!r} ({aircraft.file})")
    fdm[FCS_ENABLED] = 0.0
    return fdm, holder


def evaluate(aircraft: AircraftFile, functions: Sequence[str], states: Mapping[str, np.ndarray],
             inputs: Mapping[str, np.ndarray], scales: Mapping[str, float] | None = None,
             also: Sequence[str] = ()) -> Evaluation:
    """Every function of ``functions`` at each sample: ``states`` holds the :data:`STATE_IC` values (JSBSim units),
    ``inputs`` the other properties written (the elevator, the ``structsearch/`` ones), one array each; the
    properties ``also`` are read besides the body forces (into ``body``)."""
    jsbsim = need_jsbsim()
    fdm, holder = load(aircraft, scales)
    try:
        manager = fdm.get_property_manager()
        writes = [(manager.get_node(p, True), np.asarray(states[p], float)) for p in STATE_IC]
        writes += [(manager.get_node(p, True), np.asarray(v, float)) for p, v in inputs.items()]
        reads = list(functions) + [QBAR, *BODY_FORCES, *also]
        nodes = [manager.get_node(p, False) for p in reads]
        missing = [p for p, n in zip(reads, nodes) if n is None]
        if missing:
            raise StructSearchError(f"{aircraft.file}: JSBSim has no property {missing[0]} after loading the aircraft")
        n = len(writes[0][1])
        out = np.empty((len(nodes), n))
        started = time.perf_counter()
        run_ic = fdm.run_ic
        for k in range(n):
            for node, values in writes:
                node.set_double_value(values[k])
            run_ic()
            for j, node in enumerate(nodes):
                out[j, k] = node.get_double_value()
        seconds = time.perf_counter() - started
        geometry = {p: float(fdm[p]) for p in GEOMETRY}
    finally:
        holder.cleanup()
    m = len(functions)
    return Evaluation(dict(zip(functions, out[:m])), out[m], dict(zip([*BODY_FORCES, *also], out[m + 1:])), geometry,
                      seconds, jsbsim.__version__)
