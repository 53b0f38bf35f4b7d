"""Spectral analysis of flight-test channels (issue 15 item 2): Welch power spectra of the stalled and the
attached segments of a channel, the buffet peaks that separated flow adds, and a low-pass cut-off below them.

Stalled and attached samples come from a mask (an alpha threshold, or a separation state); each contiguous
run of at least one Welch segment contributes, weighted by its length, so no spectrum straddles a maneuver
boundary or a change of flow state.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks, welch

# Welch segment length [s]: 0.25 Hz resolution, fine enough to place a buffet peak within 1 Hz.
SEGMENT_S = 4.0
# A buffet peak: the stalled spectrum above the attached one by this factor, standing out by this prominence
# (in decades of the ratio) from its neighbourhood.
PEAK_RATIO = 3.0
PEAK_PROMINENCE_DECADES = 0.15
# The cut-off keeps this margin below the lowest peak, and never goes below the rigid-body content.
CUTOFF_MARGIN_HZ = 1.5
MIN_CUTOFF_HZ = 1.0
# A channel's noise floor: the median of its attached-flow spectrum over this band [Hz] (above the rigid-body
# motion, where a 52 Hz sensor resampled by linear interpolation is still flat); the rigid-body bandwidth ends where the spectrum falls
# to NOISE_CROSSOVER times that floor.
NOISE_FLOOR_BAND_HZ = (8.0, 16.0)
NOISE_CROSSOVER = 3.0
FLAT_RATIO = 2.0


@dataclass(frozen=True)
class ChannelSpectrum:
    """Welch spectra of one channel in stalled and attached flow, its buffet peaks and a suggested cut-off."""

    channel: str
    frequency: np.ndarray
    stalled: np.ndarray        # power spectral density [unit^2/Hz]; NaN where no stalled run was long enough
    attached: np.ndarray
    peaks_hz: tuple[float, ...]
    cutoff_hz: float | None    # None: no peak and no bandwidth found, keep the default cut-off
    bandwidth_hz: float | None = None   # rigid-body bandwidth: where the attached spectrum meets the noise


def _runs(mask: np.ndarray, minimum: int) -> list[slice]:
    """Contiguous runs of True at least ``minimum`` long."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [slice(a, b) for a, b in zip(edges[::2], edges[1::2]) if b - a >= minimum]


