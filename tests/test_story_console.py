"""Issue 43: the demo's console said "story CD: step 2 ... kept improves alpha_dot" where story.md said alpha_dot
was not adopted, in lines of up to 955 characters. The console now prints a line a round, whose verdict is the
one story.md's table gives (adopted or not, and why), none longer than 160 characters."""
import dataclasses
import re

from structsearch.diagnosis.results import Diagnosis, EffectRow, Round, TrainValidation, Unexplained
from structsearch.diagnosis.story import Story, console_lines, story_lines
from structsearch.fitting.fitter import CONSOLE_WIDTH
from structsearch.reporting.diagnosis_doc import story_markdown


def _round(baseline, validation, adopted, effects, at_floor=False):
    return Round(baseline, TrainValidation(validation, validation), 1.0, "saturated library model", 1.0, 0.1, (),
                 tuple(effects), at_floor, 0.0, 0.01, None, adopted, 1.0, validation - 1.0)


def _effect(name, after, verdict, p=1e-6, threshold=0.01):
    return EffectRow(name, None, after, after, p, 0.5, {}, False, f"model + {name}", verdict=verdict,
                     test={"p_value": p, "threshold": threshold})


def _diagnosis(rounds, **changes):
    d = Diagnosis(coefficient="CD", baseline="CD-I", noise_floor=1.0, floor_source="saturated library model",
                  noise_floor_library=1.0, explained=False, final_excess_over_floor=0.2, final_excess_se=0.01,
                  rounds=tuple(rounds), final_model=rounds[-1].baseline, final_mse=1.2,
                  unexplained=Unexplained(1.0, 0, 0.0), seconds=1.0)
    return dataclasses.replace(d, **changes)


def _story(**docs) -> Story:
    return Story(docs, tuple(story_lines(docs)))


def console_verdicts(lines: list[str]) -> dict[tuple[str, int], str | None]:
    """(coefficient, round) -> the move a console line says was adopted (None: nothing adopted)."""
    out = {}
    for line in lines:
        m = re.match(r"\s*(\S+) round (\d+): (adopted (.+?) \(|nothing adopted|at the floor)", line)
        if m:
            out[(m.group(1), int(m.group(2)))] = m.group(4)
    return out


def markdown_verdicts(text: str) -> dict[tuple[str, int], str | None]:
    """(coefficient, round) -> story.md's "adopted" column ("-": None)."""
    out, coef = {}, None
    for line in text.splitlines():
        if line.startswith("## "):
            coef = line[3:].split(":", 1)[0]
        elif line.startswith("|") and coef and re.match(r"\|\s*\d+\s*\|", line):
            cells = [c.strip() for c in line.strip("|").split("|")]
            out[(coef, int(cells[0]))] = None if cells[6] == "-" else cells[6]
    return out


def test_a_move_the_search_carried_on_but_did_not_adopt_is_said_not_adopted():
    """The complaint's case: alpha_dot passed its test in step 2 but the final choice kept the structure before
    it; story.md's table says "-" in its adopted column, and so does the console."""
    rounds = [_round("CD-I", 2.0, "lift CL-I -> CL-VI", [_effect("lift CL-I -> CL-VI", 1.5, "improves")]),
              _round("CD-I + lift", 1.5, None, [_effect("alpha_dot", 1.45, "improves")])]
    story = _story(CD=_diagnosis(rounds))
    lines = console_lines(story)
    assert console_verdicts(lines) == markdown_verdicts(story_markdown(story, "test")) == {
        ("CD", 1): "lift CL-I -> CL-VI", ("CD", 2): None}
    second = next(line for line in lines if "CD round 2" in line)
    assert "nothing adopted; best move alpha_dot" in second and "final choice kept" in second


def test_each_kind_of_round_says_why():
    rounds = [_round("Cm-I", 2.0, "second_separation_state",
                     [_effect("second_separation_state", 1.9, "look-ahead", p=0.2)]),
              _round("Cm-I + X2", 1.9, None, [_effect("pitch_rate", 1.8, "rejected", p=0.3)])]
    floor = [_round("CL-I", 1.0, None, [_effect("c", 1.0, "rejected")], at_floor=True)]
    ahead = [_round("CL-I", 2.0, None, [_effect("second_separation_state", 1.5, "look-ahead", p=0.06)])]
    story = _story(Cm=_diagnosis(rounds, coefficient="Cm", baseline="Cm-I"),
                   CL=_diagnosis(floor, coefficient="CL", baseline="CL-I", explained=True, final_mse=1.0),
                   CD=_diagnosis(ahead))
    lines = console_lines(story)
    text = "\n".join(lines)
    assert "Cm round 1: adopted second_separation_state (look-ahead): closes 10% of the gap" in text
    assert "Cm round 2: nothing adopted; best move pitch_rate (closes 10% of the gap, p 0.3) did not pass its " \
           "test (p above 0.01)" in text
    assert "CL round 1: at the floor: nothing to adopt" in text and "CL ends at CL-I: at the floor" in text
    assert "CD round 1: nothing adopted; best move second_separation_state (closes 50% of the gap, p 0.06) was a " \
           "look-ahead" in text
    assert console_verdicts(lines) == markdown_verdicts(story_markdown(story, "test"))


def test_console_lines_are_short_where_the_story_lines_are_long():
    reasons = tuple(f"t-test accepts 0 at 5%: CD0, CD_CT, CD_de, CD_alpha, CD_1mX, term_{k}" for k in range(12))
    long_name = "replace Cm_CT by Cm_CL = CL and Cm_xcgCL = x_cg/cbar*CL and " + "x" * 120
    rounds = [_round("CD-I", 2.0, None, [_effect(long_name, 1.5, "rejected", p=0.5)])]
    story = _story(CD=_diagnosis(rounds, baseline_reasons=reasons))
    assert max(map(len, story.lines)) > 300            # story.md's line names every reason
    lines = console_lines(story)
    assert max(map(len, lines)) <= CONSOLE_WIDTH
    assert "CD-I as fitted here is NOT admissible: 12 reasons, listed in story.md" in "\n".join(lines)
    assert console_verdicts(lines) == {("CD", 1): None}


def test_a_refinement_progress_line_is_wrapped_at_the_console_width_not_cut():
    """A long line is wrapped onto indented lines, each within the width, and keeps every word (a cut line lost
    the held-out MSE that says why refinement stopped)."""
    from structsearch.fitting.fitter import CONSOLE_WIDTH as PROGRESS_WIDTH
    from structsearch.fitting.fitter import console_line as _wrapped
    long = ("grid pitch: refined Cm-XXXIX -> Cm-XXXIXr-auto -> Cm-XXXIII -> Cm-XXXIIIr (= Cm-XXXIII, Cm-XXXIIIr); "
            "stopped: dropping Cm_Xde_ss (|rho(Cm_Xde_ss, Cm_1mX_ssCL)| = 0.80 > 0.8) raises the held-out MSE by 6.8%")
    wrapped = _wrapped(long).split("\n")
    assert len(long) > PROGRESS_WIDTH and len(wrapped) == 2 and max(map(len, wrapped)) <= PROGRESS_WIDTH
    assert wrapped[1].startswith("    ") and " ".join(part.strip() for part in wrapped) == long
    assert "..." not in _wrapped(long) and _wrapped("  " + long).split("\n")[1].startswith("      ")
    assert _wrapped("grid lift: refined CL-VI; stopped: nothing left to drop") == \
        "grid lift: refined CL-VI; stopped: nothing left to drop"
