"""What the effect library cannot explain (docs/interfaces.md 5.4 ``unexplained``): the share of the gap above
the library-free floor left after the adopted effects, the measured signals the rest follows and where it sits."""
from __future__ import annotations

import numpy as np

from . import floor as fl
from ..data.flightdata import FlightData
from .fitted import Fitted
from .results import PartialDependence, SignalShare, Unexplained
from .where import top_bins, where_bins


def signal_ranking(train_residual: np.ndarray, residual: np.ndarray, flex: fl.FlexibleFit, sig_train: dict,
                   sig_val: dict, gap: float, seed: int) -> tuple[tuple[SignalShare, ...], dict]:
    """The signals a gap of size ``gap`` follows, best first by their permutation importance in the flexible
    model on the validation maneuvers (it sees the signals jointly, so V counts for a dependence on V times
    delta_e even where V alone explains little, and a signal that only travels with the responsible one, such
    as the time in a maneuver that bleeds off speed, does not), ties by a one-signal fit; each with the share
    of the gap a function of it alone, fitted on the training maneuvers, removes on the validation maneuvers
    (docs/interfaces.md 5.4)."""
    fits = {f.name: f for f in fl.ranked_signals(train_residual, sig_train, residual, sig_val)}
    importance = fl.permutation_importance(flex, residual, sig_val, seed)
    mse = float(np.mean(residual ** 2))
    # without importances (the flexible model removed nothing) the one-signal fits alone order the signals
    order = sorted(fits, key=lambda n: (-importance.get(n, -np.inf), fits[n].mse))
    return tuple(SignalShare(n, float(min(max((mse - fits[n].mse) / gap, 0.0), 1.0)), importance.get(n))
                 for n in order), fits


def unexplained(mse_base: float, final: Fitted, flexible: fl.FlexibleFit, library_free: float,
                val: FlightData, sig_train: dict, sig_val: dict, x_val: np.ndarray, explained: bool,
                seed: int, first=None) -> Unexplained:
    """The share of the gap (baseline validation MSE minus the library-free floor) left after the adopted library
    effects, the signals the rest follows, where it sits. ``flexible`` is the library-free model of the final
    model's residual. ``first`` (the baseline's fit, its flexible model and signals) adds ``gap_signals``: the
    signals the whole gap followed before any effect."""
    mse_final = float(np.mean(final.residual ** 2))
    gap, remaining = mse_base - library_free, mse_final - library_free
    share = float(min(max(remaining / gap, 0.0), 1.0)) if gap > 0 else None
    note, gap_signals = None, ()
    if gap <= 0:
        note = "no gap above the library-free floor"
    elif first is not None:
        base_fit, base_flex, base_train, base_val = first
        gap_signals = signal_ranking(base_fit.train_residual, base_fit.residual, base_flex, base_train,
                                     base_val, gap, seed)[0]

    def block(**more) -> Unexplained:
        return Unexplained(library_free, flexible.n_iter, share, gap_signals=gap_signals, note=note, **more)
    if explained:
        return block()
    if not remaining > 0:
        note = ("the final model is at the library-free floor but not at the floor the library sets with "
                "several effects together (the saturated model); no single effect was significant")
        return block()
    signals, fits = signal_ranking(final.train_residual, final.residual, flexible, sig_train, sig_val,
                                   remaining, seed)
    where = top_bins(where_bins(final.residual, flexible.residual, val, x_val, seed=seed))
    curves = []
    for entry in signals[:3]:
        f = fits[entry.name]
        x, mean = fl.binned_means(sig_val[f.name], final.residual)
        curves.append(PartialDependence(f.name, tuple(f.centres.tolist()), tuple(f.values.tolist()),
                                        tuple(x.tolist()), tuple(mean.tolist())))
    return block(signals=signals, where=where, partial_dependence=tuple(curves))
