"""The same lift structure identified with and without the dynamic stalls (thesis Tables 10.1-10.3): estimates,
standard deviations, p-values and the correlation matrices side by side, with the entries the thesis discusses
(tau1-tau2 of the stall-strip state, tau1-C_Lq*) called out.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.campaign import Campaign
from ..data.errors import DeclarationError
from ..engine.results import FitResult
from ..fitting.models import build_model
from ..fitting.options import FitOptions
from ..fitting.specs import find_candidate

# The thesis' figures for the tau1-tau2 correlation of X_ss: quasi-steady stalls only, and with the dynamic
# stalls (Tables 10.2 and 10.3; docs/catalogue.md section 7).
THESIS_TAU_CORRELATION = {"quasi-steady only": 0.73, "full training set": 0.06}
CALLED_OUT = (("tau1_ss", "tau2_ss"), ("tau1_ss", "CL_qstar"))


@dataclass(frozen=True)
class Identification:
    """One fit of the structure: what Tables 10.1-10.3 print."""

    label: str
    maneuvers: tuple[str, ...]
    names: tuple[str, ...]
    estimate: tuple[float, ...]
    sd: tuple[float, ...]
    p_value: tuple[float, ...]
    correlation: tuple[tuple[float, ...], ...]

    def rho(self, a: str, b: str) -> float:
        if a not in self.names or b not in self.names:
            return float("nan")
        return float(self.correlation[self.names.index(a)][self.names.index(b)])

    def to_dict(self) -> dict:
        return {"label": self.label, "maneuvers": list(self.maneuvers), "names": list(self.names),
                "estimate": list(self.estimate), "sd": list(self.sd), "p_value": list(self.p_value),
                "correlation": [list(row) for row in self.correlation]}


@dataclass(frozen=True)
class DynamicStallStudy:
    model: str
    quasi_steady: Identification
    full: Identification

    def called_out(self) -> list[tuple[str, str, float, float]]:
        """(parameter, parameter, rho quasi-steady only, rho full training set)."""
        return [(a, b, self.quasi_steady.rho(a, b), self.full.rho(a, b)) for a, b in CALLED_OUT]

    def to_dict(self) -> dict:
        return {"model": self.model, "quasi_steady": self.quasi_steady.to_dict(), "full": self.full.to_dict(),
                "called_out": [{"a": a, "b": b, "rho_quasi_steady": rq, "rho_full": rf}
                               for a, b, rq, rf in self.called_out()]}


def _identification(label: str, result: FitResult, names_of_maneuvers) -> Identification:
    names = tuple(result.names)
    sd = result.stderr
    p = result.p_values
    corr = np.asarray(result.correlation, float)
    return Identification(label, tuple(names_of_maneuvers), names, tuple(float(result.params[n]) for n in names),
                          tuple(float(sd[n]) for n in names), tuple(float(p[n]) for n in names),
                          tuple(tuple(float(x) for x in row) for row in corr))


def dynamic_stall_study(campaign: Campaign, model_name: str = "CL-VI", options: FitOptions = FitOptions()
                        ) -> DynamicStallStudy:
    """Fit ``model_name`` on the quasi-steady training stalls only and on the whole training set."""
    candidate = find_candidate(model_name)
    model = build_model(candidate)
    train = campaign.split("train")
    kinds = [m.kind for m in campaign.maneuvers if m.split == "train"]
    quasi = [i for i, k in enumerate(kinds) if k == "quasi-steady"]
    if not quasi or len(quasi) == len(kinds):
        raise DeclarationError(f"the dynamic-stall study needs quasi-steady and other training maneuvers; this "
                               f"campaign's training set has {len(quasi)} quasi-steady of {len(kinds)}")
    fits = {}
    for label, data in (("quasi-steady only", train.select(quasi)), ("full training set", train)):
        result = model.fit(data, n_starts=options.n_starts, seed=options.seed, covariance=options.covariance)
        fits[label] = _identification(label, result, data.names)
    return DynamicStallStudy(model_name, fits["quasi-steady only"], fits["full training set"])
