"""Campaign I/O: round trips and one clear error per kind of bad input."""
import numpy as np
import pytest

from structsearch.data.campaign import Maneuver, make_campaign, read_campaign, write_campaign
from structsearch.data.errors import DataError

AIRCRAFT = {"S": 30.0, "cbar": 2.013, "b": 15.75}


def _maneuver(n=400, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    return {"t": t, "alpha": 0.1 + 0.05 * np.sin(t), "q": 0.01 * np.cos(t), "V": 80 + rng.normal(0, 0.1, n),
            "de": -0.05 + 0.01 * np.sin(2 * t), "CL": 0.6 + 0.1 * np.sin(t), "CD": 0.05 + 0 * t,
            "Cm": 0.001 * np.cos(t), "CT": 0.03 + 0 * t, "x_cg": 7.1 + 0 * t}


@pytest.fixture()
def campaign():
    maneuvers = [Maneuver("m01", "m01.csv", "quasi-steady", "train"),
                 Maneuver("m02", "m02.csv", "dynamic", "validation")]
    return make_campaign("test", AIRCRAFT, maneuvers, [_maneuver(seed=1), _maneuver(500, seed=2)])


def test_csv_round_trip_is_identical(campaign, tmp_path):
    write_campaign(campaign, tmp_path / "c")
    back = read_campaign(tmp_path / "c")
    assert back.maneuvers == campaign.maneuvers
    assert back.aircraft == AIRCRAFT
    assert set(back.data.columns) == set(campaign.data.columns)
    for k, v in campaign.data.columns.items():
        assert np.array_equal(back.data[k], v), k
    assert back.split("validation").names == ("m02",)


def test_parquet_round_trip(campaign, tmp_path):
    pytest.importorskip("pyarrow")
    write_campaign(campaign, tmp_path / "c", fmt="parquet")
    back = read_campaign(tmp_path / "c")
    for k, v in campaign.data.columns.items():
        assert np.array_equal(back.data[k], v), k


def test_rewrite_replaces_atomically(campaign, tmp_path, monkeypatch):
    """Issue 13: rewriting swaps the old and the new directory in one step (Linux renameat2), so the
    campaign exists at every moment; the two-rename fallback is never needed here."""
    import sys
    import structsearch.data.campaign_write as cmod
    write_campaign(campaign, tmp_path / "c")
    if sys.platform.startswith("linux"):
        def no_window(*args):
            raise AssertionError(f"os.replace{args}: a window without the campaign")
        monkeypatch.setattr(cmod.os, "replace", no_window)
    write_campaign(campaign, tmp_path / "c")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c"]
    assert read_campaign(tmp_path / "c").data.n_samples == campaign.data.n_samples


def test_exchange_directories_swaps_contents(tmp_path):
    import sys
    from structsearch.data.atomic import exchange_directories
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "x").write_text("new")
    (tmp_path / "b" / "y").write_text("old")
    done = exchange_directories(tmp_path / "a", tmp_path / "b")
    assert done == sys.platform.startswith("linux")
    if done:
        assert [p.name for p in (tmp_path / "b").iterdir()] == ["x"]
        assert [p.name for p in (tmp_path / "a").iterdir()] == ["y"]


@pytest.mark.parametrize("as_struct", [False, True])
def test_matlab_maneuver_files(tmp_path, as_struct):
    from scipy.io import savemat
    cols = _maneuver()
    (tmp_path / "campaign.toml").write_text(
        'name = "mat"\n[aircraft]\nS = 30.0\ncbar = 2.013\nb = 15.75\n'
        '[[maneuver]]\nid = "a"\nfile = "a.mat"\nkind = "other"\nsplit = "train"\n')
    savemat(tmp_path / "a.mat", {"flight": cols} if as_struct else {k: v[:, None] for k, v in cols.items()})
    back = read_campaign(tmp_path)
    assert np.allclose(back.data["alpha"], cols["alpha"])
    assert "alpha_dot" in back.data  # derived


def _write(tmp_path, columns, manifest_extra="", name="m.csv", kind="quasi-steady", split="train"):
    import pandas as pd
    pd.DataFrame(columns).to_csv(tmp_path / name, index=False)
    (tmp_path / "campaign.toml").write_text(
        f'name = "x"\n{manifest_extra}[aircraft]\nS = 30.0\ncbar = 2.013\nb = 15.75\n'
        f'[[maneuver]]\nid = "m"\nfile = "{name}"\nkind = "{kind}"\nsplit = "{split}"\n')


