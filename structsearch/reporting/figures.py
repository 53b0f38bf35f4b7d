"""The report's figures (matplotlib, an optional extra: ``pip install 'structsearch[figures]'``).

Each function takes arrays from :mod:`structsearch.report_data` and returns a
matplotlib Figure; :func:`save` writes it atomically as PNG. Angles are plotted in
radians (the project's unit) with degrees on a secondary axis.
"""
from __future__ import annotations

import io
import textwrap
from pathlib import Path

import numpy as np

from ..data.errors import StructSearchError
from ..data.atomic import write_bytes
from .numbers import share

try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
except ImportError:  # the core works without it; only the report needs it
    plt = None

COLOURS = {"model": "C0", "van_ingen": "C1", "measured": "0.55"}
LABELS = {"CL": "C_L [-]", "CD": "C_D [-]", "Cm": "C_m [-]"}


def require() -> None:
    if plt is None:
        raise StructSearchError("figures need matplotlib, an optional dependency: "
                                "pip install 'structsearch[figures]'")


def save(fig, path: Path) -> Path:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    write_bytes(path, buffer.getvalue())
    return path


def _degrees_axis(ax) -> None:
    ax.secondary_xaxis("top", functions=(np.degrees, np.radians)).set_xlabel("alpha [deg]")


def separation(curves: dict, alpha: np.ndarray):
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for i, (symbol, c) in enumerate(curves.items()):
        colour = f"C{i}"
        shape = f"a1 = {c['a1']:.1f}" if c.get("form", "tanh") == "tanh" else f"X0 {c['form']}"
        ax.plot(alpha, c["x0"], color=colour, lw=2,
                label=f"{symbol} ({c['kind']}): {shape}, alpha* = {c['a_star']:.3f} rad")
        for (label, a), style in zip(c["stages"].items(), (":", "--", "-.")):
            ax.axvline(a, color=colour, ls=style, lw=1, label=f"{symbol} {label}: {a:.3f} rad")
    ax.set_xlabel("alpha [rad]")
    ax.set_ylabel("X_0 [-] (1 attached, 0 separated)")
    ax.set_ylim(-0.03, 1.03)
    _degrees_axis(ax)
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    return fig


def _finish(ax, xlabel: str, ylabel: str, degrees: bool = True) -> None:
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if degrees:
        _degrees_axis(ax)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def _compare(ax, model_xy, van_ingen_xy, names, points_xy=None) -> None:
    """Measured points (corrected), the identified curve and the Van Ingen structure's curve."""
    if points_xy is not None:
        ax.scatter(*points_xy, s=2, color=COLOURS["measured"], alpha=0.35, rasterized=True,
                   label="measured, corrected to the static condition")
    ax.plot(*model_xy, color=COLOURS["model"], lw=2.2, label=f"{names[0]} (fitted)")
    if van_ingen_xy is not None:
        ax.plot(*van_ingen_xy, color=COLOURS["van_ingen"], lw=1.8, ls="--", label=f"{names[1]} (Van Ingen structure)")


def static_curve(coef: str, alpha, model, van_ingen, points, names, bands=None, note: str | None = None):
    """The identified static curve (with its 95 % bands when given: a StaticBands), the Van Ingen structure's
    and the measured points corrected to the static condition; ``note``: a remark drawn in the figure (why a
    curve lies away from the points), not left to the caption."""
    fig, ax = plt.subplots(figsize=(7, 4.2))
    if note:
        ax.text(0.02, 0.03, note, transform=ax.transAxes, fontsize=7, va="bottom", ha="left", wrap=True,
                bbox=dict(boxstyle="round", facecolor="white", edgecolor="0.7", alpha=0.9))
    if bands is not None:
        b = bands.band
        ax.fill_between(bands.alpha, b.prediction_low, b.prediction_high, color=COLOURS["model"], alpha=0.12,
                        lw=0, label=f"{bands.level:.0%} prediction band (a new measurement)")
        ax.fill_between(bands.alpha, b.confidence_low, b.confidence_high, color=COLOURS["model"], alpha=0.35,
                        lw=0, label=f"{bands.level:.0%} confidence band (the curve)")
    _compare(ax, (alpha, model[coef]), (alpha, van_ingen[coef]) if van_ingen is not None else None, names,
             (points["alpha"], points[coef]))
    _finish(ax, "alpha [rad]", LABELS[coef])
    return fig


