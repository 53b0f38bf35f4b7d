"""Units read from each maneuver file's data (structsearch.data.units): a pitch rate in deg/s, time in ms or an
airspeed in knots in one file of a campaign is one error naming that file, the column and the likely unit; the
simulated campaigns of several seeds, aircraft and formats and the pitching airfoil's phase-averaged cycles read
without a false alarm.

The ratios are checked against the unit's factor (57.3 for deg/s, 1000 for ms) within the spread the statistic
has in rad/s on the simulated campaigns: the smoothed slope of q on d(theta)/dt is 0.95-1.00 over every maneuver
kind, on d(alpha)/dt 0.62-1.23 in the stall maneuvers."""
from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from structsearch.data.campaign import read_campaign
from structsearch.data.errors import DataError

ROOT = Path(__file__).resolve().parents[1]
DEG = 180.0 / np.pi
KNOTS = 1.0 / 0.514444


def _copy(campaign, tmp_path: Path, name: str = "c") -> Path:
    target = tmp_path / name
    shutil.copytree(campaign.directory, target)
    return target


def _edit(directory: Path, files, column: str, factor: float, drop=()) -> None:
    for file in files:
        frame = pd.read_csv(directory / file)
        frame[column] = frame[column] * factor
        frame.drop(columns=[c for c in drop if c in frame]).to_csv(directory / file, index=False,
                                                                   float_format="%.17g")


def _drop_everywhere(directory: Path, column: str) -> None:
    for file in directory.glob("*.csv"):
        frame = pd.read_csv(file)
        frame.drop(columns=[column]).to_csv(file, index=False, float_format="%.17g")


def _error(directory: Path) -> DataError:
    with pytest.raises(DataError) as caught:
        read_campaign(directory)
    return caught.value


def _ratio(message: str) -> float:
    return float(re.search(r"is ([0-9.]+) \(", message)[1])


@pytest.fixture(scope="module")
def small(campaign_on_disk):
    return campaign_on_disk(0, 0.05)


def test_a_pitch_rate_in_degrees_in_one_file_is_named(small, tmp_path):
    directory = _copy(small, tmp_path)
    _edit(directory, ["m07.csv"], "q", DEG)          # a quasi-steady stall: |q| stays below 2 pi in deg/s
    error = _error(directory)
    assert error.source.endswith("m07.csv") and error.column == "q"
    assert "looks like degrees per second" in str(error) and "d(theta)/dt" in str(error)
    assert 0.9 * DEG < _ratio(str(error)) < 1.05 * DEG     # rad/s: 0.95-1.00


def test_without_theta_the_angle_of_attack_names_it(small, tmp_path):
    """Without the attitude q is compared with d(alpha)/dt; in a hand-flown quasi-steady stall the two correlate
    weakly (0.27-0.62), and the regression slope still reads the unit."""
    directory = _copy(small, tmp_path)
    _drop_everywhere(directory, "theta")
    read_campaign(directory)                          # the SI campaign without theta reads
    _edit(directory, ["m01.csv"], "q", DEG)
    error = _error(directory)
    assert error.source.endswith("m01.csv") and error.column == "q" and "d(alpha)/dt" in str(error)
    assert 0.55 * DEG < _ratio(str(error)) < 1.3 * DEG     # rad/s: 0.62-1.23


@pytest.mark.parametrize("files", [["m35.csv"], "all"])
def test_time_in_milliseconds_in_one_file_or_all(small, tmp_path, files):
    directory = _copy(small, tmp_path)
    files = [m.file for m in small.maneuvers] if files == "all" else files
    _edit(directory, files, "t", 1000.0)
    error = _error(directory)
    assert error.column == "t" and "looks like milliseconds" in str(error)
    assert Path(error.source).name in files


def test_time_in_milliseconds_at_a_fast_rate_is_read_from_the_pitch_rate(small, tmp_path):
    """1 kHz in ms is a step of 1, no slower than a real slow log: q's ratio to d(theta)/dt (1000) names it."""
    directory = _copy(small, tmp_path)
    frame = pd.read_csv(directory / "m35.csv")
    fine = np.arange(frame["t"].iloc[0], frame["t"].iloc[-1], 0.001)
    resampled = pd.DataFrame({c: np.interp(fine, frame["t"], frame[c]) for c in frame})
    resampled["t"] = fine * 1000.0
    resampled.to_csv(directory / "m35.csv", index=False, float_format="%.17g")
    error = _error(directory)
    assert error.source.endswith("m35.csv") and error.column == "t"
    assert "looks like milliseconds" in str(error) and 900 < _ratio(str(error)) < 1050