def mean_psd(x: np.ndarray, mask: np.ndarray, slices, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Length-weighted mean Welch spectrum over the runs of ``mask`` inside each of ``slices`` (maneuvers)."""
    nperseg = int(round(SEGMENT_S * fs))
    total, weight, freq = None, 0, np.fft.rfftfreq(nperseg, 1.0 / fs)
    for sl in slices:
        for run in _runs(mask[sl], nperseg):
            segment = x[sl][run]
            freq, p = welch(segment - segment.mean(), fs=fs, nperseg=nperseg)
            total = p * len(segment) if total is None else total + p * len(segment)
            weight += len(segment)
    if total is None:
        return freq, np.full(len(freq), np.nan)
    return freq, total / weight


def buffet_peaks(freq: np.ndarray, stalled: np.ndarray, attached: np.ndarray, low_hz: float = 2.0,
                 high_hz: float = 25.0) -> tuple:
    """Frequencies where separated flow adds narrow-band power: local maxima of the excess power
    (stalled - attached) where stalled / attached exceeds PEAK_RATIO, prominent by PEAK_PROMINENCE_DECADES
    of the ratio, between ``low_hz`` (the rigid-body motion below it differs between the two flow states for
    other reasons) and ``high_hz`` (structural buffet lies below it; a channel sampled slower than the record
    shows resampling images of its peaks above its Nyquist frequency, e.g. 52 - 6 Hz for a 52 Hz sensor)."""
    if np.all(np.isnan(stalled)) or np.all(np.isnan(attached)):
        return ()
    band = (freq >= low_hz) & (freq <= high_hz)
    ratio = np.log10(np.maximum(stalled, 1e-300) / np.maximum(attached, 1e-300))
    index, _ = find_peaks(np.where(band, ratio, -1e3), prominence=PEAK_PROMINENCE_DECADES)
    excess = stalled - attached
    peaks = []
    for i in index:
        if ratio[i] > np.log10(PEAK_RATIO):
            # the ratio's maximum leans towards where the attached spectrum falls off: place the peak at the
            # largest excess power within +- 0.75 Hz (the half-width of a buffet band)
            near = np.flatnonzero((np.abs(freq - freq[i]) <= 0.75) & band)
            peaks.append(float(freq[near[np.argmax(excess[near])]]))
    return tuple(dict.fromkeys(peaks))


def rigid_body_bandwidth(freq: np.ndarray, psd: np.ndarray, fs: float) -> float | None:
    """The lowest frequency above 0.5 Hz where the spectrum falls to NOISE_CROSSOVER times its noise floor
    (the median over NOISE_FLOOR_BAND_HZ): above it the channel carries more noise than motion. None when the
    spectrum is undefined or never falls that far (a channel without a white noise floor)."""
    band = (freq >= NOISE_FLOOR_BAND_HZ[0]) & (freq <= min(NOISE_FLOOR_BAND_HZ[1], 0.45 * fs))
    if np.all(np.isnan(psd)) or not band.any():
        return None
    floor = noise_floor(freq, psd, 0.9 * fs)
    halves = np.array_split(psd[band], 2)
    if not floor > 0 or not 1 / FLAT_RATIO <= np.nanmedian(halves[0]) / np.nanmedian(halves[1]) <= FLAT_RATIO:
        return None   # no white floor: a slow sensor resampled (its spectrum falls off above its Nyquist)
    below = np.flatnonzero((freq >= 0.5) & (psd <= NOISE_CROSSOVER * floor))
    return float(freq[below[0]]) if below.size else None


def noise_floor(freq: np.ndarray, psd: np.ndarray, fs: float, band_hz=NOISE_FLOOR_BAND_HZ) -> float:
    """Median power spectral density over ``band_hz`` (up to 0.5 fs): a channel's white-noise level; NaN when
    the band holds no defined value."""
    band = (freq >= band_hz[0]) & (freq <= min(band_hz[1], 0.5 * fs))
    values = psd[band]
    return float(np.nanmedian(values)) if np.any(np.isfinite(values)) else float("nan")


def suggested_cutoff(peaks: tuple[float, ...], bandwidth: float | None = None) -> float | None:
    """A low-pass cut-off below every buffet peak (by CUTOFF_MARGIN_HZ) and, when known, at the rigid-body
    bandwidth (where motion gives way to noise), never below MIN_CUTOFF_HZ; None when neither is found."""
    candidates = [min(peaks) - CUTOFF_MARGIN_HZ] if peaks else []
    if bandwidth is not None:
        candidates.append(bandwidth)
    if not candidates:
        return None
    return max(min(candidates), MIN_CUTOFF_HZ)


def channel_spectrum(channel: str, x: np.ndarray, stalled_mask: np.ndarray, slices, fs: float,
                     attached_mask: np.ndarray | None = None) -> ChannelSpectrum:
    """The spectra, peaks and cut-off of one channel, maneuver by maneuver (``slices``); attached flow is
    ``attached_mask``, by default wherever the flow is not stalled."""
    freq, stalled = mean_psd(x, stalled_mask, slices, fs)
    _, attached = mean_psd(x, ~stalled_mask if attached_mask is None else attached_mask, slices, fs)
    peaks = buffet_peaks(freq, stalled, attached)
    bandwidth = rigid_body_bandwidth(freq, attached, fs)
    return ChannelSpectrum(channel, freq, stalled, attached, peaks, suggested_cutoff(peaks, bandwidth), bandwidth)
