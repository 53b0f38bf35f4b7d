"""What a diagnosis returns: immutable typed results whose ``to_dict()`` is the JSON document of
docs/interfaces.md sections 3 and 5.4 (``diagnosis.json``), key for key and in the same order.

A number that cannot be estimated is None (a p-value, a shrink when there is no gap) or NaN (a bootstrap
spread that was not drawn); ``public`` in :mod:`structsearch.reporting.diagnosis_doc` writes both as null.
``from_dict`` reads such a document back (the fields the document derives from the first round are not read).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from .equivalence import Equivalence

STATES = ("alpha", "q", "V", "theta")


@dataclass(frozen=True)
class TrainValidation:
    """A model's MSE on the training and on the validation maneuvers."""

    train: float
    validation: float

    def to_dict(self) -> dict:
        return {"train": self.train, "validation": self.validation}

    @classmethod
    def from_dict(cls, d: Mapping) -> TrainValidation:
        return cls(d["train"], d["validation"])


@dataclass(frozen=True)
class WhereBin:
    """One bin of the gap breakdown: its share of the summed excess squared residual (with the bootstrap spread
    over maneuvers, NaN where none was drawn), the baseline's MSE in it (NaN for frequency bands) and its samples."""

    dimension: str
    bin: str
    share: float
    share_std: float
    mse: float
    samples: int

    def to_dict(self) -> dict:
        return {"dimension": self.dimension, "bin": self.bin, "share": self.share, "share_std": self.share_std,
                "mse": self.mse, "samples": self.samples}

    @classmethod
    def from_dict(cls, d: Mapping) -> WhereBin:
        return cls(d["dimension"], d["bin"], d["share"], d["share_std"], d["mse"], d["samples"])


@dataclass(frozen=True)
class EffectRow:
    """One library effect added to a round's baseline and refitted, or the reason its fit failed (``error``;
    then every other field is None)."""

    name: str
    shrink: float | None = None              # fraction of the gap it closes; None: no gap, or at the floor already
    mse_validation_after: float | None = None
    mse_train_after: float | None = None
    p_value: float | None = None             # Wald test of what it adds; None: not estimable
    overlap: float | None = None             # histogram intersection of gap and improvement shares (NaN: none)
    acts_in: Mapping[str, str] | None = None  # dimension -> the bin where it improves the fit most
    at_floor: bool | None = None
    model: str | None = None                 # the baseline with the effect added
    error: str | None = None
    # the move that made it (discovery.moves): its kind, the effect library's name when it equals one, the
    # search's verdict, and the adoption test (discovery.adoption.MoveTest.to_dict())
    kind: str | None = None
    effect: str | None = None
    verdict: str | None = None
    test: Mapping[str, Any] | None = None

    @property
    def failed(self) -> bool:
        return self.error is not None

    def to_dict(self) -> dict:
        move = {"kind": self.kind, "effect": self.effect, "verdict": self.verdict,
                "test": dict(self.test) if self.test is not None else None}
        if self.failed:
            return {"name": self.name, "error": self.error, **move}
        return {"name": self.name, "shrink": self.shrink, "mse_validation_after": self.mse_validation_after,
                "mse_train_after": self.mse_train_after, "p_value": self.p_value, "overlap": self.overlap,
                "acts_in": dict(self.acts_in or {}), "at_floor": self.at_floor, "model": self.model, **move}

    @classmethod
    def from_dict(cls, d: Mapping) -> EffectRow:
        move = {"kind": d.get("kind"), "effect": d.get("effect"), "verdict": d.get("verdict"), "test": d.get("test")}
        if "error" in d:
            return cls(d["name"], error=d["error"], **move)
        return cls(d["name"], d["shrink"], d["mse_validation_after"], d["mse_train_after"], d["p_value"],
                   d["overlap"], dict(d["acts_in"] or {}), d["at_floor"], d["model"], **move)


