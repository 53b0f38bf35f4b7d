"""Pre-filter of the measured signals: 4th-order Butterworth low-pass applied forward and backward.

Cut-off frequencies of thesis Table 5 (docs/catalogue.md section 8). Derivatives are
taken of the filtered signal, i.e. at the cut-off of their signal.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfiltfilt

CUTOFF_HZ = {
    "ax": 4.0, "ay": 4.0, "az": 8.0, "p": 5.0, "q": 5.0, "r": 4.0,
    "da": 5.0, "de": 6.0, "dr": 4.0, "alpha": 6.0, "beta": 6.0,
    # not in Table 5: air data and attitude change slowly; filtered only against sensor noise
    "V": 2.0, "qbar": 2.0, "theta": 5.0, "phi": 5.0, "h": 1.0,
}
ORDER = 4


def lowpass(signal: np.ndarray, cutoff_hz: float, fs: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forward-backward)."""
    sos = butter(ORDER, cutoff_hz, fs=fs, output="sos")
    return sosfiltfilt(sos, signal, padtype="odd", padlen=min(len(signal) - 1, 3 * 2 * ORDER * 10))


def prefilter(name: str, signal: np.ndarray, fs: float) -> np.ndarray:
    try:
        return lowpass(signal, CUTOFF_HZ[name], fs)
    except KeyError:
        raise ValueError(f"no pre-filter cut-off for signal {name!r}") from None


def derivative(filtered: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Time derivative of an already filtered signal (second order, non-uniform steps allowed)."""
    return np.gradient(filtered, t, edge_order=2)
