"""``discover``'s files: discover.json, discover.md, path.csv and the final structure's model spec; its console
lines. Everything is written atomically, and the JSON last, so that a reader never sees a half result."""
from __future__ import annotations

import csv
import dataclasses
import io
import math
from pathlib import Path

import numpy as np
from tabulate import tabulate

from ..data.atomic import write_json, write_text
from ..discovery.discovered import Discovery
from ..discovery.spec_file import spec_text
from ..fitting.candidates import Candidate
from .equations import equations
from .diagnosis_doc import public

# the set-aside structures discover.md lists (discover.json holds them all)
SET_ASIDE_SHOWN = 8
PATH_COLUMNS = ("step", "move", "kind", "effect", "structure", "mse_validation", "mse_cv", "p_value", "threshold",
                "shrink", "phase", "alpha_band", "verdict")


def noise_verdict(c, missing: str = "-") -> str:
    """The comparison's verdict by the one-standard-error rule: "yes" within noise, "no" worse, and "better" where
    the discovered structure's excess is below minus the bar (the rule's "within noise" would hide it)."""
    if c.within_noise is None:
        return missing
    bar = max(c.excess_se, 0.01) if c.excess_se is not None and math.isfinite(c.excess_se) else 0.01
    if c.excess is not None and math.isfinite(c.excess) and c.excess < -bar:
        return "better"
    return "yes" if c.within_noise else "no"


def _g(x, fmt=".4g") -> str:
    return "n/a" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, fmt)


def spec_name(found: Discovery) -> str:
    return f"{found.coefficient}_discovered.toml"


def closed_shares(found: Discovery) -> list[float]:
    """Each adopted move's share of the start's gap (the one definition of "closes"; NaN without a gap)."""
    gap = found.start_mse_validation - found.noise_floor
    before, out = found.start_mse_validation, []
    for p in found.path:
        out.append((before - p.mse_validation) / gap if gap > 0 else float("nan"))
        before = p.mse_validation
    return out


def path_rows(found: Discovery) -> list[list]:
    rows = []
    for i, p in enumerate(found.path, 1):
        where = p.where or {}
        rows.append([i, p.move, p.kind, p.effect or "", p.structure["name"], p.mse_validation,
                     "" if p.mse_cv is None else p.mse_cv, "" if p.p_value is None else p.p_value,
                     (p.test or {}).get("threshold", ""), "" if p.shrink is None else p.shrink,
                     where.get("phase", ""), where.get("alpha_band", ""), p.verdict])
    return rows


def path_csv(found: Discovery) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(PATH_COLUMNS)
    w.writerows(path_rows(found))
    return buf.getvalue()


def _against_the_grid(found: Discovery) -> list[str]:
    """The discovered structure against the grid's and the thesis' answers: excess, noise verdict, terms."""
    lines = ["## Against the grid and the thesis", ""]
    body = [[c.role, c.name, c.n_params, _g(c.mse_validation), _g(c.mse_cv), "yes" if c.admissible else "no",
             _g(c.excess, "+.1%"), _g(c.excess_se, ".1%"),
             noise_verdict(c)] for c in found.comparison]
    lines += [tabulate(body, headers=["role", "structure", "parameters", "validation MSE", "CV MSE", "admissible",
                                      "discovered's excess", "se", "within noise"], tablefmt="github"), "",
              "The discovered structure's per-maneuver relative excess of out-of-sample MSE over each reference; "
              "within noise by the ranking's one-standard-error rule (within one standard error or 1 %); \"better\" "
              "where the discovered structure is below the reference by more than that.", ""]
    said = set()
    for c in found.comparison[1:]:
        mine = set(found.comparison[0].terms)
        theirs = set(c.terms)
        if c.name in said:   # the grid's rank 1 is often the thesis' final model: one line
            continue
        said.add(c.name)
        if mine != theirs:
            lines += [f"Terms against {c.name}: only discovered {sorted(mine - theirs) or '-'}; only in {c.name} "
                      f"{sorted(theirs - mine) or '-'}.", ""]
    return lines


