"""Files from anyone, second pass: each hostile file is built in tmp_path and read by the reader a command uses (or
by the command itself); every one is one project error naming the file (and the key, column or row), or handled
safely: no traceback, no content of a file outside its directory, bounded time and size, nothing left behind."""
import json
import os
import re
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from structsearch.data.campaign import read_campaign
from structsearch.data.errors import DataError, DeclarationError, StructSearchError

SECRET = "top-secret-line-of-another-file"
SPEC_HEAD = 'name = "g"\ncoefficient = "CL"\nprefix = "G-"\n'


@contextmanager
def within(seconds: int):
    """Fail (never hang) when the body takes longer than ``seconds``: a FIFO must not block a reader."""
    def hung(*_):
        raise TimeoutError(f"still reading after {seconds} s")
    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _first_file(directory: Path) -> Path:
    return sorted(directory.glob("*.csv"))[0]


def _manifest_file_entry(directory: Path, new: str) -> None:
    """Point the first maneuver's ``file`` at ``new``."""
    toml = directory / "campaign.toml"
    old = _first_file(directory).name
    toml.write_text(toml.read_text().replace(f'file = "{old}"', f'file = "{new}"', 1))


def _refused(call, kind=StructSearchError, *words, seconds=20, longest=400):
    """``call()`` raises one project error naming ``words``, short, without a secret, in bounded time."""
    t0 = time.perf_counter()
    with within(seconds), pytest.raises(kind) as err:
        call()
    message = str(err.value)
    # the bound is on the words, not on where the test's temporary directory happens to be (its paths are long
    # under xdist's workers): every absolute path counts as one character
    assert "\n" not in message and len(re.sub(r"/[^\s',]+", "/", message)) < longest, message[:500]
    assert SECRET not in message
    for w in words:
        assert str(w) in message, message
    assert time.perf_counter() - t0 < seconds
    return message


# ----- 1. names that lead outside the campaign directory -------------------------------------------------------
@pytest.fixture
def outside(tmp_path):
    path = tmp_path / "outside.csv"
    path.write_text(f"t,alpha\n{SECRET},1\n")
    return path


@pytest.mark.parametrize("how", ["relative", "absolute", "symlink", "symlink to /etc/passwd"])
def test_a_maneuver_file_outside_the_campaign_directory_is_refused_unread(campaign_dir, outside, how):
    if how == "relative":
        _manifest_file_entry(campaign_dir, "../outside.csv")
    elif how == "absolute":
        _manifest_file_entry(campaign_dir, str(outside))
    else:
        target = _first_file(campaign_dir)
        target.unlink()
        target.symlink_to(outside if how == "symlink" else "/etc/passwd")
    _refused(lambda: read_campaign(campaign_dir), DataError, "campaign.toml", "'file'", "outside the directory")


def test_the_command_line_refuses_a_symlink_out_in_one_line(run_cli, campaign_dir, outside, tmp_path):
    target = _first_file(campaign_dir)
    target.unlink()
    target.symlink_to(outside)
    proc = run_cli("fit", "--data", campaign_dir, "--model", "CL-I", "--out", tmp_path / "o")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and SECRET not in proc.stderr + proc.stdout
    assert len(proc.stderr.strip().splitlines()) == 1 and "outside the directory" in proc.stderr


@pytest.mark.parametrize("name", ["fit.json", "ranking.csv"])
def test_a_fixed_name_in_a_given_directory_that_links_out_is_refused_unread(tmp_path, outside, name):
    """What export (``--fit DIR``) and report read by a fixed name in the directory they are given stays inside
    it: a fit.json or ranking.csv that is a link to a file elsewhere is one error, its content unread."""
    from structsearch.api.exporting import read_fit_directory
    from structsearch.reporting.choice import ranked_rows
    given = tmp_path / "given"
    given.mkdir()
    (given / name).symlink_to(outside)
    read = read_fit_directory if name == "fit.json" else ranked_rows
    message = _refused(lambda: read(given), DataError, name, "outside the directory")
    assert SECRET not in message


# ----- 2. a grid name that would write outside --out ----------------------------------------------------------
@pytest.mark.parametrize("name", ["../escape", "/tmp/escape", "..", ".hidden", "a\\b"])
def test_a_grid_name_that_is_a_path_is_refused(tmp_path, name):
    from structsearch.fitting.specs import load_grid
    spec = tmp_path / "g.toml"
    spec.write_text(f'name = {json.dumps(name)}\ncoefficient = "CL"\nprefix = "G-"\n[[entry]]\n'
                    'regressors = { c = "1" }\n')
    _refused(lambda: load_grid(str(spec)), DeclarationError, str(spec), "'name'")


