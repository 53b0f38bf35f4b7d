"""diagnosis.json and a readable diagnosis.md (no figures), story.json and story.md, the withheld-effect
benchmark's files, and what ``structsearch diagnose`` and ``demo`` print of them."""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tabulate import tabulate

from ..fitting.candidates import Candidate
from .equations import equations
from ..discovery.adoption import DEFAULT_ALPHA
from ..data.atomic import json_ready, write_json, write_text
from ..diagnosis.results import Diagnosis
from ..diagnosis.story import Story, unexplained_sentence

if TYPE_CHECKING:  # the benchmark module imports the flight simulator: loaded only to write a benchmark
    from ..diagnosis.withheld import BenchmarkResult

__all__ = ["public", "markdown", "write", "story_markdown", "write_story", "write_benchmark", "unexplained_sentence",
           "diagnosis_console_lines", "story_console_lines", "benchmark_console_line"]


def public(doc) -> dict:
    """The docs/interfaces.md section 3 document (extra fields kept) of a typed result (a :class:`Diagnosis`, a
    :class:`Story`) or of its ``to_dict()``; what could not be estimated is null."""
    if hasattr(doc, "to_dict"):
        doc = doc.to_dict()
    return json_ready(json.loads(json.dumps(doc, default=float)))


# The moves a diagnosis.md lists per table (all of them are in diagnosis.json).
MOVES_SHOWN = 15


def _test_p(e):
    """The adoption test's p-value of a move (None when it has none)."""
    return (e.test or {}).get("p_value")


def _terms(doc) -> str:
    """The final structure's terms (and lift model), in words."""
    st = doc.final_structure
    if not st:
        return ""
    text = ", ".join(f"{n} = {e}" for n, e in st["regressors"].items())
    return f" ({text}" + (f"; lift model {st['lift']})" if st.get("lift") else ")")


def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.0%}"


# one definition of the share a move closes, in every story and diagnosis text (issue 31)
CLOSES_DEFINITION = ("the share of the baseline's gap (its validation MSE above the noise floor) a move closes: the "
                     "validation MSE before the move minus after it, over the baseline's validation MSE minus the "
                     "floor; negative when a move costs. The moves of one path add up to the share of the gap "
                     "closed. (diagnosis.json's `shrink` is each move's share of its own round's gap.)")


def _share(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.0%}"


def _num(x, fmt=".2f") -> str:
    return "n/a" if x is None or not np.isfinite(x) else format(x, fmt)


def _gap_lines(doc: Diagnosis) -> list[str]:
    """The baseline's gap over the noise floor and, when there is one, where it lies."""
    m = doc.mse
    first = doc.first
    if doc.gap_explained_by_baseline:
        return [f"**The baseline is already at the noise floor**: its per-maneuver validation MSE exceeds the "
                f"floor's by {_pct(first.excess_over_floor)} +- {_pct(first.excess_se)} (within "
                "one standard error, or below 1 %).", ""]
    lines = [f"**Gap**: {m.validation - doc.noise_floor:.4g} "
             f"({_pct(m.validation / doc.noise_floor - 1 if doc.noise_floor > 0 else None)} above the "
             "floor).", ""]
    lines += ["## Where the gap lies", ""]
    for dim in ("phase", "alpha_band", "alpha_dot_sign", "frequency_band", "maneuver"):
        rows = sorted((r for r in doc.where if r.dimension == dim), key=lambda r: -r.share)
        body = [[r.bin, f"{r.share:.2f}", "-" if not np.isfinite(r.share_std) else f"{r.share_std:.2f}",
                 "-" if not np.isfinite(r.mse) else f"{r.mse:.3g}"] for r in rows[:8]]
        lines += [f"### by {dim.replace('_', ' ')}", "",
                  tabulate(body, headers=["bin", "share of excess", "+-", "MSE"], tablefmt="github"), ""]
    return lines


def _effect_lines(doc: Diagnosis) -> list[str]:
    """The table of the moves tried from the baseline."""
    lines = ["## Which effect (the moves tried from the baseline)", ""]
    body = []
    shown = doc.effects[:MOVES_SHOWN]
    for e in shown:
        if e.failed:
            body.append([e.name, e.verdict or "failed", "-", "-", "-", "-", "-", "-", e.error])
        else:
            body.append([e.name, e.verdict or "-", _share(doc.closes(0, e)), f"{e.mse_validation_after:.4g}",
                         _num(_test_p(e), ".2g"), _num(e.p_value, ".2g"), _num(e.overlap),
                         (e.acts_in or {}).get("phase", "-"), "at floor" if e.at_floor else ""])
    lines += [tabulate(body, headers=["move", "verdict", "closes (of the baseline's gap)", "validation MSE after",
                                      "p (test)", "p (Wald)",
                                      "overlap with gap", "acts most in", ""], tablefmt="github"), ""]
    if len(doc.effects) > len(shown):
        lines += [f"{len(doc.effects) - len(shown)} more moves in diagnosis.json. p (test): the structure search's "
                  "adoption test; p (Wald): the test of the parameters a nested move adds (fitted in full).", ""]
    return lines


