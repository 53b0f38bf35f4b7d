"""diagnosis.json and a readable diagnosis.md (no figures), and the withheld-effect benchmark."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from tabulate import tabulate

from ..data.atomic import json_ready, write_json, write_text


def public(doc: dict) -> dict:
    """The interfaces.md section 3 document (extra fields kept); what could not be estimated is null."""
    return json_ready(json.loads(json.dumps(doc, default=float)))


def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.0%}"


def _num(x, fmt=".2f") -> str:
    return "n/a" if x is None or not np.isfinite(x) else format(x, fmt)


def unexplained_sentence(doc: dict) -> str:
    """What the library cannot explain, in words (empty when the final model is at the floor)."""
    u = doc.get("unexplained") or {}
    if doc.get("explained") or u.get("share") is None or not u["share"] > 0:
        return ""
    text = f"{u['share']:.0%} of the gap is not explained by the library"
    top = [s for s in u.get("signals", []) if s["share"] > 0][:1]
    if top:
        text += f"; it follows {top[0]['name']} (a function of it alone removes {top[0]['share']:.0%} of the rest)"
    where = u.get("where")
    if where:
        text += f", mostly at alpha {where['alpha_band']} rad in the {where['phase']} phase"
    return text + "."


def markdown(doc: dict) -> str:
    lines = [f"# Diagnosis of {doc['coefficient']} (baseline {doc['baseline']})", ""]
    m = doc["mse"]
    u = doc.get("unexplained") or {}
    lines += [f"Validation MSE {m['validation']:.4g} (training {m['train']:.4g}); noise floor {doc['noise_floor']:.4g}: "
              f"the lowest of the saturated library model ({doc['noise_floor_library']:.4g}, the lowest any library "
              f"model reaches) and a library-free flexible model of the residual ({u.get('noise_floor', np.nan):.4g}); "
              f"spectral estimate {doc['noise_floor_spectral']:.4g}.", ""]
    lines += [f"Warning: {w}" for w in doc.get("warnings", [])] + ([""] if doc.get("warnings") else [])
    first = doc["rounds"][0] if doc["rounds"] else {}
    if doc["gap_explained_by_baseline"]:
        lines += [f"**The baseline is already at the noise floor**: its per-maneuver validation MSE exceeds the "
                  f"floor's by {_pct(first.get('excess_over_floor'))} +- {_pct(first.get('excess_se'))} (within "
                  "one standard error, or below 1 %).", ""]
    else:
        lines += [f"**Gap**: {m['validation'] - doc['noise_floor']:.4g} "
                  f"({(m['validation'] / doc['noise_floor'] - 1):.1%} above the floor).", ""]
        lines += ["## Where the gap lies", ""]
        for dim in ("phase", "alpha_band", "alpha_dot_sign", "frequency_band", "maneuver"):
            rows = sorted((r for r in doc["where"] if r["dimension"] == dim), key=lambda r: -r["share"])
            body = [[r["bin"], f"{r['share']:.2f}", "-" if not np.isfinite(r["share_std"]) else f"{r['share_std']:.2f}",
                     "-" if not np.isfinite(r["mse"]) else f"{r['mse']:.3g}"] for r in rows[:8]]
            lines += [f"### by {dim.replace('_', ' ')}", "",
                      tabulate(body, headers=["bin", "share of excess", "+-", "MSE"], tablefmt="github"), ""]
    lines += ["## Which effect", ""]
    body = []
    for e in doc["effects"]:
        if "error" in e:
            body.append([e["name"], "-", "-", "-", "-", "-", e["error"]])
        else:
            body.append([e["name"], _num(e["shrink"]), f"{e['mse_validation_after']:.4g}", f"{e['p_value']:.2g}",
                         f"{e['overlap']:.2f}", e["acts_in"]["phase"], "at floor" if e["at_floor"] else ""])
    lines += [tabulate(body, headers=["effect", "shrink", "validation MSE after", "p (Wald)",
                                      "overlap with gap", "acts most in", ""], tablefmt="github"), ""]
    lines += ["## How far it shrinks", ""]
    for i, r in enumerate(doc["rounds"]):
        best = next((e for e in r["effects"] if "error" not in e), None)
        step = (f"adding {best['name']} closes {_pct(best['shrink'])} of the gap (p = {best['p_value']:.2g})"
                if best and not r["explained_before"] else "at the floor")
        lines.append(f"{i + 1}. {r['baseline']}: validation MSE {r['mse']['validation']:.4g}, floor "
                     f"{r['noise_floor']:.4g}; {step}.")
    lines += ["", f"**Explained**: {'yes' if doc['explained'] else 'no'} (the final model's per-maneuver excess over "
              f"the floor: {_pct(doc.get('final_excess_over_floor'))} +- {_pct(doc.get('final_excess_se'))}). "
              f"Final model: {doc['final_model']}.", ""]
    sentence = unexplained_sentence(doc)
    if sentence:
        lines += ["## What the library does not explain", "", sentence, ""]
        body = [[s["name"], f"{s['share']:.2f}"] for s in u.get("signals", [])[:8]]
        lines += ["Share of the remaining gap a smooth function of one signal removes on the validation maneuvers:",
                  "", tabulate(body, headers=["signal", "share"], tablefmt="github"), ""]
    sl = doc.get("state_level")
    if sl:
        lines += ["## At the state level", ""]
        if "error" in sl:
            lines += [f"Not available: {sl['error']}", ""]
        else:
            units = {"alpha": "rad", "q": "rad/s", "V": "m/s", "theta": "rad"}
            body = [[s, units[s], f"{sl['before'][s]:.4g}", f"{sl['after'][s]:.4g}",
                     "n/a" if not np.isfinite(sl["reduction"][s]) else f"{sl['reduction'][s]:+.0%}"]
                    for s in ("alpha", "q", "theta", "V")]
            lines += [f"Validation maneuvers replayed through the simulator (recorded elevator and thrust, "
                      f"re-initialised on the measured states every {sl['window_s']:g} s); RMS state error with "
                      f"the baseline and with the best effect added:", "",
                      tabulate(body, headers=["state", "unit", "before", "after", "reduction"], tablefmt="github"),
                      ""]
    return "\n".join(lines)


def write(doc: dict, out: Path) -> tuple[Path, Path]:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "diagnosis.json", public(doc))
    write_text(out / "diagnosis.md", markdown(doc))
    return out / "diagnosis.json", out / "diagnosis.md"


def story_markdown(story: dict, command: str) -> str:
    """The Van Ingen -> final story: the lines, then each coefficient's rounds."""
    lines = ["# From the Van Ingen simulator model to the final model", "", f"Made by `{command}`.", ""]
    lines += [f"- {line}" for line in story["lines"]] + [""]
    for coef, doc in story["diagnoses"].items():
        lines += [f"## {coef}: {doc['baseline']} -> {doc['final_model']}", ""]
        body = []
        for i, r in enumerate(doc["rounds"]):
            best = next((e for e in r["effects"] if "error" not in e), None)
            body.append([i + 1, r["baseline"], f"{r['mse']['validation']:.4g}",
                         "-" if best is None else best["name"], "-" if best is None else _num(best["shrink"]),
                         "-" if best is None else f"{best['p_value']:.2g}", "yes" if r["explained_before"] else "no"])
        lines += [tabulate(body, headers=["round", "model", "validation MSE", "best effect", "shrink",
                                          "p (Wald)", "at the floor"], tablefmt="github"), "",
                  f"Noise floor {doc['noise_floor']:.4g}; explained: {'yes' if doc['explained'] else 'no'}. "
                  + unexplained_sentence(doc), ""]
    return "\n".join(lines)


def write_story(story: dict, out: Path, command: str) -> tuple[Path, Path]:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "story.json", public(story))
    write_text(out / "story.md", story_markdown(story, command))
    return out / "story.json", out / "story.md"
