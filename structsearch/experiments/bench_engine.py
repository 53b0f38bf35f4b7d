"""The engine half of ``structsearch bench``: CL-VI on a synthetic ~250,000-sample campaign with AR(1)
coloured noise, four methods side by side with the same repeats, random starts and memory trace:
structsearch's SNLS, a numpy/scipy variable-projection prototype (issue 17's baseline,
:func:`prototype_vp`), and the full 11-parameter problem by ``scipy.optimize.least_squares`` with the
analytic and with the finite-difference Jacobian.
"""
from __future__ import annotations

import os
import time
import tracemalloc
from dataclasses import dataclass

import numpy as np

from ..engine.fullnls import full_nls
from ..engine.snls import solve
from ..flight.reference import FINAL_LIFT, final_lift_model
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
    # whole processes too (``structsearch fit`` against the reference script, alternated, `repeats` times each)
    processes: bool = True


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


def _memory(model, data, problem, y, start, lower, upper) -> dict:
    """The peak memory of one start of every method at N samples, and of the variable-projection methods at 2N:
    the same maneuvers twice, twice the samples with identical per-sample character."""
    doubled = data.select(list(range(data.n_segments)) * 2)
    problem2, y2 = model.bind(doubled), doubled["CL"]
    problem2.evaluate(start)
    memory = {key: [_peak(runner, problem, y, start, lower, upper, data.n_samples)]
              for key, (_, runner) in METHODS.items()}
    for key in ("snls", "prototype"):
        memory[key].append(_peak(METHODS[key][1], problem2, y2, start, lower, upper, doubled.n_samples))
    return memory


def run_engine(config: BenchConfig = BenchConfig(), progress=None) -> dict:
    """The engine figures (see the module's docstring)."""
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
    memory = _memory(model, data, problem, y, start, lower, upper)
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