def _round_lines(doc: Diagnosis) -> list[str]:
    """How far the gap shrinks, round by round, and whether it is explained."""
    lines = ["## How far it shrinks", "", f"\"Closes\": {CLOSES_DEFINITION}", ""]
    for i, r in enumerate(doc.rounds):
        best = r.effect(r.adopted) if r.adopted else None
        step = ("at the floor" if r.explained_before and not r.adopted else
                f"adopted {r.adopted} ({best.verdict}), which closes {_share(doc.closes(i, best))} of the "
                "baseline's gap "
                f"(p = {_num(_test_p(best), '.2g')}, adoption test)"
                if best is not None else "no move passes the adoption test")
        lines.append(f"{i + 1}. {r.baseline}: validation MSE {r.mse.validation:.4g} (floor of this "
                     f"round {r.noise_floor_round:.4g}, {r.floor_source}); {step}.")
    lines += ["", f"**Explained**: {'yes' if doc.explained else 'no'} (the final model's per-maneuver excess over "
              f"the floor: {_pct(doc.final_excess_over_floor)} +- {_pct(doc.final_excess_se)}). "
              f"Final model: {doc.final_model}" + _terms(doc) + ".", ""]
    if doc.final_structure:
        lines += ["```", *equations(Candidate.from_dict(doc.final_structure)), "```", ""]
    aside = (doc.search or {}).get("set_aside") or []
    if aside:   # what the final choice left, so that no better structure the search fitted goes unsaid
        a = aside[0]
        lines += [f"The search stopped: {doc.search.get('stopped')}. It fitted {len(aside)} structures of lower "
                  f"held-out MSE than the final one (search.set_aside in diagnosis.json); the lowest, {a['name']} "
                  f"(held-out MSE {_num(a['mse'], '.4g')}, the final's excess {_pct(a['excess'])}), was set aside: "
                  f"{a['reason']}.", ""]
    return lines + equivalence_lines(doc)


def equivalence_lines(doc: Diagnosis) -> list[str]:
    """What the added terms are also the signature of: the gap stays explained by library terms, and a reader
    learns which measurement or structural anomaly the same fit would mean (first order)."""
    if not doc.equivalences:
        return []
    return ["## What the added terms are also the signature of", ""] + [
        f"- {e.term} (library effect `{e.effect}`) is {e.words()}: to first order the data cannot tell the "
        f"term from that anomaly (`structsearch simulate --anomaly {e.anomaly}`)." for e in doc.equivalences] + [""]


def _state_level_lines(sl) -> list[str]:
    """The state-level check (None: not made): the replayed states' RMS errors before and after the best effect."""
    if sl is None:
        return []
    lines = ["## At the state level", ""]
    if sl.failed:
        lines += [f"Not available: {sl.error}", ""]
    else:
        units = {"alpha": "rad", "q": "rad/s", "V": "m/s", "theta": "rad"}
        body = [[s, units[s], f"{sl.before[s]:.4g}", f"{sl.after[s]:.4g}",
                 "n/a" if not np.isfinite(sl.reduction[s]) else f"{sl.reduction[s]:+.0%}"]
                for s in ("alpha", "q", "theta", "V")]
        lines += [f"Validation maneuvers replayed through the simulator (recorded elevator and thrust, "
                  f"re-initialised on the measured states every {sl.window_s:g} s); RMS state error with "
                  f"the baseline and with the best effect added:", "",
                  tabulate(body, headers=["state", "unit", "before", "after", "reduction"], tablefmt="github"),
                  ""]
        for label, gone in (("baseline", sl.diverged_before), ("model with the effect", sl.diverged_after)):
            if gone:
                lines += [f"The replay with the {label} **diverged** on {len(gone)} maneuver(s), left out of "
                          "both RMS: " + "; ".join(d.words() for d in gone) + ".", ""]
    return lines


def _simulator_lines(sim) -> list[str]:
    """What the simulator baseline is, its own MSE and how it enters (docs/interfaces.md 7.6)."""
    if not sim:
        return []
    mse = sim.get("mse", {})
    own = ", ".join(f"{k} {v:.4g}" for k, v in mse.items() if v is not None)
    bias = sim.get("bias", {})
    lines = [f"**Baseline: the simulator {sim['source']}** ({own} without the bias; bias {bias.get('name')} = "
             f"{bias.get('value', float('nan')):.3g}). {sim.get('baseline', '')}; state level "
             f"{sim.get('state_level', '')}.", ""]
    return lines + simulator_term_lines(sim, "- ") + ([""] if sim.get("terms") else [])


