"""What ``structsearch <command> --help`` says beyond the options: a one-line summary (the top-level ``--help``
lists it), a paragraph (what the command does, what it reads and what it writes) and runnable examples.

Kept apart from :mod:`.parser` so that the parser stays a list of options; like it, imports nothing heavy.
"""
from __future__ import annotations

import argparse
import textwrap
from dataclasses import dataclass

# wide enough for the option names, narrow enough for an 80-column terminal
WIDTH = 79


@dataclass(frozen=True)
class CommandHelp:
    summary: str               # one line, in the top-level --help
    description: str           # one paragraph: what it does, reads and writes
    examples: tuple[str, ...]  # each a command line starting "structsearch <name>", with a comment after "#"


COMMANDS: dict[str, CommandHelp] = {
    "bench": CommandHelp(
        "time the SNLS engine, or run another benchmark",
        "Times the separable nonlinear least-squares engine against the prototype, full NLS and finite "
        "differences on a simulated campaign, measures its success rate over random starts and its peak memory, "
        "and (unless --no-search) times `search --grid all`. --calibration, --joint, --discovery, --reading and "
        "--trace FILE run another benchmark instead. Reads no data (it simulates its own; --trace reads a trace "
        "file); writes bench.md and bench.json (or the chosen benchmark's .md and .json) in --out.",
        ("structsearch bench --out results --no-search   # the engine alone, a few minutes",
         "structsearch bench --calibration --campaigns 10 --scale 0.1 --out results",
         "structsearch bench --trace results/trace.json --out results")),
    "simulate": CommandHelp(
        "simulate a flight-test campaign (Citation II or a transport)",
        "Flies the thesis' flight-test campaign (Table 4) in the simulator, with its sensor noise and "
        "reconstruction errors, seeded so that the same seed gives the same campaign bit for bit. Reads nothing; "
        "writes a campaign directory to --out: campaign.toml (the manifest: maneuvers, splits, the truth model) "
        "and one CSV or Parquet file per maneuver (or the raw sensor channels with --raw).",
        ("structsearch simulate --out camp --scale 0.25   # a quarter of the maneuvers, ~1 min",
         "structsearch simulate --out camp-raw --raw --seed 3")),
    "preprocess": CommandHelp(
        "turn a raw campaign (sensor channels) into a standard one",
        "Reads a raw flight-test campaign (sensor channels, docs/interfaces.md 5.2), estimates the channels' "
        "spectra, pre-filters them, reconstructs the flight path with a Kalman smoother that estimates the "
        "sensor errors, and computes the aerodynamic coefficients. Writes a standard campaign directory to "
        "--out, with preprocess.md (the cut-offs, the estimated sensor errors, the fit of the reconstruction) "
        "and, unless --no-figures, the spectra figures.",
        ("structsearch preprocess --raw camp-raw --out camp",)),
    "study": CommandHelp(
        "the thesis' comparison tables: final models against Van Ingen's",
        "Fits the thesis' final models and Van Ingen's on a campaign and writes the comparison tables: final "
        "against Van Ingen's models, the dynamic-stall study, the separation matrix, derived quantities and the "
        "collinearity of the regressors, as Markdown, LaTeX and CSV, with R^2 box plots. Reads the campaign "
        "directory --data (and the cached fits of a search in --cache); writes the tables to --out.",
        ("structsearch study --data camp --out results/study --cache results",)),
    "fit": CommandHelp(
        "fit one model structure (or two or three jointly)",
        "Fits one candidate structure (a name of the shipped grids or a spec file) to the training maneuvers "
        "of a campaign and scores it on the validation maneuvers: estimates, their covariance, confidence "
        "bands of the static curves and, with --profile, profile intervals. A drag or pitch candidate fits its "
        "lift model first. Reads the campaign directory --data; writes fit.json and fit.md to --out (and the "
        "fit to --out's cache/).",
        ("structsearch fit --data camp --model CL-VI --out results",
         "structsearch fit --data camp --joint CL-VI,CD-IXr,Cm-XXXIII --out results/joint")),
    "search": CommandHelp(
        "fit and rank every candidate of a grid",
        "Fits every candidate of a grid (separation, lift, drag, pitch, all, or a grid spec file) to a "
        "campaign, cross-validates it, judges its admissibility and ranks the candidates by held-out MSE; "
        "prints each grid's winner. Reads the campaign directory --data; writes ranking.csv, per grid its "
        "ranking and the best candidate's parameters and correlations (Markdown, LaTeX, CSV), and cache/ (every "
        "fit, reused by a later run) to --out.",
        ("structsearch search --data camp --grid lift --out results",
         "structsearch search --data camp --grid all --jobs 4 --out results")),
    "diagnose": CommandHelp(
        "where a model misses the data and which effect closes the gap",
        "Diagnoses a baseline structure: its gap to a noise floor, where in the flight envelope the gap lies, "
        "and a structure search from it that adopts the moves (effects of the library) passing their test "
        "round by round, until the model is at the floor or no move passes; what is left is described. With "
        "--benchmark, the withheld-effect benchmark on simulated campaigns instead. Reads the campaign "
        "directory --data; writes diagnosis.json and diagnosis.md to --out.",
        ("structsearch diagnose --data camp --model CD-I --out results",
         "structsearch diagnose --benchmark --scale 0.25 --out results")),
    "discover": CommandHelp(
        "search structures of one coefficient, move by move",
        "Searches the structures of one coefficient: from a minimal structure (or a named one), every move "
        "(a term, a separation state, a lift model, a simplification) is fitted and tested, the best are kept "
        "step by step, and the final structure is chosen among the admissible ones. Reads the campaign "
        "directory --data; writes discover.json, discover.md and path.csv (the moves adopted) to --out.",
        ("structsearch discover --data camp --coefficient CD --out results/discover",
         "structsearch discover --data camp --coefficient Cm --from Cm-I --beam 2 --out results/discover")),
    "report": CommandHelp(
        "the figures and one self-contained HTML page of a campaign",
        "Draws the thesis' figures for a campaign (the chosen models' static curves against Van Ingen's, "
        "centre of pressure and elevator effectiveness, dynamic stall, a diagnosis' gap, a forward replay) and "
        "puts them on one self-contained HTML page, with the rankings; the models are the search's winners in "
        "--out (or --model), their fits read from its cache or fitted. Needs matplotlib. Reads the campaign directory "
        "--data (and --out's cache/ and ranking.csv); writes report.html and figures/ to --out.",
        ("structsearch report --data camp --out results",
         "structsearch report --data camp --model CL-VI --diagnose none --out results")),
    "demo": CommandHelp(
        "the whole path on a simulated campaign, tables and report",
        "The whole path on the default simulated campaign: simulates it (or reuses the one in --out/campaign), "
        "searches every grid, tells the story of Van Ingen's models against the flight data (a diagnosis of "
        "each), writes the thesis' comparison tables and the report. Reads nothing; writes campaign/, "
        "ranking.csv and the grids' tables, story.json and story.md, study/ and report.html to --out (a full "
        "run: 7 to 11 minutes on 2 cores; --scale 0.05: about two).",
        ("structsearch demo --out results --scale 0.05   # a quick look",
         "structsearch demo --out results")),
    "compare": CommandHelp(
        "whether two output directories give the same answers",
        "Compares every CSV and JSON file of FIRST with the same file of SECOND: rankings, admissible sets, "
        "structures, moves and verdicts must be equal, numbers within --rtol. Exit status 0: the same answers; "
        "1: they differ (listed). Reads the two directories (the same command run on two machines); writes "
        "only --json FILE.",
        ("structsearch compare results/ other-machine/results/",
         "structsearch compare run1 run2 --rtol 1e-2 --json diff.json")),
    "export": CommandHelp(
        "hand a fitted model to JSBSim, or write it as a model card",
        "Exports a fitted model (a fit directory, or structures fitted here on --data) for C_L, C_D and C_m: "
        "--format json writes model.json (equations, parameters and covariance, separation states, the alpha and "
        "Mach range, the data fitted on); --format jsbsim writes JSBSim's aerodynamics.xml, the states' system "
        "systems/structsearch_states.xml, an example aircraft with the campaign's geometry and fly_stall.py, which "
        "trims it and flies a stall. --check drives JSBSim with every maneuver's recorded inputs and writes "
        "check.json: JSBSim's coefficients against structsearch's prediction. Reads fit.json and its campaign (or "
        "--data); writes to --out.",
        ("structsearch export --data camp --model CL-VI,CD-IXr,Cm-XXXIIIr --format jsbsim --out sim --check",
         "structsearch export --fit results --format json --out card")),
    "grids": CommandHelp(
        "list the shipped grids and their candidates' equations",
        "Lists every shipped grid (separation, lift, drag, pitch) and each candidate's equation; with NAME, "
        "that grid (or grid spec file, or one candidate) with its separation states' equations and what its "
        "helper functions stand for. Reads the grid specs shipped with the package (or the file NAME); "
        "writes nothing.",
        ("structsearch grids", "structsearch grids lift", "structsearch grids CD-IXr")),
}

DESCRIPTION = ("Model-structure search for aircraft stall aerodynamics: simulate or preprocess a flight-test "
               "campaign, fit and rank candidate structures of the lift, drag and pitching-moment coefficients, "
               "diagnose and discover structures, and report. Also run as `python -m structsearch`.")
EPILOG = ("Each command's --help says what it reads and writes, with examples.\n\n"
          "quick start:\n  structsearch demo --out results --scale 0.05")


def _fill(text: str) -> str:
    return textwrap.fill(text, WIDTH)


def epilog(examples: tuple[str, ...]) -> str:
    return "examples:\n" + "\n".join(f"  {line}" for line in examples)


def command_parser(sub, name: str) -> argparse.ArgumentParser:
    """The subparser of ``name`` with its summary, paragraph and examples (the epilog, kept as written)."""
    h = COMMANDS[name]
    return sub.add_parser(name, help=h.summary, description=_fill(h.description), epilog=epilog(h.examples),
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def top_level() -> dict:
    """The top-level parser's description and epilog."""
    return dict(description=_fill(DESCRIPTION), epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
