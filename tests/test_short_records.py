"""Issue 30, item 7: few or short records. The shortest maneuver in convective times cbar/V, a periodic record cut
into its cycles (``--segment cycles``, a ``cycle`` column), cross-validation and covariance on one or two long
records (structsearch.data.records, structsearch.fitting.folds)."""
import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.data.errors import DataError
from structsearch.data.flightdata import from_segments
from structsearch.data.records import MIN_CONVECTIVE_TIMES, MIN_SAMPLES, LengthRule, troughs
from structsearch.fitting.folds import fold_size_for, plan_folds
from structsearch.fitting.models import build_model
from structsearch.fitting.specs import load_grid
from structsearch.flight.synthetic import ar1_noise, pitching_airfoil

from conftest import run_cli

# a pitching airfoil in a wind tunnel: cbar 0.5 m at 38.5 m/s (cbar/V = 0.013 s), 0.83 s cycles at 1 kHz
CBAR, V, PERIOD = 0.5, 38.5, 0.83
TRUTH = {"tau1": 0.06, "tau2": 0.02, "a1": 25.0, "a_star": 0.30, "CL0": 0.05, "CL_KL": 5.5}
SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _run(cycles: float, seed: int, phase: float = -np.pi / 2, period: float = PERIOD) -> dict:
    """One wind-tunnel run (from an alpha minimum by default) with C_L of CL-II and AR(1) noise: t, alpha, q, V,
    de, CL (no CD or Cm: a lift fit needs only C_L)."""
    cols = pitching_airfoil(cycles=cycles, period=period, airspeed=V, phase=phase, alpha_noise=0.0005, seed=seed)
    data = from_segments([cols], names=["run"], constants={"cbar": CBAR})
    cl = build_model(load_grid("lift")["CL-II"]).predict(data, TRUTH)
    cols["CL"] = cl + ar1_noise(np.random.default_rng(seed + 100), len(cl), 0.9, 0.02)
    del cols["alpha_dot"]   # derived by the reader, as from a real file
    return cols


def _wind_tunnel(path, runs=(("run1", 4.0, "train"), ("run2", 2.0, "validation")), extra="", entry=""):
    """A campaign of wind-tunnel runs (one training run of four cycles by default) written to ``path``."""
    path.mkdir(parents=True, exist_ok=True)
    text = f'name = "pitching airfoil"\n{extra}[aircraft]\nS = 0.5\ncbar = {CBAR}\nb = 1.0\n'
    for i, (name, cycles, split) in enumerate(runs):
        cols = _run(cycles, seed=i + 1) if not isinstance(cycles, dict) else cycles
        pd.DataFrame(cols).to_csv(path / f"{name}.csv", index=False, float_format="%.10g")
        text += (f'[[maneuver]]\nid = "{name}"\nfile = "{name}.csv"\nkind = "dynamic"\nsplit = "{split}"\n'
                 f"{entry}")
    (path / "campaign.toml").write_text(text)
    return path


def _steady(n, dt, airspeed, kind="quasi-steady"):
    t = np.arange(n) * dt
    return {"t": t, "alpha": 0.1 + 0.02 * np.sin(t), "q": 0.02 * np.cos(t), "V": np.full(n, airspeed),
            "de": np.zeros(n), "CL": 0.5 + 0 * t}


def _one(path, columns, cbar=2.013, kind="quasi-steady", extra=""):
    path.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(columns).to_csv(path / "m.csv", index=False, float_format="%.17g")
    (path / "campaign.toml").write_text(
        f'name = "x"\n{extra}[aircraft]\nS = 30.0\ncbar = {cbar!r}\nb = 15.75\n'
        f'[[maneuver]]\nid = "m"\nfile = "m.csv"\nkind = "{kind}"\nsplit = "train"\n')
    return path