def test_the_cache_path_stays_inside_the_output_directory(tmp_path):
    import dataclasses
    from structsearch.fitting.options import FitOptions
    from structsearch.fitting.runner import cache_path
    from structsearch.fitting.specs import find_candidate
    c = dataclasses.replace(find_candidate("CL-I"), grid="../../escape", name="../x")
    path, _ = cache_path(tmp_path / "out", c, "0" * 16, None, FitOptions())
    assert path.resolve().is_relative_to((tmp_path / "out" / "cache").resolve())


# ----- 3. bounded reading --------------------------------------------------------------------------------------
def test_nul_bytes_after_valid_rows_are_refused_with_the_offset_and_a_short_line(campaign_dir):
    target = _first_file(campaign_dir)
    size = target.stat().st_size
    with target.open("ab") as f:
        f.write(b"\0" * (8 << 20))
    message = _refused(lambda: read_campaign(campaign_dir), DataError, target.name, "NUL byte")
    assert f"offset {size}" in message


def test_an_enormous_cell_is_quoted_in_at_most_a_short_excerpt(campaign_dir):
    target = _first_file(campaign_dir)
    lines = target.read_text().splitlines()
    cells = lines[1].split(",")
    cells[1] = "x" * (4 << 20)
    lines[1] = ",".join(cells)
    target.write_text("\n".join(lines) + "\n")
    _refused(lambda: read_campaign(campaign_dir), DataError, target.name, "not a number")


def test_a_huge_sparse_maneuver_file_is_refused_by_its_size_unread(campaign_dir):
    target = _first_file(campaign_dir)
    with target.open("r+b") as f:
        f.truncate(3 << 30)
    _refused(lambda: read_campaign(campaign_dir), DataError, target.name, "MiB", seconds=5)


# ----- 4. encodings and magnitudes -----------------------------------------------------------------------------
@pytest.mark.parametrize("content", ["latin-1", "binary"])
def test_a_manifest_that_is_not_utf8_is_one_error_with_the_byte_offset(campaign_dir, content):
    toml = campaign_dir / "campaign.toml"
    text = toml.read_bytes()
    toml.write_bytes(text.replace(b"[aircraft]", "# Düsseldorf\n[aircraft]".encode("latin-1"), 1)
                     if content == "latin-1" else b"\x89PNG\r\n\x1a\n\xff\xfe\0\0" + os.urandom(64))
    _refused(lambda: read_campaign(campaign_dir), DataError, "campaign.toml", "byte offset")


def test_an_absurd_magnitude_names_the_column_and_row(campaign_dir):
    import pandas as pd
    target = _first_file(campaign_dir)
    frame = pd.read_csv(target)
    frame.loc[7, "CL"] = 1e300
    frame.to_csv(target, index=False, float_format="%.17g")
    _refused(lambda: read_campaign(campaign_dir), DataError, target.name, "'CL'", "row 7", "absurd magnitude")


# ----- 5. what report, compare and export read -----------------------------------------------------------------
def _fit_doc(campaign_dir, **changes):
    from structsearch.fitting.specs import find_candidate
    c = find_candidate("CL-I")
    params = {n: 0.1 for n, _ in c.regressors} | {p: 0.5 for p in c.state_parameters}
    doc = {"model": "CL-I", "params": params, "mse": {"train": 0.01}, "data": {"source": str(campaign_dir)},
           "structure": c.to_dict()}
    doc.update(changes)
    return doc


