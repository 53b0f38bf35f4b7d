"""The report's first screen: per coefficient, the structure the user's search ranked first, written as an
equation with its estimates and standard deviations, its fit on the validation maneuvers and, for the diagnosed
coefficient, the gap story in three lines; then the table of contents (issue 43: the page opened with the
thesis' Van Ingen argument and named the fitted models in one line)."""
from __future__ import annotations

import html
import math
from typing import Mapping, Sequence

from ..diagnosis.results import Diagnosis
from ..diagnosis.story import unexplained_sentence
from .equations import equations, latex_equations
from .numbers import estimate_text, share, sig

COEF_WORDS = {"CL": "Lift, C_L", "CD": "Drag, C_D", "Cm": "Pitching moment, C_m"}


def valued_equations(c, result, lift) -> list[str]:
    """``c``'s equations with every parameter written as "(estimate ± std. dev.)" (a drag or pitch structure's
    states with its lift model's estimates)."""
    texts: dict[str, str] = {}
    lift_result = getattr(lift, "result", None)
    if lift is not None and lift_result is None:   # a joint lift read as its estimates: no std. devs. here
        texts.update({n: f"{v:.4g}" for n, v in lift.params.items()})
    for fit in ([lift_result] if lift_result is not None else []) + [result]:
        e = fit.estimates
        texts.update({n: f"({estimate_text(e.params[n], e.stderr.get(n))})" for n in e.names})
    return equations(c, texts)


def fit_line(result) -> str:
    """The fit on the validation maneuvers and the held-out MSE the ranking compares, in one line."""
    r2 = result.validation.r2
    held = ("cross-validation" if result.cv is not None else "validation")
    return (f"Validation R^2 {sig(r2.pooled, 4)} (pooled over the validation maneuvers; per maneuver mean "
            f"{sig(r2.mean, 3)}, worst {sig(r2.min, 3)}); held-out MSE {sig(result.comparison.mse, 4)} ({held}), "
            f"validation MSE {sig(result.mse_validation, 4)}; {result.n_params} parameters.")


def _top(doc: Diagnosis, dimension: str):
    rows = [w for w in doc.where if w.dimension == dimension]
    return max(rows, key=lambda w: w.share) if rows else None


def _which_effect(doc: Diagnosis) -> str:
    """The effects the diagnosis adopted, round by round, each with the share of the first round's gap it closes;
    without one, the round's effect that closes most (never one that costs, never one a test rejected as the
    answer)."""
    adopted = [(i, r.effect(r.adopted)) for i, r in enumerate(doc.rounds) if r.adopted and r.effect(r.adopted)]
    if adopted:
        steps = [f"{e.name} (closes {share(doc.closes(i, e))} of the gap)" for i, e in adopted]
        return "Which effect: adopted " + ", then ".join(steps) + "."
    fitted = [e for e in doc.effects if not e.failed]
    if not fitted:
        return "Which effect: every effect of the library failed to fit (diagnosis table below)."
    best = max(fitted, key=lambda e: doc.closes(0, e) if doc.closes(0, e) == doc.closes(0, e) else -math.inf)
    if doc.gap_explained_by_baseline:
        return (f"Which effect: the best, {best.name}, changes the validation MSE to "
                f"{sig(best.mse_validation_after, 3)}; there is no gap for it to close.")
    closes = doc.closes(0, best)
    if not closes > 0:
        return f"Which effect: none; no effect of the library closes any of the gap (the best, {best.name}, {share(closes)})."
    return f"Which effect: none adopted; the best, {best.name}, would close {share(closes)} of the gap but fails its test."


def gap_story(doc: Diagnosis) -> list[str]:
    """Where the model misses, which effect closes how much, what is left: three lines."""
    m, floor = doc.mse.validation, doc.noise_floor
    if doc.gap_explained_by_baseline:
        where = (f"Where it misses: nowhere beyond the noise: validation MSE {sig(m, 3)} against a noise floor of "
                 f"{sig(floor, 3)} (within one standard error of it).")
    else:
        bins = [b for b in (_top(doc, "phase"), _top(doc, "alpha_band")) if b is not None]
        spots = " and ".join(f"{share(b.share)} in the {b.dimension.replace('_', ' ')} {b.bin}" for b in bins)
        where = (f"Where it misses: validation MSE {sig(m, 3)}, {share(m / floor - 1)} above the noise floor "
                 f"{sig(floor, 3)}" + (f"; of the gap, {spots}." if spots else "."))
    effect = _which_effect(doc)
    left = unexplained_sentence(doc)
    rest = (f"What is left: {left}" if left else
            f"What is left: {doc.final_model} is at the noise floor." if doc.explained else
            f"What is left: the gap beyond {doc.final_model} is not attributed.")
    return [where, effect, rest]


def mathml(c) -> str:
    """``c``'s equations as MathML, which a browser renders as mathematics with nothing fetched at view time
    (latex2mathml converts the LaTeX the project writes; "" without it, or for an equation it cannot convert:
    the text equations below carry the same structure with its estimates)."""
    try:
        from latex2mathml.converter import convert
    except ImportError:
        return ""
    blocks = []
    for latex in latex_equations(c):
        try:
            # HTML5 knows <math> without its namespace, and the page names no address
            blocks.append(convert(latex, display="block").replace(' xmlns="http://www.w3.org/1998/Math/MathML"', ""))
        except Exception:   # noqa: BLE001 - a converter's failure costs the rendering, never the page
            return ""
    return "<div class='math'>" + "".join(blocks) + "</div>"