# ----- rule 1: the shortest maneuver in convective times ---------------------------------------------------
def test_the_shortest_maneuver_is_counted_in_convective_times(tmp_path):
    """1 s at 80 m/s (cbar 2.013 m: 39.7 convective times) reads, though the old rule asked for 2 s; the same
    second at 30 m/s (14.9 convective times) is one error naming file, column and the rule; a wind-tunnel cycle
    (0.83 s at cbar/V = 0.013 s: 64 convective times) reads; a handful of samples does not."""
    assert read_campaign(_one(tmp_path / "a", _steady(101, 0.01, 80.0))).data.n_samples == 101
    with pytest.raises(DataError, match=r"m.csv, column 't': maneuver is too short to fit separation dynamics: 101 "
                                        r"samples over 1 s = 14.9 convective times cbar/V \(cbar/V = 0.0671 s at its "
                                        r"mean airspeed 30 m/s\); the rule asks for at least 20 samples and 30 "
                                        r"convective times \(2.01 s here"):
        read_campaign(_one(tmp_path / "b", _steady(101, 0.01, 30.0)))
    cycle = _run(1.0, seed=3)
    assert read_campaign(_one(tmp_path / "c", cycle, cbar=CBAR)).data.n_samples == 830
    with pytest.raises(DataError, match="maneuver has 8 samples; it needs at least 20"):
        read_campaign(_one(tmp_path / "d", {k: v[:8] for k, v in cycle.items()}, cbar=CBAR))
    # a wind-tunnel cycle at 0.83 s would have been rejected by a rule of two seconds, a 0.3 s one is too short
    assert LengthRule().problem(cycle["t"], cycle["V"], CBAR) is None
    assert "23.1 convective times" in LengthRule().problem(cycle["t"][:301], cycle["V"][:301], CBAR)


@settings(max_examples=40, **SETTINGS)
@given(cbar=st.floats(0.1, 5.0), airspeed=st.floats(10.0, 250.0), dt=st.floats(1e-3, 0.05),
       n=st.integers(5, 400))
def test_a_maneuver_reads_exactly_when_it_meets_the_rule(tmp_path_factory, cbar, airspeed, dt, n):
    duration = (n - 1) * dt
    times = duration / (cbar / airspeed)
    if abs(times / MIN_CONVECTIVE_TIMES - 1.0) < 1e-6:
        return   # on the edge: rounding decides
    path = _one(tmp_path_factory.mktemp("rule"), _steady(n, dt, airspeed), cbar=cbar)
    if n >= MIN_SAMPLES and times >= MIN_CONVECTIVE_TIMES:
        assert read_campaign(path).data.n_samples == n
    else:
        with pytest.raises(DataError) as info:
            read_campaign(path)
        message = str(info.value)
        assert "m.csv" in message and "column 't'" in message and "to fit separation dynamics" in message


def test_the_rule_per_kind_from_campaign_toml(tmp_path):
    """campaign.toml's min_convective_times: a number for every kind or a table by kind; it is checked and
    written back."""
    short = _steady(101, 0.01, 30.0)   # 14.9 convective times
    assert read_campaign(_one(tmp_path / "a", short, extra="min_convective_times = 10\n")).data.n_samples == 101
    table = "[min_convective_times]\ndynamic = 10\n"
    back = read_campaign(_one(tmp_path / "b", short, kind="dynamic", extra=table))
    assert back.length_rules.for_kind("dynamic").min_convective_times == 10.0
    assert back.length_rules.for_kind("quasi-steady").min_convective_times == MIN_CONVECTIVE_TIMES
    assert read_campaign(write_campaign(back, tmp_path / "written")).length_rules == back.length_rules
    with pytest.raises(DataError, match="14.9 convective times"):
        read_campaign(_one(tmp_path / "c", short, kind="quasi-steady", extra=table))
    with pytest.raises(DataError, match=r"campaign.toml, column 'barrel-roll': \[min_convective_times\] has an "
                                        r"unknown kind"):
        read_campaign(_one(tmp_path / "d", short, extra="[min_convective_times]\nbarrel-roll = 3\n"))
    with pytest.raises(DataError, match="min_convective_times must be a number >= 0"):
        read_campaign(_one(tmp_path / "e", short, extra='min_convective_times = "many"\n'))


