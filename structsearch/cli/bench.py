"""The ``bench`` command and ``diagnose --benchmark``: experiments run from the command line and what they print."""
from __future__ import annotations

import sys
from pathlib import Path

from .options import PROFILE_CAMPAIGNS, _bounds, _jobs


def _calibration(args) -> int:
    from ..experiments.calibration import run
    from ..data.atomic import write_json, write_text
    from ..experiments.calibration_doc import calibration_dict, calibration_markdown
    say = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    cal = run(n_campaigns=args.campaigns, scale=args.scale, n_jobs=_jobs(args), progress=say, seeds=args.seeds,
              profile_campaigns=args.profile_campaigns, flight_errors=args.flight_errors,
              flight_effects=tuple(args.flight_effects), cg_moment=args.cg_moment,
              **({"kinds": args.kinds} if args.kinds else {}))
    out = Path(args.out)
    command = (f"structsearch bench --calibration --campaigns {args.campaigns} --scale {args.scale}"
               if args.seeds is None else
               f"structsearch bench --calibration --seeds {args.seeds[0]}:{args.seeds[-1] + 1} --scale {args.scale}") \
        + (f" --profile-campaigns {args.profile_campaigns}" if args.profile_campaigns != PROFILE_CAMPAIGNS else "") \
        + (" --flight-errors" if args.flight_errors else "") \
        + (f" --flight-effects {','.join(args.flight_effects)}" if args.flight_effects else "") \
        + (f" --cg-moment {args.cg_moment}" if args.cg_moment != "thesis" else "") \
        + (f" --kinds {','.join(args.kinds)}" if args.kinds else "")
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
    profile = calibration_dict(cal)["profile"]
    if profile is not None:
        print(f"profile intervals ({profile['campaigns']} campaigns): 95 % coverage {profile['pooled_coverage_95']:.3f} "
              f"(Wald {profile['pooled_wald_coverage_95']:.3f}), 68 % {profile['pooled_coverage_68']:.3f} (Wald "
              f"{profile['pooled_wald_coverage_68']:.3f})")
    print(f"best calibrated: {cal.best.kind}; wrote {out / 'calibration.md'}")
    return 0


def _reading_bench(args) -> int:
    from ..data.atomic import write_json, write_text
    from ..experiments.bench_reading import reading_markdown, run_reading
    scale = 1.0 if args.scale == 0.1 else args.scale   # --scale's default is the calibration's
    doc = run_reading(scale=scale, progress=lambda m: print(f"bench: {m}", file=sys.stderr, flush=True))
    out = Path(args.out)
    write_text(out / "reading_bench.md", reading_markdown(doc, f"structsearch bench --reading --scale {scale}"))
    write_json(out / "reading_bench.json", doc, indent=1)
    for fmt, f in doc["formats"].items():
        print(f"{fmt}: reading added {f['peak_added_bytes'] / 1e6:.1f} MB for {f['data_bytes'] / 1e6:.1f} MB of data "
              f"({f['ratio']:.2f}x)")
    return 0


def _bench_doc(path: Path) -> dict:
    """The figures ``bench.json`` holds already (none when it does not exist); one clear error if it is not one."""
    import json
    from ..data.errors import DataError
    if not path.exists():
        return {}
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DataError(f"not readable as the benchmarks' JSON ({type(exc).__name__}: {exc})", source=str(path)) \
            from None
    if not isinstance(doc, dict):
        raise DataError("not the benchmarks' JSON (an object of figures)", source=str(path))
    return doc


def _trace_bench(args) -> int:
    """``bench --trace FILE``: the recorded task graph's work, critical path and predicted walls."""
    import json
    from ..data.atomic import write_text
    from ..experiments.trace_bench import analyse, markdown, read_trace
    out = Path(args.out)
    fig = {"file": str(args.trace), **analyse(read_trace(args.trace))}
    bench_json = out / "bench.json"
    doc = _bench_doc(bench_json)
    doc["trace"] = fig   # the other benchmarks' figures stay as they were
    out.mkdir(parents=True, exist_ok=True)
    write_text(bench_json, json.dumps(doc, indent=2))   # as the other benchmarks write it
    write_text(out / "trace_bench.md", markdown(fig, f"structsearch bench --trace {args.trace} --out {out}"))
    p = fig["predicted_wall_s"]
    print(f"{fig['tasks']} tasks: work {fig['work_s']:.1f} s, critical path {fig['critical_path_s']:.1f} s, "
          f"parallelism {fig['parallelism'] or float('nan'):.1f}; predicted wall "
          + ", ".join(f"{w} workers {s:.1f} s" for w, s in p.items())
          + f"; 2 -> 16 workers {fig['predicted_speedup_2_to_16']:.2f}x; measured {fig['wall_s']:.1f} s on "
          f"{fig['workers_recorded']}")
    print(f"wrote {out / 'trace_bench.md'} and the trace entry of {bench_json}")
    return 0