def test_misspelled_column(tmp_path):
    cols = _maneuver()
    cols["Alpha"] = cols.pop("alpha")
    _write(tmp_path, cols)
    with pytest.raises(DataError, match=r"m.csv, column 'alpha': required column is missing \(found 'Alpha'"):
        read_campaign(tmp_path)


def test_nan_names_file_column_row_and_line(tmp_path):
    cols = _maneuver()
    cols["V"][123] = np.nan
    _write(tmp_path, cols)
    with pytest.raises(DataError, match=r"m.csv, column 'V', row 123: value is NaN or infinite \(line 125\)"):
        read_campaign(tmp_path)


def test_text_in_numeric_column(tmp_path):
    cols = {k: list(v) for k, v in _maneuver().items()}
    cols["q"][7] = "n/a?"
    _write(tmp_path, cols)
    with pytest.raises(DataError, match=r"column 'q', row 7: value 'n/a\?' is not a number"):
        read_campaign(tmp_path)


def test_non_increasing_time(tmp_path):
    cols = _maneuver()
    cols["t"][50] = cols["t"][49]
    _write(tmp_path, cols)
    with pytest.raises(DataError, match=r"column 't', row 50: time is not strictly increasing"):
        read_campaign(tmp_path)


def test_degrees_detected(tmp_path):
    cols = _maneuver()
    cols["alpha"] = np.rad2deg(cols["alpha"])
    _write(tmp_path, cols)
    with pytest.raises(DataError, match=r"column 'alpha', row \d+: value .* looks like degrees"):
        read_campaign(tmp_path)


def test_too_short(tmp_path):
    """Issue 30: too short is measured in convective times cbar/V (structsearch.data.records), not seconds: 0.5 s at
    80 m/s with cbar 2.013 m is 19.9 of them, below the rule's 30."""
    _write(tmp_path, _maneuver(n=51))
    with pytest.raises(DataError, match=r"m.csv, column 't': maneuver is too short to fit separation dynamics: 51 "
                                        r"samples over 0.5 s = 19.9 convective times cbar/V .* at least 20 samples "
                                        r"and 30 convective times"):
        read_campaign(tmp_path)


@pytest.mark.parametrize("field,value,message", [
    ("kind", "barrel-roll", "unknown kind 'barrel-roll'"),
    ("split", "test", "unknown split 'test'"),
])
def test_unknown_kind_or_split(tmp_path, field, value, message):
    _write(tmp_path, _maneuver(), **{field: value})
    with pytest.raises(DataError, match=rf"\[\[maneuver\]\] #1, column '{field}': {message}"):
        read_campaign(tmp_path)


def test_missing_manifest_and_file(tmp_path):
    with pytest.raises(DataError, match="campaign.toml not found"):
        read_campaign(tmp_path)
    _write(tmp_path, _maneuver())
    (tmp_path / "m.csv").unlink()
    with pytest.raises(DataError, match="maneuver file not found"):
        read_campaign(tmp_path)


def test_duplicate_ids(tmp_path):
    _write(tmp_path, _maneuver())
    text = (tmp_path / "campaign.toml").read_text()
    (tmp_path / "campaign.toml").write_text(text + '[[maneuver]]\nid = "m"\nfile = "m.csv"\nkind = "other"\n'
                                            'split = "train"\n')
    with pytest.raises(DataError, match="appears twice"):
        read_campaign(tmp_path)


def test_no_validation_maneuvers(tmp_path):
    _write(tmp_path, _maneuver())
    with pytest.raises(DataError, match="no validation maneuvers"):
        read_campaign(tmp_path).split("validation")


@pytest.mark.parametrize("aircraft,message", [
    ("S = nan\ncbar = 2.0\nb = 15.0\n", "positive finite number S"),
    ("S = 30.0\ncbar = inf\nb = 15.0\n", "positive finite number cbar"),
    ("S = 30.0\ncbar = 2.0\nb = 15.0\nIyy = -1.0\n", "Iyy must be a positive finite number"),
    ("S = 30.0\ncbar = 2.0\nb = 15.0\nx_cg_range = [7.3, 7.0]\n", "forward < aft"),
    ("S = 30.0\ncbar = 2.0\nb = 15.0\naccelerometer = [0.1, 0.0]\n", "list of 3 finite numbers"),
    ("S = 30.0\ncbar = 2.0\nb = 15.0\nIyyy = 3.0\n", "unknown key 'Iyyy'"),
])
def test_aircraft_data_is_checked(tmp_path, aircraft, message):
    """Issues 12 and 13: the optional aircraft data of interfaces.md 5.1 and the required S, cbar, b are
    validated with one clear error naming the key (a NaN or infinite value is never accepted)."""
    t = np.arange(0, 4, 0.01)
    _write(tmp_path, {"t": t, "alpha": 0.1 + 0 * t, "q": 0 * t, "V": 80 + 0 * t, "de": 0 * t, "CL": 0 * t,
                      "CD": 0 * t, "Cm": 0 * t})
    text = (tmp_path / "campaign.toml").read_text()
    text = text.replace("S = 30.0\ncbar = 2.013\nb = 15.75\n", aircraft)
    (tmp_path / "campaign.toml").write_text(text)
    with pytest.raises(DataError, match=message):
        read_campaign(tmp_path)


