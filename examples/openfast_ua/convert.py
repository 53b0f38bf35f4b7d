"""Convert the Ohio State University S809 pitching-airfoil runs shipped by OpenFAST into a structsearch campaign.

    python examples/openfast_ua/convert.py      # reads original/, writes campaign/ and static_polar.csv

The source (``original/``, copied unchanged from github.com/OpenFAST/openfast at commit a2961baa, folder
CertTest/Wind/UA_Tests, Apache-2.0: see NOTICE and LICENSE-OpenFAST): two runs of the clean S809 airfoil at
Re = 1e6 pitching 18.8 +- 10.7 deg at 0.61 Hz and 1.21 Hz (``Exp_Results/*_Validacion.txt``: alpha in degrees,
C_l, pressure drag C_dp, C_m about the quarter chord; 120 samples of 3.4 and 3.8 cycles, no time column), the
drivers that OpenFAST's UnsteadyAero runs them with (``*.dvr``: airspeed, chord, frequency, mean and amplitude)
and the airfoil's static polar (``S809_AD15.dat``).

What the conversion does, and why:

* **One phase-averaged cycle per run.** The runs carry no time stamps. A sinusoid fitted to alpha (least squares
  over the number of samples per cycle) gives each sample's phase; its mean and amplitude reproduce the driver's
  to 0.01 deg, so the samples are evenly spaced in time at 31.4 and 35.5 samples per cycle. The samples are
  averaged in as many equal phase bins as there are samples per cycle (rounded), starting at alpha's minimum:
  each bin averages 3 or 4 cycles, which is what a phase-averaged wind-tunnel cycle is. The cycle is written
  without a time column, with the driver's ``frequency`` in its [[maneuver]] entry: structsearch reads it as a
  periodic record (its separation states start at their periodic solution).
* **Columns.** alpha in radians; q = d alpha/dt (the model pitches about a fixed axis), by central differences
  around the cycle; V the driver's airspeed; de = 0; CL = C_l, CD = C_dp, Cm = C_m.
* **Aircraft.** A two-dimensional section: cbar the chord (0.457 m), S = chord x 1 m span, b = 1 m (no fit reads
  S or b).
* **Split.** The 1.21 Hz run (reduced frequency k = pi f c / V = 0.050) trains; the 0.61 Hz run (k = 0.025)
  validates: a model of the separation dynamics must carry over to the other frequency.
* ``static_polar.csv``: the S809 static polar from -20 to 40 deg (alpha in radians), to compare static
  separation curves with (docs/tutorials/pitching-airfoil.md).

Only data is taken from OpenFAST; nothing of its code.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ORIGINAL = HERE / "original"


@dataclass(frozen=True)
class Airfoil:
    """One airfoil's campaign: its directory under examples/openfast_ua, the runs (maneuver id, OSU case name,
    split), the AeroDyn polar and the polar file written beside the campaign, the manifest's words."""

    directory: str
    runs: tuple[tuple[str, str, str], ...]
    polar: str
    polar_csv: str
    title: str
    about: str
    chord: float | None = None        # None: the training run's driver's chord
    chord_note: str = ""
    drivers: dict[str, str] | None = None   # a run's driver file where its name differs from the run's

    def driver(self, case: str) -> str:
        return (self.drivers or {}).get(case, case)


AIRFOILS = (
    Airfoil("campaign", (("s809_1p2hz", "C10m100AM20_s809", "train"), ("s809_0p6hz", "C10l100AM20_s809", "validation")),
            "S809_AD15.dat", "static_polar.csv", "S809 pitching airfoil (Ohio State University, via OpenFAST)",
            "Ohio State University wind-tunnel tests of the S809 airfoil, clean, Re = 1e6, 18.8 +- 10.7 deg."),
    Airfoil("campaign_ls417", (("ls417_re1p0", "C10m100AM14_l417", "train"),
                               ("ls417_re1p5", "C10m150AM14_l417", "validation")),
            "L417_C100_AD15.dat", "static_polar_ls417.csv",
            "LS(1)-0417MOD pitching airfoil (Ohio State University, via OpenFAST)",
            "Ohio State University wind-tunnel tests of the LS(1)-0417MOD airfoil, clean, 14 +- 10.7 deg at 1.2 Hz,\n"
            "# Re = 1.0e6 (training) and 1.5e6 (validation).",
            drivers={"C10m100AM14_l417": "C10m100AM14_LS417", "C10m150AM14_l417": "C10m150AM14_LS417"}),
    Airfoil("campaign_naca", (("naca_mean20", "05014061", "train"), ("naca_mean15", "05014051", "validation")),
            "05000051_AD15.dat", "static_polar_naca.csv", "Symmetric NACA section pitching through deep dynamic stall "
            "(via OpenFAST)",
            "Pitching runs of a symmetric NACA section (the readme's NACA 14061 and 14051): mean 20 and 15 deg,\n"
            "# amplitude 10 deg, k = 0.077, Re = 1.48e6, one phase-averaged cycle each.",
            chord=0.55,
            chord_note="the readme gives k = 0.077 for both runs, which at 1.8 Hz and 40.36 m/s is a 0.55 m chord "
                       "(05014051.dvr; 05014061.dvr says 0.5)"),
)
RUNS = AIRFOILS[0].runs     # the S809 runs (the tutorial's names)
POLAR_RANGE_DEG = (-20.0, 40.0)


