"""Joint against sequential (issue 29): the final lift, drag and pitch structures fitted jointly, sharing their
separation states, against the same structures fitted one after the other (drag and pitch on the lift-only
model's states): parameters and standard deviations, validation MSE per coefficient, and the correlation of the
two stall-strip time constants. Numerics only; :mod:`structsearch.reporting.study_doc` renders it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.campaign import Campaign
from ..fitting.joint import fit_joint
from ..fitting.options import FitOptions
from ..data.coefficients import LONGITUDINAL
from .model_set import ModelSet

TAU_PAIR = ("tau1_ss", "tau2_ss")


@dataclass(frozen=True)
class ParameterComparison:
    coefficient: str          # the model the parameter belongs to (a shared state's: the lift model)
    name: str
    sequential: float
    sequential_sd: float      # drag and pitch: their two-step standard deviation on the lift-only model
    joint: float
    joint_sd: float

    def to_dict(self) -> dict:
        return {"coefficient": self.coefficient, "name": self.name, "sequential": self.sequential,
                "sequential_sd": self.sequential_sd, "joint": self.joint, "joint_sd": self.joint_sd}


@dataclass(frozen=True)
class ScoreComparison:
    coefficient: str
    structure: str
    sequential_train: float
    joint_train: float
    sequential_validation: float
    joint_validation: float

    def to_dict(self) -> dict:
        return {"coefficient": self.coefficient, "structure": self.structure,
                "mse_train": {"sequential": self.sequential_train, "joint": self.joint_train},
                "mse_validation": {"sequential": self.sequential_validation, "joint": self.joint_validation}}


@dataclass(frozen=True)
class JointComparison:
    structures: tuple[str, ...]
    parameters: tuple[ParameterComparison, ...]
    scores: tuple[ScoreComparison, ...]
    tau_correlation: tuple[float, float]    # rho(tau1_ss, tau2_ss): lift-only fit, joint fit (NaN: not estimable)
    covariance: str
    iterations: int
    weights_settled: bool
    converged: bool

    def to_dict(self) -> dict:
        return {"structures": list(self.structures), "parameters": [p.to_dict() for p in self.parameters],
                "scores": [s.to_dict() for s in self.scores],
                "tau_correlation": {"pair": list(TAU_PAIR), "sequential": self.tau_correlation[0],
                                    "joint": self.tau_correlation[1]},
                "covariance": self.covariance, "iterations": self.iterations,
                "weights_settled": self.weights_settled, "converged": self.converged}


def _rho(names, correlation, pair) -> float:
    names = list(names)
    if not all(n in names for n in pair):
        return float("nan")
    return float(correlation[names.index(pair[0]), names.index(pair[1])])


def compare_joint(final: ModelSet, campaign: Campaign, options: FitOptions) -> JointComparison:
    """Fit ``final``'s three structures jointly and set them against the sequential fits in ``final``."""
    train, validation = campaign.split("train"), campaign.split("validation")
    joint = fit_joint([final.candidates[c] for c in LONGITUDINAL], train, validation, options)
    r = joint.result
    seen: set[str] = set()
    parameters = []
    for c in LONGITUDINAL:
        seq = final.summaries[c]
        for n in seq.estimates.params:
            if n in seen or n not in r.params:
                continue
            seen.add(n)
            parameters.append(ParameterComparison(c, n, float(seq.estimates.params[n]), float(seq.estimates.stderr[n]),
                                                  float(r.params[n]), float(r.stderr[n])))
    scores = tuple(ScoreComparison(cf.coefficient, cf.model, final.summaries[cf.coefficient].mse_train,
                                   cf.train.mse, final.summaries[cf.coefficient].mse_validation, cf.validation.mse)
                   for cf in joint.coefficients)
    lift = final.summaries["CL"]
    rho = (_rho(lift.estimates.names, lift.estimates.correlation, TAU_PAIR), _rho(r.estimates.names, r.estimates.correlation, TAU_PAIR))
    return JointComparison(tuple(cand.name for cand in joint.candidates), tuple(parameters), scores,
                           tuple(float(x) if np.isfinite(x) else float("nan") for x in rho),
                           r.covariance_kind, joint.iterations, joint.weights_settled, bool(r.converged))
