"""What a library term is also the signature of: measurement or structural anomalies it equals to first order.

Some anomalies the simulator can inject (:mod:`structsearch.flight.anomalies`) change the data exactly as a
library term would, to first order: a diagnosis that closes such a gap with the term is right to call it
explained by library terms, and it says what else the fitted term is the signature of ("also the signature of
a vane lag of about 0.38 s"), converting the fitted coefficient into the anomaly's own parameter. Each
:class:`~.effects.Effect` declares its equivalents (data: the term they read, the anomaly, its parameter and
unit, and the conversion function); the diagnosis finds the terms in the structure it reached.

Declared: the alpha_dot term and a vane lag (below). Not declared, and why:

* the tail's aeroelastic loss (``tail_aeroelastic``: C_m,de times 1 - k((V/V_ref)^2 - 1)) is a term de*V^2 that no
  library term holds. A refitted C_m,de takes its campaign-weighted mean, but converting that into k needs the
  rigid C_m,de, which the data cannot give; the terms that closed it in the benchmark (alpha_dot) reproduce it
  only through how the maneuvers tie V to alpha and de, not to first order.
* ``separation_delay`` (tau2 of a steady state) is, to first order, a vane lag too (the state's target
  X0(alpha - tau2 alpha_dot) read on a lagged alpha is X0(alpha_meas - (tau2 - tau) alpha_dot)), but only as the
  difference from the state's true delay, which a refit cannot separate: no conversion.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Signature:
    """What a conversion reads, sample by sample over the maneuvers the structure was fitted on: the measured
    alpha_dot [rad/s] and V [m/s], the chord [m], and the fitted structure's total slope dC/dalpha (its separation
    states and, for drag and pitch, its lift model's C_L moving with alpha)."""

    alpha_dot: np.ndarray
    V: np.ndarray
    cbar: float
    slope: np.ndarray


@dataclass(frozen=True)
class Equivalent:
    """One anomaly a library term is first-order equivalent to. ``term`` is the regressor expression the
    conversion reads (as the effect writes it); ``convert(coefficient, signature)`` gives the anomaly's
    ``parameter`` in ``unit`` from the term's fitted coefficient."""

    anomaly: str          # a name of structsearch.flight.anomalies.ANOMALIES
    parameter: str        # in words, as the diagnosis names it
    unit: str
    term: str
    convert: Callable[[float, Signature], float]
    derivation: str


ALPHA_DOT_TERM = "alpha_dot*cbar/V"


def vane_lag_from_alpha_dot(coefficient: float, s: Signature) -> float:
    """The vane lag tau [s] whose first-order signature is nearest (least squares over the samples) to a fitted
    alpha_dot term ``coefficient * alpha_dot * cbar/V``.

    A vane reading alpha through a first-order lag tau (alpha_meas + tau d(alpha_meas)/dt = alpha) records
    alpha_meas = alpha - tau alpha_dot + O(tau^2), so a model C(alpha, ...) evaluated on the recorded alpha misses
    C(alpha) - C(alpha_meas) = tau S alpha_dot, S = dC/dalpha (the lag of the recorded alpha_dot, tau alpha_ddot,
    is second order in the slow maneuvers). The library's term is made dimensionless by cbar/V (not cbar/(2V)):
    C_alphadot alpha_dot cbar/V. Equal sample by sample where tau = C_alphadot cbar / (V S); over the campaign,
    the least-squares tau of C_alphadot cbar/V alpha_dot ~ tau S alpha_dot is

        tau = C_alphadot sum(cbar/V S alpha_dot^2) / sum(S^2 alpha_dot^2),

    which is C_alphadot / C_alpha * cbar/V for one airspeed and a constant slope (attached flow: S = C_L,alpha).
    Positive: alpha recorded late; negative: a lead. NaN when the structure's slope is zero on every moving sample.
    """
    w = s.alpha_dot ** 2
    den = float(np.sum(s.slope ** 2 * w))
    if not den > 0:
        return float("nan")
    return float(coefficient * np.sum(s.cbar / s.V * s.slope * w) / den)


VANE_LAG = Equivalent(
    "vane_lag", "vane lag", "s", ALPHA_DOT_TERM, vane_lag_from_alpha_dot,
    "alpha_meas = alpha - tau alpha_dot to first order, so the model misses tau dC/dalpha alpha_dot; with the term "
    "C_alphadot alpha_dot cbar/V, tau = C_alphadot cbar/(V dC/dalpha), in least squares over the samples")