@dataclass(frozen=True)
class Round:
    """One round: the baseline's gap, where it lies, every applicable effect (best first, failures last) and the
    effect adopted (None: the diagnosis stops here). ``noise_floor`` and ``gap`` use the diagnosis' final floor,
    the lowest of everything fitted in every round; ``noise_floor_round`` is the lowest of this round's."""

    baseline: str
    mse: TrainValidation
    noise_floor_round: float
    floor_source: str
    noise_floor_spectral: float
    gap_se: float
    where: tuple[WhereBin, ...]
    effects: tuple[EffectRow, ...]
    explained_before: bool
    excess_over_floor: float
    excess_se: float
    gap_p_value: float | None
    adopted: str | None
    noise_floor: float
    gap: float

    @property
    def best(self) -> EffectRow | None:
        """The first effect that was fitted (None when all failed)."""
        return next((e for e in self.effects if not e.failed), None)

    def effect(self, name: str) -> EffectRow | None:
        return next((e for e in self.effects if e.name == name), None)

    def to_dict(self) -> dict:
        return {"baseline": self.baseline, "mse": self.mse.to_dict(), "noise_floor_round": self.noise_floor_round,
                "floor_source": self.floor_source, "noise_floor_spectral": self.noise_floor_spectral,
                "gap_se": self.gap_se, "where": [w.to_dict() for w in self.where],
                "effects": [e.to_dict() for e in self.effects], "explained_before": self.explained_before,
                "excess_over_floor": self.excess_over_floor, "excess_se": self.excess_se,
                "gap_p_value": self.gap_p_value, "adopted": self.adopted, "noise_floor": self.noise_floor,
                "gap": self.gap}

    @classmethod
    def from_dict(cls, d: Mapping) -> Round:
        return cls(d["baseline"], TrainValidation.from_dict(d["mse"]), d["noise_floor_round"], d["floor_source"],
                   d["noise_floor_spectral"], d["gap_se"], tuple(WhereBin.from_dict(w) for w in d["where"]),
                   tuple(EffectRow.from_dict(e) for e in d["effects"]), d["explained_before"],
                   d["excess_over_floor"], d["excess_se"], d["gap_p_value"], d["adopted"], d["noise_floor"],
                   d["gap"])


@dataclass(frozen=True)
class SignalShare:
    """A measured signal a gap follows: the share of the gap a function of it alone removes on the validation
    maneuvers, and its permutation importance in the flexible model (None: the model removed nothing)."""

    name: str
    share: float
    importance: float | None

    def to_dict(self) -> dict:
        return {"name": self.name, "share": self.share, "importance": self.importance}

    @classmethod
    def from_dict(cls, d: Mapping) -> SignalShare:
        return cls(d["name"], d["share"], d.get("importance"))


@dataclass(frozen=True)
class PartialDependence:
    """The residual against one signal: the function fitted on the training maneuvers at its bin centres, and
    the validation maneuvers' mean residual per bin."""

    name: str
    x: tuple[float, ...]
    fitted: tuple[float, ...]
    validation_x: tuple[float, ...]
    validation_mean: tuple[float, ...]

    def to_dict(self) -> dict:
        return {"name": self.name, "x": list(self.x), "fitted": list(self.fitted),
                "validation_x": list(self.validation_x), "validation_mean": list(self.validation_mean)}

    @classmethod
    def from_dict(cls, d: Mapping) -> PartialDependence:
        return cls(d["name"], tuple(d["x"]), tuple(d["fitted"]), tuple(d["validation_x"]),
                   tuple(d["validation_mean"]))


@dataclass(frozen=True)
class TopBins:
    """The phase and alpha band holding the largest share of an excess."""

    phase: str
    alpha_band: str

    def to_dict(self) -> dict:
        return {"phase": self.phase, "alpha_band": self.alpha_band}

    @classmethod
    def from_dict(cls, d: Mapping | None) -> TopBins | None:
        return None if d is None else cls(d["phase"], d["alpha_band"])


@dataclass(frozen=True)
class Unexplained:
    """The docs/interfaces.md 5.4 ``unexplained`` block: what the library leaves of the gap above the
    library-free floor (``share``; None without a gap), the signals the rest follows, where it sits."""

    noise_floor: float
    flexible_iterations: int
    share: float | None
    signals: tuple[SignalShare, ...] = ()
    gap_signals: tuple[SignalShare, ...] = ()
    where: TopBins | None = None
    partial_dependence: tuple[PartialDependence, ...] = ()
    note: str | None = None

    def to_dict(self) -> dict:
        out = {"noise_floor": self.noise_floor, "flexible_iterations": self.flexible_iterations,
               "share": self.share, "signals": [s.to_dict() for s in self.signals],
               "gap_signals": [s.to_dict() for s in self.gap_signals],
               "where": None if self.where is None else self.where.to_dict(),
               "partial_dependence": [p.to_dict() for p in self.partial_dependence]}
        if self.note is not None:
            out["note"] = self.note
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> Unexplained:
        return cls(d["noise_floor"], d["flexible_iterations"], d["share"],
                   tuple(SignalShare.from_dict(s) for s in d["signals"]),
                   tuple(SignalShare.from_dict(s) for s in d["gap_signals"]), TopBins.from_dict(d["where"]),
                   tuple(PartialDependence.from_dict(p) for p in d["partial_dependence"]), d.get("note"))


