"""Command line: ``structsearch <command>`` (also ``python -m structsearch``)."""
from __future__ import annotations

import os

# One BLAS thread per process: the products here are tall and skinny (m x ~10), where
# threading costs more than it gains, and parallelism comes from joblib processes.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402


def _calibration(args) -> int:
    from .experiments.calibration import run
    from .data.atomic import write_json, write_text
    from .experiments.calibration_doc import calibration_dict, calibration_markdown
    say = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    cal = run(n_campaigns=args.campaigns, scale=args.scale, n_jobs=_jobs(args), progress=say)
    out = Path(args.out)
    command = f"structsearch bench --calibration --campaigns {args.campaigns} --scale {args.scale}"
    write_text(out / "calibration.md", calibration_markdown(cal, command))
    write_json(out / "calibration.json", calibration_dict(cal), indent=1)
    for k in cal.kinds:
        if k.worst95 is None:
            print(f"{k.kind}: not estimable on these campaigns (every standard deviation NaN)")
            continue
        missing = (f"; not estimable for {', '.join(k.not_estimable_models)}"
                   if k.not_estimable_models else "")
        print(f"{k.kind}: 95 % coverage {k.pooled95:.3f} (worst {k.worst95.coverage95:.2f} "
              f"{k.worst95.model} {k.worst95.parameter}{missing}), 68 % {k.pooled68:.3f}; gap test rejects "
              f"{k.rejections}/{k.gap_tests}; goals {'met' if k.meets_goals else 'NOT met'}")
    print(f"best calibrated: {cal.best.kind}; wrote {out / 'calibration.md'}")
    return 0


def _bench(args) -> int:
    if args.calibration:
        return _calibration(args)
    from .experiments.bench import BenchConfig, run, write
    config = BenchConfig(samples=args.samples, repeats=args.repeats, random_starts=args.starts,
                         seed=args.seed, n_jobs=_jobs(args))
    say = lambda msg: print(f"bench: {msg}", file=sys.stderr, flush=True)  # noqa: E731
    fig = run(config, progress=say)
    if not args.no_search:
        from .experiments.bench import run_search
        fig["search"] = run_search(n_jobs=_jobs(args), progress=say)
    if args.staged:
        from .experiments.bench import run_staged
        fig["staged"] = run_staged(campaigns=args.staged, n_jobs=_jobs(args), progress=say)
    md, js = write(fig, Path(args.out))
    o, r = fig["one_start"], fig["random_starts"]
    print(f"one start: SNLS {o['snls']['median_s']:.3f} s = {o['snls']['median_s'] / o['prototype']['median_s']:.2f}x "
          f"the prototype's {o['prototype']['median_s']:.3f} s; time per success over {r['n']} random starts: SNLS "
          f"{r['snls']['s_per_success']:.3f} s, prototype {r['prototype']['s_per_success']:.3f} s, full NLS "
          f"{r['full']['s_per_success']:.3f} s, finite differences {r['fd']['s_per_success']:.3f} s; peak memory "
          f"{fig['memory'][0]['peak_mb']:.0f} MB -> {fig['memory'][1]['peak_mb']:.0f} MB at 2x samples")
    if "search" in fig:
        s = fig["search"]
        print("search --grid all: " + ", ".join(f"{g} {t:.1f} s" for g, t in s["by_grid_s"].items())
              + f"; total {s['search_s']:.1f} s on {s['n_jobs']} processes = "
              f"{s['search_in_cl_vi_starts']:.0f} CL-VI starts of {s['cl_vi_start_s']:.2f} s")
    if "staged" in fig:
        st = fig["staged"]
        print(f"staged default fit reached the best of {st['random_starts']} random starts on "
              f"{st['staged_success']}/{st['campaigns']} campaigns (previous default {st['previous_success']}, "
              f"one random start {100 * st['random_start_success']:.0f} %)")
    print(f"wrote {md} and {js}")
    return 0


