"""An example JSBSim aircraft around the exported aerodynamics, and a script that trims it and flies a stall.

``aircraft/<name>/<name>.xml`` has the campaign's reference geometry (wing area, span, mean chord), its mass
and pitch inertia (roll and yaw inertias, when the campaign has none, are stated guesses: the model is
longitudinal and the flight symmetric), the centre of gravity and the aerodynamic reference point at the
recorded centre of gravity, one turbine engine at the centre of gravity thrusting along the body x axis (its
thrust is C_T * qbar * S, which the drag and pitch models read; fuel frozen so that the mass stays put), an
elevator driven by ``fcs/elevator-cmd-norm`` over the range the campaign flew, the exported states' system and
``aerodynamics.xml`` (both read from the export directory: ``fly_stall.py`` opens JSBSim with that directory as
its root).
"""
from __future__ import annotations

import re

from .card import ExportedModel
from .jsbsim_files import SYSTEM_NAME, _document
from .xml_functions import element

ENGINE = "structsearch_turbine"


def aircraft_name(model: ExportedModel) -> str:
    """A file-safe name: ``structsearch_<lift model>`` (``structsearch_CL-VI``)."""
    first = model.coefficients[0].model if model.coefficients else "model"
    return "structsearch_" + re.sub(r"[^A-Za-z0-9_-]+", "_", first)


def _number(tag: str, x: float, unit: str) -> object:
    return element(tag, text=f" {float(x)!r} ", unit=unit)


def _location(name: str | None, x: float, unit: str = "M"):
    attributes = {"unit": unit} | ({"name": name} if name else {})
    return element("location", element("x", text=repr(float(x))), element("y", text="0.0"),
                   element("z", text="0.0"), **attributes)


def _contact(name: str, x: float, y: float, z: float, spring: float = 2e5):
    where = element("location", element("x", text=repr(float(x))), element("y", text=repr(float(y))),
                    element("z", text=repr(float(z))), unit="M")
    return element("contact", where, element("static_friction", text="0.8"), element("dynamic_friction", text="0.5"),
                   element("rolling_friction", text="0.02"), _number("spring_coeff", spring, "N/M"),
                   _number("damping_coeff", spring / 4, "N/M/SEC"), element("max_steer", text="0.0", unit="DEG"),
                   element("brake_group", text="NONE"), element("retractable", text="0"), type="BOGEY", name=name)


def aircraft_xml(model: ExportedModel, name: str) -> str:
    a = model.aircraft
    x_cg = float(a.get("x_cg", 0.0))
    iyy = float(a["Iyy"])
    metrics = element("metrics", _number("wingarea", a["S"], "M2"), _number("wingspan", a["b"], "M"),
                      _number("chord", a["cbar"], "M"), _location("AERORP", x_cg), _location("EYEPOINT", x_cg),
                      _location("VRP", x_cg))
    mass = element("mass_balance", _number("ixx", a.get("Ixx", 0.8 * iyy), "KG*M2"), _number("iyy", iyy, "KG*M2"),
                   _number("izz", a.get("Izz", 1.6 * iyy), "KG*M2"), _number("emptywt", a["mass"], "KG"),
                   _location("CG", x_cg))
    engine = element("engine", element("feed", text="0"),
                     element("thruster", _location(None, x_cg),
                             element("orient", element("pitch", text="0.0"), element("roll", text="0.0"),
                                     element("yaw", text="0.0"), unit="DEG"), file="direct"),
                     file=ENGINE)
    tank = element("tank", _location(None, x_cg), _number("capacity", 1000.0, "KG"),
                   _number("contents", 0.0, "KG"), type="FUEL")
    # three contact points a wheel's height below the centre of gravity (JSBSim needs ground reactions)
    contacts = element("ground_reactions", *[_contact(n, x_cg + dx, y, -0.2 * a["b"]) for n, dx, y in
                                             (("NOSE", 0.3 * a["b"], 0.0), ("LEFT_MAIN", -0.05 * a["b"], -0.15 * a["b"]),
                                              ("RIGHT_MAIN", -0.05 * a["b"], 0.15 * a["b"]))])
    de = float(a["de_range_rad"])
    # the stick and the pitch trim (JSBSim's trim moves fcs/pitch-trim-cmd-norm) add up to the elevator command
    command = element("summer", element("input", text="fcs/elevator-cmd-norm"),
                      element("input", text="fcs/pitch-trim-cmd-norm"),
                      element("clipto", element("min", text="-1"), element("max", text="1")),
                      name="fcs/pitch-command-sum")
    elevator = element("aerosurface_scale", element("input", text="fcs/pitch-command-sum"),
                       element("range", element("min", text=repr(-de)), element("max", text=repr(de))),
                       element("output", text="fcs/elevator-pos-rad"), name="fcs/elevator-control")
    root = element("fdm_config",
                   element("fileheader", element("author", text="structsearch export"),
                           element("description", text=f"Example aircraft flying {', '.join(c.model for c in model.coefficients)}")),
                   metrics, mass, contacts, element("propulsion", engine, tank),
                   element("system", file=SYSTEM_NAME),
                   element("flight_control", element("channel", command, elevator, name="pitch"), name="structsearch"),
                   element("aerodynamics", file="../../aerodynamics.xml"),
                   name=name, version="2.0", release="ALPHA")
    guessed = [k for k in ("Ixx", "Izz") if k not in a]
    return _document(root, "\n  " + "\n  ".join([
        f"Example aircraft exported by structsearch: geometry and mass of {model.data.get('source', 'the campaign')}.",
        "Centre of gravity and aerodynamic reference point at the recorded centre of gravity (the x_cg datum).",
        "One turbine at the centre of gravity along body x; its maximum thrust covers the campaign's C_T.",
        *([f"{' and '.join(guessed)}: guessed from Iyy (the campaign has none; the model is longitudinal)."]
          if guessed else [])]) + "\n")