def _bench(args) -> int:
    if args.trace:
        return _trace_bench(args)
    if args.reading:
        return _reading_bench(args)
    if args.calibration:
        return _calibration(args)
    if args.discovery:
        return _discovery_bench(args)
    if args.joint:
        return _joint_bench(args)
    from ..experiments.bench import BenchConfig, run, write
    config = BenchConfig(samples=args.samples, repeats=args.repeats, random_starts=args.starts,
                         seed=args.seed, n_jobs=_jobs(args))
    say = lambda msg: print(f"bench: {msg}", file=sys.stderr, flush=True)  # noqa: E731
    fig = run(config, progress=say)
    # written after every part, so that a part that fails late leaves the earlier ones' figures
    md, js = write(fig, Path(args.out))
    if not args.no_search:
        from ..experiments.bench import run_search
        fig["search"] = run_search(n_jobs=_jobs(args), progress=say)
        md, js = write(fig, Path(args.out))
    if args.staged:
        from ..experiments.bench import run_staged
        fig["staged"] = run_staged(campaigns=args.staged, n_jobs=_jobs(args), progress=say)
        md, js = write(fig, Path(args.out))
    o, r = fig["one_start"], fig["random_starts"]
    print(f"one start: SNLS {o['snls']['median_s']:.3f} s = {o['snls']['median_s'] / o['prototype']['median_s']:.2f}x "
          f"the prototype's {o['prototype']['median_s']:.3f} s; time per success over {r['n']} random starts: SNLS "
          f"{r['snls']['s_per_success']:.3f} s, prototype {r['prototype']['s_per_success']:.3f} s, full NLS "
          f"{r['full']['s_per_success']:.3f} s, finite differences {r['fd']['s_per_success']:.3f} s; peak memory "
          f"{fig['memory'][0]['peak_mb']:.0f} MB -> {fig['memory'][1]['peak_mb']:.0f} MB at 2x samples")
    if "processes" in fig:
        ratio = fig["processes"]["ratio_to_script"]
        print(f"whole process: the default fit {ratio['fit_default']:.2f}x the reference script, "
              f"fit --starts 1 {ratio['fit_starts_1']:.2f}x")
    if "search" in fig:
        s = fig["search"]
        naive = f"{s['search_over_naive']:.2f}x the naive fan-out, " if "search_over_naive" in s else ""
        print("search --grid all: " + ", ".join(f"{g} {t:.1f} s" for g, t in s["by_grid_s"].items())
              + f"; total {s['search_s']:.1f} s on {s['n_jobs']} processes = {naive}"
              f"{s['search_over_critical_path']:.2f}x its chain of whole candidates (an upper bound of the critical "
              "path; bench --trace measures the path itself)")
    if "staged" in fig:
        st = fig["staged"]
        print(f"default fit reached the best admissible solution of {st['random_starts']} random starts on "
              f"{st['staged_success']}/{st['admissible_campaigns']} campaigns that have one "
              f"({st['campaigns']} campaigns; one random start {100 * st['random_start_success']:.0f} %)")
    print(f"wrote {md} and {js}")
    return 0


def _diagnose_benchmark(args) -> int:
    """``diagnose --benchmark``: the withheld-effect benchmark on simulated campaigns."""
    out = Path(args.out)
    from ..diagnosis import withheld
    from ..fitting.options import FitOptions
    from ..engine.statistics import DEFAULT_COVARIANCE
    options = FitOptions(n_starts=args.starts, covariance=args.covariance, parameter_boxes=_bounds(args),
                         cv_method="one-step")
    parts = set(args.parts.split(",")) if args.parts else {"withheld", "anomalies", "null"}
    say = None if args.quiet else lambda m: print(f"diagnose: {m}", file=sys.stderr, flush=True)
    if "jsbsim" in parts:
        _through_jsbsim(args, out, say)
        if parts == {"jsbsim"}:   # the other parts' page is not rewritten with empty tables
            return 0
    res = withheld.run(seed=args.seed, scale=args.scale,
                       null_seeds=tuple(range(args.null_seeds)) if "null" in parts else (),
                       effects=None if "withheld" in parts else (), anomalies=None if "anomalies" in parts else (),
                       n_jobs=_jobs(args), options=options,
                       progress=None if args.quiet else lambda m: print(f"diagnose: {m}", file=sys.stderr,
                                                                       flush=True))
    command = " ".join(["structsearch diagnose --benchmark --out", str(out)]
                       + ([f"--scale {args.scale:g}"] if args.scale != 1.0 else [])
                       + ([f"--seed {args.seed}"] if args.seed else [])
                       + ([f"--null-seeds {args.null_seeds}"] if args.null_seeds != 3 else [])
                       + ([f"--parts {args.parts}"] if args.parts else [])
                       + ([f"--starts {args.starts}"] if args.starts != 2 else [])
                       + ([f"--covariance {args.covariance}"] if args.covariance != DEFAULT_COVARIANCE else [])
                       + [f"--bound {n}={lo:g}:{hi:g}" for n, (lo, hi) in args.bound])
    from ..reporting.diagnosis_doc import benchmark_console_line, write_benchmark
    _, md = write_benchmark(res, out, command)
    print(benchmark_console_line(res, md))
    return 0