def driver_values(path: Path) -> dict[str, float]:
    """The numeric ``value  Key  - comment`` lines of an UnsteadyAero driver file."""
    out = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        match = re.match(r"\s*([-+]?[0-9][0-9.eE+-]*)\s+(\w+)\s", line)
        if match:
            out[match.group(2)] = float(match.group(1))
    return out


def sinusoid_fit(alpha: np.ndarray) -> tuple[float, float, float, float]:
    """(samples per cycle, mean, amplitude, phase of sample 0) of the least-squares sinusoid through alpha."""
    k = np.arange(len(alpha))

    def fit(per_cycle):
        basis = np.column_stack([np.ones(len(k)), np.cos(2 * np.pi * k / per_cycle), np.sin(2 * np.pi * k / per_cycle)])
        coef = np.linalg.lstsq(basis, alpha, rcond=None)[0]
        return float(np.sum((alpha - basis @ coef) ** 2)), coef

    grid = np.arange(10.0, min(80.0, len(alpha) / 2.5), 0.01)
    per_cycle = float(grid[np.argmin([fit(p)[0] for p in grid])])
    _, (mean, c, s) = fit(per_cycle)
    return per_cycle, float(mean), float(np.hypot(c, s)), float(np.arctan2(-s, c))


def phase_average(table: np.ndarray, per_cycle: float, phase0: float) -> np.ndarray:
    """The rows of ``table`` averaged in round(per_cycle) equal phase bins, the first starting at alpha's minimum
    (alpha = mean + amplitude cos(phase): its minimum at phase pi)."""
    bins = int(round(per_cycle))
    phase = (2 * np.pi * np.arange(len(table)) / per_cycle + phase0 - np.pi) % (2 * np.pi)
    index = np.minimum((phase / (2 * np.pi) * bins).astype(int), bins - 1)
    counts = np.bincount(index, minlength=bins)
    if np.any(counts == 0):
        raise SystemExit(f"an empty phase bin: {counts}")
    return np.column_stack([np.bincount(index, table[:, j], bins) / counts for j in range(table.shape[1])])


def one_cycle(alpha: np.ndarray) -> tuple[float, float]:
    """(mean, amplitude) of the first harmonic of a record that is one cycle of evenly spaced samples."""
    k = 2 * np.pi * np.arange(len(alpha)) / len(alpha)
    basis = np.column_stack([np.ones(len(k)), np.cos(k), np.sin(k)])
    mean, c, s = np.linalg.lstsq(basis, alpha, rcond=None)[0]
    return float(mean), float(np.hypot(c, s))


# A record of one cycle is already phase-averaged (the NACA runs: 128 samples, one cycle); its first harmonic
# matches the driver's mean and amplitude to 0.1 deg (the cycle is not a pure sinusoid), several cycles' to 0.01.
ONE_CYCLE_TOLERANCE_DEG = 0.1
CYCLES_TOLERANCE_DEG = 0.01


def convert_run(case: str, chord: float | None = None, driver_name: str | None = None) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    driver = driver_values(ORIGINAL / f"{driver_name or case}.dvr")
    table = np.loadtxt(ORIGINAL / f"{case}_Validacion.txt", skiprows=1)   # Alfa Cl Cdp Cm
    if len(table) > 100 and one_cycle_record(table[:, 0]):
        mean, amplitude = one_cycle(table[:, 0])
        cycle, per_cycle, tolerance = table, float(len(table)), ONE_CYCLE_TOLERANCE_DEG
    else:
        per_cycle, mean, amplitude, phase0 = sinusoid_fit(table[:, 0])
        cycle, tolerance = phase_average(table, per_cycle, phase0), CYCLES_TOLERANCE_DEG
    assert abs(mean - driver["Mean"]) < tolerance and abs(amplitude - driver["Amplitude"]) < tolerance, \
        (case, mean, amplitude)
    alpha = np.deg2rad(cycle[:, 0])
    step = 1.0 / (driver["Frequency"] * len(alpha))
    q = (np.roll(alpha, -1) - np.roll(alpha, 1)) / (2 * step)
    columns = {"alpha": alpha, "q": q, "V": np.full(len(alpha), driver["InflowVel"]), "de": np.zeros(len(alpha)),
               "CL": cycle[:, 1], "CD": cycle[:, 2], "Cm": cycle[:, 3]}
    facts = {"frequency": driver["Frequency"], "chord": chord or driver["Chord"], "V": driver["InflowVel"],
             "per_cycle": per_cycle, "cycles": len(table) / per_cycle, "samples": len(alpha)}
    return columns, facts


