"""A noise floor that does not depend on the effect library, and what the library cannot explain.

The saturated library model (the baseline with every library effect added) is the lowest error the
*library* can reach; a gap caused by anything the library lacks (a signal no term uses, another
hysteresis shape, a sensor error) sits above it unseen. So the floor is also estimated without the
library: a flexible model of the baseline's residual as a function of the measured signals (campaign
columns that are not modelled coefficients, the model's separation state, time in maneuver), fitted on
the training maneuvers and judged on the validation maneuvers. What it removes there is structure some
function of the signals explains; what it leaves is the floor.

The flexible model is scikit-learn's histogram gradient boosting: it captures interactions and
non-smooth dependencies (flow phases) without a basis to choose, handles 10^5 rows in seconds, and its
number of boosting iterations is chosen by maneuver-grouped cross-validation on the training maneuvers
(splitting samples would leak through the residual's autocorrelation and overfit). Training rows are
decimated (samples 10 ms apart carry nearly the same information).

The signals a gap follows are ranked by their permutation importance in the flexible model on the
validation maneuvers (it sees the signals jointly: a dependence on V times delta_e shows even where V
alone explains little, and a signal that merely travels with the responsible one does not), and each is
given the fraction of the gap a smooth function of that signal alone (means in quantile bins,
interpolated, fitted to the training residual) removes on the validation maneuvers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .offset import TERM_COLUMN_PREFIX

from ..data.flightdata import FlightData
from ..engine.ties import first_of_lowest

# Columns that are not signals: the modelled coefficients and what the simulator keeps for checking.
OUTPUT_COLUMNS = frozenset({"t", "CL", "CD", "Cm", "CX", "CZ", "CY", "Cl", "Cn"})
MAX_TRAINING_ROWS = 20_000
MAX_ITER = 200
CV_FOLDS = 3
SIGNAL_BINS = 16


@dataclass(frozen=True)
class FlexibleFit:
    """The flexible model's correction of one residual on the validation maneuvers."""

    mse: float                 # validation MSE of the residual minus the flexible model's prediction
    residual: np.ndarray       # that corrected validation residual
    n_iter: int                # boosting iterations chosen by maneuver-grouped cross-validation
    signals: tuple[str, ...]   # the inputs it used
    model: object = None       # the fitted regressor (None when no iteration generalised)


@dataclass(frozen=True)
class SignalFit:
    """A smooth function of one signal fitted to a residual: its bins and its effect on validation."""

    name: str
    mse: float                 # validation MSE after removing the function
    centres: np.ndarray        # bin centres (training quantiles)
    values: np.ndarray         # the function at the centres (mean training residual per bin)


def signals(data: FlightData, state: np.ndarray) -> dict[str, np.ndarray]:
    """The measured signals: numeric campaign columns other than coefficients, truth columns and a simulator's
    terms (``sim__...``: the baseline's own parts, not measurements), the separation state ``state`` of the model's
    phases (``X``) and the time since the maneuver began."""
    out = {k: np.asarray(v, float) for k, v in data.columns.items()
           if k not in OUTPUT_COLUMNS and not k.endswith("_true") and not k.startswith(TERM_COLUMN_PREFIX)
           and np.issubdtype(np.asarray(v).dtype, np.number)}
    out["X"] = np.asarray(state, float)
    out["time_in_maneuver"] = np.concatenate([data["t"][sl] - data["t"][sl][0] for sl in data.segment_slices()])
    return dict(sorted(out.items()))


def _groups(data: FlightData) -> np.ndarray:
    return np.concatenate([np.full(sl.stop - sl.start, i) for i, sl in enumerate(data.segment_slices())])


def _decimation(n: int) -> int:
    return max(1, int(np.ceil(n / MAX_TRAINING_ROWS)))


def _matrix(sig: dict[str, np.ndarray], names) -> np.ndarray:
    return np.column_stack([sig[n] for n in names])