def test_aircraft_data_round_trips(tmp_path):
    """The simulator's inertia and cg envelope are written to campaign.toml and read back; only numbers
    become constants a regressor may name."""
    from structsearch.flight.flighttest import build_campaign
    written = write_campaign(build_campaign(seed=2, scale=0.05), tmp_path / "c")
    back = read_campaign(written)
    # Iyy at the mean test mass: empty-mass inertia + 0.9 m^2 per kg of crew (255 kg) and mean fuel (975 kg)
    assert back.aircraft["x_cg_range"] == pytest.approx((7.0104, 7.2644))
    assert back.aircraft["Iyy"] == pytest.approx(31501.0 + 0.9 * (255.0 + 975.0))
    assert "x_cg_range" not in back.data.constants and back.data.constants["Iyy"] == back.aircraft["Iyy"]


# ----- issue 13: every bad input one clear error ------------------------------------------------------
def _rewrite(path, edit):
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(edit(lines)))


def test_blank_lines_do_not_shift_the_reported_line(tmp_path):
    cols = _maneuver()
    cols["V"][123] = np.nan
    _write(tmp_path, cols)
    _rewrite(tmp_path / "m.csv", lambda lines: lines[:10] + ["\n", "\n"] + lines[10:])
    with pytest.raises(DataError, match=r"row 123: value is NaN or infinite \(line 127\)"):
        read_campaign(tmp_path)


def test_header_only_file_and_empty_file(tmp_path):
    _write(tmp_path, _maneuver())
    _rewrite(tmp_path / "m.csv", lambda lines: lines[:1])
    with pytest.raises(DataError, match=r"m.csv, column 't': maneuver has 0 samples"):
        read_campaign(tmp_path)
    (tmp_path / "m.csv").write_text("")
    with pytest.raises(DataError, match=r"m.csv: cannot read CSV"):
        read_campaign(tmp_path)


def test_header_with_spaces_is_named(tmp_path):
    _write(tmp_path, _maneuver())
    _rewrite(tmp_path / "m.csv", lambda lines: [lines[0].replace("alpha", " alpha")] + lines[1:])
    with pytest.raises(DataError, match=r"column 'alpha': required column is missing \(found ' alpha'"):
        read_campaign(tmp_path)


def test_non_positive_airspeed(tmp_path):
    cols = _maneuver()
    cols["V"][40] = 0.0
    _write(tmp_path, cols)
    with pytest.raises(DataError, match=r"column 'V', row 40: airspeed 0 m/s is not positive \(line 42\)"):
        read_campaign(tmp_path)


def test_corrupt_parquet(tmp_path):
    _write(tmp_path, _maneuver(), name="m.parquet")
    (tmp_path / "m.parquet").write_bytes(b"PAR1 not really")
    with pytest.raises(DataError, match=r"m.parquet: cannot read Parquet"):
        read_campaign(tmp_path)


def test_writing_a_campaign_never_replaces_another_directory(campaign, tmp_path):
    """`simulate --out .` must not swap away a directory that is not a campaign."""
    (tmp_path / "notes.txt").write_text("keep me")
    with pytest.raises(DataError, match="refusing to replace it: it exists and is not a campaign directory"):
        write_campaign(campaign, tmp_path)
    assert (tmp_path / "notes.txt").read_text() == "keep me"


def test_a_quoted_field_gives_no_wrong_line_number(tmp_path):
    """Line numbers are given only when the file's lines match the rows one to one."""
    cols = _maneuver()
    cols["V"][200] = np.nan
    _write(tmp_path, cols)
    _rewrite(tmp_path / "m.csv", lambda lines: lines[:5] + [lines[5].replace(lines[5].split(",")[0],
                                                                              '"' + lines[5].split(",")[0] + '"', 1)]
             + lines[6:])
    with pytest.raises(DataError) as info:
        read_campaign(tmp_path)
    assert "row 200" in str(info.value) and "line" not in str(info.value)
