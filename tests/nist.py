"""Reader for NIST StRD nonlinear-regression files and their separable formulations.

The ``.dat`` files in ``tests/data/nist/`` are NIST Statistical Reference
Datasets (public-domain reference data, https://www.itl.nist.gov/div898/strd/),
copied from the lmfit source distribution.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data" / "nist"

# Each model as {linear coefficient: basis}; every other symbol except x (x1, x2) is nonlinear.
SEPARABLE = {
    "Misra1a": {"b1": "1 - exp(-b2*x)"},
    "Misra1b": {"b1": "1 - (1 + b2*x/2)**(-2)"},
    "Misra1c": {"b1": "1 - (1 + 2*b2*x)**(-1/2)"},
    "Misra1d": {"b1": "b2*x/(1 + b2*x)"},
    "Lanczos1": {"b1": "exp(-b2*x)", "b3": "exp(-b4*x)", "b5": "exp(-b6*x)"},
    "Lanczos2": {"b1": "exp(-b2*x)", "b3": "exp(-b4*x)", "b5": "exp(-b6*x)"},
    "Lanczos3": {"b1": "exp(-b2*x)", "b3": "exp(-b4*x)", "b5": "exp(-b6*x)"},
    "BoxBOD": {"b1": "1 - exp(-b2*x)"},
    "MGH17": {"b1": "1", "b2": "exp(-x*b4)", "b3": "exp(-x*b5)"},
    "DanWood": {"b1": "x**b2"},
    "MGH09": {"b1": "(x**2 + x*b2)/(x**2 + x*b3 + b4)"},
    "MGH10": {"b1": "exp(b2/(x + b3))"},
    "Rat42": {"b1": "1/(1 + exp(b2 - b3*x))"},
    "Rat43": {"b1": "1/(1 + exp(b2 - b3*x))**(1/b4)"},
    "Eckerle4": {"b1": "exp(-((x - b3)/b2)**2/2)/b2"},
    "Bennett5": {"b1": "(b2 + x)**(-1/b3)"},
    "ENSO": {"b1": "1", "b2": "cos(2*pi*x/12)", "b3": "sin(2*pi*x/12)",
             "b5": "cos(2*pi*x/b4)", "b6": "sin(2*pi*x/b4)",
             "b8": "cos(2*pi*x/b7)", "b9": "sin(2*pi*x/b7)"},
    "Gauss1": {"b1": "exp(-b2*x)", "b3": "exp(-(x - b4)**2/b5**2)", "b6": "exp(-(x - b7)**2/b8**2)"},
    "Gauss2": {"b1": "exp(-b2*x)", "b3": "exp(-(x - b4)**2/b5**2)", "b6": "exp(-(x - b7)**2/b8**2)"},
    "Gauss3": {"b1": "exp(-b2*x)", "b3": "exp(-(x - b4)**2/b5**2)", "b6": "exp(-(x - b7)**2/b8**2)"},
    "Thurber": {"b1": "1/(1 + b5*x + b6*x**2 + b7*x**3)", "b2": "x/(1 + b5*x + b6*x**2 + b7*x**3)",
                "b3": "x**2/(1 + b5*x + b6*x**2 + b7*x**3)", "b4": "x**3/(1 + b5*x + b6*x**2 + b7*x**3)"},
    "Hahn1": {"b1": "1/(1 + b5*x + b6*x**2 + b7*x**3)", "b2": "x/(1 + b5*x + b6*x**2 + b7*x**3)",
              "b3": "x**2/(1 + b5*x + b6*x**2 + b7*x**3)", "b4": "x**3/(1 + b5*x + b6*x**2 + b7*x**3)"},
    "Kirby2": {"b1": "1/(1 + b4*x + b5*x**2)", "b2": "x/(1 + b4*x + b5*x**2)",
               "b3": "x**2/(1 + b4*x + b5*x**2)"},
    # log[y] = b1 - b2*x1*exp(-b3*x2): fitted to log(y)
    "Nelson": {"b1": "1", "b2": "-x1*exp(-b3*x2)"},
}
# Not separable in the form sum_i c_i phi_i(theta): Chwirut1, Chwirut2 (no free linear
# coefficient), Roszman1 (a term with the fixed coefficient -1/pi).


@dataclass(frozen=True)
class NistProblem:
    name: str
    starts: tuple[dict[str, float], dict[str, float]]
    certified: dict[str, float]
    certified_stderr: dict[str, float]
    certified_rss: float
    variables: dict[str, np.ndarray]
    y: np.ndarray


def load(name: str) -> NistProblem:
    lines = (DATA / f"{name}.dat").read_text().splitlines()
    start1, start2, value, stderr = {}, {}, {}, {}
    rss = None
    for ln in lines:
        m = re.match(r"\s*(b\d+)\s*=\s*(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", ln)
        if m:
            b = m.group(1)
            start1[b], start2[b], value[b], stderr[b] = (float(x) for x in m.groups()[1:])
        m = re.match(r"\s*Residual Sum of Squares:\s+(\S+)", ln)
        if m:
            rss = float(m.group(1))
    header = [k for k, ln in enumerate(lines) if ln.startswith("Data:")][-1]
    columns = lines[header].split()[1:]
    table = np.array([[float(x) for x in ln.split()] for ln in lines[header + 1:] if ln.strip()])
    data = dict(zip(columns, table.T))
    y = data.pop("y")
    if name == "Nelson":
        y = np.log(y)
    return NistProblem(name, (start1, start2), value, stderr, rss, data, y)
