"""The thesis' story told by the diagnosis: the previous-generation simulator model (Van Ingen's
structures CL-I, CD-I, Cm-I) against the flight data, the effects that close its gap round by round,
how far each closes it, at coefficient and state level, and where it ends.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .diagnose import diagnose
from ..fitting.candidates import Candidate
from ..fitting.lift_fit import LiftFit
from .results import Diagnosis
from ..flight.reference import VAN_INGEN_MODEL_NAMES
from ..discovery.explore import DEFAULT_MAX_STEPS
from ..discovery.search_setting import DIAGNOSE, SearchSetting
from ..fitting.fitter import Fitter, console_line
from ..fitting.specs import find_candidate

# The name the drag and pitch searches know the lift structure found for C_L by.
FOUND_LIFT = "CL-story"
# Steps enough for the longest path of the story (pitch: a lift model, the centre-of-pressure and elevator terms).
STORY_ROUNDS = DEFAULT_MAX_STEPS
# A story takes one structure at a time (a beam of one): on the default campaign it reached the floor for C_L,
# C_D and C_m as the beam of three did, in 188 s against 303 s (the library-only story: 90 s), and its path is
# one line of moves to read.
STORY_BEAM = 1
STORY = DIAGNOSE.but(max_rounds=STORY_ROUNDS, beam=STORY_BEAM)


@dataclass(frozen=True)
class Story:
    """Each Van Ingen structure's diagnosis (coefficient -> diagnosis) and the story in words, a line each."""

    diagnoses: Mapping[str, Diagnosis]
    lines: tuple[str, ...]

    def to_dict(self) -> dict:
        """``story.json``: ``{"diagnoses": {coefficient: diagnosis document}, "lines": [...]}``."""
        return {"diagnoses": {coef: d.to_dict() for coef, d in self.diagnoses.items()}, "lines": list(self.lines)}


def van_ingen_story(fitter: Fitter, setting: SearchSetting = STORY) -> Story:
    """Diagnose each Van Ingen structure (a structure search from each until it is at the floor or no move
    passes), lift first: the drag and pitch searches may feed their models the lift structure found for C_L.
    ``setting`` is the search (:data:`STORY`; ``STORY.but(kinds=("effect",))``: the effect library alone, one
    effect at a time)."""
    say = fitter.say
    docs = {}
    lifts: dict[str, LiftFit] = {}
    for coef, name in VAN_INGEN_MODEL_NAMES.items():
        say(f"story: diagnosing the Van Ingen {coef} model {name}")
        told = fitter.with_progress(lambda m, c=coef: say(f"story {c}: {m}"))
        docs[coef] = diagnose(dataclasses.replace(told, lifts=dict(lifts)), find_candidate(name),
                              setting)
        if coef == "CL" and docs[coef].final_structure is not None and docs[coef].rounds[-1].baseline != name:
            # drag and pitch may be fed the lift structure the story found for C_L
            found = dataclasses.replace(Candidate.from_dict(docs[coef].final_structure), name=FOUND_LIFT,
                                        note=f"the lift structure the story found: {docs[coef].final_model}")
            say(f"story: fitting the lift structure found for CL ({found.name}) for the drag and pitch models")
            result = fitter.quiet().fit_one(found)   # its starts and folds are tasks on the workers
            if not result.failed:
                lifts[found.name] = LiftFit(found, result)
    return Story(docs, tuple(story_lines(docs)))


def _steps(doc: Diagnosis) -> list[tuple[str, float]]:
    """(move adopted, share of the baseline's gap it closed (:meth:`Diagnosis.closes`; negative: it cost, as a
    look-ahead's first move may)), round by round."""
    return [(r.adopted, doc.closes(i, r.effect(r.adopted))) for i, r in enumerate(doc.rounds) if r.adopted]


def _step_words(name: str, share: float, effect: bool) -> str:
    what = f"adding {name}" if effect else name
    if not np.isfinite(share):
        return f"{what} (no gap to close)"
    if share < 0:
        return f"{what} costs {-share:.0%} of the baseline's gap (a first move that the next builds on)"
    return f"{what} closes {share:.0%} of the baseline's gap"


# the reasons against an inadmissible baseline a story line names (story.md lists them all)
REASONS_IN_LINE = 2


def baseline_words(doc: Diagnosis) -> str:
    """" (as fitted here NOT admissible: ...)" after an inadmissible baseline's name, else ""."""
    why = doc.baseline_reasons
    if not why:
        return ""
    more = (f"; {len(why) - REASONS_IN_LINE} more, all listed at the top of story.md" if len(why) > REASONS_IN_LINE
            else "")
    return f" (as fitted here NOT admissible: {'; '.join(why[:REASONS_IN_LINE])}{more})"


def _reached(doc: Diagnosis) -> str:
    """The structure a story ends with, by its terms (a long path's name is a hash: it would tell a reader
    nothing)."""
    structure = doc.final_structure
    if not structure or not doc.rounds or doc.rounds[-1].baseline == doc.baseline:
        return doc.final_model
    terms = " + ".join(expr for expr in structure["regressors"].values())
    states = ", ".join(f"{'X_' + n if n else 'X'} {k}" for n, k in structure["states"].items())
    lift = f" on {structure['lift']}" if structure.get("lift") else ""
    return f"the structure reached, {doc.coefficient} = {terms} ({states or 'no separation state'}{lift}),"


def _above(mse: float, floor: float) -> str:
    return f"{mse / floor - 1:.0%}" if floor > 0 else "n/a"