# ----- rule 2: a periodic record cut into its cycles ---------------------------------------------------------
def test_a_run_of_four_cycles_becomes_four_maneuvers(tmp_path):
    path = _wind_tunnel(tmp_path / "wt")
    whole = read_campaign(path)
    assert [m.id for m in whole.maneuvers] == ["run1", "run2"]
    cut = read_campaign(path, segment="cycles")
    assert [m.id for m in cut.maneuvers] == ["run1.c1", "run1.c2", "run1.c3", "run1.c4", "run2.c1", "run2.c2"]
    assert [m.split for m in cut.maneuvers] == ["train"] * 4 + ["validation"] * 2
    assert {m.record for m in cut.maneuvers} == {"run1", "run2"} and {m.kind for m in cut.maneuvers} == {"dynamic"}
    assert cut.data.n_samples == whole.data.n_samples   # no sample dropped
    lengths = [s.stop - s.start for s in cut.data.segment_slices()]
    assert all(abs(n - 830) <= 8 for n in lengths), lengths
    # each cycle starts at a minimum of alpha (the flow attached and alpha still: the states' restart costs least)
    alpha = cut.data["alpha"]
    for s in cut.data.segment_slices()[1:4]:
        assert alpha[s.start] < np.mean(alpha) - 0.99 * 0.17
    # the per-maneuver key does the same; --segment none overrides it
    keyed = _wind_tunnel(tmp_path / "keyed", entry='segment = "cycles"\n')
    assert len(read_campaign(keyed).maneuvers) == 6 and len(read_campaign(keyed, segment="none").maneuvers) == 2
    # the cut campaign round-trips: its maneuvers keep their record and are not cut again
    back = read_campaign(write_campaign(cut, tmp_path / "written"), segment="cycles")
    assert [(m.id, m.record) for m in back.maneuvers] == [(m.id, m.record) for m in cut.maneuvers]
    # in memory as on disk
    from structsearch.data.cycles import segmented
    assert [m.id for m in segmented(whole, "cycles").maneuvers] == [m.id for m in cut.maneuvers]


@settings(max_examples=25, **SETTINGS)
@given(cycles=st.floats(2.0, 6.0), phase=st.floats(0.0, 2 * np.pi), period=st.floats(0.5, 1.5))
def test_cycles_from_alpha_cover_the_record_one_period_each(cycles, phase, period):
    cols = pitching_airfoil(cycles=cycles, period=period, phase=phase, alpha_noise=0.001, seed=1)
    from structsearch.data.records import cycles_from_alpha
    found = cycles_from_alpha(cols["t"], cols["alpha"], "m.csv", "m").cycles
    assert found[0].start == 0 and found[-1].stop == len(cols["t"])
    assert all(a.stop == b.start for a, b in zip(found[:-1], found[1:]))
    dt = cols["t"][1]
    interior = [(c.stop - c.start) * dt for c in found[1:-1]]
    assert all(abs(d / period - 1.0) < 0.02 for d in interior), interior
    assert abs(len(found) - cycles) <= 1


@settings(max_examples=30, **SETTINGS)
@given(runs=st.lists(st.integers(700, 1200), min_size=1, max_size=5), first=st.integers(0, 3))
def test_a_cycle_column_names_the_cycles(tmp_path_factory, runs, first):
    n = sum(runs)
    cols = _steady(n, 1e-3, V)
    cols["cycle"] = np.repeat(np.arange(first, first + len(runs)), runs).astype(float)
    path = _one(tmp_path_factory.mktemp("col"), cols, cbar=CBAR)
    cut = read_campaign(path)   # a cycle column cuts the record without being asked
    assert [m.id for m in cut.maneuvers] == [f"m.c{first + i}" for i in range(len(runs))]
    assert [s.stop - s.start for s in cut.data.segment_slices()] == runs and "cycle" not in cut.data
    assert [m.id for m in read_campaign(path, segment="none").maneuvers] == ["m"]


def test_a_bad_cycle_column_is_one_error_naming_the_row(tmp_path):
    cols = _steady(3000, 1e-3, V)
    cols["cycle"] = np.repeat([1.0, 2.0, 1.0], 1000)
    with pytest.raises(DataError, match=r"m.csv, column 'cycle', row 2000: record 'm': cycle 1 appears again after "
                                        r"other cycles"):
        read_campaign(_one(tmp_path / "a", cols, cbar=CBAR))
    cols["cycle"] = np.repeat([1.0, 2.5, 3.0], 1000)
    with pytest.raises(DataError, match=r"column 'cycle', row 1000: record 'm': cycle 2.5 is not a whole number"):
        read_campaign(_one(tmp_path / "b", cols, cbar=CBAR))


