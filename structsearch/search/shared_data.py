"""Data a grid's fits share: the splits sent to worker processes once, and what every fit of a grid
would recompute from the lift model.

A search sends about a hundred tasks to its workers. Pickling the training and validation maneuvers
(~50 MB) into each task costs the parent process about 0.1 s of hashing and copying per task and
gives every worker a private copy. Instead the parent writes the two splits once to a temporary
folder (``joblib.dump``) and each task carries only the file's path; a worker loads it once,
memory-mapped read-only, so the pages are shared between the processes.

Drag and pitch candidates all read the same lift model: its prediction on both splits, its Jacobian
and residual on the training maneuvers (the two-step covariance). :func:`lift_context` computes them
once per process and lift model.
"""
from __future__ import annotations

import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from ..data.flightdata import FlightData
from ..engine.identifiability import covariance_basis
from ..engine.statistics import inverse_factor
from ..engine.stallmodel import StallModel
from .candidate_result import CandidateResult
from .candidates import Candidate
from .models import model_with_lift, with_lift_prediction

# Backends whose workers are processes on this machine (a dask cluster's may not see this disk).
LOCAL_PROCESS_BACKENDS = ("loky", "multiprocessing")

_LOADED: dict[str, tuple[FlightData, FlightData]] = {}
_LIFT: dict[tuple, "LiftContext"] = {}


@contextmanager
def shared_splits(train: FlightData, validation: FlightData, backend: str, n_jobs: int):
    """A handle to (train, validation) for tasks: a file path for local worker processes, else the
    objects themselves (one process: nothing is pickled; remote workers: joblib sends them)."""
    if backend not in LOCAL_PROCESS_BACKENDS or n_jobs == 1:
        yield train, validation
        return
    import joblib
    with tempfile.TemporaryDirectory(prefix="structsearch-") as folder:
        path = Path(folder) / "splits.pkl"
        joblib.dump((train, validation), path)
        yield str(path)


def resolve_splits(handle) -> tuple[FlightData, FlightData]:
    """(train, validation) from a handle of :func:`shared_splits`; a path is loaded once per process."""
    if not isinstance(handle, str):
        return handle
    if handle not in _LOADED:
        import joblib
        _LOADED.clear()   # a worker serves one search at a time
        _LIFT.clear()
        _LOADED[handle] = joblib.load(handle, mmap_mode="r")
    return _LOADED[handle]


@dataclass(frozen=True, eq=False)
class LiftContext:
    """A fitted lift model as its drag and pitch candidates see it."""

    model: StallModel              # the lift candidate's model, every parameter free
    train: FlightData              # column CL replaced by the lift model's output
    validation: FlightData
    jacobian: np.ndarray           # model Jacobian on the measured training maneuvers, all parameters
    residual: np.ndarray           # measured C_L minus the lift model's output (training)
    basis: np.ndarray              # the parameters its covariance is computed on
    measured: tuple = ()           # the measured splits: held so that their ids (the memo's key) stay unique

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.nonlinear_names + self.model.linear_names

    @cached_property
    def jacobian_inverse_factor(self) -> np.ndarray:
        """R^-1 of the column-scaled Jacobian on the covariance basis (every candidate's two-step needs it)."""
        return inverse_factor(self.jacobian[:, self.basis])


def lift_context(train: FlightData, validation: FlightData, lift: CandidateResult,
                 lift_candidate: Candidate) -> LiftContext:
    """The :class:`LiftContext` of ``lift`` on these splits, computed once per process."""
    key = (id(train), id(validation), lift.name, tuple(sorted(lift.params.items())))
    if key not in _LIFT:
        if len(_LIFT) >= 4:  # a search has few lift models; keep the memory bounded all the same
            _LIFT.pop(next(iter(_LIFT)))
        model = model_with_lift(lift_candidate, None)
        jacobian, output = model.jacobian(train, lift.params)
        residual = train["CL"] - output
        names = model.nonlinear_names + model.linear_names
        basis = covariance_basis(jacobian, names, lift.not_identifiable, len(model.nonlinear_names))
        # the key holds the splits' ids: keep them alive with the entry so that no id is reused
        _LIFT[key] = LiftContext(model, with_lift_prediction(train, lift, lift_candidate),
                                 with_lift_prediction(validation, lift, lift_candidate), jacobian, residual, basis,
                                 (train, validation))
    return _LIFT[key]
