"""The command line's parser: options, choices and help, built from light modules only (no numpy at ``--help``)."""
from __future__ import annotations

import argparse
from typing import Callable, Mapping

from ..data.coefficients import COEFFICIENTS
from .._version import __version__
from .help import command_parser, top_level
from .options import (COVARIANCE_KINDS, CV_METHODS, DEFAULT_COVARIANCE, MAX_CORRELATION,
                          SEGMENT_CHOICES, CG_MOMENTS, MOMENT_REFERENCES, _Parser, _angle_degrees, _bound, _count,
                          _cutoff, _finite_float, _fraction, _non_negative, _non_negative_float, _positive_float)
from ..flight.names import AIRCRAFT_NAMES, ANOMALY_NAMES, WITHHOLDABLE
from .options import _covariance_kinds, _flight_effects  # noqa: F401  (their tests import them from here)
from .parser_bench import _add_bench

BENCHMARK_PARTS = ("withheld", "anomalies", "null", "jsbsim")


def _benchmark_parts(text: str) -> str:
    parts = [p.strip() for p in text.split(",") if p.strip()]
    bad = [p for p in parts if p not in BENCHMARK_PARTS]
    if bad or not parts:
        raise argparse.ArgumentTypeError(f"{text!r}: parts are {', '.join(BENCHMARK_PARTS)}, comma-separated")
    return ",".join(parts)


def _simulator(text: str) -> str:
    """``--simulator jsbsim:NAME_OR_DIR``: the prefix and a non-empty aircraft."""
    if not text.startswith("jsbsim:") or not text[len("jsbsim:"):].strip():
        raise argparse.ArgumentTypeError(f"{text!r}: give jsbsim:NAME_OR_DIR (one of JSBSim's aircraft such as c172p, "
                                         "an aircraft directory or an export directory)")
    return text


def _simulator_input(text: str) -> str:
    """``--simulator-input PROPERTY=COLUMN|VALUE``: a non-empty property and value."""
    prop, sep, value = text.partition("=")
    if not sep or not prop.strip() or not value.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: give PROPERTY=COLUMN or PROPERTY=VALUE (e.g. fcs/flap-pos-deg=0)")
    return text


def _admissibility_options(p) -> None:
    p.add_argument("--max-correlation", type=_fraction, default=MAX_CORRELATION,
                   help=f"admissibility: largest |correlation| of two parameters (default {MAX_CORRELATION}; "
                        "judged with the data columns centred)")


FIT_OUT = "fit-results"


def _campaign_options(p, starts: int = 4, data_required: bool = True, out: str = "results") -> None:
    """--data, --out, --starts, --seed: the options every command that fits a campaign shares."""
    p.add_argument("--data", required=data_required, help="campaign directory")
    p.add_argument("--out", default=out, help=f"output directory (default: {out})")
    p.add_argument("--starts", type=_count, default=starts, help="starts per nonlinear fit (1: the default start)")
    p.add_argument("--seed", type=_non_negative, default=0,
                   help="seed of the random starts beyond the default one (default 0; same seed, same fits)")
    p.add_argument("--bound", action="append", default=[], metavar="NAME=LO:HI", type=_bound,
                   help="search box of a nonlinear parameter, over the declared one (repeatable), "
                        "e.g. --bound tau2_ss=0:5")
    p.add_argument("--covariance", choices=COVARIANCE_KINDS, default=DEFAULT_COVARIANCE,
                   help=f"covariance estimate of every fit (default {DEFAULT_COVARIANCE}: chosen on the calibration's "
                        "tuning seeds, it meets every goal of `bench --calibration` on held-out ones)")
    p.add_argument("--flight-effects", type=_flight_effects, default=(), metavar="NAME[,NAME]",
                   help="per-flight nuisance parameters every candidate estimates with its own, reported apart "
                        "(x_cg: an offset of the recorded cg, for a model reading x_cg; intercept: an offset of the "
                        "coefficient); the campaign must record each maneuver's flight")
    p.add_argument("--segment", choices=SEGMENT_CHOICES, default=None,
                   help="cycles: cut every record into its cycles (a `cycle` column, else alpha's minima), each a "
                        "maneuver (ids m07.c1, m07.c2, ...; same kind and split); none: keep every record whole, "
                        "and join a campaign written as cycles back into its records (default: as campaign.toml's "
                        "segment keys say, and records with a `cycle` column cut)")


