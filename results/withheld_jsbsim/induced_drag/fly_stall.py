"""Trim the exported aircraft structsearch_CL-VI and fly a quasi-steady stall in JSBSim.

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
STATES = ['X_ss', 'X_w']
COEFFICIENTS = ['CL', 'CD']
STALL_ALPHA = 0.3267        # rad: the last state's a*
FT = 0.3048


def fly(csv_path=None, seconds=None, dt=0.01):
    jsbsim.FGJSBBase().debug_lvl = 0          # no banner
    fdm = jsbsim.FGFDMExec(HERE)
    fdm.set_debug_level(0)
    fdm.load_model("structsearch_CL-VI")
    fdm.set_dt(dt)
    fdm["ic/h-sl-ft"] = 5300.9273150387635 / FT
    fdm["ic/vt-fps"] = 83.22810189990645 / FT
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
        row = {"t": fdm.get_sim_time(), "alpha_deg": math.degrees(fdm["aero/alpha-rad"]),
               "V_mps": fdm["velocities/vt-fps"] * FT, "de_rad": fdm["fcs/elevator-pos-rad"]}
        row.update({c: fdm["structsearch/" + c] for c in COEFFICIENTS})
        row.update({s: fdm["structsearch/" + s] for s in STATES})
        rows.append(row)
        if row["t"] >= next_print:
            print("  ".join(f"{k} {v:8.4f}" for k, v in row.items()))
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
    lines = ["# Stall flown in JSBSim by structsearch_CL-VI", "",
             f"- trimmed at alpha {first['alpha_deg']:.2f} deg, {first['V_mps']:.1f} m/s"]
    for s in STATES:
        down = next((r for r in rows if r[s] < 0.5), None)
        lines.append(f"- {s} falls through 0.5 at alpha {down['alpha_deg']:.2f} deg (t = {down['t']:.1f} s)"
                     if down else f"- {s} stays above 0.5 (lowest {min(r[s] for r in rows):.3f})")
    if "CL" in COEFFICIENTS:
        peak = max(rows, key=lambda r: r["CL"])
        lines.append(f"- largest C_L {peak['CL']:.3f} at alpha {peak['alpha_deg']:.2f} deg, "
                     + ", ".join(f"{s} {peak[s]:.3f}" for s in STATES))
    lines.append(f"- peak alpha {top['alpha_deg']:.2f} deg at t = {top['t']:.1f} s; at the end "
                 + ", ".join(f"{s} {rows[-1][s]:.3f}" for s in STATES))
    columns = ["t", "alpha_deg"] + list(COEFFICIENTS) + list(STATES)
    lines += ["", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    next_row = 0.0
    for r in rows:
        if r["t"] >= next_row:
            lines.append("| " + " | ".join(f"{r[c]:.4f}" for c in columns) + " |")
            next_row += 1.0
    return "\n".join(lines) + "\n"


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
    print(f"peak alpha {top['alpha_deg']:.2f} deg at t = {top['t']:.1f} s; wrote {args.csv} and {args.report}")
