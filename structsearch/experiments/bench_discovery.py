"""``structsearch bench --discovery``: the structure search's cost, measured in one run on the default campaign.

* the three-coefficient story with the structure search, against the library-only story: the same engine
  restricted to the effect library's moves, one at a time (beam 1), which is what the story did before the
  structure search (the reference is measured in the same run, on the same campaign and processes);
* ``discover --from minimal`` for each coefficient, with its path length, structures fitted and the
  comparison with the thesis' final structure.
Each part uses its own empty cache, so that no part is served another's fits.
"""
from __future__ import annotations

import time
from typing import Callable

from ..data.coefficients import LONGITUDINAL


def run_discovery_bench(n_jobs: int = 2, scale: float = 1.0, seed: int = 0,
                        progress: Callable[[str], None] | None = None, coefficients=LONGITUDINAL) -> dict:
    from ..diagnosis.story import STORY, van_ingen_story
    from ..diagnosis.discover import discover_structures
    from ..fitting.fitter import temporary_fitter
    from ..fitting.options import command_options
    from ..flight.flighttest import build_campaign
    say = progress or (lambda m: None)
    campaign = build_campaign(seed=seed, scale=scale)
    out: dict = {"scale": scale, "seed": seed, "n_jobs": n_jobs, "samples": campaign.data.n_samples}
    timings = {}
    for label, setting in (("library_only", STORY.but(kinds=("effect",))), ("structure_search", STORY)):
        say(f"story ({label.replace('_', ' ')})")
        with temporary_fitter(campaign, command_options("diagnose"), n_jobs=n_jobs) as fitter:
            t0 = time.perf_counter()
            story = van_ingen_story(fitter, setting)
            timings[label] = time.perf_counter() - t0
        out[f"story_{label}"] = {"seconds": timings[label],
                                 "explained": {c: d.explained for c, d in story.diagnoses.items()},
                                 "final_model": {c: d.final_model for c, d in story.diagnoses.items()},
                                 "lines": list(story.lines)}
    out["story_ratio"] = timings["structure_search"] / timings["library_only"]
    out["discover"] = {}
    for coef in coefficients:
        say(f"discover {coef} from the minimal structure")
        with temporary_fitter(campaign, command_options("discover"), n_jobs=n_jobs) as fitter:
            t0 = time.perf_counter()
            found = discover_structures(fitter, coef)
            seconds = time.perf_counter() - t0
        thesis = next((r for r in found.comparison if r.role == "thesis final"), None)
        out["discover"][coef] = {"seconds": seconds, "moves": len(found.path),
                                 "structures_fitted": found.structures_fitted, "final": found.final.to_dict(),
                                 "path": [p.move for p in found.path],
                                 "thesis_final": None if thesis is None else thesis.to_dict()}
    return out


def markdown(fig: dict, command: str) -> str:
    s, lo = fig["story_structure_search"], fig["story_library_only"]
    lines = ["# The structure search's cost", "", f"Made by `{command}` ({fig['samples']} samples, "
             f"{fig['n_jobs']} processes, one run).", "",
             f"- The story with the structure search: {s['seconds']:.0f} s; with the effect library alone, one "
             f"effect at a time (the story before the structure search): {lo['seconds']:.0f} s; "
             f"ratio **{fig['story_ratio']:.2f}x**.",
             "- Explained (at the floor) with the structure search: "
             + ", ".join(f"{c} {'yes' if v else 'no'}" for c, v in s["explained"].items())
             + "; with the library alone: " + ", ".join(f"{c} {'yes' if v else 'no'}" for c, v in lo["explained"].items())
             + ".", "", "## discover --from minimal", "",
             "| coefficient | seconds | moves | structures fitted | final | admissible | excess over the thesis' "
             "final | within noise |", "|---|---|---|---|---|---|---|---|"]
    for coef, d in fig["discover"].items():
        t = d["thesis_final"] or {}
        ex = t.get("excess")
        lines.append(f"| {coef} | {d['seconds']:.0f} | {d['moves']} | {d['structures_fitted']} | {d['final']['name']} | "
                     f"{'yes' if d['final']['admissible'] else 'no'} | "
                     f"{'n/a' if ex is None else f'{ex:+.1%}'} +- "
                     f"{'n/a' if t.get('excess_se') is None else format(t['excess_se'], '.1%')} | "
                     f"{'n/a' if t.get('within_noise') is None else ('yes' if t['within_noise'] else 'no')} |")
    lines += [""] + [f"- {c}: " + " -> ".join(d["path"]) for c, d in fig["discover"].items()] + [""]
    return "\n".join(lines)