def _moment_reference_options(p) -> None:
    """--moment-reference, --reference-point: where a pitch model takes C_m about (fit, search, diagnose, discover)."""
    p.add_argument("--moment-reference", choices=MOMENT_REFERENCES, default=None,
                   help="take every pitch structure's C_m about the cg (as recorded) or about the fixed [aircraft] "
                        "reference_point, moved to the recorded cg by C_N (x_cg - reference_point)/cbar (default: "
                        "as each structure declares; cg unless its spec says moment_reference = \"fixed\")")
    p.add_argument("--reference-point", type=_finite_float, default=None, metavar="X",
                   help="the fixed reference point [m, body x station, the x_cg column's datum], replacing the "
                        "manifest's [aircraft] reference_point")


def build_parser(handlers: Mapping[str, Callable]) -> argparse.ArgumentParser:
    """The parser; each command's ``func`` default is ``handlers[command]``."""
    parser = _Parser(prog="structsearch", **top_level())
    parser.add_argument("--version", action="version", version=f"structsearch {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, title="commands", metavar="<command>")
    _add_bench(sub, handlers["bench"])
    _add_simulate(sub, handlers["simulate"])
    _add_preprocess(sub, handlers["preprocess"])
    _add_study(sub, handlers["study"])
    _add_fit(sub, handlers["fit"])
    _add_search(sub, handlers["search"])
    _add_diagnose(sub, handlers["diagnose"])
    _add_discover(sub, handlers["discover"])
    _add_report(sub, handlers["report"])
    _add_demo(sub, handlers["demo"])
    _add_compare(sub, handlers["compare"])
    _add_grids(sub, handlers["grids"])
    _add_export(sub, handlers["export"])
    return parser


def _add_export(sub, handler: Callable) -> None:
    """The ``export`` command."""
    e = command_parser(sub, "export")
    source = e.add_mutually_exclusive_group(required=True)
    source.add_argument("--fit", metavar="DIR", help="a fit directory (the --out of `structsearch fit`, single or "
                                                     "--joint): its fit.json and the campaign it names")
    source.add_argument("--data", metavar="DIR", help="a campaign directory: fit --model on it first, as `fit` does")
    e.add_argument("--model", metavar="NAME[,NAME...]",
                   help="with --data: the structures to fit and export, comma-separated (CL-VI,CD-IXr,Cm-XXXIIIr); "
                        "a drag or pitch model brings the lift model it reads")
    e.add_argument("--format", required=True, choices=("jsbsim", "json"),
                   help="jsbsim: aerodynamics.xml, systems/structsearch_states.xml, an example aircraft and "
                        "fly_stall.py; json: model.json, a self-contained model card")
    e.add_argument("--out", required=True, metavar="DIR", help="output directory")
    e.add_argument("--check", action="store_true",
                   help="with --format jsbsim: drive JSBSim with every maneuver's recorded inputs and compare its "
                        "coefficients with structsearch's prediction (check.json; needs the jsbsim package)")
    e.add_argument("--starts", type=_count, default=None,
                   help="with --data: starts per nonlinear fit (default: fit's)")
    e.add_argument("--seed", type=_non_negative, default=0, help="with --data: seed of the random starts (default 0)")
    e.set_defaults(func=handler)


def _add_grids(sub, handler: Callable) -> None:
    """The ``grids`` command."""
    g = command_parser(sub, "grids")
    g.add_argument("name", nargs="?", default=None,
                   help="a grid (separation, lift, drag, pitch, side, roll, yaw), a grid spec file or a candidate "
                        "name (CL-VI)")
    g.set_defaults(func=handler)


def _add_simulate(sub, handler: Callable) -> None:
    """The ``simulate`` command."""
    s = command_parser(sub, "simulate")
    s.add_argument("--aircraft", choices=AIRCRAFT_NAMES, default="citation",
                   help="citation (the thesis' Citation II, default) or transport (a twin-jet transport with one "
                        "separation state, no stall strips and no recorded cg: README)")
    s.add_argument("--out", required=True, help="campaign directory to write")
    s.add_argument("--jsbsim", metavar="NAME_OR_DIR", default=None,
                   help="fly the stall plan in JSBSim with this aircraft (one of JSBSim's own such as c172p, or an "
                        "aircraft directory) instead of the built-in simulator: the aircraft model flown, not a flight")
    s.add_argument("--modify", metavar="FILE", default=None,
                   help="with --jsbsim: a TOML modification of the aircraft ([[scale]] function = ..., factor = ...)")
    s.add_argument("--lateral", action="store_true",
                   help="with --jsbsim: fly the lateral maneuvers too (aileron and rudder doublets, a sideslip, a "
                        "wind-up turn, stalls with lateral inputs) and record the lateral channels (beta, p, r, da, "
                        "dr, CY, Cl, Cn) on every maneuver")
    s.add_argument("--seed", type=_non_negative, default=0, help="random seed (same seed, same campaign bit for bit)")
    s.add_argument("--withhold", action="append", choices=sorted(WITHHOLDABLE), metavar="EFFECT",
                   help="remove an effect from the truth model (repeatable): " + ", ".join(WITHHOLDABLE))
    s.add_argument("--anomaly", choices=sorted(ANOMALY_NAMES), metavar="NAME",
                   help="add an effect outside the diagnosis' library to the Citation's truth: " + ", ".join(ANOMALY_NAMES))
    s.add_argument("--scale", type=_fraction, default=1.0,
                   help="fraction of the maneuvers of each kind to fly (small test campaigns)")
    s.add_argument("--extras", action="store_true", help="add pullups, pushovers and phugoids")
    s.add_argument("--format", choices=("csv", "parquet"), default="csv",
                   help="maneuver file format (default csv; parquet needs pyarrow)")
    s.add_argument("--slow-errors", type=_non_negative_float, default=1.0, metavar="F",
                   help="scale of the slow reconstruction errors of a standard campaign (1, the default: realistic; "
                        "0: only sensor noise, buffet and residual biases, like a raw campaign's channels)")
    s.add_argument("--raw", action="store_true",
                   help="write the raw sensor channels (docs/interfaces.md 5.2) with the injected sensor errors recorded")
    s.add_argument("--flights", type=_non_negative, default=0, metavar="N",
                   help="fly the maneuvers on N flights (consecutive maneuvers of one loading; each maneuver's flight "
                        "recorded in campaign.toml) that share a mass, cg, engine-model and vane-calibration error on "
                        "top of the per-maneuver ones; 0, the default: no flights (the campaign of before, bit for "
                        "bit). Not with --raw")
    s.add_argument("--nominal", action="store_true",
                   help="add nominal (attached-flow) maneuvers across the envelope: doublets, 3-2-1-1 inputs, speed "
                        "and altitude changes (kind = \"nominal\"), flown with the truth's Mach and dynamic-pressure "
                        "terms, and the air data Mach and qbar in every file (Citation II; not with --anomaly, "
                        "--raw or --flights)")
    s.add_argument("--cg-spread", type=_positive_float, default=None, metavar="M",
                   help="Citation: draw each loading's cg from a band M metres wide around the middle of the default "
                        "one (281.25 in; default band 1.5 in = 0.0381 m; at most 0.2413 m, the cg envelope)")
    s.add_argument("--cg-moment", choices=CG_MOMENTS, default="thesis",
                   help="Citation: how the truth's C_m depends on the cg: thesis (default, its identified "
                        "Cm_xcgCL x_cg/cbar C_L term) or transfer (the same model about the reference point, moved to "
                        "the cg by C_N (x_cg - x_ref)/cbar alone)")
    s.set_defaults(func=handler)


def _add_preprocess(sub, handler: Callable) -> None:
    """The ``preprocess`` command."""
    pp = command_parser(sub, "preprocess")
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
    pp.set_defaults(func=handler)


def _add_study(sub, handler: Callable) -> None:
    """The ``study`` command."""
    st = command_parser(sub, "study")
    st.add_argument("--data", required=True, help="campaign directory")
    st.add_argument("--out", required=True, help="directory for the tables (Markdown, LaTeX, CSV) and box plots")
    st.add_argument("--cache", help="the search's output directory whose cache to reuse (default: --out)")
    st.add_argument("--starts", type=_count, default=4, help="starts per nonlinear fit (as search: its cache serves)")
    st.add_argument("--jobs", type=_non_negative, default=0, help="processes (0: all cores)")
    st.add_argument("--quiet", action="store_true", help="no progress on stderr")
    st.set_defaults(func=handler)


def _add_fit(sub, handler: Callable) -> None:
    """The ``fit`` command."""
    f = command_parser(sub, "fit")
    # not results/: a fit of the user's data must not land among the demo's results (a repository's committed ones)
    _campaign_options(f, out=FIT_OUT)
    which = f.add_mutually_exclusive_group(required=True)
    which.add_argument("--model", help="candidate name (CL-VI, CD-IXr, Cm-XXXIII, ...) or spec file")
    which.add_argument("--joint", metavar="LIFT,DRAG,PITCH",
                       help="fit two or three structures jointly, sharing their separation states: names or spec "
                            "files, comma-separated, or a joint spec file ([joint] structures = [...])")
    f.add_argument("--band-samples", type=_non_negative, default=0, metavar="N",
                   help="cross-check the static curves' confidence bands by N parameter draws (seeded by --seed); "
                        "with --joint of C_L, C_D and C_m also a validation maneuver's forward replay with its "
                        "sampled band (default 0: delta method only)")
    f.add_argument("--profile", action="store_true",
                   help="also the 95 %% and 68 %% profile intervals of the nonlinear parameters (each held on either "
                        "side of its estimate, the rest refitted; the statistic scaled by the reported over the white "
                        "variance) beside the Wald ones, in fit.json (profile) and fit.md; not with --joint")
    f.add_argument("--by-kind", action="store_true",
                   help="fit the global model(s) of --model (comma-separated: CL-G,CD-G,Cm-G) on stall and nominal "
                        "maneuvers together and each part on its kind alone; by_kind.json and by_kind.md compare their "
                        "validation MSE on nominal and on stall maneuvers separately")
    f.add_argument("--replay-maneuver", metavar="NAME", default=None,
                   help="the validation maneuver the joint fit's sampled replay flies (default: the deepest)")
    _moment_reference_options(f)
    f.set_defaults(func=handler)


def _add_search(sub, handler: Callable) -> None:
    """The ``search`` command."""
    r = command_parser(sub, "search")
    _campaign_options(r)
    r.add_argument("--grid", required=True, help="separation, lift, drag, pitch, all (those four), side, roll, yaw, "
                   "lateral (those three), or a grid spec file")
    r.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default 0: all cores)")
    r.add_argument("--cv-method", choices=CV_METHODS, default="refit",
                   help="cross-validation folds of a nonlinear candidate: refit (solved again from the full "
                        "fit's estimates, exact; default) or one-step (one Gauss-Newton step from them: no "
                        "solve, linearised; exact for linear candidates)")
    r.add_argument("--backend", default="loky", choices=("loky", "dask"),
                   help="loky: local processes; dask: a dask.distributed cluster")
    r.add_argument("--scheduler", default=None,
                   help="dask scheduler address (default: start a local cluster of --jobs workers)")
    r.add_argument("--joint-lift", metavar="LIFT,DRAG[,PITCH]", default=None,
                   help="fit these structures jointly first (names, spec files, or a joint spec file); drag and "
                        "pitch candidates that name its lift structure read the joint estimate, and their "
                        "two-step covariance has the joint fit as first step (writes joint_lift.json)")
    r.add_argument("--trace", metavar="FILE", default=None,
                   help="write every task (start, end, worker, the tasks it waited for) to FILE as Chrome "
                        "trace-event JSON (opens in Perfetto; structsearch bench --trace FILE analyses it)")
    r.add_argument("--quiet", action="store_true", help="no progress on stderr, lines or bar")
    _admissibility_options(r)
    _moment_reference_options(r)
    r.set_defaults(func=handler)


