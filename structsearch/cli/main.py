"""Command line: ``structsearch <command>`` (also ``python -m structsearch``).

Each command parses its options (:mod:`.parser`), calls the public API (:mod:`structsearch.api`,
:mod:`structsearch.workflows`) and prints; the work and the files are the API's.
"""
from __future__ import annotations

import os

# One BLAS thread per process: the products here are tall and skinny (m x ~10), where
# threading costs more than it gains, and parallelism comes from joblib processes.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from .console import _clip, _gap, _print_report, _print_winners, _truth_words  # noqa: E402, F401  (_gap: tests)
from .grids import _grids  # noqa: E402
from .options import _bounds, _jobs  # noqa: E402


def _progress(args, prefix: str = ""):
    """The command's progress on stderr (lines, and a bar on a terminal: :mod:`.progress`), None with
    --quiet; one per run, closed by :func:`main` (a bar an interrupted run left open is erased)."""
    if getattr(args, "quiet", False):
        return None
    if getattr(args, "progress_sink", None) is None:
        from .progress import TerminalProgress
        args.progress_sink = TerminalProgress(prefix=prefix)
    return args.progress_sink


def _settings(args, prefix: str = "", progress: bool = True):
    """The fitting settings the command line gives (structsearch.api.Settings), options a command lacks at
    their defaults."""
    from ..api.settings import Settings
    from .options import DEFAULT_COVARIANCE
    sink = _progress(args, prefix) if progress else None
    return Settings(starts=getattr(args, "starts", None), seed=getattr(args, "seed", 0),
                    covariance=getattr(args, "covariance", DEFAULT_COVARIANCE), bounds=_bounds(args),
                    jobs=getattr(args, "jobs", 0) or 0, backend=getattr(args, "backend", "loky") or "loky",
                    segment=getattr(args, "segment", None), cache=getattr(args, "cache", None) or None,
                    progress=sink, meter=sink.meter if sink is not None else None, trace=getattr(args, "trace", None),
                    flight_effects=tuple(getattr(args, "flight_effects", None) or ()),
                    moment_reference=getattr(args, "moment_reference", None),
                    reference_point=getattr(args, "reference_point", None))


def raise_error(message: str):
    from ..data.errors import DeclarationError
    raise DeclarationError(message)


def _bench(args) -> int:
    from .bench import _bench
    return _bench(args)


def _simulate(args) -> int:
    if args.jsbsim is not None or args.modify is not None or args.lateral:
        return _simulate_jsbsim(args)
    from ..api import simulate
    from ..data.campaign import write_campaign
    from ..api.settings import FlightTestPlan
    plan = FlightTestPlan(aircraft=args.aircraft, withhold=tuple(args.withhold or ()), anomaly=args.anomaly,
                          extras=args.extras, raw=args.raw, slow_errors=args.slow_errors, flights=args.flights,
                          nominal=args.nominal, cg_spread=args.cg_spread, cg_moment=args.cg_moment)
    campaign = simulate(plan, seed=args.seed, scale=args.scale)
    out = write_campaign(campaign, Path(args.out), fmt=args.format)
    d = campaign.data
    n_val = sum(m.split == "validation" for m in campaign.maneuvers)
    flown = f" on {args.flights} flights" if args.flights else ""
    n_nominal = sum(m.kind == "nominal" for m in campaign.maneuvers)
    flown += f", {n_nominal} of them nominal" if n_nominal else ""
    print(f"wrote {out}: {len(campaign.maneuvers)} maneuvers ({n_val} validation){flown}, {d.n_samples} samples; "
          f"truth: {_truth_words(campaign.extra['truth'])}")
    return 0


def _simulate_jsbsim(args) -> int:
    from ..api.simulating import simulate_jsbsim
    if args.jsbsim is None:
        raise_error(f"{'--modify' if args.modify is not None else '--lateral'} goes with --jsbsim NAME_OR_DIR")
    campaign, seconds = simulate_jsbsim(args.jsbsim, modify=args.modify, seed=args.seed, scale=args.scale,
                                        out=args.out, format=args.format, lateral=args.lateral)
    n_val = sum(m.split == "validation" for m in campaign.maneuvers)
    source = campaign.extra["source"]
    print(f"wrote {args.out}: {len(campaign.maneuvers)} maneuvers ({n_val} validation), {campaign.data.n_samples} "
          f"samples flown in JSBSim {source['jsbsim_version']} by {source['aircraft']} (modify: {source['modify']}; "
          f"{seconds:.1f} s)")
    return 0


