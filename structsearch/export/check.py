"""``export --check``: JSBSim (the library itself) driven with recorded inputs, against structsearch's prediction.

The example aircraft of the export is loaded with the export directory as JSBSim's root, its integration
suspended (the aircraft does not move: only the flight-control systems and the aerodynamics run) and
``structsearch/fill-inputs`` set to 0. For every sample of every maneuver the namespace's inputs are written
(alpha, alpha_dot, q, V, de, ... in SI units) with ``structsearch/dt-sec`` the step from the previous sample
(0 at a maneuver's first sample: the states start in equilibrium, as in the fits), one frame is run, and the
coefficients ``structsearch/CL`` ... and the states ``structsearch/X_...`` are read back.

Static points (alpha across the fitted range at three elevator settings, the other inputs at their medians,
q = alpha_dot = 0, every state in equilibrium) are compared the same way. The lag's discretisation: the export
integrates a U state by the fits' exact recursion; JSBSim's ``<lag_filter>`` would use the bilinear (Tustin)
rule, whose difference from the exact recursion on the recorded maneuvers is computed and stated too.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

import numpy as np
from scipy.signal import lfilter

from ..data.coefficients import COEFFICIENTS
from ..data.errors import StructSearchError
from ..data.flightdata import FlightData, from_segments
from ..data.optional import need_jsbsim as need_optional_jsbsim
from ..engine.separation import SeparationState, evaluate_state, is_lagged, static_separation
from .card import ExportedModel
from .jsbsim_files import DT, FILL_INPUTS, inputs_used
from .xml_functions import INPUTS, output_property, state_property

STATIC_TOLERANCE = 1e-9       # |JSBSim - structsearch| on static points
RATIO_TOLERANCE = 0.01        # max |JSBSim - structsearch| over a maneuver / the residual sd
STATIC_ALPHAS = 61

# structsearch's own prediction on some data: coefficient or state symbol -> values
Predictor = Callable[[FlightData], Mapping[str, np.ndarray]]


def need_jsbsim(what: str = "export --check drives JSBSim"):
    """The jsbsim module, or one error saying how to install it (``what`` needs it)."""
    return need_optional_jsbsim(what)


@dataclass(frozen=True)
class CheckReport:
    """``check.json``: per coefficient its static and per-maneuver differences, per state the same and the
    lag_filter (Tustin) difference, and whether the targets hold."""

    coefficients: Mapping[str, dict]
    states: Mapping[str, dict]
    samples: int
    static_points: int
    seconds: float
    jsbsim_version: str

    @property
    def passed(self) -> bool:
        """No coefficient misses a target (one whose residual sd is unknown is judged on the static points only)."""
        return all(c["passed"] is not False for c in self.coefficients.values())

    def to_dict(self) -> dict:
        return {"passed": self.passed,
                "targets": {"static_max_abs_diff": STATIC_TOLERANCE, "ratio": RATIO_TOLERANCE},
                "coefficients": dict(self.coefficients), "states": dict(self.states),
                "discretisation": ("U states: the exact recursion of the fits (first-order hold), written as "
                                   "fcs_function components; JSBSim's lag_filter (bilinear/Tustin) would differ "
                                   "from it by each state's lag_filter_max_abs_diff"),
                "samples": self.samples, "static_points": self.static_points, "seconds": self.seconds,
                "jsbsim_version": self.jsbsim_version}

    def lines(self) -> list[str]:
        out = []
        for name, c in self.coefficients.items():
            worst = c["max_ratio"]
            out.append(f"{name}: static max |diff| {c['static_max_abs_diff']:.2g}, maneuvers max |diff| "
                       f"{c['max_abs_diff']:.2g} = {'-' if worst is None else f'{worst:.2g}'} of the residual sd "
                       f"{'-' if c['residual_sd'] is None else format(c['residual_sd'], '.3g')}"
                       f"{'' if c['passed'] else ' (target NOT met)'}")
        for name, s in self.states.items():
            tustin = s.get("lag_filter_max_abs_diff")
            out.append(f"{name}: max |diff| {s['max_abs_diff']:.2g}"
                       + (f"; a Tustin lag_filter would differ by up to {tustin:.2g}" if tustin is not None else ""))
        return out


def static_points(model: ExportedModel, data: FlightData) -> FlightData:
    """Alpha across the fitted range at the lowest, median and highest elevator, other inputs at their medians,
    q = alpha_dot = 0; each point a 3-sample maneuver with constant inputs (its states in equilibrium)."""
    lo, hi = model.validity["alpha_rad"]
    columns = [c for c in inputs_used(model) if c not in ("alpha",)] + ["alpha"]
    median = {c: float(np.median(data[c])) for c in columns if c in data}
    median.update(q=0.0, alpha_dot=0.0)
    # the measured coefficients are not inputs (drag and pitch read the lift model's C_L): placeholders
    median.update({c: 0.0 for c in COEFFICIENTS if c in data})
    des = np.quantile(data["de"], [0.0, 0.5, 1.0]) if "de" in data else [0.0]
    segments = []
    for de in des:
        for alpha in np.linspace(lo, hi, STATIC_ALPHAS):
            point = dict(median, alpha=float(alpha), de=float(de))
            # uneven steps: the fits then integrate each point's states on their own; on one even grid they filter
            # all points at once and correct each start, which leaves an absolute rounding of 1e-16 in a state
            # near 0 that sqrt(X) in K_L turns into 1e-9
            segments.append({**{k: np.full(3, v) for k, v in point.items()}, "t": np.array([0.0, 0.01, 0.03])})
    return from_segments(segments, source="static points", constants=dict(data.constants))


def load_aircraft(directory: Path | None, aircraft: str, what: str = "export --check drives JSBSim"):
    """JSBSim with ``aircraft`` loaded from the root ``directory`` (None: JSBSim's own aircraft), initialised and
    its integration suspended (module docstring); None when JSBSim cannot load it."""
    jsbsim = need_jsbsim(what)
    jsbsim.FGJSBBase().debug_lvl = 0          # no banner on stdout
    fdm = jsbsim.FGFDMExec(None if directory is None else str(directory))
    fdm.set_debug_level(0)
    if not fdm.load_model(aircraft):
        return None
    fdm.run_ic()
    fdm.suspend_integration()
    return fdm


def drive(fdm, data: FlightData, columns, read) -> np.ndarray:
    """Write the namespace inputs of ``columns`` from ``data`` sample by sample (``structsearch/fill-inputs`` off,
    ``structsearch/dt-sec`` the step from the previous sample, 0 at a maneuver's first), run one frame each, and
    return the properties ``read`` (one row each, one column per sample)."""
    fdm[FILL_INPUTS] = 0.0
    manager = fdm.get_property_manager()
    inputs = [(manager.get_node(INPUTS[c].property, True), np.asarray(data[c], float)) for c in columns]
    step = manager.get_node(DT, True)
    nodes = [manager.get_node(p, False) for p in read]
    out = np.empty((len(nodes), data.n_samples))
    t = np.asarray(data["t"], float)
    for s, e in zip(data.bounds[:-1], data.bounds[1:]):
        for k in range(int(s), int(e)):
            step.set_double_value(0.0 if k == s else t[k] - t[k - 1])
            for node, values in inputs:
                node.set_double_value(values[k])
            fdm.run()
            for j, node in enumerate(nodes):
                out[j, k] = node.get_double_value()
    return out


def _jsbsim_run(directory: Path, aircraft: str, model: ExportedModel, data: FlightData):
    """JSBSim's coefficients and states along ``data`` (module docstring)."""
    fdm = load_aircraft(directory, aircraft)
    if fdm is None:
        raise StructSearchError(f"JSBSim could not load the exported aircraft {aircraft!r} from {directory}")
    names = [c.coefficient for c in model.coefficients] + [s.symbol for s in model.states]
    read = [output_property(n) if n in COEFFICIENTS else state_property(n) for n in names]
    out = drive(fdm, data, inputs_used(model), read)
    return dict(zip(names, out)), need_jsbsim().__version__


def _tustin_difference(model: ExportedModel, data: FlightData) -> dict[str, float]:
    """Per U state: max |X (bilinear lag, JSBSim's lag_filter) - X (exact recursion)| on ``data``."""
    out = {}
    t, alpha, alpha_dot = (np.asarray(data[c], float) for c in ("t", "alpha", "alpha_dot"))
    for s in model.states:
        p = s.base()
        if not is_lagged(s.kind):
            continue
        u = static_separation(alpha - p.get("tau2", 0.0) * alpha_dot, p["a1"], p["a_star"])
        exact, _ = evaluate_state(SeparationState(s.name, s.kind), p, alpha, alpha_dot, t, data.bounds,
                                  sensitivities=False)
        worst = 0.0
        for a, b in zip(data.bounds[:-1], data.bounds[1:]):
            worst = max(worst, float(np.max(np.abs(_tustin(t[a:b], u[a:b], p["tau1"]) - exact[a:b]))))
        out[s.symbol] = worst
    return out


def _tustin(t: np.ndarray, u: np.ndarray, tau1: float) -> np.ndarray:
    """JSBSim's lag_filter (C1/(s + C1), C1 = 1/tau1, bilinear), started in equilibrium."""
    dt = np.diff(t)
    c = 1.0 / tau1
    if np.allclose(dt, dt[0], rtol=1e-9):
        ca, cb = dt[0] * c / (2.0 + dt[0] * c), (2.0 - dt[0] * c) / (2.0 + dt[0] * c)
        return lfilter([ca, ca], [1.0, -cb], u, zi=[u[0] * (1.0 - ca)])[0]
    y = np.empty_like(u)
    y[0] = u[0]
    for k in range(1, len(u)):
        ca, cb = dt[k - 1] * c / (2.0 + dt[k - 1] * c), (2.0 - dt[k - 1] * c) / (2.0 + dt[k - 1] * c)
        y[k] = ca * (u[k] + u[k - 1]) + cb * y[k - 1]
    return y


def check(model: ExportedModel, directory: Path, aircraft: str, maneuvers: FlightData,
          predict: Predictor) -> CheckReport:
    """Drive the exported aircraft in JSBSim along ``maneuvers`` and on the static points; compare with
    ``predict`` (structsearch's prediction of the same fit)."""
    started = time.perf_counter()
    static = static_points(model, maneuvers)
    jsb_static, version = _jsbsim_run(directory, aircraft, model, static)
    jsb, _ = _jsbsim_run(directory, aircraft, model, maneuvers)
    ours_static, ours = predict(static), predict(maneuvers)
    tustin = _tustin_difference(model, maneuvers)
    coefficients = {}
    for c in model.coefficients:
        name = c.coefficient
        coefficients[name] = _compare(jsb[name], ours[name], jsb_static[name], ours_static[name], maneuvers,
                                      c.residual_sd, target=True)
    states = {}
    for s in model.states:
        states[s.symbol] = _compare(jsb[s.symbol], ours[s.symbol], jsb_static[s.symbol], ours_static[s.symbol],
                                    maneuvers, None, target=False)
        if s.symbol in tustin:
            states[s.symbol]["lag_filter_max_abs_diff"] = tustin[s.symbol]
    return CheckReport(coefficients, states, maneuvers.n_samples, static.n_samples,
                       round(time.perf_counter() - started, 2), version)


def _compare(jsb: np.ndarray, ours: np.ndarray, jsb_static: np.ndarray, ours_static: np.ndarray,
             data: FlightData, residual_sd: float | None, target: bool) -> dict:
    static = float(np.max(np.abs(jsb_static - ours_static)))
    per = {}
    for name, s, e in zip(data.names, data.bounds[:-1], data.bounds[1:]):
        diff = float(np.max(np.abs(jsb[s:e] - ours[s:e])))
        entry = {"max_abs_diff": diff}
        if target:
            entry.update(residual_sd=residual_sd, ratio=None if not residual_sd else diff / residual_sd)
        per[name] = entry
    out = {"static_max_abs_diff": static, "max_abs_diff": max(v["max_abs_diff"] for v in per.values())}
    if target:
        ratios = [v["ratio"] for v in per.values()]
        worst = None if any(r is None for r in ratios) else max(ratios)
        passed = static <= STATIC_TOLERANCE and (worst is None or worst <= RATIO_TOLERANCE)
        out.update(residual_sd=residual_sd, max_ratio=worst, passed=passed if worst is not None or not passed else None)
        if residual_sd is None:
            out["note"] = ("no residual standard deviation (the fit it came from did not record one): the ratio "
                           "target is not judged")
    out["maneuvers"] = per
    return out