def _unbroken(text: str) -> str:
    """Every term of an escaped equation (a summand at the top level of its line: "(estimate ± std. dev.)*factor",
    "(1 - X_ss)*CL") kept on one line: the equation wraps only between terms."""
    return "\n".join(_terms_unbroken(line) for line in text.split("\n"))


def _terms_unbroken(line: str) -> str:
    pieces, depth, start, i = [], 0, 0, 0
    while i < len(line):
        if line[i] in "()":
            depth += 1 if line[i] == "(" else -1
        elif depth == 0 and line.startswith((" + ", " - "), i):
            pieces += [line[start:i], line[i:i + 3]]
            start = i = i + 3
            continue
        i += 1
    pieces.append(line[start:])
    return "".join(p if p in (" + ", " - ") or not p.strip() else f"<span class='value'>{p}</span>" for p in pieces)


def verdict_text(verdict: Mapping | None) -> str:
    """The search's answer for one coefficient in words (docs/interfaces.md 8.1); "" without one."""
    if not verdict:
        return ""
    cost = verdict.get("cost")
    cost_text = "an unknown amount" if cost is None else f"{100 * cost:+.1f} %"
    tolerance = f"{100 * float(verdict.get('tolerance', float('nan'))):.0f} %"
    if verdict.get("status") == "admissible":
        near = ("the best fit" if verdict.get("best_admissible") == verdict.get("best_fit") else
                f"{cost_text} above the best fit {verdict.get('best_fit')}, within {tolerance}")
        return f"Admissible ({near})."
    reasons = "; ".join(verdict.get("best_fit_reasons") or []) or "no reason recorded"
    other = (f"the best admissible structure, {verdict['best_admissible']}, fits {cost_text} worse" if
             verdict.get("best_admissible") else "no structure is admissible")
    return (f"No admissible structure within {tolerance} of the best fit. The best fit, {verdict.get('best_fit')}, "
            f"is not admissible ({reasons}); {other}. The structure below is not an answer.")


def answered(verdicts: Mapping[str, Mapping], shown=None) -> bool:
    """Whether every coefficient with a verdict has an admissible answer, and every coefficient ``shown`` (default:
    those with a verdict) has a verdict."""
    return all(v.get("status") == "admissible" for v in verdicts.values()) and all(
        c in verdicts for c in (shown if shown is not None else verdicts))


def answer_html(answers: Mapping[str, tuple], source: str, diagnosis: Diagnosis | None,
                diagnosed: str | None, verdicts: Mapping[str, Mapping] | None = None,
                gaps: Mapping[str, Diagnosis] | None = None) -> str:
    """The first section of the page (module docstring); ``gaps``: per coefficient a diagnosis of the simulator's
    model (the demo's story), whose gap story each coefficient's row gives."""
    verdicts, gaps = verdicts or {}, gaps or {}
    title = "The identified models" if answered(verdicts, answers) else "The models shown"
    parts = [f"<section id='answer'><h2>{title}</h2>",
             f"<p class='source'>Each coefficient's structure {html.escape(source)}; estimates ± one standard "
             "deviation, rounded to it.</p>"]
    for coef, (c, result, lift) in answers.items():
        lines = valued_equations(c, result, lift)
        parts.append(f"<div class='model'><h3>{html.escape(COEF_WORDS.get(coef, coef))}: "
                     f"<span class='name'>{html.escape(c.name)}</span>"
                     + (f" <small>(states of {html.escape(lift.name)})</small>" if lift is not None else "")
                     + "</h3>"
                     + (f"<p class='verdict'>{html.escape(verdict_text(verdicts.get(coef)))}</p>"
                        if verdicts.get(coef) else "")
                     + f"<p class='fit'>{html.escape(fit_line(result))}</p>"
                     + mathml(c) + f"<pre class='eq'>{_unbroken(html.escape(chr(10).join(lines)))}</pre>")
        if coef in gaps:
            parts.append(f"<p class='source'>The simulator's gap: its model {html.escape(gaps[coef].baseline)} "
                         "against the flight data.</p><ul class='gap'>"
                         + "".join(f"<li>{html.escape(t)}</li>" for t in gap_story(gaps[coef])) + "</ul>")
        if diagnosis is not None and coef == diagnosed:
            parts.append(f"<p class='source'>This report's diagnosis: {html.escape(diagnosis.baseline)} against the "
                         "flight data.</p><ul class='gap'>"
                         + "".join(f"<li>{html.escape(t)}</li>" for t in gap_story(diagnosis)) + "</ul>")
        elif diagnosis is not None and coef not in gaps:   # one diagnosis per report: where the others' come from
            parts.append(f"<p class='source'>Gap story: not diagnosed in this report (structsearch report "
                         f"--diagnose {coef}, or structsearch diagnose --model {html.escape(c.name)}).</p>")
        parts.append("</div>")
    return "".join(parts) + "</section>"


def contents_html(sections: Sequence[tuple[str, str]]) -> str:
    """The table of contents: (anchor, title) of each section."""
    items = "".join(f"<li><a href='#{html.escape(a)}'>{html.escape(t)}</a></li>" for a, t in sections)
    return f"<nav id='contents'><h2>Contents</h2><ol>{items}</ol></nav>"
