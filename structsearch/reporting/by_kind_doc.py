"""``fit --by-kind``'s documents: by_kind.json (the typed record) and by_kind.md (the comparison table, each model's
estimates beside the others', what a regime alone cannot identify), and the console's table."""
from __future__ import annotations

import math
from pathlib import Path

from ..data.atomic import write_json, write_text
from ..fitting.by_kind import TOLERANCE, ByKind, KindComparison

LABEL = {"all": "global (both kinds)", "stall": "stall only", "nominal": "nominal only (attached-flow part)"}


def _g(x: float) -> str:
    return f"{x:.4g}" if x is not None and math.isfinite(x) else "NaN"


def comparison_rows(res: ByKind) -> list[list[str]]:
    """Header and one row per model and fit: the model, what it was fitted on, validation MSE per regime."""
    rows = [["model", "fitted on", "train maneuvers", "validation MSE nominal", "validation MSE stall"]]
    for c in res.comparisons:
        for f in c.fits:
            rows.append([f.part.candidate.name, LABEL[f.fitted_on], str(f.train_maneuvers),
                         _g(f.validation_mse["nominal"]), _g(f.validation_mse["stall"])])
    return rows


def verdict(c: KindComparison) -> str:
    """One line: the global model's MSE over the separate model's, per regime, against the tolerance."""
    parts = [f"{w} {_g(c.ratio(w))} ({'within' if c.within(w) else 'NOT within'} {100 * TOLERANCE:.0f} %)"
             for w in ("nominal", "stall")]
    return f"{c.name}: global / separate validation MSE: " + ", ".join(parts)


def console_table(res: ByKind) -> str:
    rows = comparison_rows(res)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip() for r in rows]
    return "\n".join(lines + [verdict(c) for c in res.comparisons])


def _md(rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    return out + ["| " + " | ".join(r) + " |" for r in rows[1:]]


def _parameters(c: KindComparison) -> list[str]:
    """Each parameter of the global model and what each fit made of it (NaN with the reason: not estimable)."""
    rows = [["parameter", *(LABEL[f.fitted_on] for f in c.fits)]]
    reasons = {f.fitted_on: dict(f.part.unidentifiable) for f in c.fits}
    summed = {f.fitted_on: {n: s for s, of in f.part.sums for n in of} for f in c.fits}
    for name in c.fit("all").result.estimates.names:
        row = [name]
        for f in c.fits:
            params = f.result.estimates.params
            lost = f.result.estimates.unidentifiable
            if name in lost:   # the data of this fit cannot identify it: its number would be arbitrary
                row.append(f"NaN ({lost[name]})")
            elif name in params:
                row.append(_g(params[name]))
            elif name in summed[f.fitted_on]:
                row.append(f"in {summed[f.fitted_on][name]}")
            else:
                row.append(f"NaN ({reasons[f.fitted_on].get(name, 'not in this model')})")
        rows.append(row)
    for f in c.fits:
        for s, of in f.part.sums:
            rows.append([s, *(_g(g.result.estimates.params[s]) if g is f else
                              _g(sum(g.result.estimates.params.get(n, math.nan) for n in of)) for g in c.fits)])
    return _md(rows)


def markdown(res: ByKind) -> str:
    held = "; ".join(f"{w}: {', '.join(ids)}" for w, ids in res.validation_maneuvers.items())
    lines = ["# Global model against models fitted to each kind of maneuver", "",
             "Every model is validated on the same held-out maneuvers, nominal and stall apart (pooled MSE over "
             f"each kind's validation maneuvers; {held}). The model fitted on the nominal maneuvers alone is the "
             "global model's attached-flow part: alpha never reaches the stall there, so the separation states stay "
             "attached and their parameters are not identified (NaN below, with the reason); the stall-only model "
             "drops the terms the stall maneuvers never excite. Its validation on the other kind is an "
             "extrapolation, shown for what it says. Drag and pitch models read the C_L of the lift model fitted "
             "on the same maneuvers, never the measured C_L (whose noise is correlated with theirs).", ""]
    lines += _md(comparison_rows(res)) + [""]
    lines += [f"- {verdict(c)}" for c in res.comparisons] + [""]
    for c in res.comparisons:
        lines += [f"## {c.name} ({c.coefficient}): estimates", ""] + _parameters(c) + [""]
    return "\n".join(lines)


def write(res: ByKind, out: Path) -> list[Path]:
    """by_kind.json and by_kind.md in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "by_kind.json", res.to_dict())
    write_text(out / "by_kind.md", markdown(res) + "\n")
    return [out / "by_kind.json", out / "by_kind.md"]