def simulator_term_lines(sim, prefix: str = "") -> list[str]:
    """A line per simulator term the final structure changed (rescaled, dropped, replaced), naming its function;
    one line for those kept."""
    terms = (sim or {}).get("terms") or {}
    changed = [f"{prefix}{t['words']}" for t in terms.values() if t.get("verdict") not in ("kept", "zero")]
    kept = [n.removeprefix("sim:") for n, t in terms.items() if t.get("verdict") == "kept"]
    zero = [n.removeprefix("sim:") for n, t in terms.items() if t.get("verdict") == "zero"]
    return changed + ([f"{prefix}kept as the simulator has them: {', '.join(kept)}"] if kept else []) + \
        ([f"{prefix}zero along the flight (not searched): {', '.join(zero)}"] if zero else [])


def markdown(doc: Diagnosis) -> str:
    lines = [f"# Diagnosis of {doc.coefficient} (baseline {doc.baseline})", ""]
    m = doc.mse
    u = doc.unexplained
    lines += [f"Validation MSE {m.validation:.4g} (training {m.train:.4g}); noise floor {doc.noise_floor:.4g} "
              f"({doc.floor_source}): the lowest of every library model fitted ({doc.noise_floor_library:.4g}, "
              f"the saturated model among them) and of a library-free flexible model of the residual "
              f"({u.noise_floor:.4g}); spectral estimate {doc.noise_floor_spectral:.4g}.", ""]
    lines += [f"Warning: {w}" for w in doc.warnings] + ([""] if doc.warnings else [])
    lines += _simulator_lines(doc.simulator)
    lines += _gap_lines(doc)
    lines += _effect_lines(doc)
    lines += _round_lines(doc)
    sentence = unexplained_sentence(doc)
    if u.gap_signals and not doc.gap_explained_by_baseline:
        top = ", ".join(f"{g.name} ({g.share:.2f})" for g in u.gap_signals[:4])
        lines += [f"Before any effect, the gap followed (share of it a function of one signal removes on the "
                  f"validation maneuvers): {top}.", ""]
    if u.note and not doc.explained:
        lines += [f"Note: {u.note}.", ""]
    if sentence:
        lines += ["## What the library does not explain", "", sentence, ""]
        body = [[s.name, f"{s.share:.2f}"] for s in u.signals[:8]]
        lines += ["Share of the remaining gap a smooth function of one signal removes on the validation maneuvers:",
                  "", tabulate(body, headers=["signal", "share"], tablefmt="github"), ""]
    lines += _state_level_lines(doc.state_level)
    return "\n".join(lines)


def write(doc: Diagnosis, out: Path) -> tuple[Path, Path]:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "diagnosis.json", public(doc))
    write_text(out / "diagnosis.md", markdown(doc))
    return out / "diagnosis.json", out / "diagnosis.md"