def one_cycle_record(alpha_deg: np.ndarray) -> bool:
    """Whether a record is a single cycle: alpha passes its mean upwards once (several cycles: once a cycle)."""
    above = alpha_deg > 0.5 * (alpha_deg.min() + alpha_deg.max())
    crossings = np.count_nonzero(above & ~np.roll(above, 1))
    return crossings == 1


def static_polar(polar: str = "S809_AD15.dat") -> np.ndarray:
    """The table of an AeroDyn polar (alpha deg, C_l, C_d, C_m) within POLAR_RANGE_DEG, alpha in radians."""
    lines = (ORIGINAL / polar).read_text(encoding="utf-8").splitlines()
    start = next(i for i, line in enumerate(lines) if "NumAlf" in line)
    rows = [[float(v) for v in line.split()[:4]] for line in lines[start + 1:]
            if line.strip() and not line.lstrip().startswith("!")]
    table = np.array(rows)
    keep = (table[:, 0] >= POLAR_RANGE_DEG[0]) & (table[:, 0] <= POLAR_RANGE_DEG[1])
    table = table[keep]
    table[:, 0] = np.deg2rad(table[:, 0])
    return table


def write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    rows = [",".join(names)] + [",".join(f"{columns[n][i]:.8g}" for n in names) for i in range(len(columns[names[0]]))]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")


def convert_airfoil(airfoil: Airfoil, root: Path) -> None:
    """Write ``root/<airfoil.directory>/`` and the airfoil's static polar beside it."""
    out = root / airfoil.directory
    out.mkdir(parents=True, exist_ok=True)
    chord = airfoil.chord
    entries = []
    for maneuver, case, split in airfoil.runs:
        columns, facts = convert_run(case, airfoil.chord, airfoil.driver(case))
        chord = chord or facts["chord"]
        write_csv(out / f"{maneuver}.csv", columns)
        k = np.pi * facts["frequency"] * chord / facts["V"]
        print(f"{maneuver}: {case}, {facts['cycles']:.2f} cycles of {facts['per_cycle']:.2f} samples averaged into "
              f"{facts['samples']} phase bins; f = {facts['frequency']} Hz, k = {k:.4f}")
        entries.append(f'[[maneuver]]\nid = "{maneuver}"\nfile = "{maneuver}.csv"\nkind = "deep-dynamic"\n'
                       f'split = "{split}"\nfrequency = {facts["frequency"]!r}   # Hz, from {airfoil.driver(case)}.dvr; '
                       f"no time column: one phase-averaged cycle\n")
    note = f"   # {airfoil.chord_note}" if airfoil.chord_note else ""
    manifest = (
        '# Written by examples/openfast_ua/convert.py from data shipped by OpenFAST (Apache-2.0, see ../NOTICE):\n'
        f'# {airfoil.about}\n'
        f'name = "{airfoil.title}"\n'
        'source = "OpenFAST CertTest/Wind/UA_Tests, commit a2961baa (Apache-2.0)"\n\n'
        f"[aircraft]   # a two-dimensional section: chord {chord} m, 1 m span\nS = {chord!r}\ncbar = {chord!r}{note}\n"
        "b = 1.0\n\n" + "\n".join(entries))
    (out / "campaign.toml").write_text(manifest, encoding="utf-8")
    polar = static_polar(airfoil.polar)
    write_csv(root / airfoil.polar_csv, {"alpha": polar[:, 0], "CL": polar[:, 1], "CD": polar[:, 2],
                                         "Cm": polar[:, 3]})
    print(f"{airfoil.polar_csv}: {len(polar)} points from {POLAR_RANGE_DEG[0]:g} to {POLAR_RANGE_DEG[1]:g} deg")


def main(root: Path = HERE) -> None:
    """Write each airfoil's campaign directory and static polar under ``root`` (the tests convert into a
    temporary ``root`` and compare with the committed files)."""
    for airfoil in AIRFOILS:
        convert_airfoil(airfoil, root)


if __name__ == "__main__":
    main()