def story_lines(docs: Mapping[str, Diagnosis]) -> list[str]:
    """One line per coefficient, in words; "above the floor" is the pooled validation MSE's excess."""
    lines = []
    for coef, doc in docs.items():
        mse, floor = doc.mse.validation, doc.noise_floor
        text = (f"{coef}: the Van Ingen model {doc.baseline}{baseline_words(doc)} misses the flight data by "
                f"{_above(mse, floor)} "
                f"above the noise floor (validation MSE {mse:.3g} against {floor:.3g})")
        steps = _steps(doc)
        effects = {r.adopted for r in doc.rounds if r.adopted and (r.effect(r.adopted).effect or
                                                                   r.effect(r.adopted).kind is None)}
        if steps:
            text += "; " + ", then ".join(_step_words(name, share, name in effects) for name, share in steps)
        verdict = ("at the floor" if doc.explained else
                   f"still {_above(doc.final_mse, floor)} above the floor")
        text += f"; {_reached(doc)} is {verdict}"
        sl = doc.state_level
        if sl is not None:   # a failed replay is said too (issue 31: its error only reached story.json)
            text += f" ({sl.words()})"
        u = doc.unexplained
        if not doc.explained and u.signals and u.share is not None:
            text += (f"; what remains is not in the library ({u.share:.0%} of the gap) and follows "
                     f"{u.signals[0].name}")
        lines.append(text + ".")
    return lines


# The console's lines (structsearch demo) are read on a terminal: one a round, wrapped at fitter.CONSOLE_WIDTH;
# the story's own lines (story.md, the report) name every reason and term, up to a thousand characters.


def console_lines(story: Story) -> list[str]:
    """What ``structsearch demo`` prints of the story: per coefficient where its Van Ingen model starts, one line a
    round with the verdict story.md's table gives it (adopted or not, and why) and where it ends; long texts are
    wrapped at :data:`CONSOLE_WIDTH` onto indented lines."""
    lines = []
    for coef, doc in story.diagnoses.items():
        mse, floor = doc.mse.validation, doc.noise_floor
        lines.append(f"{coef}: the Van Ingen model {doc.baseline} misses the flight data by {_above(mse, floor)} "
                     f"above the noise floor (validation MSE {mse:.3g} against {floor:.3g})")
        if doc.baseline_reasons:
            lines.append(f"  {doc.baseline} as fitted here is NOT admissible: {len(doc.baseline_reasons)} reasons, "
                         "listed in story.md")
        lines += [f"  {coef} round {i + 1}: {round_verdict(doc, i)}" for i in range(len(doc.rounds))]
        lines.append(f"  {coef} ends at {doc.final_model}: {_end_words(doc)}")
    return [part for line in lines for part in console_line(line).split("\n")]


def round_verdict(doc: Diagnosis, i: int) -> str:
    """Round ``i``'s verdict in words: the move adopted (story.md's "adopted" column), or why none was."""
    r = doc.rounds[i]
    if r.adopted:
        e = r.effect(r.adopted)
        return f"adopted {r.adopted}" + (f" ({e.verdict}): {_move_figures(doc, i, e)}" if e is not None else "")
    if r.explained_before:
        return "at the floor: nothing to adopt"
    best = r.best
    if best is None:
        return "nothing adopted: every move's fit failed"
    return f"nothing adopted; best move {best.name} ({_move_figures(doc, i, best)}) {_not_adopted(best)}"


def _not_adopted(e) -> str:
    """Why the best move of a round that adopts nothing was not adopted, from its verdict and test."""
    p, threshold = (e.test or {}).get("p_value"), (e.test or {}).get("threshold")
    if e.verdict == "look-ahead":
        return "was a look-ahead: neither it nor a move after it passed its test"
    if e.verdict in ("improves", "simplifies"):
        return ("passed its test, but the final choice kept this round's structure (within one standard error, "
                "fewer parameters)")
    if p is not None and threshold is not None and p > threshold:
        return f"did not pass its test (p above {threshold:.2g})"
    return "was rejected (its test and reasons: story.json)"


def _move_figures(doc: Diagnosis, i: int, e) -> str:
    share = doc.closes(i, e)
    p = (e.test or {}).get("p_value")
    closes = "closes n/a" if not np.isfinite(share) else f"closes {share:.0%}" if share >= 0 else f"costs {-share:.0%}"
    return f"{closes} of the gap, p {'n/a' if p is None else format(p, '.2g')}"


def _end_words(doc: Diagnosis) -> str:
    text = "at the floor" if doc.explained else f"still {_above(doc.final_mse, doc.noise_floor)} above the floor"
    u = doc.unexplained
    if not doc.explained and u.signals and u.share is not None:
        text += f"; what remains is not in the library ({u.share:.0%} of the gap) and follows {u.signals[0].name}"
    return text




def unexplained_sentence(doc: Diagnosis | Mapping) -> str:
    """What the library cannot explain, in words (empty when the final model is at the floor). ``doc`` is a
    diagnosis or its ``to_dict()``."""
    if not isinstance(doc, Diagnosis):
        doc = Diagnosis.from_dict(doc)
    u = doc.unexplained
    if doc.explained or u.share is None or not u.share > 0:
        return ""
    text = f"{u.share:.0%} of the gap is not explained by the library"
    top = [s for s in u.signals if s.share > 0][:1]
    if top:
        text += f"; it follows {top[0].name} (a function of it alone removes {top[0].share:.0%} of the rest)"
    if u.where is not None:
        text += f", mostly at alpha {u.where.alpha_band} rad in the {u.where.phase} phase"
    return text + "."
