"""The lateral-directional channels of a standard campaign (beta, p, r, da, dr, CY, Cl, Cn): optional, read with
their units stated (radians, rad/s, dimensionless) and checked as the longitudinal ones are: an angle in degrees or
a rate in deg/s is one error naming file, column and row. A longitudinal campaign reads as before."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from structsearch.data.campaign import read_campaign
from structsearch.data.campaign_checks import LATERAL
from structsearch.data.errors import DataError
from structsearch.engine.units import COLUMN_UNITS

sys.path.insert(0, str(Path(__file__).parent))
from airfoil_truths import TRUTHS, write_campaign  # noqa: E402


def _with_lateral(directory: Path, degrees: str | None = None, row: int = 7) -> None:
    """Every maneuver file of ``directory`` with the lateral channels (a gentle Dutch roll); ``degrees``: one
    channel of the first file given in degrees (or deg/s) from ``row`` on."""
    rng = np.random.default_rng(5)
    for k, f in enumerate(sorted(directory.glob("*.csv"))):
        lines = f.read_text(encoding="utf-8").splitlines()
        t = np.array([float(line.split(",")[0]) for line in lines[1:]])
        beta = 0.03 * np.sin(2.1 * t)
        values = {"beta": beta, "p": 0.06 * np.cos(2.1 * t), "r": -0.05 * np.cos(2.1 * t),
                  "da": 0.02 * np.sin(0.7 * t), "dr": -0.01 * np.sin(0.9 * t), "CY": -0.6 * beta,
                  "Cl": -0.08 * beta + rng.normal(0, 1e-4, len(t)), "Cn": 0.1 * beta}
        if degrees is not None and k == 0:
            values[degrees] = np.where(np.arange(len(t)) >= row, np.degrees(values[degrees]) * 100, values[degrees])
        lines[0] += "," + ",".join(LATERAL)
        lines[1:] = [line + "," + ",".join(f"{values[c][i]:.9g}" for c in LATERAL) for i, line in enumerate(lines[1:])]
        f.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_lateral_channels_are_read_with_their_units(tmp_path):
    data = write_campaign(TRUTHS["symmetric"], tmp_path / "c", seed=3)
    plain = read_campaign(data).data
    _with_lateral(data)
    campaign = read_campaign(data)
    assert set(LATERAL) <= set(campaign.data.columns)
    np.testing.assert_array_equal(campaign.data["CL"], plain["CL"])     # the longitudinal columns unchanged
    assert all(c in COLUMN_UNITS for c in LATERAL)
    assert COLUMN_UNITS["beta"] == {"rad": 1} and COLUMN_UNITS["p"] == {"rad": 1, "s": -1} and COLUMN_UNITS["Cl"] == {}


@pytest.mark.parametrize("channel, words", [("beta", "looks like degrees"), ("da", "looks like degrees"),
                                            ("dr", "looks like degrees"), ("p", "looks like degrees per second"),
                                            ("r", "looks like degrees per second")])
def test_a_lateral_channel_in_degrees_is_one_error_naming_file_column_and_row(tmp_path, channel, words):
    data = write_campaign(TRUTHS["symmetric"], tmp_path / "c", seed=3)
    _with_lateral(data, degrees=channel, row=7)
    with pytest.raises(DataError) as err:
        read_campaign(data)
    assert err.value.column == channel and words in str(err.value) and ".csv" in str(err.value)
    assert err.value.row is not None and err.value.row >= 7