def drag_polar(model, van_ingen, points, names):
    fig, ax = plt.subplots(figsize=(6, 4.5))
    _compare(ax, (model["CD"], model["CL"]), (van_ingen["CD"], van_ingen["CL"]) if van_ingen is not None else None,
             names, (points["CD"], points["CL"]))
    _finish(ax, LABELS["CD"], LABELS["CL"], degrees=False)
    return fig


def centre_of_pressure(alpha, derived, curves, x_cg_range, x_cg_ref):
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(alpha, derived["x_cp"], color=COLOURS["model"], lw=2.2, label="centre of pressure x_cp")
    if x_cg_range is not None:  # only when the campaign gives one (campaign.toml x_cg_range)
        ax.axhspan(*x_cg_range, color="C2", alpha=0.15, label="centre-of-gravity envelope")
    ax.axhline(x_cg_ref, color="C2", lw=1, label=f"mean centre of gravity ({x_cg_ref:.3f} m)")
    for i, (symbol, c) in enumerate(curves.items()):
        ax.axvline(c["a_star"], color=f"C{3 + i}", ls="--", lw=1, label=f"alpha* of {symbol} ({c['a_star']:.3f} rad)")
    _finish(ax, "alpha [rad]", "x from the datum of the campaign's x_cg column [m]")
    return fig


def elevator(alpha, model, van_ingen, names):
    fig, ax = plt.subplots(figsize=(7, 4.2))
    _compare(ax, (alpha, model), (alpha, van_ingen) if van_ingen is not None else None, names)
    _finish(ax, "alpha [rad]", "C_m_delta_e* [1/rad]")
    return fig


def traces(selection: dict):
    fig, axes = plt.subplots(3, 3, figsize=(12, 8), squeeze=False)
    for row, (coef, picks) in enumerate(selection.items()):
        for col, p in enumerate(picks):
            ax = axes[row][col]
            b = p.get("band")
            if b is not None:
                ax.fill_between(p["t"], b.prediction_low, b.prediction_high, color=COLOURS["model"], alpha=0.12,
                                lw=0, label=f"{b.level:.0%} prediction band")
                ax.fill_between(p["t"], b.confidence_low, b.confidence_high, color=COLOURS["model"], alpha=0.4,
                                lw=0, label=f"{b.level:.0%} confidence band")
            ax.plot(p["t"], p["measured"], color=COLOURS["measured"], lw=0.8, label="measured")
            ax.plot(p["t"], p["model"], color=COLOURS["model"], lw=1.2, label="model")
            ax.set_title(f"{coef}: {p['which']} ({p['maneuver']}, R^2 = {p['r2']:.3f})", fontsize=9)
            ax.set_xlabel("time [s]")
            ax.set_ylabel(LABELS[coef])
            ax.grid(alpha=0.3)
            if row == 0 and col == 0:
                ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def hysteresis_loop(h: dict):
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(h["alpha"], h["measured"], color=COLOURS["measured"], lw=0.6, label="measured")
    ax.plot(h["alpha"], h["model"], color=COLOURS["model"], lw=1.0, label="model (separation lag and delay)")
    ax.plot(h["static_alpha"], h["static"], color="k", ls="--", lw=1.5, label="static curve (no lag)")
    _finish(ax, "alpha [rad]", LABELS["CL"])
    return fig


def correlations(summaries: dict):
    fig, axes = plt.subplots(1, len(summaries), figsize=(5.2 * len(summaries), 5), squeeze=False)
    image = None
    for ax, (coef, s) in zip(axes[0], summaries.items()):
        names, matrix = list(s.estimates.names), s.estimates.correlation
        image = ax.imshow(matrix, vmin=-1, vmax=1, cmap="RdBu_r")
        ax.set_xticks(range(len(names)), names, rotation=90, fontsize=7)
        ax.set_yticks(range(len(names)), names, fontsize=7)
        for i in range(len(names)):
            for j in range(len(names)):
                if i != j and abs(matrix[i, j]) > 0.9:
                    ax.text(j, i, "!", ha="center", va="center", fontsize=9, fontweight="bold", color="w")
        ax.set_title(f"{s.name} ({coef})", fontsize=10)
    fig.colorbar(image, ax=axes[0].tolist(), shrink=0.8, label="correlation [-] (! where |rho| > 0.9)")
    return fig