@pytest.mark.parametrize("case,words", [
    ("parameter a string", ["params.CL0", "must be a number"]),
    ("regressor that is code", ["structure.regressors.bad", "cannot parse"]),
    ("covariance not square", ["parameter_covariance.matrix"]),
    ("deeply nested", ["nested"]),
    ("not utf-8", ["byte offset"]),
    ("a parameter missing", ["params.CL0", "missing"]),
    ("an unknown coefficient", ["structure.coefficient", "must be one of CL, CD, Cm, CY, Cl, Cn"]),
])
def test_a_hostile_fit_json_is_one_error_naming_the_key(campaign_dir, tmp_path, case, words):
    from structsearch.api.exporting import read_fit_directory
    fit_dir = tmp_path / "fit"
    fit_dir.mkdir()
    doc = _fit_doc(campaign_dir)
    if case == "parameter a string":
        doc["params"]["CL0"] = "0.1; rm -rf"
    elif case == "regressor that is code":
        doc["structure"]["regressors"]["bad"] = "__import__('os').system('true')"
        doc["params"]["bad"] = 0.0
    elif case == "covariance not square":
        doc["parameter_covariance"] = {"names": ["CL0", "CL_KL"], "matrix": [[1.0, 0.0]]}
    elif case == "a parameter missing":
        del doc["params"]["CL0"]
    elif case == "an unknown coefficient":
        doc["structure"]["coefficient"] = "CZ"
    text = json.dumps(doc)
    if case == "deeply nested":
        text = text[:-1] + ', "x": ' + "[" * 100_000 + "]" * 100_000 + "}"
    (fit_dir / "fit.json").write_bytes(text.encode() if case != "not utf-8" else b'{"model": "\xe9"}')
    _refused(lambda: read_fit_directory(fit_dir), DataError, "fit.json", *words)


@pytest.mark.parametrize("case", ["not utf-8", "oversized", "fifo"])
def test_a_hostile_ranking_is_one_error(tmp_path, case):
    from structsearch.reporting.choice import ranked_rows
    path = tmp_path / "ranking.csv"
    if case == "not utf-8":
        path.write_bytes(b"grid,model,rank\nlift,CL-\xff\xfe,1\n")
    elif case == "oversized":
        with path.open("wb") as f:
            f.write(b"grid,model,rank\n")
            f.truncate(64 << 20)
    else:
        os.mkfifo(path)
    _refused(lambda: ranked_rows(tmp_path), DataError, "ranking.csv", seconds=5)


def test_compare_refuses_deeply_nested_json(tmp_path):
    from structsearch.experiments.reproducibility import compare_outputs
    for side in ("a", "b"):
        (tmp_path / side).mkdir()
        (tmp_path / side / "fit.json").write_text("[" * 50_000 + "]" * 50_000)
    _refused(lambda: compare_outputs(tmp_path / "a", tmp_path / "b"), DataError, "fit.json", "nested")


def test_a_spec_nested_too_deep_is_one_error_never_a_recursion_error(tmp_path):
    from structsearch.fitting.specs import load_grid
    spec = tmp_path / "deep.toml"
    spec.write_text(SPEC_HEAD + "x = " + "[" * 5000 + "]" * 5000 + "\n")
    _refused(lambda: load_grid(str(spec)), DeclarationError, str(spec), "nested")


# ----- 6. named pipes -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["spec", "term file", "campaign.toml", "maneuver file", "manifest"])
def test_a_fifo_is_refused_at_once(campaign_dir, tmp_path, which):
    from structsearch.discovery.terms import read_terms
    from structsearch.fitting.specs import load_grid
    fifo = {"spec": tmp_path / "g.toml", "term file": tmp_path / "terms.toml",
            "campaign.toml": campaign_dir / "campaign.toml", "maneuver file": _first_file(campaign_dir),
            "manifest": tmp_path / "search_manifest.json"}[which]
    if fifo.exists():
        fifo.unlink()
    os.mkfifo(fifo)
    call = {"spec": lambda: load_grid(str(fifo)), "term file": lambda: read_terms(fifo, "CL"),
            "campaign.toml": lambda: read_campaign(campaign_dir), "maneuver file": lambda: read_campaign(campaign_dir),
            "manifest": lambda: __import__("structsearch.data.manifest").data.manifest.check_set(
                tmp_path, "search", "ranking.csv")}[which]
    _refused(call, StructSearchError, fifo.name, "FIFO" if which != "manifest" else "manifest", seconds=5)


