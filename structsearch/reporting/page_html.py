"""The report's HTML: the answer first (:mod:`.answer`), a table of contents, then the notes, the parameters,
the figures, the diagnosis, the Van Ingen comparison, the study's tables and the search's rankings. Every table
fits the page (long reasons fold, cells wrap) and prints numbers to the digits they carry."""
from __future__ import annotations

import base64
import csv
import html
import io
from pathlib import Path

from ..data.errors import DataError
from ..data.reading import excerpt, read_text
from ..diagnosis.results import Diagnosis
from ..diagnosis.story import unexplained_sentence
from ..engine.summary import PARAMETER_HEADERS, parameter_rows
from .answer import answer_html, answered, contents_html
from .numbers import share, sig, with_uncertainty
from .tables import render_table, signed_percent

STYLE = """body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:12px;margin:0.5em 0 1.5em;max-width:100%;table-layout:auto}
td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}td{overflow-wrap:break-word}th{hyphens:auto}
td.reason{max-width:28em}details summary{cursor:pointer;color:#0645ad}
figure{margin:1.5em 0}img{max-width:100%}figcaption{font-size:13px;color:#444}.note{color:#8a5a00}
h1{margin:0.2em 0}.summary td,.summary th{font-size:14px;padding:3px 10px}.summary .name{font-weight:bold}
.model{border-left:4px solid #4a7;padding:0 0 0 0.8em;margin:0.8em 0}.model h3{margin:0.2em 0}
.model .name{font-family:monospace;font-size:1.1em}pre.eq{white-space:pre-wrap;font-size:12px;background:#f6f6f6;
padding:0.4em;margin:0.3em 0}.fit{margin:0.2em 0}ul.gap{margin:0.2em 0;font-size:13px}
nav#contents ol{columns:2;font-size:14px}.source{color:#555;font-size:13px}.verdict{font-weight:bold}.value{white-space:nowrap}.math{overflow-x:auto;font-size:15px}"""

# The study's tables the page shows (stem -> title).
STUDY_TABLES = {"legacy_vs_snls": "The legacy estimator against SNLS (Table 7)",
                "final_vs_van_ingen": "Final models against Van Ingen's refitted (Tables 17, 11.1)",
                "final_vs_van_ingen_published": "Final lift model against Van Ingen's as published",
                "dynamic_stalls": "CL-VI with and without the dynamic stalls (Tables 10.1-10.3)",
                "separation_matrix": "Separation kinds, training MSE (Table 8)",
                "derived": "Derived quantities", "collinearity": "Collinearity of the lift regressors",
                "joint_vs_sequential": "The final models fitted jointly against sequentially (MSE)",
                "joint_vs_sequential_parameters": "Their parameters and standard deviations, joint and sequential"}
# The columns of a grid's ranking the page shows (of its CSV's headers); the rest are in the CSV.
RANKING_SHOWN = ("rank", "model", "admissible", "lift model", "parameters", "MSE CV", "MSE validation",
                 "R2 val. pooled", "gap to best", "within noise of best", "not admissible because")
# a reason longer than this folds into <details> (its first words stay visible)
FOLD_CHARS = 120
# diagnosis rows shown before the rest fold away
MOVES_SHOWN = 15