def engine_xml(max_thrust_newton: float) -> str:
    """A turbine whose thrust at full throttle is ``max_thrust_newton`` at every Mach and altitude (flat tables:
    the campaign's thrust is a measured C_T, not an engine model)."""
    lbf = max_thrust_newton / 4.4482216152605

    def flat(name: str, level: float):
        rows = "\n".join(f"  {m:4.1f}  {level:.3f}  {level:.3f}" for m in (0.0, 2.0))
        return element("function", element("table", element("independentVar", text="velocities/mach", lookup="row"),
                                           element("independentVar", text="atmosphere/density-altitude",
                                                   lookup="column"),
                                           element("tableData", text=f"\n        -10000  60000\n{rows}\n")),
                       name=name)
    root = element("turbine_engine", _number("milthrust", lbf, "LBS"), element("bypassratio", text="0.0"),
                   element("tsfc", text="0.6"), element("bleed", text="0.0"), element("idlen1", text="30.0"),
                   element("idlen2", text="60.0"), element("maxn1", text="100.0"), element("maxn2", text="100.0"),
                   element("augmented", text="0"), element("injected", text="0"),
                   flat("IdleThrust", 0.0), flat("MilThrust", 1.0), name=ENGINE)
    return _document(root, " flat thrust tables: full throttle gives milthrust everywhere ")


def direct_thruster_xml() -> str:
    return _document(element("direct", name="Direct"), " thrust is the engine's ")


def fly_stall_script(model: ExportedModel, name: str) -> str:
    """``fly_stall.py``: trims the example aircraft and flies a quasi-steady stall (alpha raised slowly by an
    elevator loop past the wing's separation, then recovered), printing alpha, C_L and the states and writing
    ``stall.csv``."""
    a = model.aircraft
    states = [s.symbol for s in model.states]
    stall_alpha = max((s.params[f"a_star{'_' + s.name if s.name else ''}"] for s in model.states), default=0.25)
    return FLY_STALL.format(name=name, h=float(a["trim_h_m"]), v=float(a["trim_V_mps"]),
                            states=repr(states), stall_alpha=float(stall_alpha),
                            coefficients=repr([c.coefficient for c in model.coefficients]))


