"""Typed results of the public API (:mod:`structsearch.api`); each serialises with ``to_dict()`` to the JSON
its command writes, or to the rows of the table it writes."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..data.campaign import Campaign
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.lift_fit import LiftFit


@dataclass(frozen=True)
class FitOutcome:
    """One candidate fitted as ``structsearch fit`` fits it: its result and the lift model it takes its
    separation states from (None for a lift or separation candidate)."""

    candidate: Candidate
    result: CandidateResult
    lift: LiftFit | None
    bands: Any = None          # structsearch.fitting.bands.StaticBands: the static curve's bands (None: not made)
    profile: Any = None        # structsearch.engine.profile.Profiles: profile intervals (None: not asked for)
    data: Any = None           # the campaign it was fitted on (:func:`campaign_record`)
    reference_point: float | None = None   # the campaign's fixed moment reference point [m] (None: none)

    def to_dict(self) -> dict:
        """``fit.json`` (docs/interfaces.md sections 2, 5.4 and 6.3; ``profile`` with ``fit(profile=True)``), with
        what ``export --fit`` reads (7.6): the ``structure``, every parameter's covariance and the ``data``."""
        from ..reporting.documents import fit_document, moment_reference_document, parameter_covariance
        doc = fit_document(self.result, self.lift, self.bands)
        doc["structure"] = self.candidate.to_dict()
        if self.lift is not None:
            doc["lift"]["structure"] = self.lift.candidate.to_dict()
        doc["parameter_covariance"] = parameter_covariance(self.result.estimates)
        if self.data is not None:
            doc["data"] = dict(self.data)
        if self.candidate.coefficient == "Cm":
            doc["moment_reference"] = moment_reference_document(self.candidate, self.reference_point)
        if self.profile is not None:
            doc["profile"] = self.profile.to_dict()
        return doc

    def summary(self) -> Any:
        """The fit's summary (text when printed, HTML in a notebook)."""
        return self.result.summary()


@dataclass(frozen=True)
class Ranking:
    """A search: per grid its candidates' results, best first by the ranking rule, its refinements and the wall
    time it took."""

    grids: dict[str, list[CandidateResult]]
    seconds: dict[str, float]
    refinements: dict[str, list] = field(default_factory=dict)
    joint: Any = None       # the JointFit whose lift block drag and pitch read (``search(joint_lift=...)``)
    # per grid the structures a structure search ranked beside it (the grid had no admissible structure)
    discovered: dict[str, list] = field(default_factory=dict)

    def best(self, grid: str) -> CandidateResult | None:
        """The grid's rank-1 candidate that did not fail (None if every one failed)."""
        return next((r for r in self.grids[grid] if not r.failed), None)

    @property
    def answers(self) -> dict:
        """Per grid its :class:`~structsearch.grid_search.answer.Answer` (the admissible structure ranked first when
        it fits near the best fit, else that none is near; None when nothing was fitted)."""
        from ..grid_search.answer import answer_of
        return {g: answer_of(ranked) for g, ranked in self.grids.items()}

    def to_frame(self):
        """``ranking.csv`` as a pandas DataFrame (the same columns and values)."""
        import io

        import pandas as pd

        from ..reporting.tables import ranking_csv
        return pd.read_csv(io.StringIO(ranking_csv(self.grids)))

    def to_dict(self) -> dict:
        """Per grid the rows of ``ranking.csv`` (None where a cell is empty), and the seconds per grid."""
        from ..reporting.tables import table_row
        return {"grids": {g: [table_row(r) for r in ranked] for g, ranked in self.grids.items()},
                "answers": {g: a.to_dict() if a is not None else None for g, a in self.answers.items()},
                "seconds": dict(self.seconds),
                **({"joint_lift": self.joint.to_dict()} if self.joint is not None else {})}


@dataclass(frozen=True)
class PreprocessOutcome:
    """A raw campaign preprocessed: the chain's result (``.campaign`` is the standard campaign), where it was
    written (None if nowhere), the worst R^2 per coefficient against the simulator's truth, and the seconds."""

    preprocessed: Any            # structsearch.preprocessing.pipeline.Preprocessed
    directory: Path | None
    markdown: Path | None
    worst_r2: dict[str, float]
    seconds: float
    warnings: tuple[str, ...] = ()   # what was skipped, and why (the figures without matplotlib)

    @property
    def campaign(self) -> Campaign:
        return self.preprocessed.campaign

    def to_dict(self) -> dict:
        p = self.preprocessed
        return {"directory": None if self.directory is None else str(self.directory),
                "sensor_errors": [{"name": e.name, "estimate": e.estimate, "sd": e.sd}
                                  for e in p.reconstruction.errors],
                "worst_r2": dict(self.worst_r2), "seconds": self.seconds}


@dataclass(frozen=True)
class StudyOutcome:
    """The thesis' comparison tables on a campaign and the files written (none when no ``out`` was given)."""

    study: Any                   # structsearch.thesis_study.study.Study
    written: list[Path]

    def to_dict(self) -> dict:
        return self.study.to_dict()


@dataclass(frozen=True)
class ReportOutcome:
    """``structsearch report``: the page, its figures, the notes shown on it and the seconds it took."""

    html: Path
    figures: list[Path]
    notes: list[str]
    seconds: float

    def to_dict(self) -> dict:
        return {"html": str(self.html), "figures": [str(f) for f in self.figures], "notes": list(self.notes),
                "seconds": self.seconds}


def campaign_record(campaign: Campaign) -> dict:
    """The data a fit was fitted on, as fit.json's ``data``: the campaign's directory, name and digest (the data,
    the split and the aircraft: :func:`structsearch.fitting.runner.campaign_fingerprint`) and its maneuvers."""
    from ..fitting.runner import campaign_fingerprint
    return {"source": str(Path(campaign.directory).resolve()) if campaign.directory else None,
            "name": campaign.name, "digest": campaign_fingerprint(campaign),
            "maneuvers": {s: [m.id for m in campaign.maneuvers if m.split == s] for s in ("train", "validation")}}