def _add_diagnose(sub, handler: Callable) -> None:
    """The ``diagnose`` command."""
    g = command_parser(sub, "diagnose")
    _campaign_options(g, starts=2, data_required=False)
    g.add_argument("--model", help="baseline candidate name or spec file")
    g.add_argument("--coefficient", choices=tuple(COEFFICIENTS),
                   help="check that the baseline models this (with a simulator baseline: the coefficient diagnosed)")
    g.add_argument("--baseline-column", metavar="NAME", default=None,
                   help="baseline: the simulator's coefficient along the flight, a column of the campaign's files "
                        "(a fixed offset; needs --coefficient)")
    g.add_argument("--simulator", metavar="jsbsim:NAME_OR_DIR", type=_simulator, default=None,
                   help="baseline: a JSBSim aircraft (one of JSBSim's own such as c172p, an aircraft directory, or an "
                        "export of `structsearch export --format jsbsim`) evaluated at the recorded states (a fixed "
                        "offset; its axis functions are columns sim:<function> the search may rescale, drop or "
                        "replace; needs --coefficient)")
    g.add_argument("--simulator-input", metavar="PROPERTY=COLUMN|VALUE", type=_simulator_input, action="append",
                   default=None, help="what the JSBSim aircraft reads and the campaign does not give: a campaign "
                                      "column or a constant, in the property's unit (repeatable)")
    g.add_argument("--benchmark", action="store_true",
                   help="run the withheld-effect benchmark on simulated campaigns instead")
    g.add_argument("--scale", type=_fraction, default=1.0, help="benchmark campaign scale")
    g.add_argument("--null-seeds", type=_non_negative, default=3, help="benchmark: seeds of the null case")
    g.add_argument("--parts", type=_benchmark_parts, default=None,
                   help="benchmark: which parts, comma-separated: withheld, anomalies, null (default: these three); "
                        "jsbsim: the withheld effects diagnosed through JSBSim (the truth without each effect "
                        "exported as the simulator; needs the jsbsim extra)")
    g.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default 0: all cores)")
    g.add_argument("--backend", default="loky", choices=("loky", "dask"),
                   help="loky: local processes; dask: a dask.distributed cluster (a local one of --jobs workers)")
    g.add_argument("--trace", metavar="FILE", default=None,
                   help="write every task (start, end, worker, the tasks it waited for) to FILE as Chrome "
                        "trace-event JSON (opens in Perfetto; structsearch bench --trace FILE analyses it)")
    _structure_search_options(g)
    g.add_argument("--quiet", action="store_true", help="no progress on stderr, lines or bar")
    _moment_reference_options(g)
    g.set_defaults(func=handler)