@dataclass(frozen=True)
class StateRms:
    """One value per replayed state (an RMS error, or its relative reduction)."""

    alpha: float
    q: float
    V: float
    theta: float

    def __getitem__(self, state: str) -> float:
        if state not in STATES:
            raise KeyError(state)
        return getattr(self, state)

    def to_dict(self) -> dict:
        return {s: getattr(self, s) for s in STATES}

    @classmethod
    def from_dict(cls, d: Mapping) -> StateRms:
        return cls(*(d[s] for s in STATES))


@dataclass(frozen=True)
class Divergence:
    """A replay that left the flight: the maneuver, the time into it (s) and why."""

    maneuver: str
    t: float
    why: str

    def to_dict(self) -> dict:
        return {"maneuver": self.maneuver, "t": self.t, "why": self.why}

    def words(self) -> str:
        return f"{self.maneuver} at {self.t:.1f} s ({self.why})"


@dataclass(frozen=True)
class StateLevel:
    """The forward-simulated state error on the validation maneuvers before and after the first adopted effect,
    or why it could not be computed (``error``; then the other fields are None)."""

    before: StateRms | None = None
    after: StateRms | None = None
    window_s: float | None = None
    reduction: StateRms | None = None
    error: str | None = None
    # replays that diverged, left out of the RMS (:func:`structsearch.diagnosis.state_level.divergence`)
    diverged_before: tuple[Divergence, ...] = ()
    diverged_after: tuple[Divergence, ...] = ()

    @property
    def failed(self) -> bool:
        return self.error is not None

    def to_dict(self) -> dict:
        if self.failed:
            return {"error": self.error}
        return {"before": self.before.to_dict(), "after": self.after.to_dict(), "window_s": self.window_s,
                "reduction": self.reduction.to_dict(),
                "diverged": {"before": [d.to_dict() for d in self.diverged_before],
                             "after": [d.to_dict() for d in self.diverged_after]}}

    @classmethod
    def from_dict(cls, d: Mapping) -> StateLevel:
        if "error" in d:
            return cls(error=d["error"])
        gone = d.get("diverged") or {}
        return cls(StateRms.from_dict(d["before"]), StateRms.from_dict(d["after"]), d["window_s"],
                   StateRms.from_dict(d["reduction"]),
                   diverged_before=tuple(Divergence(**x) for x in gone.get("before", ())),
                   diverged_after=tuple(Divergence(**x) for x in gone.get("after", ())))

    def words(self) -> str:
        """The replay comparison in words: the RMS alpha error before and after, and the replays that diverged."""
        if self.failed:
            return f"the state-level replay failed: {self.error}"
        text = f"replayed alpha RMS {self.before.alpha:.4f} -> {self.after.alpha:.4f} rad with the first effect"
        for label, gone in (("before", self.diverged_before), ("after", self.diverged_after)):
            if gone:
                text += (f"; the replay {label} it diverged on {len(gone)} maneuver(s), left out of both: "
                         + ", ".join(d.words() for d in gone[:3]) + (", ..." if len(gone) > 3 else ""))
        return text