def _preprocess(args) -> int:
    from ..api import preprocess
    last = {}

    def progress(stage: str, fraction: float) -> None:
        step = int(fraction * 10)
        if last.get(stage) != step:
            last[stage] = step
            print(f"preprocess: {stage} {100 * fraction:.0f} %", file=sys.stderr, flush=True)

    command = "structsearch preprocess " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["preprocess"] else \
        f"structsearch preprocess --raw {args.raw} --out {args.out}"
    res = preprocess(args.raw, args.out, cutoffs=dict(args.cutoff or []), suggested_cutoffs=args.cutoffs == "spectra",
                     stall_alpha=args.stall_alpha, stall_state=args.stall_state, figures=not args.no_figures,
                     command=command, progress=None if args.quiet else progress)
    for warning in res.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    errors = ", ".join(f"{e.name} {e.estimate:.4g} +- {e.sd:.2g}" for e in res.preprocessed.reconstruction.errors)
    print(f"sensor errors: {errors}")
    if res.worst_r2:
        print("min R^2 per maneuver against the truth: " + ", ".join(f"{k} {v:.3f}" for k, v in res.worst_r2.items()))
    print(f"wrote {res.directory} (standard campaign) and {res.markdown} in {res.seconds:.1f} s")
    return 0


def _study(args) -> int:
    from ..api import study
    command = (f"structsearch study --data {args.data} --out {args.out}" + (f" --cache {args.cache}" if args.cache
                                                                            else "")
               + (f" --starts {args.starts}" if args.starts != 4 else ""))
    res = study(args.data, settings=_settings(args), out=args.out, command=command)
    print(f"wrote {len(res.written)} files in {Path(args.out)} (final_vs_van_ingen, dynamic_stalls, separation_matrix, "
          "derived, collinearity, r2_boxes.png)")
    return 0


def _fit(args) -> int:
    from ..api import fit
    from ..data.atomic import write_json, write_text
    from ..reporting.tables import parameter_table
    if args.by_kind:
        return _fit_by_kind(args)
    if args.joint:
        if args.profile:
            raise_error("--profile goes with --model (profile intervals of a joint fit are not built)")
        return _fit_joint(args)
    if args.replay_maneuver is not None:
        raise_error("--replay-maneuver goes with --joint (a replay flies C_L, C_D and C_m)")
    res = fit(args.data, args.model, settings=_settings(args, progress=False), band_samples=args.band_samples,
              profile=args.profile)
    summary, out = res.result, Path(args.out)
    for warning in summary.warnings + (summary.flight_effects.warnings if summary.flight_effects else ()):
        print(f"warning: {warning}", file=sys.stderr)
    write_json(out / "fit.json", res.to_dict())
    from ..reporting.documents import bands_table, covariance_sentence, held_out_phrase
    from ..reporting.equations import equations
    from ..reporting.profile_doc import profile_table
    model = ("## The model\n\n```\n" + "\n".join(equations(res.candidate)) + "\n```\n\nWith the estimates:\n\n```\n"
             + "\n".join(equations(res.candidate, summary.estimates.params)) + "\n```\n\n")
    write_text(out / "fit.md", f"# {res.candidate.name}\n\n" + model
               + covariance_sentence(summary.estimates.covariance_record())
               + "\n" + parameter_table(summary.estimates, "md")
               + ("\n\n```\n" + "\n".join(summary.flight_effects.lines()) + "\n```"
                  if summary.flight_effects is not None else "")
               + ("\n\n" + bands_table(res.bands) if res.bands is not None else "")
               + ("\n\n" + profile_table(res.profile) if res.profile is not None else ""))
    not_converged = ("" if summary.optimizer.converged
                     else f"; the optimizer did NOT converge ({summary.optimizer.message}): no standard deviations")
    print(f"{res.candidate.name}: MSE train {summary.mse_train:.4g}, validation {summary.mse_validation:.4g}"
          f"{held_out_phrase(summary)}; {len(summary.insignificant)} parameter(s) accept zero, "
          f"{len(summary.estimates.at_bound)} at a bound{not_converged}; wrote {out / 'fit.json'}")
    return 0