FLY_STALL = '''"""Trim the exported aircraft {name} and fly a quasi-steady stall in JSBSim.

Run with the Python that has jsbsim installed: python fly_stall.py [--csv stall.csv] [--report stall.md]. The
export directory is
JSBSim's root (aircraft/, systems/, engine/, aerodynamics.xml). After a trim in level flight the throttle goes to
idle and an elevator loop raises alpha at 1 deg/s until it is 3 deg past the last separation state's a*, holds it
for 3 s, then lowers it at 2 deg/s back to the trim value. Prints alpha, C_L and the separation states every second;
writes the flight (stall.csv) and its report (stall.md: where each state separates, the largest C_L, the peak alpha,
the reattachment, and alpha, the coefficients and the states once a second).
"""
import argparse
import csv
import math
import os

import jsbsim

HERE = os.path.dirname(os.path.abspath(__file__))
STATES = {states}
COEFFICIENTS = {coefficients}
STALL_ALPHA = {stall_alpha!r}        # rad: the last state's a*
FT = 0.3048


def fly(csv_path=None, seconds=None, dt=0.01):
    jsbsim.FGJSBBase().debug_lvl = 0          # no banner
    fdm = jsbsim.FGFDMExec(HERE)
    fdm.set_debug_level(0)
    fdm.load_model("{name}")
    fdm.set_dt(dt)
    fdm["ic/h-sl-ft"] = {h!r} / FT
    fdm["ic/vt-fps"] = {v!r} / FT
    fdm["ic/gamma-deg"] = 0.0
    fdm["propulsion/fuel_freeze"] = 1
    fdm.run_ic()
    fdm["propulsion/set-running"] = -1
    fdm.do_trim(1)                            # full longitudinal trim: throttle, elevator, pitch
    alpha_trim, de_trim = fdm["aero/alpha-rad"], fdm["fcs/elevator-cmd-norm"]
    peak = STALL_ALPHA + math.radians(3.0)
    rise = (peak - alpha_trim) / math.radians(1.0)
    end = seconds if seconds is not None else rise + 3.0 + 10.0
    fdm["fcs/throttle-cmd-norm[0]"] = 0.0
    rows, integral, next_print = [], 0.0, 0.0
    while fdm.get_sim_time() < end:
        t = fdm.get_sim_time()
        # up at 1 deg/s, held 3 s, down at 2 deg/s
        target = alpha_trim + min(t, rise) * math.radians(1.0)
        if t > rise + 3.0:
            target = max(alpha_trim, peak - (t - rise - 3.0) * math.radians(2.0))
        error = fdm["aero/alpha-rad"] - target
        integral += error * dt
        # elevator loop on alpha with pitch-rate damping (positive command: nose down)
        command = de_trim + 4.0 * error + 2.0 * integral + 1.0 * fdm["velocities/q-rad_sec"]
        fdm["fcs/elevator-cmd-norm"] = max(-1.0, min(1.0, command))
        fdm.run()
        row = {{"t": fdm.get_sim_time(), "alpha_deg": math.degrees(fdm["aero/alpha-rad"]),
               "V_mps": fdm["velocities/vt-fps"] * FT, "de_rad": fdm["fcs/elevator-pos-rad"]}}
        row.update({{c: fdm["structsearch/" + c] for c in COEFFICIENTS}})
        row.update({{s: fdm["structsearch/" + s] for s in STATES}})
        rows.append(row)
        if row["t"] >= next_print:
            print("  ".join(f"{{k}} {{v:8.4f}}" for k, v in row.items()))
            next_print += 1.0
    if csv_path:
        with open(csv_path, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return rows


def report(rows):
    """The flight as Markdown: its landmarks (trim, where each state falls through 0.5, the largest C_L, the peak
    alpha, the states at the end) and alpha, the coefficients and the states once a second."""
    first, top = rows[0], max(rows, key=lambda r: r["alpha_deg"])
    lines = ["# Stall flown in JSBSim by {name}", "",
             f"- trimmed at alpha {{first['alpha_deg']:.2f}} deg, {{first['V_mps']:.1f}} m/s"]
    for s in STATES:
        down = next((r for r in rows if r[s] < 0.5), None)
        lines.append(f"- {{s}} falls through 0.5 at alpha {{down['alpha_deg']:.2f}} deg (t = {{down['t']:.1f}} s)"
                     if down else f"- {{s}} stays above 0.5 (lowest {{min(r[s] for r in rows):.3f}})")
    if "CL" in COEFFICIENTS:
        peak = max(rows, key=lambda r: r["CL"])
        lines.append(f"- largest C_L {{peak['CL']:.3f}} at alpha {{peak['alpha_deg']:.2f}} deg, "
                     + ", ".join(f"{{s}} {{peak[s]:.3f}}" for s in STATES))
    lines.append(f"- peak alpha {{top['alpha_deg']:.2f}} deg at t = {{top['t']:.1f}} s; at the end "
                 + ", ".join(f"{{s}} {{rows[-1][s]:.3f}}" for s in STATES))
    columns = ["t", "alpha_deg"] + list(COEFFICIENTS) + list(STATES)
    lines += ["", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    next_row = 0.0
    for r in rows:
        if r["t"] >= next_row:
            lines.append("| " + " | ".join(f"{{r[c]:.4f}}" for c in columns) + " |")
            next_row += 1.0
    return "\\n".join(lines) + "\\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--csv", default=os.path.join(HERE, "stall.csv"), help="where to write the flight")
    parser.add_argument("--report", default=os.path.join(HERE, "stall.md"),
                        help="where to write the flight's report (Markdown)")
    args = parser.parse_args()
    flown = fly(args.csv)
    with open(args.report, "w") as f:
        f.write(report(flown))
    top = max(flown, key=lambda r: r["alpha_deg"])
    print(f"peak alpha {{top['alpha_deg']:.2f}} deg at t = {{top['t']:.1f}} s; wrote {{args.csv}} and {{args.report}}")
'''
