"""Ranking of candidates and the generated tables (Markdown, LaTeX, CSV).

Ranking rule (one-standard-error rule on validation data): the candidate with
the lowest validation MSE of the modelled coefficient sets the bar; every
candidate whose per-maneuver relative excess in validation MSE is, on average,
less than one standard error of that excess (or below 1 %) is "within noise" of it. Those come first, fewest
parameters first (then lowest validation MSE); the rest follow by validation MSE.
Failed candidates come last with their reason.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from .io_atomic import write_text
from .report import render_table

# A relative excess below this is never a reason to prefer a larger model.
PRACTICAL_TOLERANCE = 0.01


def _paired_gap(a: dict, best: dict) -> tuple[float, float]:
    """Mean and standard error of the per-maneuver relative validation MSE excess over the best.

    Relative, because maneuvers differ in difficulty by orders of magnitude (a deep
    stall against a pullup); a missing effect shows as a consistent relative excess.
    """
    d = np.array(a["mse_validation_maneuvers"]) / np.array(best["mse_validation_maneuvers"]) - 1.0
    w = np.array(a["n_validation_maneuvers"], float)
    w = w / w.sum()
    mean = float(np.sum(w * d))
    if len(d) < 2:
        return mean, 0.0
    var = float(np.sum(w * (d - mean) ** 2)) / (len(d) - 1)
    return mean, float(np.sqrt(var))


def rank(summaries: list[dict]) -> list[dict]:
    """Order one grid's summaries best first; adds ``rank``, ``within_noise``, ``gap`` and ``gap_se``."""
    ok = [dict(s) for s in summaries if "error" not in s]
    failed = [dict(s) for s in summaries if "error" in s]
    if ok:
        best = min(ok, key=lambda s: s["mse_validation"])
        for s in ok:
            gap, se = _paired_gap(s, best)
            s["gap"], s["gap_se"] = gap, se
            s["within_noise"] = bool(s is best or gap <= max(se, PRACTICAL_TOLERANCE))
        top = sorted((s for s in ok if s["within_noise"]), key=lambda s: (s["n_params"], s["mse_validation"]))
        rest = sorted((s for s in ok if not s["within_noise"]), key=lambda s: s["mse_validation"])
        ok = top + rest
    for i, s in enumerate(ok + failed):
        s["rank"] = i + 1 if "error" not in s else None
    return ok + failed


COLUMNS = [("rank", "rank"), ("name", "model"), ("lift", "lift model"), ("n_params", "parameters"),
           ("mse_train", "MSE train"), ("mse_validation", "MSE validation"),
           ("mse_cx_validation", "MSE C_X val."), ("mse_cz_validation", "MSE C_Z val."),
           ("r2_validation_mean", "R2 val. mean"), ("r2_validation_min", "R2 val. min"),
           ("r2_validation_max", "R2 val. max"), ("aic", "AIC"), ("n_insignificant", "t-test accepts 0"),
           ("n_high_corr", "|rho| > 0.9"), ("within_noise", "within noise of best")]


def table_rows(ranked: list[dict]) -> list[dict]:
    rows = []
    for s in ranked:
        row = {"grid": s["grid"], "model": s["name"], "rank": s.get("rank"), "lift": s.get("lift") or "-"}
        if "error" in s:
            row["error"] = s["error"]
        else:
            r2 = s.get("r2_validation") or {}
            row.update({"n_params": s["n_params"], "mse_train": s["mse_train"], "mse_validation": s["mse_validation"],
                        "mse_cx_validation": s.get("mse_cx_validation"), "mse_cz_validation": s.get("mse_cz_validation"),
                        "r2_validation_mean": r2.get("mean"), "r2_validation_min": r2.get("min"),
                        "r2_validation_max": r2.get("max"), "aic": s["aic"],
                        "n_insignificant": len(s["insignificant"]), "n_high_corr": len(s["high_correlations"]),
                        "within_noise": s["within_noise"]})
        rows.append(row)
    return rows


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else ""
    if isinstance(v, float):
        return f"{v:.4g}"
    return v


def grid_table(ranked: list[dict], fmt: str) -> str:
    rows = table_rows(ranked)
    keys = [k if k != "name" else "model" for k, _ in COLUMNS]
    headers = [h for _, h in COLUMNS] + ["error"]
    body = [[_fmt(r.get(k)) for k in keys] + [r.get("error", "")] for r in rows]
    out = render_table(body, headers, fmt)
    return out if fmt == "csv" else out + "\n"


def parameter_table(summary: dict, fmt: str) -> str:
    rows = []
    for name, value in summary["params"].items():
        se, p = summary["stderr"][name], summary["p_values"][name]
        flags = []
        if name in summary["at_bound"]:
            flags.append("at bound")
        if name in summary["insignificant"]:
            flags.append("accepts 0")
        if any(name in pair[:2] for pair in summary["high_correlations"]):
            flags.append("|rho| > 0.9")
        rows.append([name, value, se, value / se if se else float("nan"), p, "; ".join(flags)])
    headers = ["parameter", "estimate", "std. dev.", "t", "p", "flags"]
    out = render_table(rows, headers, fmt, floatfmt=".4g")
    return out if fmt == "csv" else out + "\n"


def correlation_table(summary: dict, fmt: str) -> str:
    """Parameter correlation matrix of a candidate (thesis Tables 12, 14, 16); |rho| > 0.9 marked *."""
    names = summary["correlation"]["names"]
    matrix = np.asarray(summary["correlation"]["matrix"])
    if fmt == "csv":
        return render_table([[n] + [f"{v:.4f}" for v in row] for n, row in zip(names, matrix)], [""] + names, fmt)
    body = [[n] + [f"{v:+.2f}" + ("*" if i != j and abs(v) > 0.9 else "") for j, v in enumerate(row)]
            for i, (n, row) in enumerate(zip(names, matrix))]
    return render_table(body, [""] + names, fmt, numparse=False) + "\n"


def write_tables(ranked_by_grid: dict[str, list[dict]], out: Path) -> list[Path]:
    """``ranking.csv`` plus, per grid, the ranking (thesis Tables 8, 9, 10, 20) and the best candidate's
    parameters (Tables 11, 13, 15) and correlation matrix (Tables 12, 14, 16) in md/tex/csv."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    fields = ["grid", "model", "rank", "mse_train", "mse_validation", "n_params", "lift", "mse_cx_validation",
              "mse_cz_validation", "r2_validation_mean", "r2_validation_min", "r2_validation_max", "aic",
              "n_insignificant", "n_high_corr", "within_noise", "error"]
    w.writerow(fields)
    for grid, ranked in ranked_by_grid.items():
        for r in table_rows(ranked):
            w.writerow([r.get(f, "") if r.get(f) is not None else "" for f in fields])
    write_text(out / "ranking.csv", buf.getvalue())
    written.append(out / "ranking.csv")
    for grid, ranked in ranked_by_grid.items():
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in grid)
        for fmt in ("md", "tex", "csv"):
            p = out / f"{safe}.{fmt}"
            write_text(p, grid_table(ranked, fmt))
            written.append(p)
        best = next((s for s in ranked if "error" not in s), None)
        if best is not None:
            for fmt in ("md", "tex", "csv"):
                p = out / f"{safe}_best_parameters.{fmt}"
                write_text(p, parameter_table(best, fmt))
                written.append(p)
                if "correlation" in best:
                    p = out / f"{safe}_best_correlation.{fmt}"
                    write_text(p, correlation_table(best, fmt))
                    written.append(p)
    return written