def _add_discover(sub, handler: Callable) -> None:
    """The ``discover`` command."""
    d = command_parser(sub, "discover")
    _campaign_options(d, starts=2)
    d.add_argument("--coefficient", choices=tuple(COEFFICIENTS), required=True, help="the coefficient to model")
    d.add_argument("--from", dest="start", default="minimal",
                   help="the structure to start from: 'minimal' (default), a candidate name or a spec file")
    d.add_argument("--lift", action="append", default=[], metavar="NAME",
                   help="a lift model drag or pitch structures may be fed (repeatable; default: the start's own "
                        "and the thesis' CL-VI)")
    d.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default 0: all cores)")
    d.add_argument("--backend", default="loky", choices=("loky", "dask"),
                   help="loky: local processes; dask: a dask.distributed cluster (a local one of --jobs workers)")
    d.add_argument("--trace", metavar="FILE", default=None,
                   help="write every task (start, end, worker, the tasks it waited for) to FILE as Chrome "
                        "trace-event JSON (opens in Perfetto; structsearch bench --trace FILE analyses it)")
    _structure_search_options(d)
    d.add_argument("--exhaustive", action="store_true",
                   help="instead of a search move by move: every structure of the term library of 1 to --max-terms "
                        "terms (C_L: on two states of its own, kind U; C_D, C_m: fed --lift, default CL-VI), fitted "
                        "as one grid of independent tasks and ranked like a grid")
    d.add_argument("--max-terms", type=_count, default=3,
                   help="with --exhaustive: the most terms a structure has (default 3)")
    d.add_argument("--quiet", action="store_true", help="no progress on stderr, lines or bar")
    _moment_reference_options(d)
    d.set_defaults(func=handler)