def _through_jsbsim(args, out: Path, say) -> None:
    """``diagnose --benchmark --parts jsbsim``: the withheld effects through JSBSim (api.withheld_jsbsim)."""
    import time
    from ..api import withheld_jsbsim
    from ..api.settings import Settings
    from ..engine.statistics import DEFAULT_COVARIANCE
    from ..data.atomic import write_json, write_text
    from ..flight.flighttest import build_campaign
    t0 = time.perf_counter()
    campaign = build_campaign(seed=args.seed, scale=args.scale)
    work = out / "withheld_jsbsim"
    # the fits are cached under the benchmark's folder: a run stopped half way resumes where it was
    settings = Settings(starts=args.starts, seed=args.seed, covariance=args.covariance, jobs=_jobs(args),
                        bounds=_bounds(args) or None, progress=say, cache=work / "cache")
    command = " ".join(["structsearch diagnose --benchmark --parts jsbsim --out", str(out)]
                       + ([f"--scale {args.scale:g}"] if args.scale != 1.0 else [])
                       + ([f"--seed {args.seed}"] if args.seed else [])
                       + ([f"--starts {args.starts}"] if args.starts != 2 else [])
                       + ([f"--covariance {args.covariance}"] if args.covariance != DEFAULT_COVARIANCE else [])
                       + [f"--bound {n}={lo:g}:{hi:g}" for n, (lo, hi) in args.bound])
    rows = []
    for effect in withheld_jsbsim.effects():   # the page is written again after each row: a long run shows its rows
        if say is not None:
            say(f"withheld through JSBSim: {effect}")
        rows.append(withheld_jsbsim.row(campaign, effect, work, settings))
        seconds = time.perf_counter() - t0
        md = write_text(out / "withheld_jsbsim_benchmark.md", withheld_jsbsim.markdown(rows, command, seconds))
        write_json(out / "withheld_jsbsim_benchmark.json", withheld_jsbsim.to_json(rows, command, seconds))
    hits = sum(r.hit and r.closes_half for r in rows)
    print(f"withheld through JSBSim: {hits} of {len(rows)} adopted first and closing half the gap; wrote {md}")


def _discovery_bench(args) -> int:
    """``bench --discovery``: the story's and discover's cost at full scale (experiments.bench_discovery)."""
    import json
    from ..data.atomic import write_json, write_text
    from ..experiments.bench_discovery import markdown, run_discovery_bench
    out = Path(args.out)
    say = lambda msg: print(f"bench: {msg}", file=sys.stderr, flush=True)  # noqa: E731
    fig = run_discovery_bench(n_jobs=_jobs(args), seed=args.seed if args.seed != 2025 else 0, progress=say)
    command = f"structsearch bench --discovery --out {out}" + (f" --jobs {args.jobs}" if args.jobs != 2 else "")
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "discovery_bench.md", markdown(fig, command))
    write_json(out / "discovery_bench.json", json.loads(json.dumps(fig, default=float)))
    print(f"story {fig['story_structure_search']['seconds']:.0f} s with the structure search, "
          f"{fig['story_library_only']['seconds']:.0f} s with the effect library alone ({fig['story_ratio']:.2f}x); "
          + "; ".join(f"discover {c} {d['seconds']:.0f} s" for c, d in fig["discover"].items()))
    print(f"wrote {out / 'discovery_bench.md'} and {out / 'discovery_bench.json'}")
    return 0


def _joint_bench(args) -> int:
    """``bench --joint``: a joint fit of the final models against the sequential ones (experiments.bench_joint)."""
    import json
    from ..data.atomic import write_json, write_text
    from ..experiments.bench_joint import markdown, run_joint_bench
    out = Path(args.out)
    say = lambda msg: print(f"bench: {msg}", file=sys.stderr, flush=True)  # noqa: E731
    fig = run_joint_bench(seed=args.seed if args.seed != 2025 else 0, progress=say)
    command = f"structsearch bench --joint --out {out}"
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "joint_bench.md", markdown(fig, command))
    write_json(out / "joint_bench.json", json.loads(json.dumps(fig, default=float)))
    print(f"joint fit {fig['joint_seconds']:.1f} s, {fig['cost_ratio']:.2f}x the sequential fits; bands "
          f"{fig['bands_ratio']:.1%} of a fit; wrote {out / 'joint_bench.md'}")
    return 0
