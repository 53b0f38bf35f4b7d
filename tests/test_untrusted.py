"""Files from anyone: specs, term files, campaigns and caches that are hostile or wrong get one clear error (exit
2), run no code and write nothing wrong; interrupted runs leave no process and no temporary file behind."""
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from structsearch.data.campaign import read_campaign
from structsearch.data.errors import DataError, DeclarationError

CANARY = Path(tempfile.gettempdir()) / "structsearch-untrusted-canary"
HOSTILE = f"__import__('os').system('touch {CANARY}')"


def _one_line_error(proc, *words):
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def test_a_spec_regressor_that_is_code_runs_nothing(run_cli, campaign_dir, tmp_path):
    spec = tmp_path / "evil.toml"
    spec.write_text(f'name = "evil"\ncoefficient = "CL"\nprefix = "E-"\n[[entry]]\nname = "E-I"\n'
                    f'regressors = {{ CL0 = "1", bad = "{HOSTILE}" }}\n')
    proc = run_cli("fit", "--data", campaign_dir, "--model", spec, "--out", tmp_path / "o")
    _one_line_error(proc, str(spec), "'bad'", "unexpected character")
    assert not CANARY.exists()


def test_a_term_that_is_code_runs_nothing(run_cli, campaign_dir, tmp_path):
    terms = tmp_path / "terms.toml"
    terms.write_text(f'[terms]\nCL_x = "{HOSTILE}"\n')
    proc = run_cli("discover", "--data", campaign_dir, "--coefficient", "CL", "--terms", terms, "--out", tmp_path / "o")
    _one_line_error(proc, str(terms), "'CL_x'")
    assert not CANARY.exists()


def test_division_by_zero_in_a_spec_is_one_line(run_cli, campaign_dir, tmp_path):
    spec = tmp_path / "zero.toml"
    spec.write_text('name = "z"\ncoefficient = "CL"\nprefix = "Z-"\n[[entry]]\nname = "Z-I"\n'
                    'regressors = { CL0 = "1", CL_de = "de/0" }\n')
    _one_line_error(run_cli("fit", "--data", campaign_dir, "--model", spec, "--out", tmp_path / "o"),
                    "divides by zero")


@pytest.mark.parametrize("text,message", [
    ('name = "g"\ncoefficient = "CL"\nprefix = "G-"\nsplti = 1\n[[entry]]\nregressors = { c = "1" }\n',
     "unknown key 'splti'"),
    ('name = "g"\ncoefficient = "CL"\nprefix = "G-"\n[[entry]]\nregresors = { c = "1" }\n',
     "unknown key 'regresors' (did you mean 'regressors'?)"),
])
def test_unknown_keys_of_a_spec_are_refused_with_the_close_match(tmp_path, text, message):
    from structsearch.fitting.specs import load_grid
    spec = tmp_path / "g.toml"
    spec.write_text(text)
    with pytest.raises(DeclarationError) as err:
        load_grid(str(spec))
    assert message in str(err.value) and str(spec) in str(err.value)


def test_unknown_keys_of_a_term_file_are_refused(tmp_path):
    from structsearch.discovery.terms import read_terms
    path = tmp_path / "t.toml"
    path.write_text('coeficient = "CL"\n[terms]\nCL_a3 = "alpha**3"\n')
    with pytest.raises(DeclarationError, match="unknown key 'coeficient' \\(did you mean 'coefficient'\\?\\)"):
        read_terms(path, "CL")


def _edit_manifest(directory, old, new):
    toml = directory / "campaign.toml"
    text = toml.read_text()
    assert old in text
    toml.write_text(text.replace(old, new, 1))


@pytest.mark.parametrize("old,new,message", [
    ('split = "', 'splti = "validation"\nsplit = "', "unknown key 'splti' (did you mean 'split'?)"),
    ("[aircraft]", "[aircarft]\nS = 1.0\n[aircraft]", "unknown key 'aircarft' (did you mean 'aircraft'?)"),
    ('name = "', 'fromat = "raw"\nname = "', "unknown key 'fromat' (did you mean 'format'?)"),
])
def test_unknown_keys_of_a_campaign_manifest_are_refused(campaign_dir, old, new, message):
    _edit_manifest(campaign_dir, old, new)
    with pytest.raises(DataError) as err:
        read_campaign(campaign_dir)
    assert message in str(err.value) and "campaign.toml" in str(err.value)


def _first_file(directory):
    return sorted(directory.glob("*.csv"))[0]


def test_a_binary_or_huge_file_is_refused_at_once_without_reading_it(campaign_dir):
    target = _first_file(campaign_dir)
    with target.open("wb") as f:
        f.truncate(2 * 1024 ** 3)            # a 2 GB sparse file: NUL bytes
    t0 = time.perf_counter()
    with pytest.raises(DataError, match="not a text file|MiB such a file may have") as err:
        read_campaign(campaign_dir)
    assert time.perf_counter() - t0 < 5 and target.name in str(err.value)
    target.write_bytes(b"1,2,3\n" * 10)
    with pytest.raises(DataError, match="holds numbers, not column names"):
        read_campaign(campaign_dir)


def test_duplicate_columns_and_booleans_are_refused(campaign_dir):
    target = _first_file(campaign_dir)
    frame = pd.read_csv(target)
    header = ",".join(list(frame.columns) + ["alpha"])
    body = "\n".join(",".join(map(str, row)) + f",{row[1]}" for row in frame.to_numpy()[:5])
    target.write_text(header + "\n" + body + "\n")
    with pytest.raises(DataError, match="column 'alpha': column appears twice"):
        read_campaign(campaign_dir)