def _simulate(args) -> int:
    from .data.campaign import write_campaign
    from .flight.flighttest import build_campaign
    campaign = build_campaign(seed=args.seed, withhold=args.withhold or (), scale=args.scale,
                              extras=args.extras, aircraft=args.aircraft, anomaly=args.anomaly, raw=args.raw,
                              slow_errors=args.slow_errors)
    out = write_campaign(campaign, Path(args.out), fmt=args.format)
    d = campaign.data
    n_val = sum(m.split == "validation" for m in campaign.maneuvers)
    print(f"wrote {out}: {len(campaign.maneuvers)} maneuvers ({n_val} validation), {d.n_samples} samples; "
          f"truth: {campaign.extra['truth']}")
    return 0


def _cutoff(text: str) -> tuple[str, float]:
    """One --cutoff NAME=HZ."""
    import math
    name, eq, value = text.partition("=")
    try:
        hz = float(value)
    except ValueError:
        hz = math.nan
    if not (eq and name.strip() and math.isfinite(hz) and hz > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected CHANNEL=HZ with a positive frequency, e.g. q=2")
    return name.strip(), hz


def _preprocess(args) -> int:
    import time
    import numpy as np
    from .data.campaign import read_campaign, write_campaign
    from .preprocess.pipeline import preprocess, truth_agreement
    from .report.preprocess_doc import write
    started = time.perf_counter()
    if Path(args.raw).resolve() == Path(args.out).resolve():
        raise_error(f"--out {args.out} is the raw campaign itself: it would be replaced; give another directory")
    raw = read_campaign(args.raw, fmt="raw")
    last = {}

    def progress(stage: str, fraction: float) -> None:
        step = int(fraction * 10)
        if last.get(stage) != step:
            last[stage] = step
            print(f"preprocess: {stage} {100 * fraction:.0f} %", file=sys.stderr, flush=True)

    result = preprocess(raw, dict(args.cutoff or []), use_suggested=args.cutoffs == "spectra",
                        stall_alpha_rad=None if args.stall_alpha is None else np.deg2rad(args.stall_alpha),
                        stall_state=args.stall_state,
                        progress=None if args.quiet else progress)
    out = write_campaign(result.campaign, Path(args.out))
    seconds = time.perf_counter() - started
    command = "structsearch preprocess " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["preprocess"] else \
        f"structsearch preprocess --raw {args.raw} --out {args.out}"
    md = write(result, out, command, seconds, figures=not args.no_figures)
    worst = {}
    for _, name, r2 in truth_agreement(result.campaign):
        worst[name] = np.fmin(worst.get(name, np.inf), r2)   # a NaN R^2 (constant truth) does not hide others
    errors = ", ".join(f"{e.name} {e.estimate:.4g} +- {e.sd:.2g}" for e in result.reconstruction.errors)
    print(f"sensor errors: {errors}")
    if worst:
        print("min R^2 per maneuver against the truth: " + ", ".join(f"{k} {v:.3f}" for k, v in worst.items()))
    print(f"wrote {out} (standard campaign) and {md} in {seconds:.1f} s")
    return 0


def _study(args) -> int:
    from .data.campaign import read_campaign
    from .fitting.options import FitOptions
    from .study.study import run_study
    from .report import figures
    from .report.study_doc import write
    campaign = read_campaign(args.data)
    out = Path(args.out)
    cache = Path(args.cache) if args.cache else out
    study = run_study(campaign, cache, FitOptions(n_starts=args.starts), n_jobs=_jobs(args),
                      progress=None if args.quiet else stderr_progress)
    command = (f"structsearch study --data {args.data} --out {args.out}" + (f" --cache {args.cache}" if args.cache
                                                                            else "")
               + (f" --starts {args.starts}" if args.starts != 4 else ""))
    written = write(study, out, command, figures=figures.plt is not None)
    print(f"wrote {len(written)} files in {out} (final_vs_van_ingen, dynamic_stalls, separation_matrix, derived, "
          "collinearity, r2_boxes.png)")
    return 0


def stderr_progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def raise_error(message: str):
    from .data.errors import DeclarationError
    raise DeclarationError(message)


def _fit(args) -> int:
    from .data.campaign import read_campaign
    from .data.atomic import write_json, write_text
    from .fitting.options import check_box_names, FitOptions
    from .fitting.candidate_fit import fit_lift_model, fit_staged
    from .fitting.specs import resolve_candidate
    from .report.documents import fit_document
    from .report.tables import parameter_table
    campaign = read_campaign(args.data)
    candidate = resolve_candidate(args.model)
    options = FitOptions(n_starts=args.starts, seed=args.seed, covariance=args.covariance, parameter_boxes=_bounds(args))
    check_box_names(options.parameter_boxes, [candidate])
    train, validation = campaign.split("train"), campaign.split("validation")
    lift = fit_lift_model(candidate, train, validation, options)
    summary = fit_staged(candidate, train, validation, lift, options)
    if summary.failed:
        raise_error(summary.error)
    out = Path(args.out)
    write_json(out / "fit.json", fit_document(summary, lift))
    write_text(out / "fit.md", f"# {candidate.name}\n\n" + parameter_table(summary, "md"))
    not_converged = "" if summary.converged else f"; the optimizer did NOT converge ({summary.message})"
    print(f"{candidate.name}: MSE train {summary.mse_train:.4g}, validation {summary.mse_validation:.4g}; "
          f"{len(summary.insignificant)} parameter(s) accept zero, {len(summary.at_bound)} at a bound"
          f"{not_converged}; wrote {out / 'fit.json'}")
    return 0


def _search(args) -> int:
    from .data.campaign import read_campaign
    from .fitting.options import check_box_names, FitOptions
    from .search.pipeline import grids_for, search
    from .report.tables import write_tables
    from .study.thesis_estimator import thesis_estimator_fits
    campaign = read_campaign(args.data)
    options = FitOptions(n_starts=args.starts, seed=args.seed, covariance=args.covariance, parameter_boxes=_bounds(args),
                        cv_method=args.cv_method)
    check_box_names(options.parameter_boxes, [c for g in grids_for(args.grid) for c in g.candidates])
    client = _dask_client(args) if args.backend == "dask" else None
    try:
        result = search(campaign, args.grid, Path(args.out), n_jobs=_jobs(args), options=options,
                        backend=args.backend, max_correlation=_max_correlation(args),
                        progress=None if args.quiet else stderr_progress)
    finally:
        if client is not None:
            client.close()
    write_tables(result.grids, Path(args.out), thesis_estimator_fits(result.grids, campaign))
    _print_winners(result)
    print(f"wrote {Path(args.out) / 'ranking.csv'} and the tables of each grid")
    return 0


def _bound(text: str) -> tuple[str, tuple[float, float]]:
    """One --bound NAME=LO:HI."""
    import math
    name, eq, box = text.partition("=")
    lo, colon, hi = box.partition(":")
    try:
        lo_v, hi_v = float(lo), float(hi)
    except ValueError:
        lo_v = hi_v = math.nan
    if not (eq and colon and name.strip().isidentifier() and math.isfinite(lo_v) and math.isfinite(hi_v)):
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=LO:HI with finite numbers, e.g. tau2_ss=0:5")
    if not lo_v < hi_v:
        raise argparse.ArgumentTypeError(f"{text!r}: LO must be below HI")
    return name.strip(), (lo_v, hi_v)


def _bounds(args) -> tuple:
    """The --bound options as ((name, (lo, hi)), ...), the last one of a name winning."""
    return tuple(sorted(dict(getattr(args, "bound", None) or []).items()))


def _max_correlation(args) -> float:
    return args.max_correlation


def _dask_client(args):
    """A dask.distributed Client: the given scheduler, else a local cluster of --jobs single-threaded workers."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise_error("--backend dask needs the optional dependency dask.distributed "
                    "(pip install 'structsearch[dask]')")
    if args.scheduler:
        return Client(args.scheduler)
    return Client(LocalCluster(n_workers=_jobs(args), threads_per_worker=1, processes=True,
                               dashboard_address=None))


def _held_out(s) -> str:
    if s.cv is None:
        return "validation"
    return f"{s.cv_folds}-fold {'one-step ' if s.cv_method == 'one-step' else ''}CV"


def _print_winners(result) -> None:
    from .search.ranking import passed_over
    for grid, ranked in result.grids.items():
        ok = [s for s in ranked if not s.failed]
        failed = len(ranked) - len(ok)
        if not ok:
            print(f"{grid}: every candidate failed")
            continue
        best, runner_up = ok[0], (ok[1] if len(ok) > 1 else None)
        margin = ""
        if runner_up is not None:
            margin = (f"; next {runner_up.name} ({runner_up.n_params} parameters, {_held_out(best)} MSE "
                      f"{runner_up.comparison.mse / best.comparison.mse - 1:+.1%})")
        not_converged = [s.name for s in ok if not s.converged]
        warning = (f"; optimizer did not converge for {', '.join(not_converged)}" if not_converged else "")
        n_admissible = sum(bool(s.admissible) for s in ok)
        status = "" if best.admissible else " (NOT admissible: no candidate is)"
        print(f"{grid}: {best.name}{status} ({best.n_params} parameters, {_held_out(best)} MSE "
              f"{best.comparison.mse:.4g}, validation MSE {best.mse_validation:.4g}){margin}; {len(ok)} fitted "
              f"({n_admissible} admissible), {failed} failed"
              f"{warning}, {result.seconds[grid]:.1f} s")
        for s in passed_over(ranked)[:3]:
            print(f"  passed over {s.name} ({_held_out(s)} MSE {s.comparison.mse / best.comparison.mse - 1:+.1%}): "
                  f"{'; '.join(s.reasons)}")


def _simulated_as(directory: Path) -> dict | None:
    """How the campaign in ``directory`` was simulated (seed, scale, ...), or None if there is none."""
    import tomllib
    toml = directory / "campaign.toml"
    if not toml.exists():
        return None
    try:
        doc = tomllib.loads(toml.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return {"manifest": "unreadable"}
    return {k: doc.get(k) for k in ("seed", "scale", "withheld", "slow_errors", "extras")}


def _demo(args) -> int:
    import time
    from .data.campaign import read_campaign, write_campaign
    from .flight.flighttest import build_campaign
    from .fitting.options import FitOptions
    from .search.pipeline import search
    from .report.tables import write_tables
    from .study.thesis_estimator import thesis_estimator_fits
    out = Path(args.out)
    t0 = time.perf_counter()
    camp_dir = out / "campaign"
    wanted = {"seed": 0, "scale": float(args.scale), "withheld": "none", "slow_errors": 1.0, "extras": False}
    found = _simulated_as(camp_dir)
    if found == wanted:
        campaign = read_campaign(camp_dir)
        print(f"reusing the simulated campaign in {camp_dir}")
    else:
        if found is not None:
            print(f"{camp_dir} holds another campaign ({', '.join(f'{k} = {v}' for k, v in found.items())}); "
                  "simulating it again")
        print(f"simulating the default flight-test campaign (seed 0, scale {args.scale}) ...", flush=True)
        write_campaign(build_campaign(seed=0, scale=args.scale), camp_dir)
        campaign = read_campaign(camp_dir)
    t_sim = time.perf_counter() - t0
    jobs = _jobs(args)
    result = search(campaign, "all", out, n_jobs=jobs, options=FitOptions(n_starts=args.starts),
                    max_correlation=_max_correlation(args), progress=None if args.quiet else stderr_progress)
    write_tables(result.grids, out, thesis_estimator_fits(result.grids, campaign))
    total = time.perf_counter() - t0
    _print_winners(result)
    print(f"campaign: {len(campaign.maneuvers)} maneuvers, {campaign.data.n_samples} samples "
          f"({t_sim:.0f} s); search of {sum(len(r) for r in result.grids.values())} candidates on {jobs} "
          f"process(es): {total - t_sim:.0f} s; total {total:.0f} s")
    print(f"tables and ranking.csv in {out}")
    from .diagnosis.story import van_ingen_story
    from .report.diagnosis_doc import write_story
    t1 = time.perf_counter()
    # the story's diagnoses use the diagnose command's defaults (2 starts), not the search's --starts
    story = van_ingen_story(campaign, progress=None if args.quiet else stderr_progress, n_jobs=jobs)
    _, story_md = write_story(story, out, f"structsearch demo --out {out}"
                              + (f" --scale {args.scale:g}" if args.scale != 1.0 else ""))
    print(f"the story, Van Ingen's simulator model against the flight data ({time.perf_counter() - t1:.0f} s; "
          f"{story_md}):")
    for line in story["lines"]:
        print(f"  {line}")
    from .study.study import run_study
    from .report import figures
    from .report.study_doc import write as write_study
    t2 = time.perf_counter()
    study = run_study(campaign, out, FitOptions(n_starts=args.starts), n_jobs=jobs,
                      progress=None if args.quiet else stderr_progress)
    written = write_study(study, out / "study", f"structsearch study --data {camp_dir} --out {out / 'study'} "
                          f"--cache {out}" + (f" --starts {args.starts}" if args.starts != 4 else ""),
                          figures=figures.plt is not None)
    print(f"the thesis' comparison tables: {len(written)} files in {out / 'study'} ({time.perf_counter() - t2:.0f} s)")
    if figures.plt is None:
        print("no figures: the report needs matplotlib (pip install 'structsearch[figures]')")
        return 0
    from .report.page import build
    _print_report(build(campaign, out, options=FitOptions(n_starts=args.starts), n_jobs=jobs, story=story["lines"],
                        progress=None if args.quiet else stderr_progress))
    return 0


def _report(args) -> int:
    from .data.campaign import read_campaign
    from .report.page import build
    from .search.pipeline import grids_for
    from .fitting.options import check_box_names, FitOptions
    campaign = read_campaign(args.data)
    options = FitOptions(n_starts=args.starts, seed=args.seed, covariance=args.covariance, parameter_boxes=_bounds(args))
    check_box_names(options.parameter_boxes, [c for g in grids_for("all") for c in g.candidates])
    res = build(campaign, Path(args.out), options=options, n_jobs=_jobs(args),
                diagnose_coefficient=None if args.diagnose == "none" else args.diagnose, models=tuple(args.model or ()),
                progress=None if args.quiet else lambda m: print(m, file=sys.stderr, flush=True))
    _print_report(res)
    return 0


def _print_report(res: dict) -> None:
    for note in res["notes"]:
        print(f"note: {note}")
    print(f"wrote {res['html']} with {len(res['figures'])} figures in {res['html'].parent / 'figures'} "
          f"({res['seconds']:.0f} s)")


def _diagnose(args) -> int:
    import json
    from .data.atomic import write_text
    out = Path(args.out)
    if args.benchmark:
        from .diagnosis import withheld
        from .fitting.options import FitOptions
        from .engine.statistics import DEFAULT_COVARIANCE
        options = FitOptions(n_starts=args.starts, covariance=args.covariance, parameter_boxes=_bounds(args), cv_folds=0)
        res = withheld.run(seed=args.seed, scale=args.scale, null_seeds=tuple(range(args.null_seeds)),
                           n_jobs=_jobs(args), options=options,
                           progress=None if args.quiet else lambda m: print(f"diagnose: {m}", file=sys.stderr,
                                                                           flush=True))
        command = " ".join(["structsearch diagnose --benchmark --out", str(out)]
                           + ([f"--scale {args.scale:g}"] if args.scale != 1.0 else [])
                           + ([f"--seed {args.seed}"] if args.seed else [])
                           + ([f"--null-seeds {args.null_seeds}"] if args.null_seeds != 3 else [])
                           + ([f"--starts {args.starts}"] if args.starts != 2 else [])
                           + ([f"--covariance {args.covariance}"] if args.covariance != DEFAULT_COVARIANCE else [])
                           + [f"--bound {n}={lo:g}:{hi:g}" for n, (lo, hi) in args.bound])
        write_text(out / "withheld_benchmark.json", json.dumps(res, indent=2, default=float))
        write_text(out / "withheld_benchmark.md", withheld.markdown(res, command))
        hits = sum(r["ranked_first"] for r in res["rows"])
        outside = res["outside"]
        good = sum(r["located"] and not r["false_claim"] and r["signal_first"] for r in outside)
        print(f"withheld effect ranked first {hits}/{len(res['rows'])}; out-of-library effects located, not falsely "
              f"explained and their signal first {good}/{len(outside)}; false alarms "
              f"{sum(n['alarm_combined'] for n in res['null'])}/{len(res['null'])} (Wald test alone "
              f"{sum(bool(n['alarm_test']) for n in res['null'])}); wrote {out / 'withheld_benchmark.md'}")
        return 0
    if not args.data or not args.model:
        raise_error("diagnose needs --data and --model (or --benchmark)")
    from .data.campaign import read_campaign
    from .diagnosis.diagnose import diagnose
    from .fitting.specs import resolve_candidate
    from .report.diagnosis_doc import write
    from .fitting.options import check_box_names, FitOptions
    campaign = read_campaign(args.data)
    baseline = resolve_candidate(args.model, args.coefficient)
    options = FitOptions(n_starts=args.starts, seed=args.seed, covariance=args.covariance, parameter_boxes=_bounds(args))
    check_box_names(options.parameter_boxes, [baseline])
    doc = diagnose(campaign, baseline, options=options, n_jobs=_jobs(args), seed=args.seed,
                   progress=None if args.quiet else lambda m: print(f"diagnose: {m}", file=sys.stderr, flush=True))
    js, md = write(doc, out)
    best = next((e for e in doc["effects"] if "error" not in e), None)
    from .report.diagnosis_doc import unexplained_sentence
    verdict = ("the baseline is at the noise floor" if doc["gap_explained_by_baseline"] else
               f"best effect {best['name']} closes {best['shrink']:.0%} of the gap" if best and best["shrink"] is not None
               else "no effect fitted")
    print(f"{doc['coefficient']} {doc['baseline']}: {verdict}; final model {doc['final_model']}; explained: "
          f"{'yes' if doc['explained'] else 'no'}; wrote {js} and {md}")
    for line in filter(None, [unexplained_sentence(doc)] + [f"warning: {w}" for w in doc.get("warnings", [])]):
        print(line)
    return 0


def _admissibility_options(p) -> None:
    from .search.admissibility import MAX_CORRELATION
    p.add_argument("--max-correlation", type=_fraction, default=MAX_CORRELATION,
                   help=f"admissibility: largest |correlation| of two parameters (default {MAX_CORRELATION}; "
                        "judged with the data columns centred)")


def _campaign_options(p, starts: int = 4, data_required: bool = True) -> None:
    """--data, --out, --starts, --seed: the options every command that fits a campaign shares."""
    p.add_argument("--data", required=data_required, help="campaign directory")
    p.add_argument("--out", default="results", help="output directory (default: results)")
    p.add_argument("--starts", type=_count, default=starts, help="starts per nonlinear fit (1: the default start)")
    p.add_argument("--seed", type=_non_negative, default=0)
    p.add_argument("--bound", action="append", default=[], metavar="NAME=LO:HI", type=_bound,
                   help="search box of a nonlinear parameter, over the declared one (repeatable), "
                        "e.g. --bound tau2_ss=0:5")
    from .engine.statistics import COVARIANCE_KINDS, DEFAULT_COVARIANCE
    p.add_argument("--covariance", choices=COVARIANCE_KINDS, default=DEFAULT_COVARIANCE,
                   help=f"covariance estimate of every fit (default {DEFAULT_COVARIANCE}, the best calibrated "
                        "by `bench --calibration`)")


class _Parser(argparse.ArgumentParser):
    """Bad options are one line naming the option (no usage block), exit status 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _count(text: str) -> int:
    """An integer >= 1 (starts, repeats, campaigns, samples)."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {value}")
    return value


def _non_negative(text: str) -> int:
    """An integer >= 0 (seeds; --jobs, where 0 means all cores)."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, not {value}")
    return value


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def _float_option(text: str, ok, requirement: str) -> float:
    """A number that passes ``ok``; otherwise "must <requirement>, not <text>"."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not ok(value):
        raise argparse.ArgumentTypeError(f"must {requirement}, not {text}")
    return value


def _angle_degrees(text: str) -> float:
    """A finite angle of attack in degrees, within +-90."""
    return _float_option(text, lambda v: -90.0 < v < 90.0, "be an angle of attack in degrees within +-90")


def _non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    import math
    return _float_option(text, lambda v: math.isfinite(v) and v >= 0.0, "be a finite number >= 0")


def _fraction(text: str) -> float:
    """A number in (0, 1] (scales, correlation limits)."""
    return _float_option(text, lambda v: 0.0 < v <= 1.0, "lie in (0, 1]")


def _jobs(args) -> int:
    """--jobs as a process count: 0 means every core."""
    return args.jobs or os.cpu_count() or 1


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="structsearch", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("bench", help="measure speed, robustness and memory of the SNLS engine")
    b.add_argument("--out", default="results", help="output directory (default: results)")
    b.add_argument("--samples", type=_count, default=250_000, help="samples in the benchmark campaign")
    b.add_argument("--repeats", type=_count, default=3, help="repeats of every single-start timing (every method alike)")
    b.add_argument("--starts", type=_count, default=20, help="random starts for the success rate")
    b.add_argument("--seed", type=_non_negative, default=2025)
    b.add_argument("--jobs", type=_non_negative, default=2, help="processes for the random starts and the search")
    b.add_argument("--no-search", action="store_true", help="skip the search --grid all benchmark")
    b.add_argument("--staged", type=_count, default=None, metavar="CAMPAIGNS",
                   help="also measure the default fit's success over this many seeded campaigns (50: ~10 min)")
    b.add_argument("--calibration", action="store_true",
                   help="instead: Monte Carlo calibration of the covariances on simulated campaigns "
                        "(writes calibration.md and calibration.json)")
    b.add_argument("--campaigns", type=_count, default=50, help="--calibration: number of seeded campaigns")
    b.add_argument("--scale", type=_fraction, default=0.1, help="--calibration: fraction of the maneuvers flown")
    b.set_defaults(func=_bench)

    from .flight.aero import TRUTHS, WITHHOLDABLE
    from .flight.anomalies import ANOMALIES
    s = sub.add_parser("simulate", help="simulate a flight-test campaign (thesis Table 4) of the Citation II or the "
                                        "twin-jet transport")
    s.add_argument("--aircraft", choices=tuple(TRUTHS), default="citation",
                   help="citation (the thesis' Citation II, default) or transport (a twin-jet transport with one "
                        "separation state, no stall strips and no recorded cg: README)")
    s.add_argument("--out", required=True, help="campaign directory to write")
    s.add_argument("--seed", type=_non_negative, default=0, help="random seed (same seed, same campaign bit for bit)")
    s.add_argument("--withhold", action="append", choices=sorted(WITHHOLDABLE), metavar="EFFECT",
                   help="remove an effect from the truth model (repeatable): " + ", ".join(WITHHOLDABLE))
    s.add_argument("--anomaly", choices=sorted(ANOMALIES), metavar="NAME",
                   help="add an effect outside the diagnosis' library to the Citation's truth: " + ", ".join(ANOMALIES))
    s.add_argument("--scale", type=_fraction, default=1.0,
                   help="fraction of the maneuvers of each kind to fly (small test campaigns)")
    s.add_argument("--extras", action="store_true", help="add pullups, pushovers and phugoids")
    s.add_argument("--format", choices=("csv", "parquet"), default="csv")
    s.add_argument("--slow-errors", type=_non_negative_float, default=1.0, metavar="F",
                   help="scale of the slow reconstruction errors of a standard campaign (1, the default: realistic; "
                        "0: only sensor noise, buffet and residual biases, like a raw campaign's channels)")
    s.add_argument("--raw", action="store_true",
                   help="write the raw sensor channels (docs/interfaces.md 5.2) with the injected sensor errors recorded")
    s.set_defaults(func=_simulate)

    pp = sub.add_parser("preprocess", help="turn a raw flight-test campaign (docs/interfaces.md 5.2) into a standard one: "
                                           "spectra, pre-filter, flight-path reconstruction, coefficients")
    pp.add_argument("--raw", required=True, help="raw campaign directory (format = \"raw\")")
    pp.add_argument("--out", required=True, help="standard campaign directory to write, with preprocess.md")
    pp.add_argument("--cutoffs", choices=("table5", "spectra"), default="table5",
                    help="default cut-offs: thesis Table 5 (default) or those the spectra suggest")
    pp.add_argument("--cutoff", action="append", type=_cutoff, metavar="CHANNEL=HZ",
                    help="pre-filter cut-off of one channel (repeatable; over campaign.toml's [cutoffs])")
    pp.add_argument("--stall-alpha", type=_angle_degrees, metavar="DEG",
                    help="stalled flow for the spectra: alpha above this [deg] (default: campaign.toml's "
                         "stall_alpha [rad], else the angle of maximum normal force less 1 deg)")
    pp.add_argument("--stall-state", metavar="COLUMN",
                    help="stalled flow for the spectra: where this column (a separation state, 1 attached, 0 "
                         "separated) is below 0.5, instead of an alpha threshold")
    pp.add_argument("--no-figures", action="store_true", help="skip the spectra figures (no matplotlib needed)")
    pp.add_argument("--quiet", action="store_true", help="no progress on stderr")
    pp.set_defaults(func=_preprocess)

    st = sub.add_parser("study", help="the thesis' comparison tables on a campaign: final models against Van Ingen's, "
                                      "the dynamic-stall study, the separation matrix, derived quantities")
    st.add_argument("--data", required=True, help="campaign directory")
    st.add_argument("--out", required=True, help="directory for the tables (Markdown, LaTeX, CSV) and box plots")
    st.add_argument("--cache", help="the search's output directory whose cache to reuse (default: --out)")
    st.add_argument("--starts", type=_count, default=4, help="starts per nonlinear fit (as search: its cache serves)")
    st.add_argument("--jobs", type=_non_negative, default=0, help="processes (0: all cores)")
    st.add_argument("--quiet", action="store_true", help="no progress on stderr")
    st.set_defaults(func=_study)

    f = sub.add_parser("fit", help="fit one model structure to a campaign")
    _campaign_options(f)
    f.add_argument("--model", required=True, help="candidate name (CL-VI, CD-IXr, Cm-XXXIII, ...) or spec file")
    f.set_defaults(func=_fit)

    r = sub.add_parser("search", help="fit and rank every candidate of a grid")
    _campaign_options(r)
    r.add_argument("--grid", required=True, help="separation, lift, drag, pitch, all, or a grid spec file")
    r.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default 0: all cores)")
    from .fitting.options import CV_METHODS
    r.add_argument("--cv-method", choices=CV_METHODS, default="refit",
                   help="cross-validation folds of a nonlinear candidate: refit (solved again from the full "
                        "fit's estimates, exact; default) or one-step (one Gauss-Newton step from them: no "
                        "solve, linearised; exact for linear candidates)")
    r.add_argument("--backend", default="loky", choices=("loky", "dask"),
                   help="loky: local processes; dask: a dask.distributed cluster")
    r.add_argument("--scheduler", default=None,
                   help="dask scheduler address (default: start a local cluster of --jobs workers)")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    _admissibility_options(r)
    r.set_defaults(func=_search)

    g = sub.add_parser("diagnose", help="where the model misses the data, which effect causes it, how far it shrinks")
    _campaign_options(g, starts=2, data_required=False)
    g.add_argument("--model", help="baseline candidate name or spec file")
    g.add_argument("--coefficient", choices=("CL", "CD", "Cm"), help="check that the baseline models this")
    g.add_argument("--benchmark", action="store_true",
                   help="run the withheld-effect benchmark on simulated campaigns instead")
    g.add_argument("--scale", type=_fraction, default=1.0, help="benchmark campaign scale")
    g.add_argument("--null-seeds", type=_non_negative, default=3, help="benchmark: seeds of the null case")
    g.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default 0: all cores)")
    g.add_argument("--quiet", action="store_true")
    g.set_defaults(func=_diagnose)

    p = sub.add_parser("report", help="figures and one self-contained HTML page for a campaign")
    _campaign_options(p)  # the search's defaults, so that its cached fits are reused
    p.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes for the fits (default 0: all cores)")
    p.add_argument("--diagnose", choices=("CL", "CD", "Cm", "none"), default="Cm",
                   help="coefficient whose gap breakdown is shown (default Cm; none: skip the diagnosis)")
    p.add_argument("--model", action="append", metavar="NAME",
                   help="use this lift, drag or pitch structure instead of the search's winner (repeatable)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_report)

    d = sub.add_parser("demo", help="simulate the default campaign, search every grid, write all tables and the report")
    d.add_argument("--out", default="results", help="output directory (default: results)")
    d.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default: all cores)")
    d.add_argument("--starts", type=_count, default=4)
    d.add_argument("--scale", type=_fraction, default=1.0, help="fraction of the campaign to fly (quick looks)")
    d.add_argument("--quiet", action="store_true")
    _admissibility_options(d)
    d.set_defaults(func=_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from .data.errors import StructSearchError
    try:
        return args.func(args)
    except StructSearchError as exc:
        print(f"structsearch {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"structsearch {args.command}: error: {exc}", file=sys.stderr)
        return 2