# ----- 7 and 9. wrong TOML types in a spec ---------------------------------------------------------------------
@pytest.mark.parametrize("body,key", [
    ('[[entry]]\nregressors = "CL0"\n', "'regressors'"),
    ('[[entry]]\nregressors = ["1", "alpha"]\n', "'regressors'"),
    ('[[entry]]\nname = 3\nregressors = { c = "1" }\n', "'name'"),
    ('lift = 7\n[[entry]]\nregressors = { c = "1" }\n', "'lift'"),
    ('[blocks]\nb = "1"\n[[entry]]\nblocks = ["b"]\n', "'blocks'"),
    ('[blocks]\nb = { c = "1" }\n[[entry]]\nblocks = "b"\n', "'blocks'"),
    ('[blocks]\nb = { c = "1" }\n[[entry]]\nblocks = [1]\n', "'blocks'"),
    ('bounds = [0, 1]\n[[entry]]\nregressors = { c = "1" }\n', "'bounds'"),
    ('[[entry]]\nregressors = { c = "1" }\nbounds = [1, 2]\n', "'bounds'"),
    ('[[entry]]\nregressors = { c = "1" }\nstates = ["S"]\n', "'states'"),
    ('[[entry]]\nname = "G-I"\nregressors = { c = "1" }\n[[entry]]\nfrom = "G-I"\ndrop = "c"\n', "'drop'"),
    ('[[entry]]\nkinds = { ss = "S" }\nregressors = { c = "1" }\n', "'kinds'"),
    ('[[entry]]\nregressors = { c = "1" }\nnote = { text = "a table" }\n', "'note'"),
    ('[[entry]]\nname = ""\nregressors = { c = "1" }\n', "'name'"),
    ('[[entry]]\nregressors = { c = 1e999 }\n', "'regressors'"),
    ('[[entry]]\nregressors = { c = "1", k = "K_L(X_ss)" }\nstates = { ss = "Z" }\n', "kind 'Z'"),
    ('[[entry]]\nregressors = { c = "1" }\nlift = "nosuch"\n', "'nosuch'"),
    ('[[entry]]\nregressors = { c = "1" }\n[[entry]]\nalways = [["a"]]\ncombinations = [["b"]]\n', "'always'"),
    ('[[entry]]\nregressors = { c = "1", d = "١٢٣٤٥٦٧٨٩٠١٢٣٤٥٦٧٨٩٠١٢٣٤٥٦٧٨٩٠١٢٣٤٥٦٧٨٩٠١٢٣٤٥٦٧٨٩٠*alpha" }\n',
     "unexpected character"),
])
def test_a_spec_value_of_the_wrong_type_is_one_error_naming_the_key(tmp_path, body, key):
    from structsearch.fitting.specs import load_grid
    spec = tmp_path / "g.toml"
    spec.write_text(SPEC_HEAD + body, encoding="utf-8")
    _refused(lambda: load_grid(str(spec)), DeclarationError, str(spec), key)


# ----- 8. regressors that overflow or divide by zero -----------------------------------------------------------
@pytest.mark.parametrize("expression", ["exp(1000*alpha)", "1/pos(alpha-10)"])
def test_a_regressor_that_overflows_is_one_error_naming_it_and_the_candidate(run_cli, campaign_dir, tmp_path,
                                                                             expression):
    spec = tmp_path / "ov.toml"
    spec.write_text(SPEC_HEAD + f'[[entry]]\nname = "G-I"\nregressors = {{ CL0 = "1", big = "{expression}" }}\n')
    proc = run_cli("fit", "--data", campaign_dir, "--model", spec, "--out", tmp_path / "o")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "G-I" in lines[0] and "regressor 'big' is" in lines[0] and "row" in lines[0]
    assert ("overflow" if expression.startswith("exp") else "NaN or infinite") in lines[0]


# ----- 10 and 11. cache entries: bounded, and signed -----------------------------------------------------------
class _Result:
    def to_json(self):
        return {"name": "CL-I", "mse": 0.25}


def test_a_huge_sparse_or_fifo_cache_entry_is_a_miss_read_at_once(tmp_path):
    from structsearch.fitting.runner import read_cached
    said = []
    sparse, fifo = tmp_path / "sparse.json", tmp_path / "fifo.json"
    with sparse.open("wb") as f:
        f.truncate(512 << 20)
    os.mkfifo(fifo)
    with within(5):
        assert read_cached(sparse, "k", said.append) is None and read_cached(fifo, "k", said.append) is None
    assert len(said) == 2 and all("refitting" in m for m in said) and "MiB" in said[0] and "FIFO" in said[1]


