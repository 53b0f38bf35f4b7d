"""Where a gap lies: each validation sample's bin (maneuver, alpha band, flight phase, sign of alpha_dot), each
bin's share of the summed excess squared residual with a bootstrap over maneuvers, the share per frequency band,
and where an effect improves the fit most.

Per sample, the excess is r_baseline^2 - r_floor^2; the shares of one dimension sum to 1 (NaN everywhere when
there is no excess to share).
"""
from __future__ import annotations

import numpy as np

from ..data.flightdata import FlightData
from .results import TopBins, WhereBin

ALPHA_BAND = 0.04          # rad
FREQ_BANDS = (0.0, 0.5, 1.0, 2.0, 5.0, np.inf)  # Hz
N_BOOTSTRAP = 200


def bins(data: FlightData, x: np.ndarray) -> dict[str, np.ndarray]:
    """Per sample: the bin label of each dimension."""
    alpha, alpha_dot = data["alpha"], data["alpha_dot"]
    labels = {"maneuver": np.concatenate([[name] * (sl.stop - sl.start) for name, sl in
                                          zip(data.names, data.segment_slices())]).astype(object)}
    lo = np.floor(alpha / ALPHA_BAND) * ALPHA_BAND
    labels["alpha_band"] = np.array([f"{a:.2f}-{a + ALPHA_BAND:.2f}" for a in lo], dtype=object)
    x_dot = np.concatenate([np.gradient(x[sl], data["t"][sl]) for sl in data.segment_slices()])
    phase = np.where(x > 0.9, "attached", np.where(x < 0.1, "stalled",
                                                   np.where(x_dot < 0, "separating", "reattaching")))
    labels["phase"] = phase.astype(object)
    labels["alpha_dot_sign"] = np.where(alpha_dot >= 0, "alpha increasing", "alpha decreasing").astype(object)
    return labels


def shares(excess: np.ndarray, labels: np.ndarray):
    """Each bin's share of the positive summed excess; NaN everywhere when there is no excess to share."""
    keys = sorted(set(labels))
    sums = np.array([excess[labels == k].sum() for k in keys])
    pos = np.clip(sums, 0, None)
    total = pos.sum()
    return keys, (pos / total if total > 0 else np.full(len(keys), np.nan))


def _frequency_excess(r_base, r_sat, data):
    """Excess power per frequency band, summed over maneuvers (same normalisation as squared residuals)."""
    out = np.zeros(len(FREQ_BANDS) - 1)
    for sl in data.segment_slices():
        f = np.fft.rfftfreq(sl.stop - sl.start, float(np.median(np.diff(data["t"][sl]))))
        for r, sign in ((r_base[sl], 1.0), (r_sat[sl], -1.0)):
            spec = np.abs(np.fft.rfft(r)) ** 2 / len(r) * 2
            spec[0] /= 2
            for i in range(len(out)):
                out[i] += sign * spec[(f >= FREQ_BANDS[i]) & (f < FREQ_BANDS[i + 1])].sum()
    return out


def where_bins(r_base, r_sat, data: FlightData, x: np.ndarray, seed: int = 0) -> tuple[WhereBin, ...]:
    """Shares of the excess squared residual by bin, with bootstrap standard deviations over maneuvers."""
    excess = r_base ** 2 - r_sat ** 2
    labels = bins(data, x)
    rng = np.random.default_rng(seed)
    slices = data.segment_slices()
    out = []
    maneuver_of = np.concatenate([np.full(sl.stop - sl.start, i) for i, sl in enumerate(slices)])
    for dim, lab in labels.items():
        keys, share = shares(excess, lab)
        # excess summed per (maneuver, bin): a bootstrap over maneuvers adds rows of this table
        code = np.searchsorted(np.array(keys, dtype=object), lab)
        table = np.zeros((len(slices), len(keys)))
        np.add.at(table, (maneuver_of, code), excess)
        boot = []
        for _ in range(N_BOOTSTRAP if dim != "maneuver" else 0):
            pos = np.clip(table[rng.integers(0, len(slices), len(slices))].sum(axis=0), 0, None)
            boot.append(pos / pos.sum() if pos.sum() > 0 else np.zeros(len(keys)))
        spread = np.std(boot, axis=0) if boot else np.full(len(keys), np.nan)
        for k, s, sd in zip(keys, share, spread):
            mask = lab == k
            out.append(WhereBin(dim, str(k), float(s), float(sd), float(np.mean(r_base[mask] ** 2)),
                                int(mask.sum())))
    fx_ = _frequency_excess(r_base, r_sat, data)
    pos = np.clip(fx_, 0, None)
    for i, s in enumerate(pos / pos.sum() if pos.sum() > 0 else pos):
        hi = FREQ_BANDS[i + 1]
        label = f"{FREQ_BANDS[i]:g}-{hi:g} Hz" if np.isfinite(hi) else f">{FREQ_BANDS[i]:g} Hz"
        out.append(WhereBin("frequency_band", label, float(s), float("nan"), float("nan"), 0))
    return tuple(out)


def where(r_base, r_sat, data: FlightData, x: np.ndarray, seed: int = 0) -> list[dict]:
    """:func:`where_bins` as the rows of ``diagnosis.json``'s ``where``."""
    return [b.to_dict() for b in where_bins(r_base, r_sat, data, x, seed)]


def top_bins(rows) -> TopBins | None:
    """The phase and alpha band holding the largest share of an excess; None when there is no excess."""
    out = {}
    for dim in ("phase", "alpha_band"):
        found = [r for r in rows if r.dimension == dim and np.isfinite(r.share)]
        if not found:
            return None
        out[dim] = max(found, key=lambda r: r.share).bin
    return TopBins(out["phase"], out["alpha_band"])


def overlap(gap_rows, r_base, r_new, data, x):
    """Histogram intersection of gap shares and improvement shares over alpha bands and phases, and the
    bins where the effect improves the fit most (where it acts); NaN and no bins where it improves nothing
    or there is no gap."""
    labels = bins(data, x)
    improvement = r_base ** 2 - r_new ** 2
    scores, acts = [], {}
    for dim in ("alpha_band", "phase"):
        keys, imp = shares(improvement, labels[dim])
        gap = {row.bin: row.share for row in gap_rows if row.dimension == dim}
        scores.append(float(sum(min(gap.get(k, 0.0), s) for k, s in zip(keys, imp))))
        if np.all(np.isnan(imp)):
            return float("nan"), {}
        acts[dim] = str(keys[int(np.nanargmax(imp))])
    return float(np.mean(scores)), acts