def _fit_joint(args) -> int:
    from ..api import fit_joint
    from ..data.atomic import write_json, write_text
    from ..reporting.documents import joint_markdown
    res = fit_joint(args.data, args.joint, settings=_settings(args), band_samples=args.band_samples,
                    replay_maneuver=args.replay_maneuver)
    out = Path(args.out)
    write_json(out / "fit.json", res.to_dict())
    write_text(out / "fit.md", joint_markdown(res))
    r = res.result
    not_converged = "" if r.converged else f"; the optimizer did NOT converge ({r.message})"
    unsettled = "" if res.weights_settled else f"; the weights did NOT settle in {res.iterations} iterations"
    mses = ", ".join(f"{c.coefficient} {c.train.mse:.4g}/{c.validation.mse:.4g}" for c in res.coefficients)
    print(f"{res.name} (joint): MSE train/validation {mses}; {len(res.shared)} shared separation parameters, "
          f"{len(r.at_bound)} at a bound{not_converged}{unsettled}; wrote {out / 'fit.json'}")
    return 0


def _fit_by_kind(args) -> int:
    from ..api.by_kind import fit_by_kind
    from ..reporting.by_kind_doc import console_table, write
    if args.joint or args.profile or args.band_samples or args.replay_maneuver is not None:
        raise_error("--by-kind goes with --model only (not --joint, --profile, --band-samples or --replay-maneuver)")
    res = fit_by_kind(args.data, args.model, settings=_settings(args), out=args.out)
    paths = write(res, Path(args.out))
    print(console_table(res))
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0


def _search(args) -> int:
    from ..api import search
    ranking = search(args.data, args.grid, settings=_settings(args), out=args.out, cv_method=args.cv_method,
                     scheduler=args.scheduler, max_correlation=args.max_correlation, joint_lift=args.joint_lift)
    if ranking.joint is not None:
        j = ranking.joint
        print(f"joint lift model: {j.name}, {j.iterations} weight iterations"
              f"{'' if j.weights_settled else ' (weights did NOT settle)'}"
              f"{'' if j.result.converged else '; optimizer did NOT converge'}; "
              f"wrote {Path(args.out) / 'joint_lift.json'}")
    _print_winners(ranking)
    print(f"wrote {Path(args.out) / 'ranking.csv'} and the tables of each grid")
    return 0


def _demo(args) -> int:
    from ..workflows import demo
    sink = _progress(args)
    # stdout's lines go through the sink too: on a terminal they must not land on a line the bar is drawn on
    say = (lambda m: sink.write(m, sys.stdout)) if sink is not None else (lambda m: print(m, flush=True))
    res = demo(args.out, jobs=_jobs(args), starts=args.starts, scale=args.scale,
               max_correlation=args.max_correlation, say=say, winners=_print_winners,
               progress=sink, meter=sink.meter if sink is not None else None)
    if res.report is not None:
        _print_report(res.report)
    return 0


def _report(args) -> int:
    from ..api import report
    res = report(args.data, args.out, settings=_settings(args),
                 diagnose=None if args.diagnose == "none" else args.diagnose, models=tuple(args.model or ()))
    _print_report(res)
    return 0


def _diagnose(args) -> int:
    if args.benchmark:
        from .bench import _diagnose_benchmark
        return _diagnose_benchmark(args)
    baselines = [o for o, v in (("--model", args.model), ("--baseline-column", args.baseline_column),
                                ("--simulator", args.simulator)) if v]
    if not args.data or len(baselines) != 1:
        raise_error("diagnose needs --data and one baseline: --model NAME, --baseline-column NAME or --simulator "
                    "jsbsim:AIRCRAFT (or --benchmark)" + (f"; given {', '.join(baselines)}" if baselines else ""))
    from ..api import diagnose
    from ..reporting.diagnosis_doc import diagnosis_console_lines
    out = Path(args.out)
    diagnosis = diagnose(args.data, args.model, settings=_settings(args, "diagnose: "),
                         coefficient=args.coefficient, out=out, terms=args.terms, beam=args.beam,
                         max_steps=args.max_steps, baseline_column=args.baseline_column or None,
                         simulator=args.simulator, simulator_inputs=tuple(args.simulator_input or ()))
    for line in diagnosis_console_lines(diagnosis, (out / "diagnosis.json", out / "diagnosis.md")):
        print(line)
    return 0


def _discover(args) -> int:
    from ..api import discover
    from ..reporting.discovery_doc import discovery_console_lines
    out = Path(args.out)
    if args.exhaustive:
        return _exhaustive(args, out)
    found = discover(args.data, args.coefficient, settings=_settings(args, "discover: "), start=args.start,
                     lifts=args.lift, terms=args.terms, beam=args.beam, max_steps=args.max_steps, out=out,
                     command="structsearch " + " ".join(sys.argv[1:]))
    for line in discovery_console_lines(found, out):
        print(line)
    return 0


