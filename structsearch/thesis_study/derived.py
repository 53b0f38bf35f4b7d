"""Derived physical quantities of a fitted lift model and the collinearity of the regressors in the data
(thesis chapter 11's discussion), and the separation grid as the thesis' 3 x 3 matrix (Table 8).

Caveats the thesis makes: alpha and delta_e move together in trimmed flight (the elevator holds the angle of
attack), and q and alpha_dot come close in quasi-steady stalls (the flight path hardly turns), so derivatives
on such pairs trade off; a high variance inflation factor names the regressor whose estimate the data pin least.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.flightdata import FlightData
from ..engine.stallmodel import StallModel

KINDS = ("S", "Q", "U")


@dataclass(frozen=True)
class DerivedQuantity:
    name: str
    value: float
    unit: str
    meaning: str

    def to_dict(self) -> dict:
        return {"name": self.name, "value": self.value, "unit": self.unit, "meaning": self.meaning}


def physical_quantities(params: dict[str, float], data: FlightData) -> list[DerivedQuantity]:
    """tau* = tau V/cbar for every time constant (at the data's mean airspeed), alpha* in degrees, and the
    attached-flow lift-curve slope (the Kirchhoff terms' sum at X = 1)."""
    v = float(np.mean(data["V"]))
    cbar = float(data.constants["cbar"])
    out = [DerivedQuantity("mean airspeed", v, "m/s", "of the maneuvers the model was fitted on")]
    for name, value in params.items():
        if name.startswith("tau"):
            out.append(DerivedQuantity(f"{name}*", value * v / cbar, "-", f"{name} V/cbar (chords travelled)"))
        elif name.startswith("a_star"):
            out.append(DerivedQuantity(f"{name} [deg]", float(np.rad2deg(value)), "deg", "half-separated angle"))
    kirchhoff = [k for k in params if k.startswith("CL_KL")]
    if kirchhoff:
        out.append(DerivedQuantity("lift-curve slope, attached", float(sum(params[k] for k in kirchhoff)), "1/rad",
                                   " + ".join(kirchhoff) + " (every state at X = 1)"))
    return out


@dataclass(frozen=True)
class Collinearity:
    correlations: tuple[tuple[str, str, float], ...]    # pairs of data columns
    vif: tuple[tuple[str, float], ...]                   # regressor, variance inflation factor
    condition_number: float                              # of the column-scaled regression matrix

    def to_dict(self) -> dict:
        return {"correlations": [{"a": a, "b": b, "correlation": v} for a, b, v in self.correlations],
                "vif": [{"regressor": n, "vif": v} for n, v in self.vif], "condition_number": self.condition_number}


def collinearity(model: StallModel, params: dict[str, float], data: FlightData) -> Collinearity:
    """Correlations of alpha with delta_e and of q with alpha_dot, and the VIF of every regressor of ``model``
    at ``params`` (the constant excluded from the VIFs; columns centred), the scaled condition number."""
    pairs = []
    for a, b in (("alpha", "de"), ("q", "alpha_dot")):
        if a in data and b in data:
            pairs.append((a, b, float(np.corrcoef(data[a], data[b])[0, 1])))
    theta = np.array([params[n] for n in model.nonlinear_names], float)
    phi = model.bind(data).evaluate(theta).phi
    names = model.linear_names
    varying = [j for j in range(phi.shape[1]) if np.std(phi[:, j]) > 0]
    centred = phi[:, varying] - phi[:, varying].mean(axis=0)
    vif = []
    if len(varying) > 1:
        inverse = np.linalg.pinv(np.corrcoef(centred, rowvar=False))
        vif = [(names[j], float(inverse[i, i])) for i, j in enumerate(varying)]
    elif varying:
        vif = [(names[varying[0]], 1.0)]
    norms = np.linalg.norm(phi, axis=0)
    if np.any(norms == 0):   # a regressor that is zero throughout: the matrix is singular
        return Collinearity(tuple(pairs), tuple(vif), float("inf"))
    singular = np.linalg.svd(phi / norms, compute_uv=False)
    return Collinearity(tuple(pairs), tuple(vif), float(singular[0] / singular[-1]))


def separation_matrix(results) -> tuple[tuple[str, ...], tuple[tuple[float, ...], ...]]:
    """Training MSE of the two-state separation candidates ``X_ss/X_w A/B`` as rows A (stall strips) by
    columns B (wing) over S, Q, U (thesis Table 8); NaN where a candidate failed or is absent."""
    mse = {}
    for r in results:
        name = getattr(r, "name", "")
        if name.startswith("X_ss/X_w ") and not r.failed and r.train is not None:
            a, b = name.split(" ")[1].split("/")
            mse[(a, b)] = r.train.mse
    return KINDS, tuple(tuple(float(mse.get((a, b), np.nan)) for b in KINDS) for a in KINDS)
