"""A simulator as the baseline of a diagnosis: its coefficient along the flight, a fixed offset (docs/interfaces.md
7.6).

The simulator's coefficient at every recorded sample (a column the user's simulator wrote into the campaign, or
JSBSim evaluated at the recorded states: :mod:`structsearch.export.jsbsim_baseline`) enters every structure of the
search with coefficient 1 and nothing of it is refitted: each structure is fitted to the gap, flight minus
simulator, and predicts the coefficient as simulator plus structure. The diagnosis then runs unchanged
(:func:`.diagnose.diagnose_search`) on a campaign whose coefficient column holds that gap, so that where the gap
lies, which effect closes it and how far it shrinks are computed as for one of our own baselines.

The search starts from the simulator with one constant bias (``<coefficient>_bias = 1``): a search needs a structure
with a term to start from, and a constant shift (a zero-lift angle, a trim offset) is the simplest difference of a
simulator from a flight. The simulator alone, without that bias, is reported beside it (:func:`simulator_record`).
The simulator column itself is removed from the gap's campaign: it is the offset, not a measured signal, and the
library-free floor reads every measured column.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..data.coefficients import COEFFICIENTS
from ..data.campaign import Campaign
from ..data.errors import DataError, DeclarationError
from ..discovery.terms import SimulatorTerm
from ..fitting.candidates import Candidate

# --simulator jsbsim:NAME_OR_DIR: the prefix of a JSBSim aircraft as the diagnosis baseline
JSBSIM_PREFIX = "jsbsim:"


def simulator_target(text: str) -> str:
    """The aircraft of ``--simulator jsbsim:NAME_OR_DIR``; one error for anything else."""
    if not text.startswith(JSBSIM_PREFIX) or not text[len(JSBSIM_PREFIX):].strip():
        raise DeclarationError(f"--simulator {text!r}: give jsbsim:NAME_OR_DIR (one of JSBSim's aircraft such as "
                               "c172p, an aircraft directory, or an export directory of `structsearch export "
                               "--format jsbsim`); a simulator's coefficient written into the campaign is "
                               "--baseline-column")
    return text[len(JSBSIM_PREFIX):].strip()
GRID = "simulator"


@dataclass(frozen=True)
class SimulatorBaseline:
    """A simulator's coefficient at every sample of a campaign (``campaign.data`` order): ``source`` names it in
    the diagnosis ("column CL_sim", "jsbsim:DIR"), ``kind`` is "column" or "jsbsim", ``detail`` what else the
    document records (the aircraft, the JSBSim version)."""

    coefficient: str
    source: str
    kind: str
    values: np.ndarray = field(repr=False)
    detail: Mapping[str, object] = field(default_factory=dict)
    column: str | None = None      # the campaign column it was read from (removed from the gap's campaign)
    # the simulator's own terms, "sim:<function>" -> values, which sum to ``values`` (a grey box: each becomes a
    # column the search may rescale, drop or replace; empty: the simulator is one black-box offset)
    terms: Mapping[str, np.ndarray] = field(default_factory=dict, repr=False)
    # per term, the campaign signals it reads (a library term that replaces it must read one of them)
    term_signals: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    @property
    def term_columns(self) -> dict[str, str]:
        """Each term's campaign column in the gap's campaign: ``sim__`` and the function's last path component
        (made unique), a name an expression can read."""
        return term_columns(tuple(self.terms))


TERM_COLUMN_PREFIX = "sim__"


def term_columns(names) -> dict[str, str]:
    """``sim:<function>`` -> a column name of :data:`TERM_COLUMN_PREFIX` and the function's last path component
    (characters other than letters, digits and _ replaced by _; a repeat gets _2, _3, ...)."""
    out: dict[str, str] = {}
    for name in names:
        tail = re.sub(r"\W", "_", name.rsplit("/", 1)[-1].split(":")[-1]) or "term"
        column, k = TERM_COLUMN_PREFIX + tail, 2
        while column in out.values():
            column, k = f"{TERM_COLUMN_PREFIX}{tail}_{k}", k + 1
        out[name] = column
    return out


def _where(campaign: Campaign, segment: int) -> str:
    """The file of a campaign's ``segment``-th maneuver (its manifest, for a campaign without files)."""
    m = campaign.maneuvers[segment] if segment < len(campaign.maneuvers) else None
    if campaign.directory is not None:
        return str(campaign.directory / m.file) if m is not None else str(campaign.directory / "campaign.toml")
    return m.id if m is not None else campaign.name