def test_cutting_as_read_and_cutting_in_memory_give_the_same_data(tmp_path):
    # alpha_dot from the whole record in both: derived per cycle it would be one-sided at every cut, exactly
    # where the separation states restart
    from structsearch.data.cycles import segmented
    path = _wind_tunnel(tmp_path / "wt")   # no alpha_dot column: the reader derives it
    as_read = read_campaign(path, segment="cycles")
    in_memory = segmented(read_campaign(path), "cycles")
    assert as_read.data.names == in_memory.data.names
    for column in ("alpha", "alpha_dot", "t"):
        np.testing.assert_array_equal(as_read.data[column], in_memory.data[column])


def test_segment_none_joins_written_cycles_back_into_their_records(tmp_path):
    """A campaign written as cycles (each names its record) stays cut when read again; --segment none joins each
    record's cycles back into one maneuver, equal to the record over the rows the cycles cover. Cycles that do not
    follow one another are one error naming the record."""
    import shutil
    path = _wind_tunnel(tmp_path / "wt")
    cut = read_campaign(path, segment="cycles")
    written = write_campaign(cut, tmp_path / "written")
    again = read_campaign(written)
    assert again.data.names == cut.data.names and all(m.record for m in again.maneuvers)
    joined = read_campaign(written, segment="none")
    assert joined.data.names == ("run1", "run2") and not any(m.record for m in joined.maneuvers)
    assert [m.split for m in joined.maneuvers] == ["train", "validation"]
    assert joined.data.n_samples == cut.data.n_samples
    for column in ("t", "alpha", "alpha_dot", "CL"):
        np.testing.assert_allclose(joined.data[column], cut.data[column], rtol=1e-9, atol=1e-12)
    whole = read_campaign(path)
    first = whole.data.segment_slices()[0]
    t_whole, t_joined = whole.data["t"][first], joined.data["t"][joined.data.segment_slices()[0]]
    a = int(np.searchsorted(t_whole, t_joined[0] - 1e-9))
    np.testing.assert_allclose(t_joined, t_whole[a:a + len(t_joined)], rtol=1e-9)
    # a cycle removed from the written campaign: its neighbours no longer follow one another
    broken = tmp_path / "broken"
    shutil.copytree(written, broken)
    toml = (broken / "campaign.toml").read_text()
    entries = toml.split("[[maneuver]]")
    (broken / "campaign.toml").write_text("[[maneuver]]".join(entries[:2] + entries[3:]))
    with pytest.raises(DataError, match=r"--segment none: the cycles of record 'run1' do not follow one another"):
        read_campaign(broken, segment="none")


def test_a_cycle_too_short_is_an_error_naming_the_record_and_the_cycle(tmp_path):
    """Never dropped: a named cycle of 0.2 s (15 convective times), and a record whose cycles from alpha last 0.3 s
    each (23 convective times), are errors naming the file, the record, the cycle and its first row."""
    cols = _steady(2200, 1e-3, V)
    cols["cycle"] = np.repeat([1.0, 2.0, 3.0], [1000, 200, 1000])
    with pytest.raises(DataError, match=r"m.csv, column 't', row 1000: cycle c2 of record 'm' \(rows 1000-1199, line "
                                        r"1002, found by its cycle column\) is too short to fit separation dynamics: "
                                        r"200 samples over 0.199 s = 15.3 convective times"):
        read_campaign(_one(tmp_path / "a", cols, cbar=CBAR))
    fast = _run(4.0, seed=5, period=0.3)
    with pytest.raises(DataError, match=r"column 't', row 0: cycle c1 of record 'run1' \(rows 0-\d+, line 2, found "
                                        r"by alpha\) is too short to fit separation dynamics: \d+ samples over 0.\d+ "
                                        r"s = 2\d(\.\d)? convective times"):
        read_campaign(_wind_tunnel(tmp_path / "b", runs=(("run1", fast, "train"),)), segment="cycles")


