"""``structsearch bench``: speed, robustness and memory of the SNLS engine, measured side by side.

Figures (issue 2): the final lift model CL-VI (6 nonlinear + 5 linear
parameters) on a synthetic ~250,000-sample campaign with AR(1) coloured noise:

* four methods, each with the same repeats, random starts and memory trace: structsearch's
  SNLS, a numpy/scipy variable-projection prototype (issue 17's baseline, :func:`prototype_vp`),
  and the full 11-parameter problem by ``scipy.optimize.least_squares`` with the analytic and
  with the finite-difference Jacobian;
* like for like: the time per start that reaches the best answer over the same random starts;
* one start from the default start point: median wall time, iterations, answer;
* peak memory (Python allocations, traced) at N, and at 2N for the variable-projection methods;
* with ``run_search``: ``search --grid all`` in CL-VI starts measured in the same run;
  with ``run_staged``: the default fit's success against 64 random starts.
"""
from __future__ import annotations

import json
import os
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..flight.reference import FINAL_LIFT, final_lift_model
from ..engine.fullnls import full_nls
from ..engine.snls import solve
from ..flight.synthetic import campaign, with_coefficient


@dataclass(frozen=True)
class BenchConfig:
    samples: int = 250_000
    repeats: int = 3
    random_starts: int = 20
    seed: int = 2025
    n_jobs: int = 2
    noise_sigma: float = 0.01
    noise_phi: float = 0.95


