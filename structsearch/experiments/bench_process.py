"""The whole-process half of ``structsearch bench`` (issue 27, "the command line's own cost").

``structsearch fit --model CL-VI`` (the default fit) and ``... --starts 1`` are timed as whole processes
(interpreter start, imports, reading the campaign, fitting, statistics, cross-validation, writing)
against the whole process of an independent numpy/scipy variable-projection script
(``reference_vp_script.py`` beside this module, which imports nothing from structsearch) on the same
simulated campaign written to a temporary directory: alternated, median of ``repeats``. Whether the
default fit reached the best *admissible* optimum (inside the box, on no bound) is judged against the
processes' own answers and ``random_starts`` uniform random starts inside the box.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).with_name("reference_vp_script.py")
# relative cost within which two fits reach the same optimum (as run_staged)
SAME_OPTIMUM_RTOL = 1e-6


def timed_process(command: list[str], cwd: Path) -> tuple[float, float, str]:
    """Wall time [s], peak resident memory [MB] and standard output of one process (an error if it fails)."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(command, cwd=cwd, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        text, problem = out.read().decode(), err.read().decode()
    if proc.returncode:
        raise RuntimeError(f"{' '.join(command)} failed ({proc.returncode}): {problem[-2000:]}")
    return seconds, usage.ru_maxrss / 1024, text


def commands(data: Path, work: Path) -> dict[str, list[str]]:
    """The three processes: the default fit, the fit from one start, the reference script."""
    fit = [sys.executable, "-m", "structsearch", "fit", "--data", str(data), "--model", "CL-VI"]
    return {"fit_default": fit + ["--out", str(work / "default")],
            "fit_starts_1": fit + ["--starts", "1", "--out", str(work / "starts1")],
            "script": [sys.executable, str(SCRIPT), str(data)]}


def _fit_answer(path: Path, n_train: int) -> dict:
    """A fit's answer; ``at_bound`` as the script and the random starts judge it: where the solver left a parameter
    on its bound (:data:`AT_BOUND_RTOL` of the span), not ``fit.json``'s practical flag (which also counts an
    estimate within its standard deviation of a bound), so that every answer is held to the same rule."""
    from ..engine.results import AT_BOUND_RTOL
    doc = json.loads(path.read_text())
    on_bound = [n for n, (lo, hi) in doc["bounds"].items()
                if min(doc["params"][n] - lo, hi - doc["params"][n]) <= AT_BOUND_RTOL * (hi - lo)]
    return {"rss": float(doc["mse"]["train"]) * n_train, "at_bound": sorted(on_bound), "params": doc["params"]}


def best_admissible(campaign, random_starts: int, seed: int, n_jobs: int) -> dict:
    """The lowest RSS of CL-VI over ``random_starts`` uniform random starts inside its box on the training
    maneuvers, among the solutions on no bound (:data:`AT_BOUND_RTOL` of the span, as ``FitResult.at_bound``)."""
    from joblib import Parallel, delayed
    from ..engine.results import AT_BOUND_RTOL
    from ..fitting.models import build_model
    from ..fitting.specs import resolve_candidate
    model = build_model(resolve_candidate("CL-VI"))
    train = campaign.split("train")
    problem, y = model.bind(train), train["CL"]
    lower, upper = model.bound_vectors(train)
    points = lower + np.random.default_rng(seed).uniform(size=(random_starts, len(lower))) * (upper - lower)
    fits = [o for o in Parallel(n_jobs=n_jobs)(delayed(solve_or_none)(problem, y, p, lower, upper) for p in points)
            if o is not None]
    span = upper - lower
    admissible = [2 * o.cost for o in fits
                  if np.all(np.minimum(o.theta - lower, upper - o.theta) > AT_BOUND_RTOL * span)]
    return {"n": random_starts, "admissible": len(admissible),
            "best_rss": float(min(admissible)) if admissible else float("nan"),
            "best_any_rss": float(min((2 * o.cost for o in fits), default=float("nan")))}


def solve_or_none(problem, y, start, lower, upper):
    """One SNLS solve from ``start``; None when it fails (a random start may land where Phi is singular)."""
    from ..data.errors import FitError
    from ..engine.snls import solve
    try:
        out = solve(problem, y, start, lower, upper)
    except (FitError, np.linalg.LinAlgError, FloatingPointError):
        return None
    return out if np.isfinite(out.cost) else None


def run_process(samples_seed: int = 0, repeats: int = 3, random_starts: int = 20, n_jobs: int = 2,
                progress=None, scale: float = 1.0) -> dict:
    """The whole-process comparison on the default simulated campaign of seed ``samples_seed`` (258,000
    samples; ``scale`` < 1 keeps fewer maneuvers)."""
    from ..data.campaign import write_campaign
    from ..flight.flighttest import build_campaign
    say = progress or (lambda m: None)
    campaign = build_campaign(seed=samples_seed, scale=scale)
    n_train = campaign.split("train").n_samples
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        data = write_campaign(campaign, work / "campaign")
        runs = {key: [] for key in commands(data, work)}
        for r in range(repeats):
            for key, command in commands(data, work).items():   # alternated: every repeat runs each once
                say(f"whole process {key}, repeat {r + 1}/{repeats}")
                runs[key].append(timed_process(command, work))
        answers = {"fit_default": _fit_answer(work / "default" / "fit.json", n_train),
                   "fit_starts_1": _fit_answer(work / "starts1" / "fit.json", n_train)}
        script = json.loads(runs["script"][-1][2])
        answers["script"] = {"rss": script["rss"], "at_bound": script["at_bound"], "params": script["theta"]}
    say(f"{random_starts} random starts of CL-VI for the best admissible optimum")
    reference = best_admissible(campaign, random_starts, 10_000 + samples_seed, n_jobs)
    candidates = [reference["best_rss"]] + [a["rss"] for a in answers.values() if not a["at_bound"]]
    best = float(np.nanmin(candidates))
    for a in answers.values():
        a["reached_best_admissible"] = bool(not a["at_bound"] and a["rss"] <= best * (1 + SAME_OPTIMUM_RTOL))
    median = {k: float(np.median([t for t, _, _ in v])) for k, v in runs.items()}
    return {"samples": campaign.data.n_samples, "train_samples": n_train, "repeats": repeats,
            "seconds": {k: [t for t, _, _ in v] for k, v in runs.items()}, "median_s": median,
            "peak_rss_mb": {k: float(max(m for _, m, _ in v)) for k, v in runs.items()},
            "ratio_to_script": {k: median[k] / median["script"] for k in ("fit_default", "fit_starts_1")},
            "script_read_s": script["read_s"], "script_fit_s": script["fit_s"], "script_nfev": script["nfev"],
            "answers": answers, "random_starts": reference, "best_admissible_rss": best}