def flexible_fit(r_train: np.ndarray, train: FlightData, train_signals: dict, r_val: np.ndarray,
                 val_signals: dict, seed: int = 0) -> FlexibleFit:
    """Histogram gradient boosting of ``r_train`` on the signals; its correction of ``r_val``."""
    from sklearn.ensemble import HistGradientBoostingRegressor
    names = tuple(n for n in train_signals if n in val_signals and np.ptp(train_signals[n]) > 0)
    step = _decimation(len(r_train))
    x, y, groups = _matrix(train_signals, names)[::step], r_train[::step], _groups(train)[::step]

    def model(n_iter):
        return HistGradientBoostingRegressor(max_iter=n_iter, learning_rate=0.1, max_leaf_nodes=15,
                                             min_samples_leaf=max(20, len(y) // 200), l2_regularization=1.0,
                                             early_stopping=False, random_state=seed)
    unique = np.unique(groups)
    folds = min(CV_FOLDS, len(unique))
    if folds >= 2:
        # held-out MSE after each iteration, summed over maneuver-grouped folds
        rng = np.random.default_rng(seed)
        fold_of = dict(zip(unique, rng.permutation(len(unique)) % folds))
        which = np.array([fold_of[g] for g in groups])
        curve = np.zeros(MAX_ITER + 1)
        for k in range(folds):
            fit = model(MAX_ITER).fit(x[which != k], y[which != k])
            held, target = x[which == k], y[which == k]
            curve[0] += np.sum(target ** 2)
            for i, pred in enumerate(fit.staged_predict(held), start=1):
                curve[i] += np.sum((target - pred) ** 2)
        # the fewest iterations among those equal up to rounding
        n_iter = first_of_lowest(range(len(curve)), curve.__getitem__)
    else:
        n_iter = 0
    if n_iter == 0:  # nothing the signals explain generalises across maneuvers
        return FlexibleFit(float(np.mean(r_val ** 2)), r_val.copy(), 0, names)
    fit = model(n_iter).fit(x, y)
    corrected = r_val - fit.predict(_matrix(val_signals, names))
    return FlexibleFit(float(np.mean(corrected ** 2)), corrected, n_iter, names, fit)


def permutation_importance(flex: FlexibleFit, r_val: np.ndarray, val_signals: dict, seed: int = 0
                           ) -> dict[str, float]:
    """How much of what the flexible model removes on the validation maneuvers each signal carries: the rise
    of the corrected MSE when that signal's values are shuffled, over the MSE the model removes. Empty when
    the model removes nothing on the validation maneuvers: then no signal's share of it can be estimated.
    The model sees signals jointly, so a dependence on V times alpha counts for V, which a function of V
    alone may miss."""
    removed = float(np.mean(r_val ** 2)) - flex.mse
    if flex.model is None or not removed > 0:
        return {}
    rng = np.random.default_rng(seed)
    base = _matrix(val_signals, flex.signals)
    out = {}
    for j, name in enumerate(flex.signals):
        shuffled = base.copy()
        shuffled[:, j] = rng.permutation(shuffled[:, j])
        mse = float(np.mean((r_val - flex.model.predict(shuffled)) ** 2))
        out[name] = (mse - flex.mse) / removed
    return out


def binned_means(signal: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean signal and mean residual in each of up to SIGNAL_BINS quantile bins of the signal (empty bins
    left out)."""
    edges = np.unique(np.quantile(signal, np.linspace(0, 1, SIGNAL_BINS + 1)))
    if len(edges) < 2:
        return np.array([float(signal[0])]), np.array([float(np.mean(residual))])
    index = np.clip(np.searchsorted(edges, signal, side="right") - 1, 0, len(edges) - 2)
    counts = np.bincount(index, minlength=len(edges) - 1)
    keep = counts > 0
    return ((np.bincount(index, weights=signal, minlength=len(edges) - 1)[keep] / counts[keep]),
            (np.bincount(index, weights=residual, minlength=len(edges) - 1)[keep] / counts[keep]))


def signal_fit(name: str, r_train: np.ndarray, train_signal: np.ndarray, r_val: np.ndarray,
               val_signal: np.ndarray) -> SignalFit:
    """Means of ``r_train`` in quantile bins of one signal, interpolated: the residual explained by that
    signal alone, applied to the validation maneuvers."""
    centres, values = binned_means(train_signal, r_train)
    corrected = r_val - np.interp(val_signal, centres, values)
    return SignalFit(name, float(np.mean(corrected ** 2)), centres, values)


def ranked_signals(r_train: np.ndarray, train_signals: dict, r_val: np.ndarray, val_signals: dict
                   ) -> list[SignalFit]:
    """One :func:`signal_fit` per signal present in both splits, lowest validation MSE first."""
    fits = [signal_fit(n, r_train, train_signals[n], r_val, val_signals[n])
            for n in train_signals if n in val_signals and np.ptp(train_signals[n]) > 0]
    return sorted(fits, key=lambda f: f.mse)