def test_a_record_that_is_not_periodic_is_not_cut(tmp_path):
    rng = np.random.default_rng(4)
    cols = _steady(5000, 1e-3, V)
    cols["alpha"] = 0.2 + np.cumsum(rng.normal(0, 0.002, 5000))   # a random walk
    with pytest.raises(DataError, match=r"column 'alpha'.*record 'm': alpha (does not look periodic|never falls|"
                                        r"completes fewer)"):
        read_campaign(_one(tmp_path / "a", cols, cbar=CBAR), segment="cycles")
    assert troughs(np.full(10, 0.1)).size == 0


# ----- rule 3: cross-validation and covariance with few records -------------------------------------------------
def test_fold_plans_for_few_records(tmp_path):
    cut = read_campaign(_wind_tunnel(tmp_path / "wt"), segment="cycles")
    train = cut.split("train")
    assert fold_size_for(cut.maneuvers) == 1
    plan = plan_folds(train, 5, fold_size_for(cut.maneuvers))
    assert plan.scheme == "maneuvers" and plan.folds == ((0,), (1,), (2,), (3,))
    # the same four as flight-test maneuvers (a fold keeps three, so that it keeps every kind): no folds, and why
    assert plan_folds(train, 5, 3).scheme == "none"
    three = from_segments([_steady(3000, 0.01, 80.0)] * 3, names=["a", "b", "c"], constants={"cbar": 2.013})
    none = plan_folds(three, 5, 3)
    assert none.scheme == "none" and "fewer than two folds of 3" in none.note and not none.folds
    # one long record: five blocked folds, the j-th block of every record held out
    whole = read_campaign(tmp_path / "wt").split("train")
    blocks = plan_folds(whole, 5)
    assert blocks.scheme == "blocks" and blocks.n_folds == 5 and len(blocks.units) == 5
    assert blocks.units[0][0] == 0 and blocks.units[-1][1] == whole.n_samples
    two = from_segments([_steady(2000, 0.01, 80.0), _steady(3000, 0.01, 80.0)], names=["a", "b"],
                        constants={"cbar": 2.013})
    assert plan_folds(two, 5).folds == tuple((j, 5 + j) for j in range(5))
    # too short for two blocks of the rule: no cross-validation, with the reason
    short = from_segments([_steady(500, 1e-3, V)], names=["a"], constants={"cbar": CBAR})   # 38 cbar/V
    plan = plan_folds(short, 5)
    assert plan.scheme == "none" and "too short for two blocks" in plan.note
    assert plan_folds(whole, 0).note == "no cross-validation asked (0 folds)"


def test_blocked_folds_last_the_campaigns_own_shortest_maneuver(tmp_path):
    """campaign.toml's min_convective_times sets the shortest block of a blocked fold, as it sets the shortest
    maneuver: the four-cycle run (about 256 cbar/V) holds five blocks of the default 30 cbar/V, two of 100."""
    import structsearch
    short = from_segments([_steady(500, 1e-3, V)], names=["a"], constants={"cbar": CBAR})   # 38 cbar/V
    assert plan_folds(short, 5, 3, block_convective_times=15.0).n_folds == 2
    assert plan_folds(short, 5, 3, block_convective_times=0.0).n_folds == 5   # the sample rule alone
    default = structsearch.fit(_wind_tunnel(tmp_path / "default"), "CL-II", settings=structsearch.Settings(starts=1)).to_dict()
    own = structsearch.fit(_wind_tunnel(tmp_path / "own", extra="min_convective_times = 100\n"), "CL-II",
                           settings=structsearch.Settings(starts=1)).to_dict()
    assert default["cross_validation"]["folds"] == 5
    assert own["cross_validation"]["scheme"] == "blocks" and own["cross_validation"]["folds"] == 2


