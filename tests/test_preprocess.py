"""Issue 15: from raw channels to coefficients. The Kalman smoother against filterpy and against a synthetic
constant-bias flight integrated independently, the spectra's bandwidth, the whole chain on simulated raw
campaigns of both aircraft (sensor errors within 3 standard deviations, coefficients against the truth), the
command end to end, and one clear error for each kind of bad input."""
from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.integrate import solve_ivp

from structsearch.cli import main
from structsearch.data.campaign import _parse_cutoffs, read_campaign, write_campaign
from structsearch.data.errors import DataError, DeclarationError, FitError
from structsearch.data.reduction import G
from structsearch.preprocessing.spectra import rigid_body_bandwidth
from structsearch.flight.flighttest import build_campaign
from structsearch.preprocessing.kalman import filter_smooth
from structsearch.preprocessing.kinematics import SENSOR_ERRORS
from structsearch.preprocessing.pipeline import preprocess, truth_agreement
from structsearch.preprocessing.reconstruction import reconstruct


@dataclass(frozen=True)
class _Linear:
    """x = (position, velocity, bias); the measurement is position + bias; no record resets."""

    f: np.ndarray
    n_states = 3
    kinematic = slice(0, 0)

    def transition(self, x, u0, u1):
        return self.f @ x, self.f

    def measure(self, x):
        h = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
        return h @ x, h

    def initial(self, x, y):
        return x[:0]