def test_a_parquet_column_of_booleans_is_refused(tmp_path):
    pytest.importorskip("pyarrow")
    from structsearch.data.tables import read_table
    path = tmp_path / "m.parquet"
    pd.DataFrame({"t": [0.0, 1.0], "de": [True, False]}).to_parquet(path)
    with pytest.raises(DataError, match="column 'de': holds booleans"):
        read_table(path)


def test_a_pitch_rate_in_degrees_per_second_is_refused(campaign_dir):
    target = _first_file(campaign_dir)
    frame = pd.read_csv(target)
    assert np.abs(frame["q"]).max() < 1.0     # small values: the magnitude alone would not tell
    frame["q"] = np.degrees(frame["q"])
    frame.to_csv(target, index=False, float_format="%.17g")
    with pytest.raises(DataError, match="column 'q': q looks like degrees per second: the ratio of q to d\\((theta|alpha)\\)/dt is 5[0-9]") as err:
        read_campaign(campaign_dir)
    assert target.name in str(err.value)


def test_an_extra_column_in_one_file_names_that_file(campaign_dir):
    target = _first_file(campaign_dir)
    frame = pd.read_csv(target)
    frame["Mach"] = 0.2
    frame.to_csv(target, index=False, float_format="%.17g")
    with pytest.raises(DataError, match="column 'Mach': column appears in 1 of") as err:
        read_campaign(campaign_dir)
    assert target.name in str(err.value)


def test_a_write_error_names_the_file_meant_and_leaves_no_temporary_twin(tmp_path):
    from structsearch.data.atomic import write_text
    if os.geteuid() == 0:
        # root writes through permissions: a path under a file is refused for anyone
        (tmp_path / "plain").write_text("x")
        with pytest.raises(OSError) as err:
            write_text(tmp_path / "plain" / "out.json", "{}")
        assert str(tmp_path / "plain" / "out.json") in str(err.value)
        return
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    with pytest.raises(OSError) as err:
        write_text(locked / "out.json", "{}")
    assert str(locked / "out.json") in str(err.value)


def test_orphan_temporary_files_of_dead_runs_are_removed(tmp_path):
    from structsearch.data.atomic import write_text
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    orphan = tmp_path / f".out.json.{dead}-abc.tmp"
    orphan.write_text("half")
    mine = tmp_path / f".out.json.{os.getpid()}-def.tmp"     # a live writer's: kept
    mine.write_text("busy")
    write_text(tmp_path / "out.json", "{}")
    assert not orphan.exists() and mine.exists()


def test_a_ranking_of_an_interrupted_search_is_not_read_as_whole(tmp_path):
    from structsearch.data.manifest import begin_set, check_set, finish_set
    (tmp_path / "ranking.csv").write_text("grid,model,rank\n")
    begin_set(tmp_path, "search")
    with pytest.raises(DataError, match="did not finish"):
        check_set(tmp_path, "search", "ranking.csv")
    finish_set(tmp_path, "search", [tmp_path / "ranking.csv"])
    check_set(tmp_path, "search", "ranking.csv")
    (tmp_path / "ranking.csv").write_text("grid,model,rank\nlift,CL-I,1\n")
    with pytest.raises(DataError, match="not the file the last search wrote"):
        check_set(tmp_path, "search", "ranking.csv")


def _children(pid):
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return [int(p) for p in out.split()]


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/stat")
    return not (status.exists() and status.read_text().split()[2] == "Z")


def _search(campaign_dir, out, tmp):
    env = {**os.environ, "TMPDIR": str(tmp)}
    return subprocess.Popen([sys.executable, "-m", "structsearch", "search", "--data", str(campaign_dir), "--grid",
                             "lift", "--jobs", "2", "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _wait_for_workers(proc, seconds=60):
    t0 = time.time()
    while time.time() - t0 < seconds:
        kids = _children(proc.pid)    # the worker processes and their helpers
        if len(kids) >= 2 and any((Path(proc.args[-1]) / "cache").rglob("*.json")):
            return kids
        time.sleep(0.5)
    raise AssertionError("the search never got going")


def _running_search(campaign_dir, tmp_path):
    """A ``--jobs 2`` search with its own temporary directory, once its workers have cached a fit."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = _search(campaign_dir, tmp_path / "out", tmp)
    return proc, _wait_for_workers(proc), tmp


def _all_gone(pids, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.5)
    return not any(_alive(p) for p in pids)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and ps --ppid")
def test_ctrl_c_prints_one_line_and_leaves_no_worker_or_temporary_file(campaign_dir, tmp_path):
    proc, kids, tmp = _running_search(campaign_dir, tmp_path)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err.strip().splitlines()[-1] == ("structsearch search: interrupted; the fits finished so far are cached: "
                                            "run the same command again to resume"), err
    assert "Traceback" not in err
    assert _all_gone(kids, 60)
    assert not list(tmp.glob("structsearch-*"))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and ps --ppid")
def test_kill_9_leaves_no_worker_and_the_next_run_removes_its_temporary_files(campaign_dir, tmp_path):
    proc, kids, tmp = _running_search(campaign_dir, tmp_path)
    proc.kill()
    proc.communicate(timeout=30)
    assert _all_gone(kids, 60), "a worker outlived the search by 60 s"
    from structsearch.data.atomic import remove_orphans
    remove_orphans(tmp, "structsearch-")      # what the next search does first
    assert not list(tmp.glob("structsearch-*"))