# a change below this share of the largest cell is "little": the before and after panels then look alike
LITTLE_CHANGE = 0.05


def after_move(move: str) -> str:
    """ "after <move>" in words: a move's label starts with its verb ("add Cm_K21_ss = ..."), an effect's name
    does not ("after adding Cm_K21_ss"), so that no title reads "after adding add"."""
    verbs = ("add ", "drop ", "replace ", "make ", "remove ")
    return f"after {move}" if move.lower().startswith(verbs) else f"after adding {move}"


def gap_titles(g: dict, move: str) -> tuple[str, str]:
    """The before and after panels' titles of the gap breakdown: the model after the move is named once (its name,
    "Cm-X + add ...", already says the move: "after adding add ..." read twice)."""
    after = f"after: {g['model']}" if move in g["model"] else f"{after_move(move)}: {g['model']}"
    return f"before: {g['baseline']} (MSE {g['mse_before']:.3g})", f"{after} (MSE {g['mse_after']:.3g})"


def gap_change_words(before: np.ndarray, after: np.ndarray) -> str:
    """The third panel's title: how much the move changes the cells, saying so when the two maps look alike."""
    change = after - before
    finite = np.isfinite(change)
    scale = np.nanmax(np.abs(before[np.isfinite(before)])) if np.isfinite(before).any() else np.nan
    if not finite.any() or not scale > 0:
        return "change (after - before): none to show"
    largest = float(np.max(np.abs(change[finite])) / scale)
    total = float(np.nansum(change) / np.nansum(before)) if np.nansum(before) > 0 else np.nan
    words = f"change (after - before): MSE summed over cells {share(total, signed=True)}"
    if largest < LITTLE_CHANGE:
        words += f";\nlittle changes (every cell by < {LITTLE_CHANGE:.0%} of the largest): the two maps look alike"
    return words


def gap(before: np.ndarray, after: np.ndarray, maneuvers, bands, labels):
    """Validation MSE per (maneuver, alpha band) before and after a move, and the change itself (a diverging
    map), so that a move that changes little shows as little rather than as two identical panels."""
    fig, axes = plt.subplots(1, 3, figsize=(17, 0.9 + 0.32 * len(maneuvers) + 1.5), squeeze=False)
    finite = np.concatenate([before[np.isfinite(before)], after[np.isfinite(after)]])
    positive = finite[finite > 0]
    norm = LogNorm(vmin=positive.min(), vmax=positive.max()) if positive.size else None
    extent = (bands[0], bands[-1], len(maneuvers) - 0.5, -0.5)
    image = None
    for ax, cells, title in zip(axes[0][:2], (before, after), labels):
        image = ax.imshow(np.ma.masked_invalid(cells), aspect="auto", cmap="viridis", norm=norm,
                          extent=extent, interpolation="nearest")
        ax.set_title(textwrap.fill(title, 50), fontsize=9)
    fig.colorbar(image, ax=axes[0][:2].tolist(), label="validation MSE in the cell [-]")
    change = after - before
    reach = float(np.nanmax(np.abs(change))) if np.isfinite(change).any() else 1.0
    diff = axes[0][2].imshow(np.ma.masked_invalid(change), aspect="auto", cmap="RdBu_r", vmin=-reach, vmax=reach,
                             extent=extent, interpolation="nearest")
    axes[0][2].set_title("\n".join(textwrap.fill(part, 50) for part in gap_change_words(before, after).split("\n")),
                         fontsize=9)
    fig.colorbar(diff, ax=axes[0][2], label="change of the cell's MSE [-] (blue: lower after)")
    for ax in axes[0]:
        ax.set_yticks(range(len(maneuvers)), maneuvers, fontsize=7)
        ax.set_xlabel("alpha band [rad]")
        ax.set_ylabel("validation maneuver")
    return fig