def test_filter_and_smoother_equal_filterpy_on_a_linear_model():
    kalman = pytest.importorskip("filterpy.kalman")
    rng = np.random.default_rng(0)
    dt = 0.1
    f = np.array([[1.0, dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    q = np.diag([1e-4, 1e-3, 0.0])
    r = np.array([0.04, 0.01])
    n = 200
    x = np.array([0.0, 1.0, 0.3])
    y = np.empty((n, 2))
    for k in range(n):
        x = f @ x + rng.multivariate_normal(np.zeros(3), q + 1e-15 * np.eye(3))
        y[k] = [x[0] + x[2], x[1]] + rng.normal(0, np.sqrt(r))
    x0, p0 = np.zeros(3), np.diag([1.0, 1.0, 1.0])
    ours = filter_smooth(_Linear(f), np.zeros((n, 1)), y, np.ones((n, 2), bool), np.eye(1, n, 0, bool)[0], x0, p0,
                         q, r)
    h = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    means, covs, _, _ = kalman.batch_filter(x0, p0, y, [f] * n, [q] * n, [h] * n, [np.diag(r)] * n,
                                            update_first=True)
    smoothed, smoothed_cov, _, _ = kalman.rts_smoother(means, covs, [f] * n, [q] * n)
    assert np.allclose(ours.filtered, means, atol=1e-9)
    assert np.allclose(ours.smoothed, smoothed, atol=1e-8)
    assert np.allclose(ours.smoothed_cov, smoothed_cov, atol=1e-10)


def _synthetic_flight(rng, errors, duration=60.0, fs=100.0, n_maneuvers=6):
    """Maneuvers integrated by scipy from smooth specific forces and pitch rate, recorded with white noise and
    the given constant sensor errors: nothing from the simulator or the filter's discretisation."""
    t = np.arange(0.0, duration, 1.0 / fs)
    out = []
    for m in range(n_maneuvers):
        a1, a2, w1, w2 = rng.uniform(0.5, 1.5), rng.uniform(0.5, 1.5), rng.uniform(0.1, 0.4), rng.uniform(0.1, 0.4)

        def inputs(time):
            return (0.3 * a1 * np.sin(w1 * time), -G + 2.0 * a2 * np.sin(w2 * time + m),
                    0.05 * np.sin(0.3 * w1 * time + m) * a2)

        def rhs(time, s):
            u, w, theta, h = s
            ax, az, q = inputs(time)
            return [ax - G * np.sin(theta) - q * w, az + G * np.cos(theta) + q * u, q,
                    u * np.sin(theta) - w * np.cos(theta)]

        s = solve_ivp(rhs, (0, t[-1]), [80.0, 4.0, 0.05, 2000.0], t_eval=t, rtol=1e-10, atol=1e-10).y
        ax, az, q = inputs(t)
        u, w, theta, h = s
        noise = lambda sd: rng.normal(0, sd, len(t))  # noqa: E731
        out.append({"ax": ax + errors["ax_bias"] + noise(0.02), "az": az + errors["az_bias"] + noise(0.03),
                    "q": q + errors["q_bias"] + noise(0.001), "q_dot": np.gradient(q, t),
                    "V": errors["V_scale"] * np.hypot(u, w) + noise(0.1),
                    "alpha": errors["alpha_scale"] * np.arctan2(w, u) + errors["alpha_bias"] + noise(0.0005),
                    "theta": theta + noise(0.0005), "h": h + noise(1.0)})
    slices, start = [], 0
    for _ in out:
        slices.append(slice(start, start + len(t)))
        start += len(t)
    return {k: np.concatenate([o[k] for o in out]) for k in out[0]}, slices, fs


def test_smoother_recovers_constant_sensor_errors_of_a_synthetic_flight():
    """The reconstruction on independently integrated kinematics (no simulator): every sensor error within
    3 standard deviations, and the standard deviations small enough to mean something."""
    rng = np.random.default_rng(7)
    errors = {"ax_bias": 0.08, "az_bias": -0.12, "q_bias": 0.003, "alpha_bias": 0.01, "alpha_scale": 1.05,
              "V_scale": 0.97}
    channels, slices, fs = _synthetic_flight(rng, errors)
    cutoffs = {c: 50.0 * 0.45 for c in ("V", "alpha", "theta", "h")}
    # white noise: one-sided density 2 sd^2 / fs
    psd = {"ax": 2 * 0.02 ** 2 / fs, "az": 2 * 0.03 ** 2 / fs, "q": 2 * 0.001 ** 2 / fs}
    rec = reconstruct(channels, slices, fs, cutoffs, psd)
    for name in SENSOR_ERRORS:
        e = rec.error(name)
        assert abs(e.estimate - errors[name]) <= 3 * e.sd, (name, e)
    assert rec.error("alpha_bias").sd < 0.002 and rec.error("q_bias").sd < 1e-4
    # the kinematics are consistent only with the errors estimated
    for c in rec.consistency:
        assert c.after < c.before, c


def test_rigid_body_bandwidth_is_where_motion_meets_the_noise():
    rng = np.random.default_rng(3)
    fs, n = 100.0, 100_000
    from scipy.signal import butter, sosfiltfilt, welch
    motion = sosfiltfilt(butter(4, 1.0, fs=fs, output="sos"), rng.normal(size=n)) * 20
    x = motion + rng.normal(0, 0.05, n)
    freq, p = welch(x, fs=fs, nperseg=400)
    bandwidth = rigid_body_bandwidth(freq, p, fs)
    assert 1.0 <= bandwidth <= 3.0
    # a slow sensor resampled by interpolation has no white floor: no bandwidth
    slow = np.interp(np.arange(n), np.arange(0, n, 8), x[::8])
    freq, p = welch(slow, fs=fs, nperseg=400)
    assert rigid_body_bandwidth(freq, p, fs) is None


@pytest.fixture(scope="module", params=["citation", pytest.param("transport", marks=pytest.mark.slow)])
def processed(request):
    raw = build_campaign(seed=4, scale=0.1, raw=True, aircraft=request.param)
    return raw, preprocess(raw, use_suggested=True)


def test_injected_sensor_errors_are_recovered_within_three_sd(processed):
    raw, p = processed
    for e in p.reconstruction.errors:
        injected = raw.extra[f"injected_{e.name}"]
        assert abs(e.estimate - injected) <= 3 * e.sd, (e, injected)
        assert e.sd < {"ax_bias": 0.01, "az_bias": 0.01, "q_bias": 1e-4, "alpha_bias": 1e-3, "alpha_scale": 0.01,
                       "V_scale": 0.005}[e.name]


def test_coefficients_match_the_truth_on_every_maneuver(processed):
    """Issue 15's targets C_L 0.97, C_D 0.95, C_m 0.80; the C_D target is checked with the engine model's
    per-maneuver thrust error (3 %, in the raw thrust channel by design) removed as an offset."""
    _, p = processed
    for (maneuver, name, r2), (_, _, r2_less_offset) in zip(truth_agreement(p.campaign),
                                                           truth_agreement(p.campaign, less_offset=True)):
        assert (r2_less_offset if name == "CD" else r2) >= {"CL": 0.97, "CD": 0.95, "Cm": 0.80}[name], (maneuver,
                                                                                                      name, r2)


def test_buffet_peaks_in_the_record_and_the_cutoffs_below_them(processed):
    from structsearch.flight.measurement import BUFFET_HZ
    _, p = processed
    q = next(s for s in p.spectra if s.channel == "q")
    assert all(min(abs(x - f) for x in q.peaks_hz) <= 1.0 for f in BUFFET_HZ)
    assert p.cutoff("q").applied_hz < min(BUFFET_HZ) and p.cutoff("q").source == "spectra"
    assert p.cutoff("alpha").source == "Table 5"


@pytest.mark.slow
def test_preprocess_command_end_to_end(tmp_path, capsys):
    raw_dir, out = tmp_path / "raw", tmp_path / "std"
    assert main(["simulate", "--raw", "--scale", "0.05", "--seed", "2", "--out", str(raw_dir)]) == 0
    toml = raw_dir / "campaign.toml"
    toml.write_text(toml.read_text() + "\n[cutoffs]\nde = 3.5\n")
    assert main(["preprocess", "--raw", str(raw_dir), "--out", str(out), "--cutoff", "q=2.5"]) == 0
    captured = capsys.readouterr()
    assert "preprocess: reconstruction" in captured.err and "sensor errors:" in captured.out
    campaign = read_campaign(out)
    assert {"CL", "CD", "Cm", "alpha_dot", "CT", "CX", "CZ", "theta", "h"} <= set(campaign.data.columns)
    e = campaign.extra
    rows = [line.split("|")[1].strip() for line in (out / "preprocess.md").read_text().splitlines()
            if line.startswith("| ") and "Hz" not in line and "---" not in line][:20]
    assert rows.count("q") == 1 and rows.count("de") == 1
    assert e["cutoff_q_hz"] == 2.5 and e["cutoff_de_hz"] == 3.5 and e["cutoff_az_hz"] == 8.0
    assert "estimated_alpha_scale" in e and e["estimated_alpha_scale_sd"] > 0
    assert e["preprocessed_by"].startswith("structsearch")
    md = (out / "preprocess.md").read_text()
    assert "command line" in md and "campaign.toml" in md and (out / "spectra_body_rates.png").stat().st_size > 0
    # the written campaign fits like any other
    assert main(["fit", "--data", str(out), "--model", "CL-I", "--out", str(tmp_path / "fit")]) == 0


def test_preprocess_without_matplotlib_writes_everything_but_the_figures(small_raw, tmp_path, capsys, monkeypatch):
    """Issue 30: without the figures extra, the campaign and the record are written, the figures skipped with one
    warning line (before: one error, and the coefficients asked for were not written). Two of the small raw
    campaign's maneuvers are enough (the path under test is the figures', not the estimation's)."""
    import shutil
    from structsearch.reporting import figures
    monkeypatch.setattr(figures, "plt", None)
    raw = tmp_path / "raw"
    shutil.copytree(small_raw, raw)
    entries = (raw / "campaign.toml").read_text().split("[[maneuver]]")
    (raw / "campaign.toml").write_text("[[maneuver]]".join(entries[:3]))
    out = tmp_path / "std"
    assert main(["preprocess", "--raw", str(raw), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "matplotlib" in warnings[0]
    assert {"CL", "CD", "Cm"} <= set(read_campaign(out).data.columns)
    md = (out / "preprocess.md").read_text()
    assert "Spectra figures not drawn" in md and not list(out.glob("*.png"))


@pytest.fixture(scope="module")
def small_raw(tmp_path_factory):
    return write_campaign(build_campaign(seed=5, scale=0.05, raw=True), tmp_path_factory.mktemp("raw") / "c")


def test_bad_raw_inputs_give_one_clear_error(small_raw, tmp_path):
    import pandas as pd
    import shutil
    broken = tmp_path / "broken"
    shutil.copytree(small_raw, broken)
    first = broken / "m01.csv"
    frame = pd.read_csv(first)
    frame.loc[10:, "t"] += 0.005
    frame.to_csv(first, index=False)
    with pytest.raises(DataError, match=r"m01.csv, column 't', row 10: time step"):
        preprocess(read_campaign(broken, fmt="raw"))
    raw = read_campaign(small_raw, fmt="raw")
    without_iyy = replace(raw, aircraft={k: v for k, v in raw.aircraft.items() if k != "Iyy"})
    with pytest.raises(DataError, match=r"column 'Iyy': \[aircraft\] Iyy is missing"):
        preprocess(without_iyy)
    with pytest.raises(DeclarationError, match=r"--cutoff wind=2: no channel 'wind'"):
        preprocess(raw, {"wind": 2.0})
    with pytest.raises(DeclarationError, match=r"--cutoff q=60: a cut-off lies between 0 and the Nyquist"):
        preprocess(raw, {"q": 60.0})
    with pytest.raises(DataError, match=r"only .* % of the samples are stalled \(alpha above 57.3 deg; command line\)"):
        preprocess(raw, stall_alpha_rad=1.0)
    with pytest.raises(DataError, match=r"column 'stall_alpha': stall_alpha must be an angle of attack in radians"):
        preprocess(replace(raw, extra={**raw.extra, "stall_alpha": 12.0}))
    toml = broken / "campaign.toml"
    toml.write_text(toml.read_text() + "\n[cutoffs]\nq = -1\n")
    with pytest.raises(DataError, match=r"campaign.toml, column 'q': \[cutoffs\] q must be a positive"):
        read_campaign(broken, fmt="raw")
    assert main(["preprocess", "--raw", str(small_raw), "--out", str(small_raw)]) == 2   # would replace it
    short = replace(raw, maneuvers=raw.maneuvers[:1], data=raw.data.select([0]))
    for samples, error, message in ((300, DataError, "preprocess needs maneuvers longer than 4 s"),
                                    (700, FitError, "no maneuver is longer than 8 s")):
        cut = replace(short, data=replace(short.data, columns={k: v[:samples] for k, v in short.data.columns.items()}))
        with pytest.raises(error, match=message):
            preprocess(cut, stall_alpha_rad=0.0)
    with pytest.raises(SystemExit) as exit_info:
        main(["preprocess", "--raw", str(small_raw), "--out", str(tmp_path / "x"), "--cutoff", "q=fast"])
    assert exit_info.value.code == 2


@settings(max_examples=60, deadline=None)
@given(st.dictionaries(st.text(min_size=1, max_size=5),
                       st.one_of(st.floats(allow_nan=True), st.integers(), st.text(max_size=3), st.booleans()),
                       max_size=4))
def test_cutoffs_table_reader_returns_positive_frequencies_or_one_data_error(table):
    try:
        parsed = _parse_cutoffs(table, "campaign.toml")
    except DataError as exc:
        assert "campaign.toml" in str(exc)
        return
    assert set(parsed) == set(table) and all(v > 0 and np.isfinite(v) for v in parsed.values())


def test_stalled_flow_from_a_separation_state_column(small_raw):
    raw = read_campaign(small_raw, fmt="raw")
    state = np.where(raw.data["alpha_true"] > 0.22, 0.1, 1.0)
    with_state = replace(raw, data=replace(raw.data, columns={**raw.data.columns, "X": state}))
    p = preprocess(with_state, stall_state="X")
    assert p.stall_alpha_source == "separation state X below 0.5" and "stall_alpha_deg" not in p.campaign.extra
    assert p.campaign.extra["stalled_flow"] == "separation state X below 0.5"
    with pytest.raises(DeclarationError, match="--stall-state Y: no such column"):
        preprocess(with_state, stall_state="Y")
    with pytest.raises(DataError, match=r"column 'V': a separation state lies in \[0, 1\]"):
        preprocess(with_state, stall_state="V")