def markdown(found: Discovery, command: str = "") -> str:
    start = found.start
    lines = [f"# Structure discovery for {found.coefficient}", ""]
    if command:
        lines += [f"Made by `{command}`.", ""]
    lines += [f"From {start['name']} ({', '.join(start['regressors'].values())}"
              + (f"; lift model {start['lift']}" if start.get("lift") else "") + f"): validation MSE "
              f"{_g(found.start_mse_validation)}. {found.structures_fitted} structures fitted in "
              f"{len(found.steps)} steps ({found.seconds:.0f} s); the search stopped: {found.stopped}.", "",
              "## Path", ""]
    if found.path:
        closes = closed_shares(found)
        body = [[i, p.move, p.effect or "", p.verdict, _g(p.mse_validation), _g(p.mse_cv), _g(p.p_value, ".2g"),
                 _g(c, ".0%"), (p.where or {}).get("phase", ""), (p.where or {}).get("alpha_band", "")]
                for i, (p, c) in enumerate(zip(found.path, closes), 1)]
        lines += [tabulate(body, headers=["step", "move", "effect", "verdict", "validation MSE", "CV MSE",
                                          "p (test)", "closes (of the start's gap)", "phase", "alpha band"],
                           tablefmt="github"), ""]
        tests = sorted({(p.test or {}).get("test", "") for p in found.path} - {""})
        stands = [f"{p.move} stands for {p.test['stands_for']}" for p in found.path
                  if p.test and p.test.get("stands_for")]
        lines += ["Tests: " + "; ".join(tests) + ". A move improves when its test passes (or, a library effect, "
                  "when it is within one standard error of a move whose test passed"
                  + (": " + ", ".join(stands) if stands else "") + "); it simplifies with fewer parameters within "
                  "one standard error; it repairs when it removes a reason against admissibility. Closes: the share "
                  f"of the start's gap (its validation MSE above the floor, {_g(found.noise_floor)}) the move closes, "
                  "as in every story and diagnosis: the validation MSE before the move minus after it, over the "
                  "start's minus the floor (negative: it costs); the steps add up to the share closed. "
                  "(discover.json's and path.csv's `shrink` is each move's share of its own step's gap.)", ""]
    else:
        lines += ["No move passed the test: the start is the structure found.", ""]
    f = found.final
    lines += ["## Final structure", "", f"{f.name}: validation MSE {_g(f.mse_validation)}, CV MSE {_g(f.mse_cv)}, "
              + ("admissible" if f.admissible else "not admissible: " + "; ".join(f.reasons))
              + ("; at the floor" if found.explained else "; above the floor") + ".", ""]
    if found.answer is not None:
        lines += [f"The answer: {found.answer.sentence()}.", ""]
    lines += [tabulate([[n, e] for n, e in f.structure["regressors"].items()], headers=["parameter", "term"],
                       tablefmt="github"), ""]
    lines += ["```", *equations(Candidate.from_dict(f.structure)), "```", ""]
    if f.structure.get("states"):
        lines += ["States: " + ", ".join(f"X{'_' + s if s else ''}: {k}" for s, k in f.structure["states"].items())
                  + (f" (from the lift model {f.structure['lift']})" if f.structure.get("lift") else ""), ""]
    if f.spec:
        lines += [f"Written as a model spec: `{f.spec}` (`structsearch fit --model {f.spec}`).", ""]
    lines += set_aside_lines(found)
    lines += _against_the_grid(found)
    return "\n".join(lines)


def set_aside_lines(found: Discovery) -> list[str]:
    """How the final structure was chosen, and the structures with a lower held-out MSE it was chosen over: why
    each was set aside and what that costs (the final structure's excess over it)."""
    lines = [f"Chosen as {found.final_rule}." if found.final_rule else "", ""]
    if not found.set_aside:
        return lines + ["No structure the search fitted has a lower held-out MSE.", ""]
    shown = found.set_aside[:SET_ASIDE_SHOWN]
    body = [[a.name, a.n_params, _g(a.mse), _g(a.excess, "+.1%"), _g(a.excess_se, ".1%"), a.reason]
            for a in shown]
    lines += [f"## Better structures set aside ({len(found.set_aside)})", "",
              tabulate(body, headers=["structure", "parameters", "held-out MSE", "final's excess", "se", "why set "
                                      "aside"], tablefmt="github"), "",
              "Held-out MSE: cross-validation, else validation (what the search compares); the final's excess: its "
              "per-maneuver relative excess of out-of-sample MSE over the structure (what setting it aside costs)"
              + (f"; {len(found.set_aside) - len(shown)} more in discover.json" if len(found.set_aside) > len(shown)
                 else "") + ".", ""]
    return lines


def write_discovery(found: Discovery, out: Path, command: str = "") -> Discovery:
    """Write the spec, path.csv, discover.md and (last) discover.json; the result with ``final.spec`` set."""
    out.mkdir(parents=True, exist_ok=True)
    spec = out / spec_name(found)
    final = Candidate.from_dict(found.final.structure)
    write_text(spec, spec_text(final, f"the structure structsearch discover found for {found.coefficient}"))
    found = dataclasses.replace(found, final=dataclasses.replace(found.final, spec=str(spec)))
    write_text(out / "path.csv", path_csv(found))
    write_text(out / "discover.md", markdown(found, command))
    write_json(out / "discover.json", public(found))
    return found


def discovery_console_lines(found: Discovery, out: Path) -> list[str]:
    f = found.final
    lines = [f"{found.coefficient}: {len(found.path)} moves from {found.start['name']} to {f.name} "
             f"(validation MSE {_g(found.start_mse_validation)} -> {_g(f.mse_validation)}; "
             f"{'admissible' if f.admissible else 'not admissible'}; {found.structures_fitted} structures, "
             f"{found.seconds:.0f} s)"]
    for i, (p, c) in enumerate(zip(found.path, closed_shares(found)), 1):
        lines.append(f"  {i}. {p.move} ({'' if p.verdict == 'improves' else p.verdict + ', '}"
                     f"p {_g(p.p_value, '.2g')}, closes {_g(c, '.0%')} of the start's gap)")
    if found.answer is not None and not found.answer.answered:
        lines.append(f"  {found.answer.sentence()}")
    if found.set_aside:
        a = found.set_aside[0]
        lines.append(f"  set aside {len(found.set_aside)} structures of lower held-out MSE; the lowest {a.name} "
                     f"({_g(a.mse)}, final's excess {_g(a.excess, '+.1%')}): {a.reason}")
    for c in found.comparison[1:]:
        lines.append(f"  against {c.role} {c.name}: excess {_g(c.excess, '+.1%')} +- {_g(c.excess_se, '.1%')}, "
                     f"within noise: {noise_verdict(c, 'n/a')}")
    lines.append(f"wrote {out / 'discover.json'}, discover.md, path.csv and {f.spec}")
    return lines
