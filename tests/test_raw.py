"""Raw flight-test campaigns (issue 15 items 1 and 6, first part): the format, its reader, simulate --raw."""
import numpy as np
import pandas as pd
import pytest

from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.data.errors import DataError
from structsearch.flight import aircraft as ac
from structsearch.flight.flighttest import build_campaign
from structsearch.flight.raw import ACCELEROMETER, specific_force_at


@pytest.fixture(scope="module")
def raw(simulated_campaign):
    return simulated_campaign(seed=4, scale=0.05, raw=True)


def test_lever_arm_terms_equal_the_rigid_body_cross_products():
    rng = np.random.default_rng(0)
    ax, az, q, q_dot = rng.normal(size=4)
    r = np.array(ACCELEROMETER)
    omega, omega_dot = np.array([0.0, q, 0.0]), np.array([0.0, q_dot, 0.0])
    expect = np.array([ax, 0.0, az]) + np.cross(omega_dot, r) + np.cross(omega, np.cross(omega, r))
    got = specific_force_at(ax, az, q, q_dot)
    assert got == pytest.approx((expect[0], expect[2]), rel=1e-12)


def test_raw_channels_carry_the_injected_sensor_errors(raw):
    """Independent checks against the truth columns: the airspeed scale factor, the vane's scale and bias,
    and the accelerometer's normal-axis bias (specific force from the truth coefficients, mass and thrust)."""
    d, e = raw.data, raw.extra
    assert e["format"] == "raw" and "alpha_dot" not in d and "CL" not in d
    assert np.median(d["V"] / d["V_true"]) == pytest.approx(e["injected_V_scale"], abs=2e-3)
    slope, intercept = np.polyfit(d["alpha_true"], d["alpha"], 1)
    assert slope == pytest.approx(e["injected_alpha_scale"], abs=0.01)
    assert intercept == pytest.approx(e["injected_alpha_bias"], abs=0.002)
    residuals = []
    for sl in d.segment_slices():
        a, V, h, m = d["alpha_true"][sl], d["V_true"][sl], d["h"][sl], d["mass"][sl]
        qs = 0.5 * ac.density(h) * V ** 2 * raw.aircraft["S"]
        cz = -d["CL_true"][sl] * np.cos(a) - d["CD_true"][sl] * np.sin(a)
        q = d["q_true"][sl]
        q_dot = np.gradient(q, d["t"][sl])
        az = qs * cz / m - q_dot * ACCELEROMETER[0] - q * q * ACCELEROMETER[2]
        residuals.append((d["az"][sl] - az)[np.abs(d["alpha_true"][sl]) < 0.15])  # attached: no buffet
    assert np.mean(np.concatenate(residuals)) == pytest.approx(e["injected_az_bias"], abs=0.02)


def test_raw_campaign_round_trip_and_format_errors(raw, tmp_path):
    written = write_campaign(raw, tmp_path / "raw")
    back = read_campaign(written, fmt="raw")
    assert back.extra["format"] == "raw" and back.extra["injected_alpha_scale"] == pytest.approx(
        raw.extra["injected_alpha_scale"], rel=1e-9)
    with pytest.raises(DataError, match=r"column 'format': a raw campaign where a standard one is needed.*preprocess"):
        read_campaign(written)
    standard = write_campaign(build_campaign(seed=4, scale=0.05), tmp_path / "standard")
    with pytest.raises(DataError, match="a standard campaign where a raw one is needed"):
        read_campaign(standard, fmt="raw")
    first = written / "m01.csv"
    pd.read_csv(first).drop(columns=["thrust"]).to_csv(first, index=False)
    with pytest.raises(DataError, match=r"m01.csv, column 'thrust': required column is missing"):
        read_campaign(written, fmt="raw")
    toml = written / "campaign.toml"
    toml.write_text(toml.read_text().replace('format = "raw"', 'format = "rare"'))
    with pytest.raises(DataError, match="unknown format 'rare'"):
        read_campaign(written, fmt="raw")


def test_buffet_peaks_are_found_where_the_simulator_puts_them():
    """Issue 15 item 2: Welch spectra of stalled against attached samples find the injected buffet peaks
    (6, 10, 12, 15 Hz) within 1 Hz, and nothing else, in the longitudinal accelerometer and the rate gyro;
    the suggested cut-off lies below them."""
    from structsearch.preprocessing.spectra import channel_spectrum
    from structsearch.flight.measurement import BUFFET_HZ
    c = build_campaign(seed=4, scale=0.1, raw=True)
    d = c.data
    fs = 1.0 / np.median(np.diff(d["t"][:100]))
    stalled = d["alpha"] > 0.22
    for channel in ("ax", "q"):
        s = channel_spectrum(channel, d[channel], stalled, d.segment_slices(), fs)
        assert all(min(abs(p - f) for p in s.peaks_hz) <= 1.0 for f in BUFFET_HZ), (channel, s.peaks_hz)
        assert all(min(abs(p - f) for f in BUFFET_HZ) <= 1.0 for p in s.peaks_hz), (channel, s.peaks_hz)
        assert 1.0 <= s.cutoff_hz < min(BUFFET_HZ)
    # the vane sees no buffet: no peak, no cut-off suggested (the default stays)
    assert channel_spectrum("alpha", d["alpha"], stalled, d.segment_slices(), fs).cutoff_hz is None