def _add_report(sub, handler: Callable) -> None:
    """The ``report`` command."""
    p = command_parser(sub, "report")
    _campaign_options(p)  # the search's defaults, so that its cached fits are reused
    p.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes for the fits (default 0: all cores)")
    p.add_argument("--diagnose", choices=("CL", "CD", "Cm", "none"), default="Cm",
                   help="coefficient whose gap breakdown is shown (default Cm; none: skip the diagnosis)")
    p.add_argument("--model", action="append", metavar="NAME",
                   help="use this lift, drag or pitch structure instead of the search's winner (repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr, lines or bar")
    p.set_defaults(func=handler)


def _add_demo(sub, handler: Callable) -> None:
    """The ``demo`` command."""
    d = command_parser(sub, "demo")
    d.add_argument("--out", default="results", help="output directory (default: results)")
    d.add_argument("--jobs", type=_non_negative, default=0, help="parallel processes (default: all cores)")
    d.add_argument("--starts", type=_count, default=4, help="starts per nonlinear fit (default 4)")
    d.add_argument("--scale", type=_fraction, default=1.0, help="fraction of the campaign to fly (quick looks)")
    d.add_argument("--quiet", action="store_true",
                   help="no progress on stderr, lines or bar (the story's lines are still printed)")
    _admissibility_options(d)
    d.set_defaults(func=handler)


def _add_compare(sub, handler: Callable) -> None:
    """The ``compare`` command."""
    c = command_parser(sub, "compare")
    c.add_argument("first", help="an output directory (e.g. of `demo --out A`)")
    c.add_argument("second", help="the output directory of the same command elsewhere")
    c.add_argument("--rtol", type=_non_negative_float, default=1e-3,
                   help="relative tolerance of numbers (default 1e-3: see docs/reproducibility.md)")
    c.add_argument("--json", metavar="FILE", help="also write the comparison as JSON")
    c.set_defaults(func=handler)


def _structure_search_options(p) -> None:
    """The structure search's options (diagnose, discover)."""
    p.add_argument("--terms", metavar="FILE", help="a term library in TOML (docs/interfaces.md, 'Term library')")
    p.add_argument("--beam", type=_count, default=None, help="structures each step expands (default 3)")
    p.add_argument("--max-steps", type=_count, default=None, help="steps of the search at most (default 20)")