def _exhaustive(args, out: Path) -> int:
    from ..api.discovering import discover_exhaustive
    from ..data.errors import DeclarationError
    moves_only = [f for f, v in (("--from", args.start != "minimal"), ("--beam", args.beam is not None),
                                 ("--max-steps", args.max_steps is not None)) if v]
    if moves_only:
        raise DeclarationError(f"{moves_only[0]} belongs to the search move by move, not to --exhaustive")
    if len(args.lift) > 1:
        raise DeclarationError("--exhaustive feeds drag and pitch structures one lift model: give --lift once")
    ranking = discover_exhaustive(args.data, args.coefficient, settings=_settings(args, "discover: "),
                                  max_terms=args.max_terms, lift=args.lift[0] if args.lift else None,
                                  terms=args.terms, out=out)
    _print_winners(ranking)
    print(f"wrote {out / 'ranking.csv'}, the grid {out / ('exhaustive_' + args.coefficient + '.toml')} and its tables")
    return 0


def _compare(args) -> int:
    from ..api import Tolerances, compare_outputs
    from ..data.atomic import write_json
    for d in (args.first, args.second):
        if not Path(d).is_dir():
            raise_error(f"{d}: not a directory")
    found = compare_outputs(args.first, args.second, Tolerances(rtol=args.rtol))
    if args.json:
        write_json(Path(args.json), found.to_dict())
    print(found.summary())
    return 0 if found.same else 1


def _export(args) -> int:
    from ..api.exporting import export
    settings = _settings(args, progress=False)
    res = export(fit_dir=args.fit, campaign=args.data, models=args.model, fmt=args.format, out=args.out,
                 check=args.check, settings=settings)
    names = ", ".join(f"{c.coefficient} {c.model}" for c in res.model.coefficients)
    print(f"exported {names} as {args.format}: {len(res.written)} files in {Path(args.out)}")
    if res.check is not None:
        for line in res.check.lines():
            print(_clip(line))
        print(f"check: {'passed' if res.check.passed else 'targets NOT met'} (wrote {Path(args.out) / 'check.json'})")
        return 0 if res.check.passed else 1
    return 0


HANDLERS = {"bench": _bench, "simulate": _simulate, "preprocess": _preprocess, "study": _study, "fit": _fit,
            "search": _search, "diagnose": _diagnose, "discover": _discover, "report": _report, "demo": _demo,
            "compare": _compare, "grids": _grids,
            "export": _export}


def build_parser() -> argparse.ArgumentParser:
    """The command line's parser (imports nothing heavy: ``structsearch --help`` stays fast)."""
    from .parser import build_parser as build
    return build(HANDLERS)


def _terminate(signum, frame):
    # SIGTERM (a scheduler, a dead terminal) ends the run as Ctrl-C does: cached fits kept, workers and
    # temporary files removed by the same clean-up
    raise KeyboardInterrupt


def _run(args) -> int:
    try:
        return args.func(args)
    finally:
        if getattr(args, "progress_sink", None) is not None:
            args.progress_sink.close()


RESUMABLE = ("search", "fit", "diagnose", "discover", "report", "demo", "study")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from ..data.errors import StructSearchError
    import signal
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _terminate)
    import tempfile
    from ..data.atomic import remove_dead_runs
    remove_dead_runs(Path(tempfile.gettempdir()))   # what a run killed with -9 left (it could not clean up)
    try:
        return _run(args)
    except KeyboardInterrupt:
        again = (" the fits finished so far are cached: run the same command again to resume"
                 if args.command in RESUMABLE else "")
        print(f"structsearch {args.command}: interrupted;{again}" if again else
              f"structsearch {args.command}: interrupted", file=sys.stderr)
        return 130
    except (StructSearchError, OSError) as exc:
        print(f"structsearch {args.command}: error: {_one_line(str(exc))}", file=sys.stderr)
        return 2


# The longest error line printed: the messages quote short excerpts of what they read; this bounds any other.
MAX_ERROR_CHARACTERS = 2000


def _one_line(message: str) -> str:
    message = " ".join(message.split("\n"))
    if len(message) <= MAX_ERROR_CHARACTERS:
        return message
    return f"{message[:MAX_ERROR_CHARACTERS]}... ({len(message) - MAX_ERROR_CHARACTERS} more characters)"