def check_values(campaign: Campaign, values: np.ndarray, column: str) -> np.ndarray:
    """``values`` as floats, one per sample of the campaign, each finite; else one :class:`DataError` naming the
    maneuver's file, ``column`` and the row within the maneuver."""
    values = np.asarray(values, float)
    if values.shape != (campaign.data.n_samples,):
        raise DataError(f"the simulator's coefficient has {values.size} values for {campaign.data.n_samples} samples",
                        source=_where(campaign, 0), column=column)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        k = int(bad[0])
        segment = int(np.searchsorted(campaign.data.bounds, k, side="right") - 1)
        row = k - int(campaign.data.bounds[segment])
        raise DataError(f"the simulator's coefficient is {values[k]!r}, not a finite number", source=_where(campaign, segment),
                        column=column, row=row)
    return values


def column_baseline(campaign: Campaign, coefficient: str, column: str) -> SimulatorBaseline:
    """The simulator's coefficient a campaign column holds (``--baseline-column``)."""
    check_coefficient(coefficient)
    if column == coefficient:
        raise DeclarationError(f"--baseline-column {column}: that is the measured coefficient itself; name the column "
                               "the simulator wrote (e.g. CL_sim)")
    if column not in campaign.data:
        source = str(campaign.directory / "campaign.toml") if campaign.directory is not None else campaign.name
        raise DataError("the campaign's maneuver files have no such column (the simulator's coefficient along the "
                        "flight: a free column of every maneuver file)", source=source, column=column)
    values = check_values(campaign, campaign.data[column], column)
    return SimulatorBaseline(coefficient, f"column {column}", "column", values, column=column)


def library_terms(baseline: SimulatorBaseline) -> tuple[SimulatorTerm, ...]:
    """The simulator's terms as the structure search's grey-box terms (none for a black-box simulator); a term that
    is zero at every sample (flaps retracted all flight) is none: nothing of it can be rescaled or dropped."""
    columns = baseline.term_columns
    return tuple(SimulatorTerm(name, columns[name], tuple(baseline.term_signals.get(name, ())))
                 for name, values in baseline.terms.items() if np.any(np.asarray(values) != 0))


def check_coefficient(coefficient: str | None) -> None:
    if coefficient not in COEFFICIENTS:
        raise DeclarationError("a simulator baseline needs --coefficient: the coefficient the simulator's values are "
                               f"of (one of {', '.join(COEFFICIENTS)})")


def gap_campaign(campaign: Campaign, baseline: SimulatorBaseline) -> Campaign:
    """``campaign`` with its coefficient column replaced by flight minus simulator (and the simulator's own column
    removed); a simulator's terms become columns (:attr:`SimulatorBaseline.term_columns`)."""
    c = baseline.coefficient
    if c not in campaign.data:
        raise DataError("the campaign has no column for the diagnosed coefficient",
                        source=str(campaign.directory) if campaign.directory else campaign.name, column=c)
    columns = {k: v for k, v in campaign.data.columns.items() if k != baseline.column}
    columns[c] = np.asarray(campaign.data[c], float) - baseline.values
    for name, column in baseline.term_columns.items():
        columns[column] = np.asarray(baseline.terms[name], float)
    # a new Campaign: its split cache (kept in the instance) starts empty
    return dataclasses.replace(campaign, data=campaign.data.with_columns(columns))


def start_structure(baseline: SimulatorBaseline) -> Candidate:
    """Where the search starts: the simulator (the fixed offset) and one constant bias."""
    c = baseline.coefficient
    return Candidate(baseline.source, GRID, c, ((f"{c}_bias", "1"),),
                     note=f"{baseline.source} as a fixed offset, with a constant bias")


