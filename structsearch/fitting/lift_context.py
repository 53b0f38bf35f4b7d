"""What every drag or pitch fit on one lift model would otherwise recompute, computed once per process:
the lift model's prediction on both splits, its Jacobian and residual on the training maneuvers (for the
two-step covariance).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..data.flightdata import FlightData
from ..engine.identifiability import covariance_basis
from ..engine.stallmodel import StallModel
from ..engine.statistics import inverse_factor
from .lift_fit import LiftFit
from .models import model_with_lift, with_lift_prediction

_CONTEXTS: dict[tuple, "LiftContext"] = {}


@dataclass(frozen=True, eq=False)
class LiftContext:
    """A fitted lift model as its drag and pitch candidates see it on one pair of splits."""

    model: StallModel              # the lift candidate's model, every parameter free
    train: FlightData              # column CL replaced by the lift model's output
    validation: FlightData
    jacobian: np.ndarray           # model Jacobian on the measured training maneuvers, all parameters
    residual: np.ndarray           # measured C_L minus the lift model's output (training)
    basis: np.ndarray              # the parameters its covariance is computed on
    influence: np.ndarray | None = None   # a joint lift's influence series on the basis (else the two-step
    #                                       covariance uses ``jacobian`` and ``residual``)
    measured: tuple = ()           # the measured splits: held so that their ids (the memo's key) stay unique

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.nonlinear_names + self.model.linear_names

    @cached_property
    def jacobian_inverse_factor(self) -> np.ndarray:
        """R^-1 of the column-scaled Jacobian on the covariance basis (every candidate's two-step needs it)."""
        return inverse_factor(self.jacobian[:, self.basis])


def lift_context(train: FlightData, validation: FlightData, lift: LiftFit) -> LiftContext:
    """The :class:`LiftContext` of ``lift`` on these splits, computed once per process."""
    key = (id(train), id(validation), lift.name, tuple(sorted(lift.cache_key.items())))
    if key not in _CONTEXTS:
        if len(_CONTEXTS) >= 4:  # a search has few lift models; keep the memory bounded all the same
            _CONTEXTS.pop(next(iter(_CONTEXTS)))
        model = model_with_lift(lift.candidate, None)
        jacobian, output = model.jacobian(train, lift.params)
        residual = train["CL"] - output
        names = model.nonlinear_names + model.linear_names
        if lift.influence is None:
            basis = covariance_basis(jacobian, names, lift.not_identifiable, len(model.nonlinear_names))
        else:  # a joint lift: the parameters its joint fit identifies, in the order of its influence series
            basis = np.array([n in lift.influence_names for n in names])
            order = [lift.influence_names.index(n) for n in names if n in lift.influence_names]
            if len(order) != len(lift.influence_names):
                raise ValueError(f"the joint lift's influence names {lift.influence_names} are not {lift.name}'s")
        # the key holds the splits' ids: keep them alive with the entry so that no id is reused
        _CONTEXTS[key] = LiftContext(model, with_lift_prediction(train, lift.params, lift.candidate),
                                     with_lift_prediction(validation, lift.params, lift.candidate), jacobian,
                                     residual, basis,
                                     None if lift.influence is None else np.asarray(lift.influence)[:, order],
                                     (train, validation))
    return _CONTEXTS[key]


def forget_lift_contexts() -> None:
    """Drop the memo (a worker process that starts serving another search)."""
    _CONTEXTS.clear()