def test_a_declared_sample_rate_is_checked(small, tmp_path):
    directory = _copy(small, tmp_path)
    toml = directory / "campaign.toml"
    toml.write_text("sample_rate = 100\n" + toml.read_text())
    read_campaign(directory)                          # 100 Hz, as flown
    toml.write_text(toml.read_text().replace("sample_rate = 100", "sample_rate = 50"))
    error = _error(directory)
    assert error.column == "t" and "sample_rate = 50 Hz" in str(error)
    toml.write_text(toml.read_text().replace("sample_rate = 50", "sample_rate = -1"))
    assert _error(directory).column == "sample_rate"


@pytest.fixture(scope="module")
def nominal(campaign_on_disk):
    """A campaign whose files carry qbar, Mach and h: two channels that imply the airspeed."""
    return campaign_on_disk(0, 0.05, nominal=True)


def test_an_airspeed_in_knots_is_named_from_qbar_and_mach(nominal, tmp_path):
    directory = _copy(nominal, tmp_path)
    read_campaign(directory)
    _edit(directory, ["m38.csv"], "V", KNOTS)
    error = _error(directory)
    assert error.source.endswith("m38.csv") and error.column == "V" and "looks like knots" in str(error)
    assert "sqrt(2 qbar / the ISA density at h)" in str(error)
    _edit(directory, [m.file for m in nominal.maneuvers], "V", 1.0, drop=("qbar",))
    error = _error(directory)                         # Mach and the ISA speed of sound at h
    assert error.column == "V" and "Mach times the ISA speed of sound at h" in str(error)


def test_an_airspeed_outside_the_declared_envelope(small, tmp_path):
    """The envelope names a unit only where the file's median airspeed leaves it: a deep stall at 65 m/s is 127
    in knots, inside a Citation's 45-140 m/s, and passes (the data guide says so)."""
    directory = _copy(small, tmp_path)
    toml = directory / "campaign.toml"
    toml.write_text(toml.read_text().replace("[aircraft]\n", "[aircraft]\nV_range = [45.0, 140.0]\n"))
    read_campaign(directory)
    _edit(directory, ["m07.csv"], "V", KNOTS)      # 92 m/s, 179 in knots
    error = _error(directory)
    assert error.source.endswith("m07.csv") and error.column == "V"
    assert "looks like knots" in str(error) and "V_range [45, 140]" in str(error)
    toml.write_text(toml.read_text().replace("V_range = [45.0, 140.0]", "V_range = [140.0, 45.0]"))
    assert _error(directory).column == "V_range"


SLOW = pytest.mark.slow


@pytest.mark.parametrize("seed, options", [(1, {"extras": True}),
                                           *[pytest.param(seed, {"extras": True}, marks=SLOW) for seed in (2, 3, 8)],
                                           pytest.param(4, {"nominal": True}, marks=SLOW),
                                           pytest.param(5, {"aircraft": "transport"}, marks=SLOW),
                                           pytest.param(6, {"raw": True}, marks=SLOW),
                                           pytest.param(7, {"anomaly": "two_break_stall"}, marks=SLOW)])
def test_simulated_campaigns_read_without_a_false_alarm(campaign_on_disk, seed, options):
    """Every maneuver kind (pullups, pushovers and phugoids too), a second aircraft, a raw campaign."""
    if options.get("raw"):
        from structsearch.data.campaign import write_campaign
        from structsearch.flight.flighttest import build_campaign
        import tempfile
        with tempfile.TemporaryDirectory() as where:
            write_campaign(build_campaign(seed=seed, scale=0.05, raw=True), Path(where) / "raw")
            assert read_campaign(Path(where) / "raw", fmt="raw").maneuvers
        return
    assert campaign_on_disk(seed, 0.05, **options).maneuvers


def test_the_pitching_airfoils_cycles_read_without_a_false_alarm():
    """Phase-averaged cycles without a t column: q = d(alpha)/dt of the pitching motion, ratio 1."""
    from structsearch.data.units import rate_slope
    from structsearch.data import records
    from structsearch.data.tables import read_table
    directory = ROOT / "examples" / "openfast_ua" / "campaign"
    campaign = read_campaign(directory)
    for m in campaign.maneuvers:
        columns = records.with_cycle_time(read_table(directory / m.file), m.id, m.frequency, m.file)
        reference, slope = rate_slope(columns)
        assert reference == "alpha" and slope == pytest.approx(1.0, abs=0.15)