def simulator_record(campaign: Campaign, baseline: SimulatorBaseline, bias: float) -> dict:
    """The document's ``simulator`` block: what the simulator is, its own MSE on both splits (without the bias),
    the bias the search started from, and how the baseline enters."""
    c = baseline.coefficient
    mse = {}
    for split in ("train", "validation"):
        idx = [i for i, m in enumerate(campaign.maneuvers) if m.split == split]
        gap = np.concatenate([np.asarray(campaign.data[c], float)[s] - baseline.values[s]
                              for s in (campaign.data.segment_slices()[i] for i in idx)]) if idx else np.empty(0)
        mse[split] = float(np.mean(gap ** 2)) if gap.size else None
    return {"source": baseline.source, "kind": baseline.kind, **dict(baseline.detail),
            "mse": mse, "bias": {"name": f"{c}_bias", "value": float(bias)},
            "baseline": (f"the simulator's {c} enters every structure with coefficient 1 (a fixed offset: none of "
                         f"it is refitted); the search starts from it plus the constant bias {c}_bias, and every "
                         "structure is fitted to flight minus simulator"),
            "state_level": "not replayed: the state-level replay needs the simulator's whole model in the loop"}


def terms_record(baseline: SimulatorBaseline, final: Candidate, estimates) -> dict:
    """What the final structure made of each simulator term (a grey box; empty for a black box): ``kept``,
    ``rescaled`` (its factor 1 + c and the standard error of c: the flight's term is ``factor`` times the
    simulator's), ``dropped`` or ``replaced`` (by the terms the structure added in its place), each with a
    sentence that names the simulator's function."""
    if not baseline.terms:
        return {}
    regressors, known = dict(final.regressors), dict(final.known)
    params, stderr = dict(estimates.params), dict(estimates.stderr)
    added = [n for n in regressors if n not in baseline.terms and n != f"{baseline.coefficient}_bias"]
    out = {}
    for name in baseline.terms:
        function = name.removeprefix("sim:")
        if not np.any(np.asarray(baseline.terms[name]) != 0):
            entry = {"verdict": "zero", "words": f"the simulator's {function} is zero along the flight (not searched)"}
        elif f"-{name}" in known:
            verdict = "replaced" if added else "dropped"
            entry = {"verdict": verdict,
                     "words": (f"the simulator's {function} is dropped: the flight shows none of it"
                               if verdict == "dropped" else
                               f"the simulator's {function} is dropped; the structure adds {', '.join(added)}")}
        elif name in regressors:
            factor, se = 1.0 + float(params[name]), float(stderr.get(name, float("nan")))
            entry = {"verdict": "rescaled", "factor": factor, "stderr": se,
                     "words": f"the simulator's {function} rescaled by {factor:.3g} ± {se:.2g}: the flight's is "
                              f"{factor:.3g} times the simulator's"}
        else:
            entry = {"verdict": "kept", "words": f"the simulator's {function} kept as it is"}
        out[name] = {"column": baseline.term_columns[name], **entry}
    return out


def without_bias_reasons(diagnosis, start: Candidate):
    """``diagnosis`` without the t-test reason about the start's bias alone: a bias the test accepts as zero says
    the simulator has no constant offset, not that the baseline is degenerate (the other reasons stay, and the
    warning that lists them)."""
    alone = re.compile(r"t-test accepts 0 at [^:]+: " + re.escape(start.regressors[0][0]))
    reasons = tuple(r for r in diagnosis.baseline_reasons if not alone.fullmatch(r))
    if reasons == diagnosis.baseline_reasons:
        return diagnosis
    head = f"the baseline {start.name} as fitted here is not admissible: "
    warnings = tuple(w for w in diagnosis.warnings if not w.startswith(head))
    if reasons:
        warnings += (head + "; ".join(reasons),)
    return dataclasses.replace(diagnosis, baseline_reasons=reasons, warnings=warnings)
