"""The anomalies a diagnosis' added terms are also the signature of (:mod:`structsearch.discovery.equivalents`).

A gap closed by a library term stays "explained by library terms"; the diagnosis adds what else the fitted term
is the first-order signature of, in the anomaly's own parameter ("also the signature of a vane lag of about
0.38 s"). Only terms the structure reached holds and the baseline lacked are read: a term the baseline had was
fitted to what the baseline already modelled.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..data.flightdata import FlightData
from ..discovery.effects import equivalents_of
from ..discovery.equivalents import Signature
from ..fitting.candidates import Candidate
from ..fitting.models import predict_candidate

# [rad] the step of the central difference of the structure's slope dC/dalpha: small against the curvature of
# the stall (a1 ~ 70 per rad), large against rounding
SLOPE_STEP = 1e-4


@dataclass(frozen=True)
class Equivalence:
    """A term of the structure reached that is, to first order, also the signature of an anomaly: the library
    effect that declares it, the fitted parameter and its value, the anomaly's parameter converted from it, and
    the baseline's terms the structure dropped (a coefficient that replaced a term also carries that term's part,
    and the conversion is then rougher)."""

    effect: str
    term: str
    coefficient: float
    anomaly: str
    parameter: str
    value: float
    unit: str
    dropped: tuple[str, ...] = ()
    # the structure has lagged separation states (Q, U) whose time constants take up part of a vane lag too: on a
    # simulated campaign with the final lift structure the alpha_dot term carried a fifth to an eighth of it
    # (tests/test_equivalence.py), so the value is then the part the term carries, not the whole lag
    partial: bool = False

    def words(self) -> str:
        """"also the signature of a vane lag of about 0.38 s" (with the term, and what it replaced)."""
        value = "an undetermined size" if not np.isfinite(self.value) else f"about {self.value:.2g} {self.unit}"
        text = f"also the signature of a {self.parameter} of {value} ({self.term} = {self.coefficient:.4g}"
        if self.dropped:
            text += f"; it replaced {', '.join(self.dropped)}, whose part it also carries"
        if self.partial:
            text += "; only the part the term carries: the separation states' time constants take up the rest"
        return text + ")"

    def to_dict(self) -> dict:
        return {"effect": self.effect, "term": self.term, "coefficient": self.coefficient, "anomaly": self.anomaly,
                "parameter": self.parameter, "value": self.value, "unit": self.unit, "dropped": list(self.dropped),
                "partial": self.partial, "words": self.words()}

    @classmethod
    def from_dict(cls, d: Mapping) -> Equivalence:
        return cls(d["effect"], d["term"], d["coefficient"], d["anomaly"], d["parameter"],
                   float("nan") if d["value"] is None else d["value"], d["unit"], tuple(d.get("dropped", ())),
                   bool(d.get("partial", False)))


def slope(c: Candidate, params: Mapping[str, float], data: FlightData, lift=None) -> np.ndarray:
    """The fitted structure's total dC/dalpha per sample: alpha shifted both ways, states and the lift model's C_L
    recomputed (alpha_dot is unchanged by a constant shift, as a first-order vane lag leaves it)."""
    out = []
    for step in (SLOPE_STEP, -SLOPE_STEP):
        shifted = data.with_columns({**data.columns, "alpha": data["alpha"] + step})
        out.append(predict_candidate(c, params, shifted, lift))
    return (out[0] - out[1]) / (2 * SLOPE_STEP)


def equivalences(baseline: Candidate, final: Candidate, params: Mapping[str, float], data: FlightData,
                 lift=None) -> tuple[Equivalence, ...]:
    """The equivalences of the terms ``final`` (fitted with ``params`` on ``data``) added to ``baseline``."""
    old = {expr.replace(" ", "") for _, expr in baseline.regressors}
    added = [(name, expr) for name, expr in final.regressors if expr.replace(" ", "") not in old and name in params]
    found = [(name, effect, q) for name, expr in added for effect, q in equivalents_of(expr)]
    if not found:
        return ()
    kept = {expr.replace(" ", "") for _, expr in final.regressors}
    dropped = tuple(name for name, expr in baseline.regressors if expr.replace(" ", "") not in kept)
    # a drag or pitch structure's states are its lift model's, fitted on the same lagged alpha
    lagged = final.lift is not None or any(kind != "S" for _, kind in final.states)
    signature = Signature(data["alpha_dot"], data["V"], float(data.constants["cbar"]),
                          slope(final, params, data, lift))
    return tuple(Equivalence(effect, name, float(params[name]), q.anomaly, q.parameter,
                             q.convert(float(params[name]), signature), q.unit, dropped, lagged)
                 for name, effect, q in found)
