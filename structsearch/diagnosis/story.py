"""The thesis' story told by the diagnosis: the previous-generation simulator model (Van Ingen's
structures CL-I, CD-I, Cm-I) against the flight data, the effects that close its gap round by round,
how far each closes it, at coefficient and state level, and where it ends.
"""
from __future__ import annotations

from typing import Callable

from .diagnose import diagnose
from ..data.campaign import Campaign
from ..flight.reference import VAN_INGEN_MODEL_NAMES
from ..search.runner import Settings
from ..search.specs import find_candidate

# Rounds enough for Van Ingen's lift to gain the second state, q* and delta_e of the final model.
STORY_ROUNDS = 4


def van_ingen_story(campaign: Campaign, settings: Settings = Settings(n_starts=2, cv_folds=0),
                    progress: Callable[[str], None] | None = None, n_jobs: int = 1) -> dict:
    """Diagnose each Van Ingen structure (as many rounds as effects keep closing its gap)."""
    say = progress or (lambda m: None)
    docs = {}
    for coef, name in VAN_INGEN_MODEL_NAMES.items():
        say(f"story: diagnosing the Van Ingen {coef} model {name}")
        docs[coef] = diagnose(campaign, find_candidate(name), settings=settings, max_rounds=STORY_ROUNDS,
                              progress=lambda m, c=coef: say(f"story {c}: {m}"), n_jobs=n_jobs)
    return {"diagnoses": docs, "lines": story_lines(docs)}


def _steps(doc: dict) -> list[tuple[str, float]]:
    """(effect adopted, fraction of the first round's gap it closed), round by round. A round adopted its
    best effect when the next round (or, after the last round, the final model) is that effect's model."""
    rounds = doc["rounds"]
    gap = rounds[0]["mse"]["validation"] - doc["noise_floor"] if rounds else 0.0
    following = [r["baseline"] for r in rounds[1:]] + [doc["final_model"]]
    out = []
    for r, next_model in zip(rounds, following):
        best = next((e for e in r["effects"] if "error" not in e), None)
        if best is not None and best["model"] == next_model:
            closed = r["mse"]["validation"] - best["mse_validation_after"]
            out.append((best["name"], closed / gap if gap > 0 else float("nan")))
    return out


def story_lines(docs: dict[str, dict]) -> list[str]:
    """One line per coefficient, in words."""
    lines = []
    for coef, doc in docs.items():
        mse, floor = doc["mse"]["validation"], doc["noise_floor"]
        text = (f"{coef}: the Van Ingen model {doc['baseline']} misses the flight data by "
                f"{mse / floor - 1:.0%} above the noise floor (validation MSE {mse:.3g} against {floor:.3g})")
        steps = _steps(doc)
        if steps:
            text += "; " + ", then ".join(f"adding {name} closes {share:.0%} of that gap" for name, share in steps)
        verdict = ("at the floor" if doc["explained"] else
                   f"still {doc['final_excess_over_floor']:.0%} above the floor")
        text += f"; {doc['final_model']} is {verdict}"
        sl = doc.get("state_level") or {}
        if "before" in sl:
            text += (f" (replayed alpha RMS {sl['before']['alpha']:.4f} -> {sl['after']['alpha']:.4f} rad with the "
                     "first effect)")
        unexplained = doc.get("unexplained") or {}
        if not doc["explained"] and unexplained.get("signals"):
            text += (f"; what remains is not in the library ({unexplained['share']:.0%} of the gap) and follows "
                     f"{unexplained['signals'][0]['name']}")
        lines.append(text + ".")
    return lines
