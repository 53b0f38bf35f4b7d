"""The public Python API (docs/interfaces.md 6.1): exports, a light command line, the tutorial, the API beside
the command it mirrors."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import structsearch
from structsearch.cli import main

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numpy", "scipy", "sympy", "pandas")


def _python(code: str, timeout: float = 60) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=ROOT)


def test_api_functions_are_plain_functions_beside_their_subpackages():
    """structsearch.search, .report, .study and .preprocess are the API functions; the subpackages that do the
    work have other names (grid_search, reporting, thesis_study, preprocessing), so importing them hides nothing."""
    import inspect

    import structsearch.grid_search.pipeline  # noqa: F401
    import structsearch.preprocessing.pipeline  # noqa: F401
    import structsearch.reporting.page  # noqa: F401
    import structsearch.thesis_study.study  # noqa: F401
    from structsearch import api
    assert [structsearch.search, structsearch.report, structsearch.study, structsearch.preprocess] == \
        [api.search, api.report, api.study, api.preprocess]
    assert all(inspect.isfunction(f) for f in (structsearch.search, structsearch.report))
    assert "grid" in inspect.signature(structsearch.search).parameters


def test_every_exported_name_resolves_and_is_listed():
    listed = dir(structsearch)
    assert sorted(structsearch.__all__) == sorted([*structsearch._EXPORTS, "__version__"])
    for name in structsearch.__all__:
        assert getattr(structsearch, name) is not None, name
        assert name in listed, name
    for name in ("fit", "search", "diagnose", "simulate", "preprocess", "study", "report", "demo", "SeparableModel",
                 "StallModel", "FitResult", "CandidateResult", "FitOptions", "LiftFit", "fit_report", "FlightData",
                 "Campaign", "read_campaign", "write_campaign", "StructSearchError", "DataError",
                 "DeclarationError", "FitError"):
        assert name in structsearch.__all__, name
    with pytest.raises(AttributeError):
        structsearch.no_such_name  # noqa: B018
    assert (ROOT / "structsearch" / "py.typed").exists()


def test_import_and_parser_load_no_numeric_library():
    """``structsearch --help`` must stay fast: building the parser imports none of numpy, scipy, sympy, pandas."""
    proc = _python("import sys, structsearch, structsearch.cli\nstructsearch.cli.build_parser()\n"
                   f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == ""


def test_light_choices_equal_their_owners():
    from structsearch.cli import options as cli_options
    from structsearch.engine.statistics import COVARIANCE_KINDS, DEFAULT_COVARIANCE
    from structsearch.fitting.options import CV_METHODS
    from structsearch.flight import aero, anomalies, names
    from structsearch.grid_search.admissibility import MAX_CORRELATION
    assert tuple(cli_options.COVARIANCE_KINDS) == tuple(COVARIANCE_KINDS)
    assert cli_options.DEFAULT_COVARIANCE == DEFAULT_COVARIANCE
    assert cli_options.MAX_CORRELATION == MAX_CORRELATION
    assert tuple(cli_options.CV_METHODS) == tuple(CV_METHODS)
    assert names.AIRCRAFT_NAMES == tuple(aero.TRUTHS)
    assert names.ANOMALY_NAMES == tuple(anomalies.ANOMALIES)
    assert aero.WITHHOLDABLE is names.WITHHOLDABLE


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"structsearch {structsearch.__version__}"


@pytest.mark.slow
def test_fit_is_the_fit_command(tmp_path):
    """The API's fit gives the document the command writes, number for number."""
    campaign = structsearch.simulate(scale=0.05, seed=1)
    structsearch.write_campaign(campaign, tmp_path / "c")
    assert main(["fit", "--data", str(tmp_path / "c"), "--model", "CL-VI", "--starts", "1",
                 "--out", str(tmp_path / "o")]) == 0
    written = json.loads((tmp_path / "o" / "fit.json").read_text())
    outcome = structsearch.fit(tmp_path / "c", "CL-VI", settings=structsearch.Settings(starts=1))
    from structsearch.data.atomic import json_ready
    assert json.loads(json.dumps(json_ready(outcome.to_dict()))) == written
    assert outcome.lift is None and outcome.result.estimates.params == written["params"]
    with pytest.raises(structsearch.StructSearchError, match="no_such_parameter"):
        structsearch.fit(campaign, "CL-VI", settings=structsearch.Settings(bounds={"no_such_parameter": (0.0, 1.0)}))


@pytest.mark.slow
def test_tutorial_runs():
    """examples/tutorial.py: the main path in Python, on a small campaign, as a notebook user sees it."""
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "tutorial.py")], capture_output=True, text=True,
                          timeout=900, env=dict(os.environ, PYTHONPATH=str(ROOT)), cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout
    assert "campaign: 24 maneuvers (19 for training)" in out and "CL-VI: MSE train" in out and "CD-IXr on CL-VI" in out
    # issue 43: on 6 maneuvers it printed "best drag structure" of a ranking none of whose rows was admissible;
    # the campaign is now large enough for the claim (if a change made it false, the tutorial says so instead)
    assert "best admissible drag structure: CD-" in out and "no drag structure is admissible" not in out
    line = next(s for s in out.splitlines() if s.startswith("CD-IXr on CL-VI"))
    assert "1 of 6 parameters on few maneuvers" in line   # as on the full campaign
    assert "CD-I: validation MSE " in out and "final model " in out
