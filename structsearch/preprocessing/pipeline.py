"""From raw flight-test channels to a standard campaign (issue 15): spectra and cut-offs, the zero-phase
pre-filter per maneuver, the flight-path reconstruction, and the coefficients of thesis Eqs. 1-4.

Numerics only: the command line writes the campaign and :mod:`structsearch.reporting.preprocess_doc` the record.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Mapping

import numpy as np

from ..data.coefficients import COEFFICIENTS
from .._version import __version__
from ..data.campaign import Campaign, make_campaign
from ..data.errors import DataError, DeclarationError
from ..data.prefilter import CUTOFF_HZ, derivative, lowpass
from ..data.reduction import (body_force_coefficients, isa_density, lift_drag, pitch_moment_coefficient,
                              specific_force_at_cg)
from .spectra import SEGMENT_S, ChannelSpectrum, channel_spectrum, noise_floor
from .reconstruction import Reconstruction, reconstruct

# Channels whose spectra the record shows, by figure.
CHANNEL_GROUPS = {"specific forces": ("ax", "ay", "az"), "body rates": ("p", "q", "r"),
                  "air data and attitude": ("alpha", "beta", "V", "theta", "phi", "h"),
                  "controls": ("de", "da", "dr")}
# The band [Hz] whose median attached-flow spectrum is an input's noise floor for the filter's process noise:
# above the rigid-body motion, below where a slow sensor's resampling images start. Wider than spectra's
# NOISE_FLOOR_BAND_HZ, which must also be flat to judge a bandwidth; the jackknife standard deviations do not
# rest on this level.
NOISE_BAND_HZ = (10.0, 25.0)
# Stalled flow for the spectra, by default: above the angle of attack of maximum normal force less this margin.
STALL_MARGIN_RAD = np.deg2rad(1.0)
MIN_STALLED_SHARE = 0.02
RECONSTRUCTION_CHANNELS = ("ax", "az", "q", "r", "phi", "V", "alpha", "theta", "h")


@dataclass(frozen=True)
class Cutoff:
    channel: str
    default_hz: float | None     # thesis Table 5 (or the defaults beside it)
    suggested_hz: float | None   # from the buffet peaks (None: no peak)
    applied_hz: float | None     # None: not filtered
    source: str                  # where the applied value comes from


@dataclass(frozen=True)
class Preprocessed:
    campaign: Campaign
    raw: Campaign
    spectra: tuple[ChannelSpectrum, ...]
    cutoffs: tuple[Cutoff, ...]
    reconstruction: Reconstruction
    stall_alpha_rad: float
    stall_alpha_source: str

    def cutoff(self, channel: str) -> Cutoff:
        return next(c for c in self.cutoffs if c.channel == channel)


def sample_rate(raw: Campaign) -> float:
    """The common sample rate [Hz]; every maneuver must be uniformly sampled at it (the filters assume so)."""
    d = raw.data
    slices = d.segment_slices()
    first = np.diff(d["t"][slices[0]])
    fs = 1.0 / float(np.median(first))
    for m, sl in zip(raw.maneuvers, slices):
        dt = np.diff(d["t"][sl])
        bad = np.flatnonzero(np.abs(dt * fs - 1.0) > 0.01)
        if bad.size:
            where = raw.directory / m.file if raw.directory is not None else m.id
            raise DataError(f"time step {dt[bad[0]]:g} s where the campaign is sampled every {1 / fs:g} s; "
                            "preprocess needs uniformly sampled channels (resample them first)",
                            source=str(where), column="t", row=int(bad[0]) + 1)
    return fs


def _aircraft_value(raw: Campaign, key: str, why: str) -> float:
    if key not in raw.aircraft:
        where = str(raw.directory / "campaign.toml") if raw.directory is not None else raw.name
        raise DataError(f"[aircraft] {key} is missing: {why}", source=where, column=key)
    return float(raw.aircraft[key])


def default_stall_alpha(raw: Campaign) -> float:
    """The angle of attack of the largest binned median normal-force coefficient (from az, V and the ISA),
    less :data:`STALL_MARGIN_RAD`: where the flow has separated on every aircraft."""
    d = raw.data
    mass = d["mass"] if "mass" in d else _aircraft_value(raw, "mass", "needed without a mass column")
    rho = d["rho"] if "rho" in d else isa_density(d["h"])
    cn = -mass * d["az"] / (0.5 * rho * d["V"] ** 2 * float(raw.aircraft["S"]))
    alpha = d["alpha"]
    edges = np.arange(np.quantile(alpha, 0.01), np.quantile(alpha, 0.999), np.deg2rad(0.5))
    which = np.digitize(alpha, edges)
    medians = [(np.median(cn[which == i]), 0.5 * (edges[i - 1] + edges[i])) for i in range(1, len(edges))
               if np.count_nonzero(which == i) >= 50]
    if not medians:
        raise DataError("too few samples to find the angle of maximum normal force (50 per 0.5 deg bin); give "
                        "--stall-alpha DEG", source=str(raw.directory or raw.name), column="alpha")
    return float(max(medians)[1] - STALL_MARGIN_RAD)


def _channels(raw: Campaign) -> list[str]:
    recorded = set(raw.data.columns)
    return [c for group in CHANNEL_GROUPS.values() for c in group if c in recorded]


def choose_cutoffs(raw: Campaign, spectra: Mapping[str, ChannelSpectrum], overrides: Mapping[str, float],
                   use_suggested: bool, fs: float) -> tuple[Cutoff, ...]:
    """Per channel: the command line's override, else campaign.toml's ``[cutoffs]``, else the suggestion from
    the spectra when ``use_suggested``, else thesis Table 5."""
    toml = {k: float(v) for k, v in raw.cutoffs_hz.items()}
    channels = _channels(raw)
    for source, given in (("--cutoff", overrides), ("campaign.toml [cutoffs]", toml)):
        for name, hz in given.items():
            if name not in raw.data.columns or name == "t":
                raise DeclarationError(f"{source} {name}={hz:g}: no channel {name!r} in the raw campaign "
                                       f"(have: {', '.join(sorted(c for c in raw.data.columns if c != 't'))})")
            if not 0 < hz < fs / 2:
                raise DeclarationError(f"{source} {name}={hz:g}: a cut-off lies between 0 and the Nyquist "
                                       f"frequency {fs / 2:g} Hz")
    out = []
    for c in channels + sorted((set(overrides) | set(toml)) - set(channels)):
        default = CUTOFF_HZ.get(c)
        suggested = spectra[c].cutoff_hz if c in spectra else None
        if c in overrides:
            applied, source = overrides[c], "command line"
        elif c in toml:
            applied, source = toml[c], "campaign.toml"
        elif use_suggested and suggested is not None:
            applied, source = suggested, "spectra"
        else:
            applied, source = default, "Table 5" if c in ("ax", "ay", "az", "p", "q", "r", "da", "de", "dr",
                                                          "alpha", "beta") else "default"
        out.append(Cutoff(c, default, suggested, applied, source if applied is not None else "not filtered"))
    return tuple(out)


def _filtered(data, name: str, hz: float | None, fs: float) -> np.ndarray:
    """Zero-phase low-pass, maneuver by maneuver (no filter runs across a maneuver boundary)."""
    x = np.asarray(data[name], dtype=float)
    if hz is None:
        return x
    return np.concatenate([lowpass(x[sl], hz, fs) for sl in data.segment_slices()])


def _derivative(data, x: np.ndarray) -> np.ndarray:
    return np.concatenate([derivative(x[sl], data["t"][sl]) for sl in data.segment_slices()])


def _stalled_flow(raw: Campaign, stall_alpha_rad: float | None,
                  stall_state: str | None) -> tuple[np.ndarray, float, str]:
    """The samples of stalled flow for the spectra, the stall angle of attack [rad] (NaN when a separation state
    says) and where the choice comes from; refused when too few samples are stalled."""
    d = raw.data
    if stall_alpha_rad is not None:
        stall_alpha, stall_source = float(stall_alpha_rad), "command line"
    elif "stall_alpha" in raw.extra:
        value = raw.extra["stall_alpha"]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) < np.pi / 2:
            where = str(raw.directory / "campaign.toml") if raw.directory is not None else raw.name
            raise DataError(f"stall_alpha must be an angle of attack in radians, not {value!r}", source=where,
                            column="stall_alpha")
        stall_alpha, stall_source = float(value), "campaign.toml"
    else:
        stall_alpha, stall_source = default_stall_alpha(raw), "maximum normal force less 1 deg"
    stalled = d["alpha"] > stall_alpha
    if stall_state is not None:   # a separation state from an earlier identification: separated below one half
        if stall_state not in d:
            raise DeclarationError(f"--stall-state {stall_state}: no such column in the raw campaign")
        x = d[stall_state]
        if np.nanmin(x) < -0.01 or np.nanmax(x) > 1.01:
            raise DataError(f"a separation state lies in [0, 1]; this column spans {np.nanmin(x):g} to "
                            f"{np.nanmax(x):g}", source=str(raw.directory or raw.name), column=stall_state)
        stalled, stall_source = x < 0.5, f"separation state {stall_state} below 0.5"
        stall_alpha = float(np.nan)
    if np.mean(stalled) < MIN_STALLED_SHARE:
        what = (f"alpha above {np.rad2deg(stall_alpha):.1f} deg; " if np.isfinite(stall_alpha) else "") + stall_source
        raise DataError(f"only {100 * np.mean(stalled):.1f} % of the samples are stalled ({what}); give a lower "
                        "--stall-alpha or another --stall-state",
                        source=str(raw.directory or raw.name), column="alpha")
    return stalled, stall_alpha, stall_source


def _check_cutoffs(cutoffs: tuple[Cutoff, ...], hz: Mapping[str, float | None], fs: float) -> None:
    """Refuse a cut-off at or above the Nyquist frequency, or a channel the reconstruction needs left unfiltered."""
    for c in cutoffs:
        if c.applied_hz is not None and not c.applied_hz < fs / 2:
            raise DeclarationError(f"channel {c.channel!r}: cut-off {c.applied_hz:g} Hz ({c.source}) is not below the "
                                   f"Nyquist frequency {fs / 2:g} Hz; give --cutoff {c.channel}=HZ")
    for needed in ("ax", "az", "q", "V", "alpha", "theta", "h"):
        if hz.get(needed) is None:
            raise DeclarationError(f"channel {needed!r} needs a cut-off (--cutoff {needed}=HZ)")


def _noise_levels(raw: Campaign, spectra: Mapping[str, ChannelSpectrum], fs: float) -> dict[str, float]:
    """The noise floor of the specific forces and the pitch rate (the filter's process noise), from their
    attached-flow spectra (stalled where there is none)."""
    noise = {}
    for c in ("ax", "az", "q"):
        sp = spectra[c]
        level = noise_floor(sp.frequency, np.where(np.isnan(sp.attached), sp.stalled, sp.attached), fs, NOISE_BAND_HZ)
        if not np.isfinite(level) or level <= 0:
            raise DataError(f"no noise floor in the {c} spectrum between {NOISE_BAND_HZ[0]:g} and "
                            f"{NOISE_BAND_HZ[1]:g} Hz: preprocess needs maneuvers longer than {SEGMENT_S:g} s sampled at "
                            f"{2 * NOISE_BAND_HZ[0] / 0.45:.0f} Hz or more (this campaign: {fs:g} Hz)",
                            source=str(raw.directory or raw.name), column=c)
        noise[c] = level
    return noise


def _coefficient_columns(raw: Campaign, c: Mapping[str, np.ndarray], accelerometer: tuple, iyy: float,
                         s_ref: float, cbar: float) -> dict[str, np.ndarray]:
    """The standard campaign's columns: the coefficients of thesis Eqs. 1-4 from the corrected channels ``c``,
    those channels, and the raw campaign's other columns passed through."""
    d = raw.data
    ax, az = specific_force_at_cg(c["ax"], c["az"], c["q"], c["q_dot"], accelerometer)
    mass = d["mass"] if "mass" in d else np.full(d.n_samples, float(raw.aircraft["mass"]))
    rho = c["rho"] if "rho" in c else isa_density(c["h"])
    qs = 0.5 * rho * c["V"] ** 2 * s_ref
    thrust = c["thrust"]
    cx, cz = body_force_coefficients(ax, az, mass, thrust, qs)
    cl, cd = lift_drag(cx, cz, c["alpha"])
    zero = np.zeros(d.n_samples)
    cm = pitch_moment_coefficient(c["q_dot"], iyy, qs, cbar, thrust=thrust,
                                  thrust_line_z=float(raw.aircraft.get("thrust_line_z", 0.0)),
                                  p=c.get("p", zero), r=c.get("r", zero), ixx=float(raw.aircraft.get("Ixx", 0.0)),
                                  izz=float(raw.aircraft.get("Izz", 0.0)), ixz=float(raw.aircraft.get("Ixz", 0.0)))
    columns = {"t": d["t"], "alpha": c["alpha"], "q": c["q"], "V": c["V"], "de": c["de"], "CL": cl, "CD": cd,
               "Cm": cm, "alpha_dot": _derivative(d, c["alpha"]), "CT": thrust / qs, "CX": cx, "CZ": cz,
               "theta": c["theta"], "h": c["h"], "mass": mass}
    passed = [k for k in d.columns if k not in columns and k not in ("ax", "ay", "az", "thrust")]
    columns.update({k: (d[k] if k.endswith("_true") else c[k]) for k in passed})
    return columns


def _extra_with_record(raw: Campaign, rec: Reconstruction, cutoffs: tuple[Cutoff, ...], stall_alpha: float,
                       stall_source: str) -> dict:
    """The raw campaign's extra keys (less its format) with the record of this preprocessing."""
    record = {"preprocessed_by": f"structsearch {__version__}",
              "preprocessed_from": str(raw.directory) if raw.directory is not None else raw.name,
              "stalled_flow": stall_source, "reconstruction_step_s": rec.step_s}
    if np.isfinite(stall_alpha):
        record["stall_alpha_deg"] = float(np.rad2deg(stall_alpha))
    record.update({f"cutoff_{x.channel}_hz": x.applied_hz for x in cutoffs if x.applied_hz is not None})
    for e in rec.errors:
        record[f"estimated_{e.name}"] = e.estimate
        record[f"estimated_{e.name}_sd"] = e.sd
    extra = {k: v for k, v in raw.extra.items() if k != "format"}
    extra.update(record)
    return extra


def preprocess(raw: Campaign, overrides: Mapping[str, float] | None = None, use_suggested: bool = False,
               stall_alpha_rad: float | None = None, stall_state: str | None = None,
               progress: Callable[[str, float], None] | None = None) -> Preprocessed:
    """The whole chain on a raw campaign (:func:`structsearch.data.campaign.read_campaign` with ``fmt="raw"``)."""
    say = progress or (lambda stage, fraction: None)
    d = raw.data
    fs = sample_rate(raw)
    slices = d.segment_slices()
    iyy = _aircraft_value(raw, "Iyy", "the pitch inertia turns pitch acceleration into C_m")
    s_ref, cbar = float(raw.aircraft["S"]), float(raw.aircraft["cbar"])
    if "mass" not in d:
        _aircraft_value(raw, "mass", "the mass turns specific forces into forces (or give a mass column)")
    # spectra of stalled against attached flow
    say("spectra", 0.0)
    stalled, stall_alpha, stall_source = _stalled_flow(raw, stall_alpha_rad, stall_state)
    # attached flow: the lower half of the angles of attack flown (trim and entry conditions), clear of the
    # separation that begins well below the stall on some aircraft
    attached = (d["alpha"] <= np.median(d["alpha"])) & ~stalled
    channels = _channels(raw)
    spectra = {}
    for i, c in enumerate(channels):
        spectra[c] = channel_spectrum(c, d[c], stalled, slices, fs, attached)
        say("spectra", (i + 1) / len(channels))
    cutoffs = choose_cutoffs(raw, spectra, dict(overrides or {}), use_suggested, fs)
    hz = {c.channel: c.applied_hz for c in cutoffs}
    _check_cutoffs(cutoffs, hz, fs)
    # pre-filter, then reconstruct
    f = {c: _filtered(d, c, hz.get(c), fs) for c in d.columns if c != "t" and not c.endswith("_true")}
    f["q_dot"] = _derivative(d, f["q"])
    noise = _noise_levels(raw, spectra, fs)
    accelerometer = tuple(raw.aircraft.get("accelerometer", (0.0, 0.0, 0.0)))
    # the kinematic equations hold between signals filtered alike: the reconstruction sees every channel at
    # the lowest of their cut-offs (a linear zero-phase filter commutes with the linear terms)
    common = min(hz[c] for c in RECONSTRUCTION_CHANNELS if c in hz and hz[c] is not None)
    g = {c: _filtered(d, c, common, fs) for c in RECONSTRUCTION_CHANNELS if c in d}
    g["q_dot"] = _derivative(d, g["q"])
    rec = reconstruct(g, slices, fs, {c: common for c in g}, noise, accelerometer,
                      lambda x: say("reconstruction", x))
    # coefficients from the corrected channels (thesis Eqs. 1-4)
    say("coefficients", 0.0)
    columns = _coefficient_columns(raw, rec.correct(f), accelerometer, iyy, s_ref, cbar)
    segments = [{k: v[sl] for k, v in columns.items()} for sl in slices]
    extra = _extra_with_record(raw, rec, cutoffs, stall_alpha, stall_source)
    # the raw campaign's length rules go with its coefficients (a lowered minimum must read back)
    standard = replace(make_campaign(raw.name, raw.aircraft, raw.maneuvers, segments, extra),
                       length_rules=raw.length_rules)
    say("coefficients", 1.0)
    return Preprocessed(standard, raw, tuple(spectra.values()), cutoffs, rec, stall_alpha, stall_source)


def truth_agreement(campaign: Campaign, less_offset: bool = False) -> list[tuple[str, str, float]]:
    """Per maneuver and coefficient, R^2 of the reconstructed coefficient against ``<coefficient>_true`` when
    the campaign carries it (a simulated one): (maneuver, coefficient, R^2). ``less_offset`` removes each
    maneuver's mean error first (what a per-maneuver constant error, e.g. a thrust model's, leaves)."""
    d = campaign.data
    out = []
    for m, sl in zip(campaign.maneuvers, d.segment_slices()):
        for name in COEFFICIENTS:
            if f"{name}_true" in d:
                truth, error = d[f"{name}_true"][sl], d[name][sl] - d[f"{name}_true"][sl]
                if less_offset:
                    error = error - error.mean()
                ss = np.sum((truth - truth.mean()) ** 2)
                out.append((m.id, name, float(1 - np.sum(error ** 2) / ss) if ss > 0 else float("nan")))
    return out