@dataclass(frozen=True, kw_only=True)   # twenty fields: built by keyword, never by position
class Diagnosis:
    """The diagnosis of one coefficient's baseline (docs/interfaces.md sections 3 and 5.4). The top-level
    ``mse``, ``where``, ``effects`` and ``noise_floor_spectral`` are the first round's; ``state_level`` is None
    when it was not asked for or no effect was adopted."""

    coefficient: str
    baseline: str
    noise_floor: float
    floor_source: str
    noise_floor_library: float
    explained: bool
    final_excess_over_floor: float
    final_excess_se: float
    rounds: tuple[Round, ...]
    final_model: str
    final_mse: float
    unexplained: Unexplained
    warnings: tuple[str, ...] = ()
    state_level: StateLevel | None = None
    seconds: float = field(default=float("nan"), compare=False)
    # the structure reached (Candidate.to_dict(): terms, states, lift model), the structure search's numbers
    final_structure: Mapping[str, Any] | None = None
    search: Mapping[str, Any] | None = None
    # why the baseline, as fitted on this campaign, is not admissible by the ranking's rules (empty: it is); a
    # story told from a degenerate fit says so (issue 31)
    baseline_reasons: tuple[str, ...] = ()
    # the anomalies the terms it added are also the first-order signature of (.equivalence)
    equivalences: tuple[Equivalence, ...] = ()
    # a simulator as the baseline (.offset.simulator_record): what it is, its own MSE and the bias the search
    # started from; None when the baseline is one of our own structures
    simulator: Mapping[str, Any] | None = None

    @property
    def baseline_admissible(self) -> bool:
        return not self.baseline_reasons

    def closes(self, round_index: int, effect: EffectRow | None) -> float:
        """The share of the baseline's gap (its validation MSE above the noise floor) that ``effect``, tried in
        round ``round_index``, closes: the one definition of "closes" in every story and diagnosis text
        (negative: it costs). NaN when there is no gap or no effect. The JSON's ``shrink`` is the share of the
        round's own gap, capped to [0, 1] (docs/interfaces.md section 3)."""
        gap = self.first.mse.validation - self.noise_floor
        if effect is None or effect.failed or not gap > 0:
            return float("nan")
        return (self.rounds[round_index].mse.validation - effect.mse_validation_after) / gap

    @property
    def first(self) -> Round:
        return self.rounds[0]

    @property
    def mse(self) -> TrainValidation:
        return self.first.mse

    @property
    def where(self) -> tuple[WhereBin, ...]:
        return self.first.where

    @property
    def effects(self) -> tuple[EffectRow, ...]:
        return self.first.effects

    @property
    def noise_floor_spectral(self) -> float:
        return self.first.noise_floor_spectral

    @property
    def gap_explained_by_baseline(self) -> bool:
        """Whether the baseline itself is at the floor (the first round's verdict)."""
        return self.first.explained_before

    @property
    def best_effect(self) -> EffectRow | None:
        """The first round's best fitted effect (None when every fit failed)."""
        return self.first.best

    def to_dict(self) -> dict[str, Any]:
        out = {"coefficient": self.coefficient, "baseline": self.baseline, "mse": self.mse.to_dict(),
               "noise_floor": self.noise_floor, "floor_source": self.floor_source,
               "noise_floor_library": self.noise_floor_library, "noise_floor_spectral": self.noise_floor_spectral,
               "where": [w.to_dict() for w in self.where], "effects": [e.to_dict() for e in self.effects],
               "explained": self.explained, "gap_explained_by_baseline": self.gap_explained_by_baseline,
               "final_excess_over_floor": self.final_excess_over_floor, "final_excess_se": self.final_excess_se,
               "rounds": [r.to_dict() for r in self.rounds], "final_model": self.final_model,
               "final_mse": self.final_mse, "unexplained": self.unexplained.to_dict(),
               "warnings": list(self.warnings), "baseline_admissible": self.baseline_admissible,
               "baseline_reasons": list(self.baseline_reasons),
               "equivalences": [e.to_dict() for e in self.equivalences]}
        if self.simulator is not None:
            out["simulator"] = dict(self.simulator)
        if self.state_level is not None:
            out["state_level"] = self.state_level.to_dict()
        if self.final_structure is not None:
            out["final_structure"] = dict(self.final_structure)
        if self.search is not None:
            out["search"] = dict(self.search)
        out["seconds"] = self.seconds
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> Diagnosis:
        """A diagnosis read back from its document (``mse``, ``where``, ``effects``, ``noise_floor_spectral`` and
        ``gap_explained_by_baseline`` are taken from its first round)."""
        sl = d.get("state_level")
        return cls(coefficient=d["coefficient"], baseline=d["baseline"], noise_floor=d["noise_floor"],
                   floor_source=d["floor_source"], noise_floor_library=d["noise_floor_library"],
                   explained=d["explained"], final_excess_over_floor=d["final_excess_over_floor"],
                   final_excess_se=d["final_excess_se"], rounds=tuple(Round.from_dict(r) for r in d["rounds"]),
                   final_model=d["final_model"], final_mse=d["final_mse"],
                   unexplained=Unexplained.from_dict(d["unexplained"]), warnings=tuple(d.get("warnings", ())),
                   state_level=None if sl is None else StateLevel.from_dict(sl),
                   seconds=d.get("seconds", float("nan")), final_structure=d.get("final_structure"),
                   search=d.get("search"), baseline_reasons=tuple(d.get("baseline_reasons", ())),
                   equivalences=tuple(Equivalence.from_dict(e) for e in d.get("equivalences", ())),
                   simulator=d.get("simulator"))