def _image(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _number(text: str) -> str:
    """A CSV cell as the page prints it: a float at 4 significant digits, anything else as it is."""
    try:
        value = float(text)
    except ValueError:
        return text
    return text if text.lstrip("-").isdigit() else sig(value, 4)


def _gap(text: str) -> str:
    """The gap to best as the console and the Markdown tables give it: a signed percentage."""
    try:
        return signed_percent(float(text))
    except ValueError:
        return text


def _fold(text: str) -> str:
    """A long text folded: its first words, the rest behind a click."""
    text = html.escape(text)
    if len(text) <= FOLD_CHARS:
        return text
    cut = text.rfind(" ", 0, FOLD_CHARS)
    cut = cut if cut > 0 else FOLD_CHARS
    return f"<details><summary>{text[:cut]} …</summary>{text[cut:]}</details>"


def csv_table(path: Path, top: int, columns: tuple[str, ...] | None = None) -> str | None:
    """The first ``top`` rows of a CSV table as HTML (``columns``: only these, in the CSV's order), numbers
    rounded; None when there is no such table."""
    if not path.exists():
        return None
    try:
        rows = [r for r in csv.reader(io.StringIO(read_text(path), newline=""))
                if r and not r[0].startswith("# command:")]
    except csv.Error as exc:
        raise DataError(f"not a CSV table: {excerpt(exc)}", source=str(path)) from None
    if len(rows) < 2:
        return None
    keep = [i for i, h in enumerate(rows[0]) if columns is None or h in columns]
    head = "".join(f"<th>{html.escape(rows[0][i])}</th>" for i in keep)
    body = []
    for r in rows[1:top + 1]:
        cells = []
        for i in keep:
            v = r[i] if i < len(r) else ""
            long = rows[0][i] == "not admissible because"
            shown = _gap(v) if rows[0][i] == "gap to best" else _number(v)
            cells.append(f"<td class='reason'>{_fold(v)}</td>" if long else f"<td>{html.escape(shown)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    more = f"<p>{len(rows) - 1 - top} more rows in {html.escape(path.name)}.</p>" if len(rows) - 1 > top else ""
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>{more}"


def parameter_html(fit) -> str:
    """A fit's parameters: estimate and std. dev. at the std. dev.'s two significant digits, t and p at 3 and 2,
    the flags in words."""
    idx = {h: PARAMETER_HEADERS.index(h) for h in ("estimate", "std. dev.", "ref. dof", "t", "p (two-sided)")}
    rows = []
    for r in parameter_rows(fit):
        est, sd = with_uncertainty(r[idx["estimate"]], r[idx["std. dev."]])
        r = list(r)
        r[idx["estimate"]], r[idx["std. dev."]] = est, sd
        r[idx["ref. dof"]], r[idx["t"]] = sig(r[idx["ref. dof"]], 3), sig(r[idx["t"]], 3)
        r[idx["p (two-sided)"]] = sig(r[idx["p (two-sided)"]], 2)
        rows.append(r)
    return render_table(rows, PARAMETER_HEADERS, "html", numparse=False)


def summary_html(answers, verdicts=None) -> str:
    """One row per coefficient: the structure, whether the search answers with it, its validation R^2 and
    held-out MSE (the first thing read)."""
    verdicts = verdicts or {}

    def status(coef):
        v = verdicts.get(coef)
        if not v:
            return "-"
        if v.get("status") == "admissible":
            return "admissible"
        return f"no admissible structure within {100 * float(v.get('tolerance', float('nan'))):.0f} % of the best fit"
    rows = "".join(f"<tr><td>{coef}</td><td class='name'>{html.escape(c.name)}</td>"
                   f"<td>{html.escape(status(coef))}</td>"
                   f"<td>{sig(r.validation.r2.pooled, 4)}</td><td>{sig(r.comparison.mse, 4)}</td></tr>"
                   for coef, (c, r, _) in answers.items())
    return ("<table class='summary'><thead><tr><th>coefficient</th><th>structure</th><th>the search's verdict</th>"
            f"<th>validation R^2</th><th>held-out MSE</th></tr></thead><tbody>{rows}</tbody></table>")


def diagnosis_html(diagnosis: dict) -> str:
    """The diagnosis' moves with the share of the gap each closes; a value that cannot be given says why."""
    typed = Diagnosis.from_dict(diagnosis)
    no_gap = typed.gap_explained_by_baseline or not typed.first.mse.validation > typed.noise_floor
    parts = [f"<p>Validation MSE {sig(typed.mse.validation, 4)}, noise floor {sig(typed.noise_floor, 4)}; final "
             f"model {html.escape(typed.final_model)}; explained: {'yes' if typed.explained else 'no'}. "
             f"{html.escape(unexplained_sentence(typed))}</p>"]
    if no_gap:
        parts.append("<p>The baseline is at the noise floor: there is no gap for a move to close, so the table "
                     "gives each move's validation MSE instead of a share.</p>")
    rows = []
    for e in typed.effects:
        if e.failed:
            rows.append([e.name, "not fitted", "-", "-", f"fit failed: {e.error}"])
            continue
        closes = sig(e.mse_validation_after, 4) if no_gap else share(typed.closes(0, e))
        p = "not estimable" if e.p_value is None else sig(e.p_value, 2)
        rows.append([e.name, closes, p, (e.acts_in or {}).get("phase", "-"), ""])
    head = ["effect", "validation MSE after" if no_gap else "closes (of the baseline's gap)", "p-value",
            "acts most in (phase)", "why not fitted"]
    parts.append(render_table(rows[:MOVES_SHOWN], head, "html", numparse=False))
    if len(rows) > MOVES_SHOWN:
        parts.append(f"<details><summary>{len(rows) - MOVES_SHOWN} more moves</summary>"
                     + render_table(rows[MOVES_SHOWN:], head, "html", numparse=False) + "</details>")
    return "".join(parts)


def page_title(verdicts, shown=None) -> str:
    """The page's title: "identified models" only when the search answers every coefficient it judged and judged
    every coefficient the page shows (``shown``; default those judged): a structure shown without the search's
    verdict (a grid not searched, a model named with --model) is said to be one."""
    verdicts = verdicts or {}
    missing = [c for c, v in verdicts.items() if v.get("status") != "admissible"]
    unjudged = [c for c in (shown if shown is not None else verdicts) if c not in verdicts]
    if not missing and not unjudged:
        return "identified models"
    parts = ([f"no admissible structure near the best fit for {', '.join(missing)}"] if missing else []) + (
        [f"{', '.join(unjudged)} shown without a search's verdict"] if unjudged else [])
    return "search results, " + "; ".join(parts)


def render_html(campaign, out: Path, fits, ms, vi, written, notes, diagnosis, story=None, gaps=None) -> str:
    """The page (module docstring)."""
    d = campaign.data
    n_val = sum(m.split == "validation" for m in campaign.maneuvers)
    identified = answered(fits.verdicts, fits.answers)
    parameters = "Identified parameters" if identified else "Parameters of the models shown"
    sections = [("answer", "The identified models" if identified else "The models shown"),
                ("notes", "How the models were chosen"),
                ("parameters", parameters)] + ([("figures", "Figures")] if written else [])
    if diagnosis is not None:
        sections.append(("diagnosis", f"Diagnosis of {diagnosis['baseline']}"))
    if vi is not None or story:
        sections.append(("van-ingen", "Against Van Ingen's structures"))
    study = out / "study"
    study_tables = [(stem, csv_table(study / f"{stem}.csv", 40)) for stem in STUDY_TABLES]
    if any(t for _, t in study_tables):
        sections.append(("study", "The thesis' comparison tables"))
    rankings = [(grid, csv_table(out / f"{grid}.csv", 10, RANKING_SHOWN))
                for grid in ("separation", "lift", "drag", "pitch")]
    if any(t for _, t in rankings):
        sections.append(("rankings", "Search rankings"))
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>structsearch report: "
             f"{html.escape(campaign.name)}</title><style>{STYLE}</style></head><body>",
             f"<h1>{html.escape(campaign.name)}: {page_title(fits.verdicts, list(fits.answers))}</h1>",
             summary_html(fits.answers, fits.verdicts),
             answer_html(fits.answers, fits.source, None if diagnosis is None else Diagnosis.from_dict(diagnosis),
                         fits.diagnosis_coefficient, fits.verdicts, gaps),
             contents_html(sections),
             f"<h2 id='notes'>How the models were chosen</h2><p>{len(campaign.maneuvers)} maneuvers ({n_val} "
             f"validation), {d.n_samples} samples. "
             + ("The figures draw " + ", ".join(f"{c} {html.escape(n)}" for c, n in fits.names.items()) + "."
                if written else "No figures: they draw a lift, drag and pitch model together (a note says why "
                                "one is missing).") + "</p>"]
    parts += [f"<p class='note'>{html.escape(n)}</p>" for n in notes]
    parts.append(f"<h2 id='parameters'>{parameters}</h2>")
    # the answers' structures first, then any structure only the figures draw (the lift model a drag or pitch
    # winner reads when it is not the lift winner)
    shown = [r for _, r, _ in fits.answers.values()]
    if ms is not None:
        shown += [s for s in ms.summaries.values() if s.name not in {r.name for r in shown}]
    for s in shown:
        parts.append(f"<h3>{html.escape(s.name)}</h3><p>MSE training {sig(s.mse_train, 4)}, validation "
                     f"{sig(s.mse_validation, 4)}</p>" + parameter_html(s.estimates))
    if written:
        parts.append("<h2 id='figures'>Figures</h2>")
    for f in written:
        parts.append(f"<figure><h3>{html.escape(f.title)}</h3><img src='{_image(out / 'figures' / f.file)}' "
                     f"alt='{html.escape(f.title)}'><figcaption>{html.escape(f.caption)}</figcaption></figure>")
    if diagnosis is not None:
        parts.append(f"<h2 id='diagnosis'>Diagnosis of {html.escape(diagnosis['baseline'])}</h2>"
                     + diagnosis_html(diagnosis))
    parts += _comparison_html(vi, story, study, study_tables, rankings)
    parts.append("</body></html>")
    return "\n".join(parts)


def _comparison_html(vi, story, study: Path, study_tables, rankings) -> list[str]:
    """The sections after the diagnosis: the Van Ingen comparison, the study's tables, the search's rankings."""
    parts = []
    if vi is not None or story:
        parts.append("<h2 id='van-ingen'>Against Van Ingen's structures</h2>")
    if vi is not None:
        parts.append("<p>Refitted on this campaign: "
                     + "; ".join(f"{html.escape(s.name)}: MSE validation {sig(s.mse_validation, 4)}"
                                 + (f" (at a bound: {html.escape(', '.join(s.estimates.at_bound))})"
                                    if s.estimates.at_bound else "") for s in vi.summaries.values())
                     + ". An estimate on its bound means the structure fits these data best at the edge of its "
                       "physical range: a sign that it misses something the data contain.</p>")
    if story:
        parts.append("<h3>From Van Ingen's models to structures at the floor</h3><ul>"
                     + "".join(f"<li>{_fold(line)}</li>" for line in story) + "</ul>"
                     "<p>Details: story.md (made by <code>structsearch demo</code>).</p>")
    if any(t for _, t in study_tables):
        parts.append("<h2 id='study'>The thesis' comparison tables (structsearch study)</h2><p>Markdown, LaTeX "
                     "and CSV of each in study/.</p>")
        parts += [f"<h3>{html.escape(STUDY_TABLES[stem])}</h3>{t}" for stem, t in study_tables if t]
        if (study / "r2_boxes.png").exists():
            parts.append(f"<figure><h3>Per-maneuver R^2 (thesis Fig. 12)</h3><img src='{_image(study / 'r2_boxes.png')}' "
                         "alt='R^2 box plots'></figure>")
    if any(t for _, t in rankings):
        parts.append("<h2 id='rankings'>Search rankings (first ten of each grid)</h2><p>The columns that decide "
                     "the ranking; every column is in each grid's CSV.</p>")
        parts += [f"<h3>{grid}</h3>{t}" for grid, t in rankings if t]
    return parts