def partial_dependence(curves: list[dict], coefficient: str):
    """The residual the library leaves against each of its top signals: validation means per bin (points) and
    the smooth function fitted on the training maneuvers (line)."""
    fig, axes = plt.subplots(1, len(curves), figsize=(4.2 * len(curves), 3.4), squeeze=False)
    for ax, c in zip(axes[0], curves):
        ax.plot(c["validation_x"], c["validation_mean"], "o", color=COLOURS["measured"], ms=4,
                label="validation: mean residual per bin")
        ax.plot(c["x"], c["fitted"], color=COLOURS["model"], lw=1.5, label="function fitted on training")
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_xlabel(c["name"])
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(f"{coefficient} residual [-]")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def replay_traces(r, states=("alpha", "q", "V", "theta")):
    units = {"alpha": "[rad]", "q": "[rad/s]", "V": "[m/s]", "theta": "[rad]"}
    fig, axes = plt.subplots(len(states), 1, figsize=(10, 2.1 * len(states)), sharex=True)
    t = r.t - r.t[0]
    for ax, s in zip(axes, states):
        ax.plot(t, r.measured[s], color=COLOURS["measured"], lw=1.0, label="measured")
        ax.plot(t, r.simulated[s], color=COLOURS["model"], lw=1.0, label="simulated (identified model)")
        for start in r.window_starts[1:]:
            ax.axvline(t[start], color="0.8", lw=0.6)
        ax.set_ylabel(f"{s} {units[s]}")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("time [s] (grey lines: re-initialised on the measured states)")
    fig.tight_layout()
    return fig


def spectra(group: str, spectra_by_channel: dict, cutoffs: dict):
    """Welch spectra of stalled against attached flow for one channel group, with the detected buffet peaks
    (dotted) and the applied cut-off (dashed)."""
    fig, axes = plt.subplots(1, len(spectra_by_channel), figsize=(4.2 * len(spectra_by_channel), 3.4),
                             squeeze=False)
    for ax, (channel, s) in zip(axes[0], spectra_by_channel.items()):
        keep = s.frequency > 0
        ax.semilogy(s.frequency[keep], s.attached[keep], color="C0", lw=1, label="attached")
        ax.semilogy(s.frequency[keep], s.stalled[keep], color="C3", lw=1, label="stalled")
        for p in s.peaks_hz:
            ax.axvline(p, color="C3", ls=":", lw=1)
        if cutoffs.get(channel) is not None:
            ax.axvline(cutoffs[channel], color="k", ls="--", lw=1, label=f"cut-off {cutoffs[channel]:.2g} Hz")
        ax.set_title(channel)
        ax.set_xlabel("frequency [Hz]")
        ax.set_xlim(0, min(30.0, float(s.frequency.max())))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("power spectral density [unit^2/Hz]")
    fig.suptitle(group)
    return fig


def r2_boxes(r2: dict, coefficients, models, splits=("train", "validation")):
    """Per-maneuver R^2 box plots (thesis Fig. 12): ``r2[(model, coefficient, split)]`` -> values."""
    fig, axes = plt.subplots(1, len(coefficients), figsize=(3.3 * len(coefficients), 3.8), squeeze=False)
    for ax, coefficient in zip(axes[0], coefficients):
        data, labels, colours = [], [], []
        for i, model in enumerate(models):
            for split in splits:
                values = [v for v in r2.get((model, coefficient, split), ()) if np.isfinite(v)]
                if values:
                    data.append(values)
                    labels.append(f"{model}\n{split}")
                    colours.append(f"C{i}")
        if data:
            boxes = ax.boxplot(data, patch_artist=True, widths=0.6)
            for patch, colour in zip(boxes["boxes"], colours):
                patch.set_facecolor(colour)
                patch.set_alpha(0.45)
            ax.set_xticks(range(1, len(labels) + 1), labels, rotation=90, fontsize=6)
        ax.set_title(coefficient)
        ax.grid(alpha=0.3, axis="y")
    axes[0][0].set_ylabel("R^2 per maneuver [-]")
    return fig
