"""The record of a preprocessing run (issue 15): ``preprocess.md`` and its spectra figures.

Everything here renders a :class:`structsearch.preprocessing.pipeline.Preprocessed`; the numbers come from there.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from tabulate import tabulate

from ..data.atomic import write_text
from ..data.coefficients import COEFFICIENTS
from ..preprocessing.pipeline import CHANNEL_GROUPS, Preprocessed, truth_agreement
from ..preprocessing.reconstruction import Reconstruction


def _hz(x) -> str:
    return "-" if x is None else f"{x:.2f}"


def _group_file(group: str) -> str:
    return "spectra_" + group.replace(" ", "_") + ".png"


def _errors_table(rec: Reconstruction, injected: dict) -> str:
    rows = []
    for e in rec.errors:
        row = [e.name, e.unit, f"{e.estimate:.6g}", f"{e.sd:.2g}", f"{e.filter_sd:.2g}", f"{e.jackknife_sd:.2g}"]
        truth = injected.get(f"injected_{e.name}")
        if injected:
            row += ["-" if truth is None else f"{truth:.6g}",
                    "-" if truth is None or not e.sd > 0 else f"{(e.estimate - truth) / e.sd:+.2f}"]
        rows.append(row)
    headers = ["sensor error", "unit", "estimate", "sd", "smoother sd", "jackknife sd"]
    if injected:
        headers += ["injected", "(estimate - injected) / sd"]
    return tabulate(rows, headers, tablefmt="github", disable_numparse=True)


def markdown(p: Preprocessed, command: str, seconds: float | None = None, figures: bool = True) -> str:
    rec = p.reconstruction
    injected = {k: float(v) for k, v in p.raw.extra.items() if str(k).startswith("injected_")}
    lines = [f"# Preprocessing of {p.raw.name}", "", f"Command: `{command}`", ""]
    if seconds is not None:
        lines += [f"Wall time: {seconds:.1f} s ({p.raw.data.n_samples} samples, {len(p.raw.maneuvers)} maneuvers).",
                  ""]
    lines += ["## Spectra and cut-offs", "",
              (f"Stalled flow: alpha above {np.rad2deg(p.stall_alpha_rad):.1f} deg ({p.stall_alpha_source}); "
               if np.isfinite(p.stall_alpha_rad) else f"Stalled flow: {p.stall_alpha_source}; ")
              + "attached flow: the lower half of the angles of attack flown. Buffet peaks are where the stalled "
              "spectrum exceeds the attached one (2-25 Hz); the rigid-body bandwidth is where the attached "
              "spectrum falls to 3x its noise floor; the suggested cut-off lies below both the peaks and that "
              "bandwidth. Pre-filter: 4th-order Butterworth, forward and backward, maneuver by maneuver.", ""]
    spectra = {s.channel: s for s in p.spectra}
    rows = []
    for c in p.cutoffs:
        s = spectra.get(c.channel)
        rows.append([c.channel, ", ".join(f"{x:.2f}" for x in s.peaks_hz) if s and s.peaks_hz else "-",
                     _hz(s.bandwidth_hz if s else None), _hz(c.default_hz), _hz(c.suggested_hz), _hz(c.applied_hz),
                     c.source])
    lines += [tabulate(rows, ["channel", "buffet peaks [Hz]", "rigid-body bandwidth [Hz]", "Table 5 / default [Hz]",
                              "suggested [Hz]", "applied [Hz]", "from"], tablefmt="github", disable_numparse=True), ""]
    if figures:
        for group in CHANNEL_GROUPS:
            if any(c in spectra for c in CHANNEL_GROUPS[group]):
                lines.append(f"![{group}]({_group_file(group)})")
    else:
        lines.append(f"(Spectra figures not drawn: {NO_FIGURES}.)")
    lines += ["", "## Flight-path reconstruction", "",
              f"Extended Kalman filter and RTS smoother over u, w, theta, h with the sensor errors as constant "
              f"states shared by all maneuvers; step {rec.step_s:g} s ({rec.n_steps} steps); every channel "
              "filtered at the lowest of their cut-offs for it; measurement noise from an EM step. The standard "
              "deviation is the larger of the smoother's and a delete-a-group jackknife over maneuvers.", "",
              _errors_table(rec, injected), "",
              "Consistency residuals (RMS of measured minus smoothed kinematics), sensor errors nominal and "
              "estimated:", ""]
    lines += [tabulate([[c.channel, f"{c.before:.4g}", f"{c.after:.4g}"] for c in rec.consistency],
                       ["channel", "before", "after"], tablefmt="github", disable_numparse=True), ""]
    agreement = truth_agreement(p.campaign)
    if agreement:
        lines += ["## Coefficients against the simulator's truth", "",
                  "Per-maneuver R^2 of the reconstructed coefficient against the `_true` column (a simulated "
                  "campaign); issue 15's targets: C_L 0.97, C_D 0.95, C_m 0.80 on every maneuver. The last column "
                  "removes each maneuver's mean error first: the simulator's thrust channel carries a 3 % engine-"
                  "model error per maneuver, which shifts C_X and C_D by a constant no reduction can remove.", ""]
        offset = truth_agreement(p.campaign, less_offset=True)
        rows = []
        for name in COEFFICIENTS:
            values = np.array([r for _, n, r in agreement if n == name])
            if values.size:
                worst = min((r, m) for m, n, r in agreement if n == name)
                rows.append([name, f"{values.min():.4f}", worst[1], f"{np.median(values):.4f}",
                             f"{min(r for _, n, r in offset if n == name):.4f}"])
        lines += [tabulate(rows, ["coefficient", "min R^2", "worst maneuver", "median R^2",
                                  "min R^2 less each maneuver's mean error"], tablefmt="github",
                           disable_numparse=True), ""]
    return "\n".join(lines) + "\n"


NO_FIGURES = "matplotlib, an optional dependency, is not installed (pip install 'structsearch[figures]')"


def figures_available() -> bool:
    from . import figures as fig
    return fig.plt is not None


def write(p: Preprocessed, out: Path, command: str, seconds: float | None = None, figures: bool = True) -> Path:
    """``preprocess.md`` and, with ``figures``, the spectra figures under ``out``. Without matplotlib the figures
    are skipped (the caller warns: :func:`figures_available`) and the record says so; the campaign and the record
    are written all the same."""
    out = Path(out)
    figures = figures and figures_available()
    if figures:
        from . import figures as fig
        spectra = {s.channel: s for s in p.spectra}
        applied = {c.channel: c.applied_hz for c in p.cutoffs}
        for group, channels in CHANNEL_GROUPS.items():
            present = {c: spectra[c] for c in channels if c in spectra}
            if present:
                fig.save(fig.spectra(group, present, applied), out / _group_file(group))
    return write_text(out / "preprocess.md", markdown(p, command, seconds, figures))