def test_an_entry_edited_with_its_digest_recomputed_is_never_served(tmp_path, monkeypatch):
    from structsearch.fitting import runner
    monkeypatch.setenv("STRUCTSEARCH_CACHE_KEY_FILE", str(tmp_path / "keys" / "cache.key"))
    path = tmp_path / "out" / "cache" / "lift" / "CL-I.json"
    runner.write_cached(path, "question", _Result())
    assert (tmp_path / "keys" / "cache.key").stat().st_mode & 0o777 == 0o600
    assert not (tmp_path / "keys").resolve().is_relative_to((tmp_path / "out").resolve())
    served = []
    monkeypatch.setattr(runner.CandidateResult, "from_json", staticmethod(lambda content: served.append(content)
                                                                            or content))
    said = []
    assert runner.read_cached(path, "question", said.append) == {"name": "CL-I", "mse": 0.25} and not said
    doc = json.loads(path.read_text())
    doc["content"]["mse"] = 0.01                           # a better fit, by hand
    doc["digest"] = runner.content_digest(doc["content"])  # and a digest that matches it
    path.write_text(json.dumps(doc))
    assert runner.read_cached(path, "question", said.append) is None
    assert len(said) == 1 and "not signed" in said[0] and "refitting" in said[0]


# ----- 12. what killed runs leave behind -----------------------------------------------------------------------
def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_the_next_run_removes_the_folders_and_semaphores_of_a_killed_one(tmp_path):
    from structsearch.data.atomic import remove_dead_runs
    pid = _dead_pid()
    folder = tmp_path / f"structsearch-{pid}-workers-abc"
    folder.mkdir()
    semaphore = Path("/dev/shm") / f"sem.loky-{pid}-hostiletest"
    if not Path("/dev/shm").is_dir():
        pytest.skip("no /dev/shm")
    semaphore.write_bytes(b"")
    try:
        remove_dead_runs(tmp_path)
        assert not folder.exists() and not semaphore.exists()
    finally:
        semaphore.unlink(missing_ok=True)


def test_a_killed_campaign_write_leaves_nothing_after_the_next_write(tmp_path, simulated_campaign):
    from structsearch.data.campaign import write_campaign
    left = tmp_path / f".c.{_dead_pid()}-x1y2"
    left.mkdir()
    (left / "m01.csv").write_text("t\n")
    write_campaign(simulated_campaign(seed=1, scale=0.05, slow_errors=0.0), tmp_path / "c")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and ps --ppid")
def test_a_search_killed_as_its_workers_start_leaves_no_process_and_nothing_in_dev_shm(campaign_dir, tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp)}
    proc = subprocess.Popen([sys.executable, "-m", "structsearch", "search", "--data", str(campaign_dir), "--grid",
                             "lift", "--jobs", "2", "--out", str(tmp_path / "out")], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    kids = []
    deadline = time.time() + 60
    while time.time() < deadline and len(kids) < 3:
        out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(proc.pid)], capture_output=True, text=True).stdout
        kids = [int(p) for p in out.split()]
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    deadline = time.time() + 20
    while time.time() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.5)
    assert kids and not any(_alive(k) for k in kids), "a worker outlived the search by 20 s"
    semaphores = [p for p in os.listdir("/dev/shm") if p.startswith(f"sem.loky-{proc.pid}-")]
    from structsearch.data.atomic import remove_dead_runs
    remove_dead_runs(tmp)                 # what the next command does first
    assert not [p for p in os.listdir("/dev/shm") if p.startswith(f"sem.loky-{proc.pid}-")], semaphores
    assert not list(tmp.iterdir())


def _alive(pid: int) -> bool:
    status = Path(f"/proc/{pid}/stat")
    try:
        return status.read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.parametrize("doc, words", [
    ("[1, 2]", ["not a JSON object"]),
    ('{"complete": "yes", "files": {}}', ["'complete'", "not a boolean"]),
    ('{"complete": true, "files": [1]}', ["'files'", "not a table"]),
    ('{"complete": true, "files": {"lift.md": 5}}', ["'lift.md'", "5"]),
    ('{"complete": true, "files": {"../x": "00"}}', ["'../x'", "not a file of its directory"]),
])
def test_a_malformed_manifest_is_one_error_naming_its_key(tmp_path, doc, words):
    """A manifest whose verdict or list is malformed names what is wrong (before: "the manifest is unreadable",
    for every fault alike), and one that lists a file outside its directory is refused before anything uses it."""
    from structsearch.data.manifest import check_set, manifest_path
    manifest_path(tmp_path, "search").write_text(doc)
    (tmp_path / "ranking.csv").write_text("grid,model,rank\n")
    _refused(lambda: check_set(tmp_path, "search", "ranking.csv"), DataError, "search manifest", *words)