def bench_data(samples: int, seed: int, sigma: float, phi: float):
    """A synthetic campaign with about ``samples`` samples (60 s maneuvers at 100 Hz)."""
    per = 6000
    n = max(3, int(round(samples / per)))
    kinds = {"quasi-steady": n - 2 * (n // 4), "dynamic": n // 4, "deep-dynamic": n // 4}
    model = final_lift_model()
    data = campaign(kinds, duration=per * 0.01, dt=0.01, seed=seed)
    return model, with_coefficient(data, model, FINAL_LIFT, noise_sigma=sigma, noise_phi=phi, seed=seed + 1)


def prototype_vp(problem, y, theta0, lower, upper, tol: float = 1e-10, max_nfev: int = 1000):
    """The baseline of issue 17: variable projection as a competent numpy/scipy prototype writes it.

    Per theta one thin QR of Phi (numpy), c and the residual from it, the Golub-Pereyra Jacobian
    -(I - Q Q^T) DPhi c - Q R^-T (DPhi^T r) with the derivative matrices assembled densely per
    parameter, the last evaluation cached for the Jacobian, and all m residuals handed to scipy's
    ``least_squares`` (trf, the same bounds, scaling and tolerances as structsearch). It shares only
    the model's ``evaluate`` (Phi and its derivative columns) with structsearch; none of its linear algebra.
    Returns (RSS, function evaluations, Jacobian evaluations).
    """
    from scipy.optimize import least_squares
    k = len(theta0)
    last: dict = {}

    def parts(theta):
        key = theta.tobytes()
        if key not in last:
            last.clear()
            ev = problem.evaluate(theta)
            q, r = np.linalg.qr(ev.phi)
            qty = q.T @ y
            c = np.linalg.solve(r, qty)
            last[key] = (ev, q, r, c, y - q @ qty)
        return last[key]

    def jac(theta):
        ev, q, r, c, res = parts(theta)
        n = ev.phi.shape[1]
        cols = []
        for j in range(k):
            d = np.zeros((len(y), n))
            sel = ev.params == j
            d[:, ev.rows[sel]] = ev.dphi[:, sel]
            a = d @ c
            a -= q @ (q.T @ a)
            b = q @ np.linalg.solve(r.T, d.T @ res)
            cols.append(-(a + b))
        return np.column_stack(cols)

    span = upper - lower
    x0 = np.clip(theta0, lower + 1e-10 * span, upper - 1e-10 * span)
    sol = least_squares(lambda th: parts(th)[4], x0, jac=jac, bounds=(lower, upper), method="trf",
                        x_scale=span, ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)
    res = parts(sol.x)[4]
    return float(res @ res), int(sol.nfev), int(sol.njev or 0)


def _prototype_run(problem, y, start, lower, upper):
    out, dt = _timed(prototype_vp, problem, y, start, lower, upper)
    return out[0], dt, out[1], out[2]


def _timed(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def _snls_run(problem, y, start, lower, upper):
    out, dt = _timed(solve, problem, y, start, lower, upper)
    return float(2 * out.cost), dt, out.nfev, out.njev


def _full_run(problem, y, start, lower, upper, jacobian="analytic"):
    fit, dt = _timed(full_nls, problem, y, start, lower, upper, jacobian=jacobian)
    return fit.rss, dt, fit.nfev, fit.njev


def _fd_run(problem, y, start, lower, upper):
    return _full_run(problem, y, start, lower, upper, "2-point")


# method key -> (table label, one-start runner); every method gets the same repeats, starts and memory trace
METHODS = {
    "snls": ("structsearch SNLS (variable projection, compressed)", _snls_run),
    "prototype": ("numpy/scipy variable-projection prototype (issue 17's baseline)", _prototype_run),
    "full": ("scipy least_squares, all 11 parameters, analytic Jacobian", _full_run),
    "fd": ("scipy least_squares, all 11 parameters, finite-difference Jacobian", _fd_run),
}


def _peak(runner, problem, y, start, lower, upper, samples: int):
    """Peak traced Python/numpy allocation of one start of ``runner``, with its wall time and evaluations."""
    tracemalloc.start()
    rss, dt, nfev, _ = runner(problem, y, start, lower, upper)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return {"samples": samples, "peak_mb": peak / 2**20, "seconds": dt, "nfev": nfev, "rss": rss}


def run(config: BenchConfig = BenchConfig(), progress=None) -> dict:
    say = progress or (lambda msg: None)
    model, data = bench_data(config.samples, config.seed, config.noise_sigma, config.noise_phi)
    problem = model.bind(data)
    y = data["CL"]
    lower, upper = model.bound_vectors()
    start = model.start_vector()
    say(f"data: {data.n_samples} samples in {data.n_segments} maneuvers")
    problem.evaluate(start)  # compile sympy regressors once, outside the timings

    one = {}
    for key, (label, runner) in METHODS.items():
        say(f"one start, {label}: {config.repeats} repeats")
        runs = [runner(problem, y, start, lower, upper) for _ in range(config.repeats)]
        one[key] = {"median_s": float(np.median([r[1] for r in runs])), "rss": runs[0][0], "nfev": runs[0][2],
                    "njev": runs[0][3]}

    rng = np.random.default_rng(config.seed)
    starts = lower + rng.uniform(size=(config.random_starts, len(start))) * (upper - lower)
    from joblib import Parallel, delayed
    multi = {}
    for key, (label, runner) in METHODS.items():
        say(f"{config.random_starts} random starts, {label}")
        multi[key] = Parallel(n_jobs=config.n_jobs)(delayed(runner)(problem, y, s, lower, upper) for s in starts)
    best = min(min(r[0] for r in runs) for runs in multi.values())
    best = min([best] + [o["rss"] for o in one.values()])

    def ok(rss):
        return rss <= best * (1 + 1e-6)

    random = {}
    for key, runs in multi.items():
        hits = int(sum(ok(r[0]) for r in runs))
        total = float(sum(r[1] for r in runs))
        random[key] = {"success": hits, "median_s": float(np.median([r[1] for r in runs])), "total_s": total,
                       # like for like: the expected wall time per start that reaches the best answer
                       "s_per_success": total / hits if hits else float("nan")}
    for key in one:
        one[key]["reached_best"] = bool(ok(one[key]["rss"]))

    say("memory of one start of every method at N, and of the variable-projection methods at 2N")
    # the same maneuvers twice: twice the samples with identical per-sample character
    doubled = data.select(list(range(data.n_segments)) * 2)
    problem2, y2 = model.bind(doubled), doubled["CL"]
    problem2.evaluate(start)
    memory = {key: [_peak(runner, problem, y, start, lower, upper, data.n_samples)]
              for key, (_, runner) in METHODS.items()}
    for key in ("snls", "prototype"):
        memory[key].append(_peak(METHODS[key][1], problem2, y2, start, lower, upper, doubled.n_samples))
    import resource
    snls_mem = memory["snls"]
    return {
        "process_peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "config": config.__dict__,
        "machine": {"cpus": os.cpu_count()},
        "model": model.name,
        "n_nonlinear": len(model.nonlinear_names), "n_linear": len(model.linear_names),
        "samples": data.n_samples, "maneuvers": data.n_segments,
        "methods": {k: v[0] for k, v in METHODS.items()},
        "one_start": one,
        "random_starts": {"n": config.random_starts, "best_rss": best, **random},
        "memory_by_method": memory,
        "memory": snls_mem,
        "scaling": {"time_ratio": snls_mem[1]["seconds"] / snls_mem[0]["seconds"],
                    "memory_ratio": snls_mem[1]["peak_mb"] / snls_mem[0]["peak_mb"]},
    }


def _peak_rss_mb(pid: int) -> float:
    """Peak resident memory (VmHWM) of a process in MB; 0 where /proc is not available."""
    try:
        for line in open(f"/proc/{pid}/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def _children(pid: int) -> list[int]:
    out = []
    try:
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    fields = open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()
                    if int(fields[1]) == pid:
                        out.append(int(entry))
                except (OSError, IndexError, ValueError):
                    continue
    except OSError:
        pass
    return out


def run_search(n_jobs: int = 2, seed: int = 0, progress=None) -> dict:
    """``search --grid all`` on the default simulated campaign, from an empty cache."""
    import tempfile
    from ..flight.flighttest import build_campaign
    from ..fitting.options import FitOptions
    from ..search.pipeline import search
    from ..report.tables import write_tables
    say = progress or (lambda m: None)
    say("simulating the default campaign for the search benchmark")
    t0 = time.perf_counter()
    campaign = build_campaign(seed=seed)
    t_sim = time.perf_counter() - t0
    say("one CL-VI start (the unit of the search's wall time), three times")
    unit = one_start_unit(campaign)
    with tempfile.TemporaryDirectory() as tmp:
        say("search --grid all from an empty cache")
        t0 = time.perf_counter()
        result = search(campaign, "all", Path(tmp), n_jobs=n_jobs, options=FitOptions())
        write_tables(result.grids, Path(tmp))
        total = time.perf_counter() - t0
        workers = _children(os.getpid())
        worker_peaks = [_peak_rss_mb(p) for p in workers]
    winners = {g: next((s.name for s in r if not s.failed), None) for g, r in result.grids.items()}
    main_peak = _peak_rss_mb(os.getpid())
    with tempfile.TemporaryDirectory() as tmp:
        say("search --grid all --cv-method one-step from an empty cache")
        t0 = time.perf_counter()
        one_step = search(campaign, "all", Path(tmp), n_jobs=n_jobs, options=FitOptions(cv_method="one-step"))
        write_tables(one_step.grids, Path(tmp))
        total_one_step = time.perf_counter() - t0
    return {"samples": campaign.data.n_samples, "simulate_s": t_sim, "search_s": total,
            "cl_vi_start_s": unit, "search_in_cl_vi_starts": total / unit,
            "by_grid_s": result.seconds, "candidates": {g: len(r) for g, r in result.grids.items()},
            "failed": {g: sum(s.failed for s in r) for g, r in result.grids.items()},
            "winners": winners, "n_jobs": n_jobs, "main_peak_rss_mb": main_peak,
            "worker_peak_rss_mb": worker_peaks,
            "one_step": {"search_s": total_one_step, "search_in_cl_vi_starts": total_one_step / unit,
                         "by_grid_s": one_step.seconds, **ranking_agreement(result.grids, one_step.grids)}}


def ranking_agreement(refit: dict, one_step: dict) -> dict:
    """How the rankings of two searches of the same grids agree: the same first candidate and the same
    admissible ones per grid, the candidates whose rank moved, the largest relative CV MSE difference."""
    out = {"same_first": {}, "same_admissible": {}, "moved": {}, "max_rel_cv_difference": {}}
    for g, ranked in refit.items():
        a = {s.name: s for s in ranked if not s.failed}
        b = {s.name: s for s in one_step[g] if not s.failed}
        first = lambda r: next((s.name for s in r if not s.failed), None)  # noqa: E731
        out["same_first"][g] = first(ranked) == first(one_step[g])
        out["same_admissible"][g] = {n for n, s in a.items() if s.admissible} == \
            {n for n, s in b.items() if s.admissible}
        out["moved"][g] = sorted(n for n in a if n in b and a[n].rank != b[n].rank)
        diffs = [abs(b[n].cv.mse / a[n].cv.mse - 1) for n in a
                 if n in b and a[n].cv is not None and b[n].cv is not None and a[n].cv.mse > 0]
        out["max_rel_cv_difference"][g] = float(np.nanmax(diffs)) if diffs and not np.all(np.isnan(diffs)) \
            else float("nan")
    return out


def one_start_unit(campaign, repeats: int = 3) -> float:
    """Median wall time of one CL-VI fit from its declared start on the campaign's training maneuvers,
    with the default covariance (what ``structsearch fit --model CL-VI --starts 1`` computes, without
    cross-validation and I/O): the machine-independent unit the search is measured in."""
    from ..fitting.models import build_model
    from ..fitting.specs import resolve_candidate
    model = build_model(resolve_candidate("CL-VI"))
    train = campaign.split("train")
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        model.fit(train, n_starts=1)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def run_staged(campaigns: int = 50, scale: float = 0.05, random_starts: int = 64, n_jobs: int = 2,
               progress=None) -> dict:
    """Success of the default fit of CL-VI (reaches the best cost of ``random_starts`` uniform random
    starts inside the bounds, within 1e-6 relative) over seeded simulated campaigns: the staged fit
    (``structsearch fit``: the quasi-steady version from its declared start and a quasi-random point,
    then CL-VI from those estimates, its declared start and three quasi-random points) against the
    previous default (declared start plus three quasi-random points) and a single random start."""
    from joblib import Parallel, delayed
    from ..flight.flighttest import build_campaign
    from ..fitting.models import build_model
    from ..fitting.options import FitOptions
    from ..fitting.candidate_fit import fit_staged
    from ..fitting.specs import resolve_candidate
    say = progress or (lambda m: None)
    candidate = resolve_candidate("CL-VI")
    model = build_model(candidate)
    rows = []
    for seed in range(campaigns):
        campaign = build_campaign(seed=seed, scale=scale)
        train, validation = campaign.split("train"), campaign.split("validation")
        problem, y = model.bind(train), train["CL"]
        lower, upper = model.bound_vectors(train)
        rng = np.random.default_rng(10_000 + seed)
        points = lower + rng.uniform(size=(random_starts, len(lower))) * (upper - lower)
        random_fits = Parallel(n_jobs=n_jobs)(delayed(solve)(problem, y, p, lower, upper) for p in points)
        random_rss = [float(2 * o.cost) for o in random_fits]
        best_random = min(random_fits, key=lambda o: o.cost)
        span = upper - lower
        on_bound = [name for name, v, lo, hi, w in zip(model.nonlinear_names, best_random.theta, lower, upper, span)
                    if min(v - lo, hi - v) <= 1e-6 * w]
        t0 = time.perf_counter()
        staged = fit_staged(candidate, train, validation, None, FitOptions(cv_folds=0))
        t_staged = time.perf_counter() - t0
        t0 = time.perf_counter()
        previous = model.fit(train, n_starts=4, seed=0)
        t_previous = time.perf_counter() - t0
        staged_rss = float(staged.mse_train * len(y))
        previous_rss = float(np.sum(previous.residuals ** 2))
        best = min(min(random_rss), staged_rss, previous_rss)
        ok = best * (1 + 1e-6)
        rows.append({"seed": seed, "samples": len(y), "best_rss": best, "best_on_bound": on_bound,
                     "staged_ok": staged_rss <= ok,
                     "previous_ok": previous_rss <= ok,
                     "random_ok": int(sum(r <= ok for r in random_rss)),
                     "staged_s": t_staged, "previous_s": t_previous})
        say(f"campaign {seed}: staged {'reaches' if rows[-1]['staged_ok'] else 'MISSES'} the best; "
            f"{rows[-1]['random_ok']}/{random_starts} random starts do")
    n = len(rows)
    return {"campaigns": n, "scale": scale, "random_starts": random_starts,
            "samples_median": float(np.median([r["samples"] for r in rows])),
            "staged_success": int(sum(r["staged_ok"] for r in rows)),
            "previous_success": int(sum(r["previous_ok"] for r in rows)),
            "random_start_success": float(sum(r["random_ok"] for r in rows) / (n * random_starts)),
            "staged_median_s": float(np.median([r["staged_s"] for r in rows])),
            "previous_median_s": float(np.median([r["previous_s"] for r in rows])),
            "missed": [r["seed"] for r in rows if not r["staged_ok"]],
            "best_on_bound": {r["seed"]: r["best_on_bound"] for r in rows if r["best_on_bound"]}, "rows": rows}


def staged_markdown(s: dict) -> str:
    n = s["campaigns"]
    return "\n".join([
        "## Default fit right the first time (CL-VI, staged starts)", "",
        f"{n} seeded simulated campaigns at scale {s['scale']} (median {s['samples_median']:.0f} training "
        f"samples); success = within 1e-6 relative of the best RSS found by {s['random_starts']} uniform random "
        "starts inside the bounds (and by the fits below).", "",
        "| fit | reached the best | median wall time [s] |", "|---|---|---|",
        f"| staged (`structsearch fit`: the previous default plus the estimates of the quasi-steady version) | {s['staged_success']}/{n} "
        f"({100 * s['staged_success'] / n:.0f} %) | {s['staged_median_s']:.2f} (with statistics) |",
        f"| previous default (declared start + 3 quasi-random) | {s['previous_success']}/{n} "
        f"({100 * s['previous_success'] / n:.0f} %) | {s['previous_median_s']:.2f} (with statistics) |",
        f"| one uniform random start | {100 * s['random_start_success']:.0f} % of {n * s['random_starts']} | |",
        "", f"Campaigns the staged fit missed: {', '.join(map(str, s['missed'])) or 'none'}. Campaigns whose best "
        "random start ends on a bound of the search box (a solution admissibility rejects): "
        + (", ".join(f"{seed} ({', '.join(names)})" for seed, names in s["best_on_bound"].items()) or "none")
        + ".", ""])


def search_markdown(s: dict) -> str:
    lines = ["## search --grid all (default simulated campaign, empty cache)", "",
             f"{s['samples']} samples; {s['n_jobs']} processes; simulation {s['simulate_s']:.1f} s (not counted).", "",
             "| grid | candidates | failed | wall time [s] | ranked first |", "|---|---|---|---|---|"]
    for g, sec in s["by_grid_s"].items():
        lines.append(f"| {g} | {s['candidates'][g]} | {s['failed'][g]} | {sec:.1f} | {s['winners'][g]} |")
    lines += [f"| **all** | {sum(s['candidates'].values())} | {sum(s['failed'].values())} | "
              f"**{s['search_s']:.1f}** | |", "",
              "The drag and pitch times include fitting the lift models they depend on when the lift grid has "
              "not done so already (it has, in `all`).", "",
              f"One CL-VI start (declared start, default covariance, training maneuvers) took "
              f"{s['cl_vi_start_s']:.2f} s in the same run: the search took **{s['search_in_cl_vi_starts']:.0f} "
              "CL-VI starts' worth** of wall time (issue 17's target: 10).", "",
              f"Peak resident memory: main process {s['main_peak_rss_mb']:.0f} MB, workers "
              + ", ".join(f"{w:.0f} MB" for w in s["worker_peak_rss_mb"]) +
              f" (sum {s['main_peak_rss_mb'] + sum(s['worker_peak_rss_mb']):.0f} MB).", ""]
    o = s.get("one_step")
    if o:
        lines += ["### The same search with `--cv-method one-step`", "",
                  "Each cross-validation fold of a nonlinear candidate by one Gauss-Newton step from the full "
                  "fit instead of a solve (linear candidates: exact either way).", "",
                  "| grid | wall time [s] | same first | same admissible | candidates whose rank moved | "
                  "largest relative CV MSE difference |", "|---|---|---|---|---|---|"]
        for g, sec in o["by_grid_s"].items():
            moved = ", ".join(o["moved"][g]) or "none"
            lines.append(f"| {g} | {sec:.1f} | {'yes' if o['same_first'][g] else 'NO'} | "
                         f"{'yes' if o['same_admissible'][g] else 'NO'} | {moved} | "
                         f"{o['max_rel_cv_difference'][g]:.2%} |")
        lines += [f"| **all** | **{o['search_s']:.1f}** | | | | |", "",
                  f"That is **{o['search_in_cl_vi_starts']:.0f} CL-VI starts' worth** of wall time.", ""]
    return "\n".join(lines)


def to_markdown(fig: dict) -> str:
    o, r, sc = fig["one_start"], fig["random_starts"], fig["scaling"]
    labels = fig["methods"]
    n = r["n"]
    headline = r["prototype"]["s_per_success"] / r["snls"]["s_per_success"]
    lines = [
        "# structsearch bench",
        "",
        f"Model {fig['model']} ({fig['n_nonlinear']} nonlinear + {fig['n_linear']} linear parameters) on a "
        f"synthetic campaign of {fig['samples']} samples in {fig['maneuvers']} maneuvers "
        f"(AR(1) noise, sigma {fig['config']['noise_sigma']}, phi {fig['config']['noise_phi']}); "
        f"{fig['machine']['cpus']} CPUs. Every method gets the same repeats ({fig['config']['repeats']}), the same "
        f"{n} random starts and the same memory trace.",
        "",
        "## Like for like: time to the best answer from the same random starts",
        "",
        f"{n} uniform random starts inside the bounds, {fig['config']['n_jobs']} processes; success = within 1e-6 "
        f"relative of the best RSS any method found ({r['best_rss']:.8g}). Time per success = the starts' summed "
        "wall time / the starts that reached the best: the expected cost of the answer by multistart.",
        "",
        "| method | reached the best | median wall time per start [s] | time per success [s] |",
        "|---|---|---|---|",
    ]
    for key, label in labels.items():
        m = r[key]
        lines.append(f"| {label} | {m['success']}/{n} | {m['median_s']:.3f} | {m['s_per_success']:.3f} |")
    lines += [
        "",
        f"Headline: structsearch reaches the best answer **{headline:.1f}x** faster than the numpy/scipy "
        f"prototype (time per success), {r['full']['s_per_success'] / r['snls']['s_per_success']:.1f}x faster than "
        f"full NLS with the analytic Jacobian and {r['fd']['s_per_success'] / r['snls']['s_per_success']:.1f}x "
        "faster than scipy's default.",
        "",
        "## One start from the default start point",
        "",
        "| method | median wall time [s] | ratio to the prototype | function evaluations | Jacobian evaluations "
        "| RSS | reached the best |",
        "|---|---|---|---|---|---|---|",
    ]
    for key, label in labels.items():
        m = o[key]
        lines.append(f"| {label} | {m['median_s']:.3f} | {m['median_s'] / o['prototype']['median_s']:.2f} | "
                     f"{m['nfev']} | {m['njev'] or '-'} | {m['rss']:.6g} | {'yes' if m['reached_best'] else 'no'} |")
    lines += ["", f"One start of structsearch takes **{o['snls']['median_s'] / o['prototype']['median_s']:.2f}x** the "
              "prototype's wall time (issue 17's target: at most 0.8x).", "",
              "## Memory and scaling (one start, traced Python/numpy allocations)", "",
              "| method | samples | peak memory [MB] | wall time [s] | function evaluations |", "|---|---|---|---|---|"]
    for key, rows in fig["memory_by_method"].items():
        for m in rows:
            lines.append(f"| {labels[key]} | {m['samples']} | {m['peak_mb']:.1f} | {m['seconds']:.3f} | {m['nfev']} |")
    lines += ["", f"Doubling the samples multiplies the SNLS time by {sc['time_ratio']:.2f} and its peak memory by "
              f"{sc['memory_ratio']:.2f}. Peak resident memory of the whole bench process (interpreter, "
              f"both data sets, all fits): {fig['process_peak_rss_mb']:.0f} MB.", "",
              "Success counts over a handful of starts carry binomial noise of about "
              f"sqrt(n p (1-p)) = {np.sqrt(n * 0.25):.1f} starts at p = 1/2.", ""]
    if "search" in fig:
        lines.append(search_markdown(fig["search"]))
    if "staged" in fig:
        lines.append(staged_markdown(fig["staged"]))
    return "\n".join(lines)


def write(fig: dict, out: Path) -> tuple[Path, Path]:
    from ..data.atomic import write_text
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / "bench.md", out / "bench.json"
    write_text(md, to_markdown(fig))
    write_text(js, json.dumps(fig, indent=2))
    return md, js