def story_markdown(story: Story, command: str) -> str:
    """The Van Ingen -> final story: the lines, then each coefficient's rounds."""
    lines = ["# From Van Ingen's models to structures at the floor", "", f"Made by `{command}`.", "",
             "Each coefficient's Van Ingen model (the simulator's) is diagnosed against the flight data and moves "
             "are adopted until none passes its test; the path need not end at the thesis' final model (`structsearch "
             "discover` searches for that).", "", f"\"Closes\": {CLOSES_DEFINITION}", "",
             "Adopted: a move whose test (column \"p (test)\": the Wald test of a nested move's new parameters, else "
             f"a paired out-of-sample test) rejects at {DEFAULT_ALPHA:.2f} divided by the number of moves tried at that round "
             "(Bonferroni), and none once the structure is at the floor; a small p in a round that adopts nothing "
             "did not reach that bar. \"CL-story\" is the lift structure the C_L story reached, offered to drag and "
             "pitch beside the thesis' CL-VI. A replay figure is as measured: a first move that repairs a fit or "
             "swaps the lift model may replay worse before the next moves build on it.", ""]
    degenerate = [d for d in story.diagnoses.values() if d.baseline_reasons]
    if degenerate:
        lines += ["**The story starts from a baseline that is not admissible as fitted here** ("
                  + ", ".join(d.baseline for d in degenerate) + "): its gap is that of a degenerate fit, and "
                  "the first moves partly repair the fit rather than add an effect. Why (the ranking's rules):", ""]
        lines += [f"- {d.baseline}: " + "; ".join(d.baseline_reasons) for d in degenerate] + [""]
    lines += [f"- {line}" for line in story.lines] + [""]
    for coef, doc in story.diagnoses.items():
        lines += [f"## {coef}: {doc.baseline} -> {doc.final_model}", ""]
        body = []
        for i, r in enumerate(doc.rounds):
            best = r.effect(r.adopted) if r.adopted else r.best
            closes = doc.closes(i, best) if best is not None else float("nan")
            body.append([i + 1, r.baseline, f"{r.mse.validation:.4g}",
                         "-" if best is None else best.name, "-" if best is None else _share(closes),
                         "-" if best is None else _num(_test_p(best), ".2g"), r.adopted or "-",
                         "yes" if r.explained_before else "no"])
        lines += [tabulate(body, headers=["round", "model", "validation MSE", "best move",
                                          "closes (of the baseline's gap)", "p (test)", "adopted", "at the floor"],
                           tablefmt="github"), "",
                  f"Noise floor {doc.noise_floor:.4g}; explained: {'yes' if doc.explained else 'no'}. "
                  + unexplained_sentence(doc), ""]
        ahead = [i + 1 for i, r in enumerate(doc.rounds) if r.adopted and r.effect(r.adopted) is not None
                 and r.effect(r.adopted).verdict == "look-ahead"]
        if ahead:
            lines += [f"Round{'s' if len(ahead) > 1 else ''} {', '.join(map(str, ahead))}: a look-ahead, kept though "
                      "its own test does not pass, because the next move passes against the structure before it "
                      "(two moves that pay only together).", ""]
        lines += ["The floor is the lowest validation MSE this diagnosis found (its structures and a library-free "
                  "model of the residual); another structure can lie below it.", ""]
    return "\n".join(lines)


def write_story(story: Story, out: Path, command: str) -> tuple[Path, Path]:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "story.json", public(story))
    write_text(out / "story.md", story_markdown(story, command))
    return out / "story.json", out / "story.md"


def write_benchmark(result: BenchmarkResult, out: Path, command: str) -> tuple[Path, Path]:
    """``withheld_benchmark.json`` (NaN written as NaN, as before) and ``withheld_benchmark.md``."""
    from ..diagnosis.withheld import markdown as benchmark_markdown
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "withheld_benchmark.json", json.dumps(result.to_dict(), indent=2, default=float))
    write_text(out / "withheld_benchmark.md", benchmark_markdown(result, command))
    return out / "withheld_benchmark.json", out / "withheld_benchmark.md"


def diagnosis_console_lines(diagnosis: Diagnosis, written: tuple[Path, Path] | None = None) -> list[str]:
    """What ``structsearch diagnose`` prints: the verdict line (ending with the files ``written``, the json and
    the md, when given), then what the library does not explain and the warnings, a line each."""
    d = diagnosis
    best = d.best_effect
    verdict = ("the baseline is at the noise floor" if d.gap_explained_by_baseline else
               f"best effect {best.name} closes {_share(d.closes(0, best))} of the baseline's gap"
               if best and best.shrink is not None
               else "no effect fitted")
    head = (f"{d.coefficient} {d.baseline}: {verdict}; final model {d.final_model}; explained: "
            f"{'yes' if d.explained else 'no'}")
    if written is not None:
        head += f"; wrote {written[0]} and {written[1]}"
    sl = d.state_level
    replay = []
    if sl is not None and (sl.failed or sl.diverged_before or sl.diverged_after):
        # an error inside the command reaches the console, not only the json (issue 31)
        replay = [f"warning: {sl.words()}"]
    also = [f"{e.term}: {e.words()}" for e in d.equivalences]
    also += [line for line in simulator_term_lines(d.simulator) if not line.startswith(("kept as", "zero along"))]
    return [head] + [line for line in also + [unexplained_sentence(d)] + [f"warning: {w}" for w in d.warnings]
                     + replay if line]


def story_console_lines(story: Story) -> list[str]:
    """The story's lines as ``structsearch demo`` prints them (indented by two spaces)."""
    return [f"  {line}" for line in story.lines]


def benchmark_console_line(result: BenchmarkResult, written: Path | None = None) -> str:
    """The summary ``structsearch diagnose --benchmark`` prints (ending with the Markdown file ``written``)."""
    text = (f"withheld effect ranked first {result.ranked_first}/{len(result.rows)}; out-of-library effects right "
            f"(located, not falsely explained and their signal first, or explained with the equivalence named) "
            f"{result.outside_scored}/{len(result.outside)}; false "
            f"alarms {result.false_alarms}/{len(result.null)} (Wald test alone {result.false_alarms_test})")
    return text + (f"; wrote {written}" if written is not None else "")