def test_a_blocked_fold_flies_the_states_over_the_whole_record():
    """Noise-free C_L of CL-II: every blocked fold recovers the truth from the other blocks, so the held-out
    residuals vanish. A fold fitted on the kept pieces as maneuvers of their own would restart its states at the
    pieces' edges and miss."""
    from structsearch.fitting.cross_validation import cross_validate
    cols = pitching_airfoil(cycles=4.0, airspeed=V, phase=-np.pi / 2)
    data = from_segments([cols], names=["run"], constants={"cbar": CBAR})
    model = build_model(load_grid("lift")["CL-II"])
    data = from_segments([{**cols, "CL": model.predict(data, TRUTH)}], names=["run"], constants={"cbar": CBAR})
    result = model.fit(data)   # from the default start: the folds start from the full fit, wherever it ended
    plan = plan_folds(data, 5)
    held = cross_validate(model, data, result, plan)
    assert plan.scheme == "blocks" and np.max(np.abs(held)) < 1e-6


def test_fit_on_one_record_has_blocked_cross_validation_and_states_its_few_dof(tmp_path):
    import structsearch
    fitted = structsearch.fit(_wind_tunnel(tmp_path / "wt"), "CL-II", settings=structsearch.Settings(starts=1))
    doc = fitted.to_dict()
    assert doc["cross_validation"]["scheme"] == "blocks" and doc["cross_validation"]["folds"] == 5
    assert math.isfinite(doc["mse"]["cv"]) and doc["mse"]["cv"] < 1.5 * doc["mse"]["train"]
    cov = doc["covariance"]
    assert cov["groups"] == 1 and set(cov["reference_dof"].values()) == {1.0}
    assert cov["few_maneuvers"] == list(doc["params"]) and "--segment cycles" in cov["note"]
    # the same campaign in memory, cut by the API
    cut = structsearch.fit(read_campaign(tmp_path / "wt"), "CL-II", settings=structsearch.Settings(starts=1, segment="cycles"))
    assert cut.result.cv_scheme == "maneuvers" and cut.result.cv_folds == 4 and cut.result.estimates.n_maneuvers == 4


def test_cli_fit_of_a_pitching_airfoil_cut_into_cycles(tmp_path):
    """The issue's case: one training run of four cycles at cbar/V = 0.013 s and 1 kHz, `fit --segment cycles`:
    four maneuvers, leave-one-cycle-out cross-validation with a finite MSE, the covariance's groups and every
    parameter's reference dof stated (and flagged: fewer than five)."""
    path = _wind_tunnel(tmp_path / "wt")
    proc = run_cli("fit", "--data", path, "--model", "CL-II", "--segment", "cycles", "--out", tmp_path / "out",
                   timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "4-fold CV" in proc.stdout and "on few maneuvers" in proc.stdout
    doc = json.loads((tmp_path / "out" / "fit.json").read_text())
    assert doc["mse"]["cv_folds"] == 4 and math.isfinite(doc["mse"]["cv"])
    assert doc["cross_validation"]["scheme"] == "maneuvers" and "4 folds of the 4 training cycles" in \
        doc["cross_validation"]["note"]
    cov = doc["covariance"]
    assert cov["kind"] == "hac-maneuver" and cov["groups"] == 4
    assert set(cov["reference_dof"]) == set(doc["params"]) and all(1 <= d <= 3 for d in cov["reference_dof"].values())
    assert cov["few_maneuvers"] and "Few maneuvers" in (tmp_path / "out" / "fit.md").read_text()
    for name, value in TRUTH.items():   # the cut costs no bias: the truth within 5 %
        assert doc["params"][name] == pytest.approx(value, rel=0.05), name


def test_cli_a_record_shorter_than_the_rule_is_one_line_naming_file_column_and_rule(tmp_path):
    path = _wind_tunnel(tmp_path / "wt", runs=(("run1", 0.3, "train"), ("run2", 2.0, "validation")))
    proc = run_cli("fit", "--data", path, "--model", "CL-II", "--out", tmp_path / "out", timeout=60)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "run1.csv, column 't': maneuver is too short to fit separation dynamics" in proc.stderr
    assert "convective times" in proc.stderr


def test_segment_choices_of_the_command_line_equal_their_owner():
    from structsearch.cli import options as cli_options
    from structsearch.data.records import SEGMENT_CHOICES
    assert tuple(cli_options.SEGMENT_CHOICES) == SEGMENT_CHOICES
