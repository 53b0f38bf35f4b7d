"""``structsearch fit --by-kind``: a global model fitted on stall and nominal maneuvers together, against the models
fitted to each kind alone, every one validated on the same held-out maneuvers, nominal and stall apart.

Three fits per model, each on its own campaign whose validation maneuvers are all of the original's:

* ``all``: the global model on every training maneuver;
* ``stall``: its stall part (:func:`structsearch.fitting.regimes.stall_part`) on the stall training maneuvers;
* ``nominal``: its attached-flow part (:func:`structsearch.fitting.regimes.attached_part`) on the nominal ones.

A drag or pitch model reads the C_L and the states of the lift model fitted the same way: the global lift, that
lift's stall part or its attached-flow part (whose states are all 1). None reads the measured C_L, which carries
each maneuver's own measurement noise (correlated with that of C_D and C_m): the three fits differ in the
maneuvers they learn from, never in what a prediction reads.
"""
from __future__ import annotations

import os
from typing import Sequence

from ..data.campaign import REGIMES, Campaign, regime
from ..data.errors import DataError, DeclarationError
from ..fitting.by_kind import ByKind, KindComparison, RegimeFit, regime_mse
from ..fitting.candidates import Candidate
from ..fitting.lift_fit import LiftFit
from ..fitting.options import check_box_names
from ..fitting.regimes import Part, attached_part, stall_part
from .settings import as_campaign
from .settings import Settings, command_fitter


def fit_by_kind(campaign: Campaign | str | os.PathLike, models: str | Sequence[str], *,
                settings: Settings = Settings(), out: str | os.PathLike | None = None) -> ByKind:
    """Fit each of ``models`` (global model names, "CL-G,CD-G,Cm-G" or a list) as ``fit --by-kind`` does; the fits
    are cached under ``settings.cache`` (default ``out``, else a temporary directory)."""
    from ..fitting.specs import lift_candidate, resolve_candidate
    names = [n.strip() for n in (models.split(",") if isinstance(models, str) else models) if n.strip()]
    if not names:
        raise DeclarationError("--by-kind needs at least one model (--model CL-G,CD-G,Cm-G)")
    candidates = [resolve_candidate(n) for n in names]
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    _check_regimes(campaign)
    check_box_names(settings.boxes(), candidates)
    say = settings.progress
    validation_kinds = [m.kind for m in campaign.maneuvers if m.split == "validation"]
    variants = {"all": campaign,
                "stall": campaign.keeping(lambda m: m.split == "validation" or regime(m.kind) == "stall"),
                "nominal": campaign.keeping(lambda m: m.split == "validation" or regime(m.kind) == "nominal")}
    fits: dict[str, list[RegimeFit]] = {c.name: [] for c in candidates}
    for fitted_on, data in variants.items():
        if say is not None:
            say(f"fit --by-kind: {', '.join(names)} on the {_maneuvers(fitted_on)}")
        train = data.split("train")
        n_train = sum(m.split == "train" for m in data.maneuvers)
        with command_fitter("fit", data, settings, out) as fitter:
            lifts: dict[str, LiftFit] = {}
            for c in candidates:
                lift = lift_candidate(c.lift) if c.lift else None
                part = _part(c, lift, fitted_on, train)
                if part.candidate.lift and part.candidate.lift not in lifts:
                    lift_part = _part(lift, None, fitted_on, train)
                    lifts[part.candidate.lift] = LiftFit(lift_part.candidate,
                                                         _fitted(fitter, lift_part.candidate, lifts))
                result = _fitted(fitter, part.candidate, lifts)
                fits[c.name].append(RegimeFit(fitted_on, part, result, regime_mse(result, validation_kinds),
                                              n_train))
    held_out = {w: tuple(m.id for m in campaign.maneuvers if m.split == "validation" and regime(m.kind) == w)
                for w in REGIMES}
    return ByKind(tuple(KindComparison(c.name, c.coefficient, tuple(fits[c.name])) for c in candidates), held_out)


def _part(c: Candidate, lift: Candidate | None, fitted_on: str, train) -> Part:
    """The model fitted on ``fitted_on``'s training maneuvers: the global one, its stall or its attached part."""
    if fitted_on == "all":
        return Part(c)
    if fitted_on == "stall":
        return stall_part(c, train, f"{c.lift}.stall" if c.lift else None)
    return attached_part(c, lift, f"{c.lift}.nominal" if c.lift else None)


def _fitted(fitter, candidate: Candidate, lifts: dict):
    result = fitter.with_lifts(lifts).fit_one(candidate)
    if result.failed:
        raise DeclarationError(f"fit --by-kind: fitting {candidate.name} failed: {result.error}")
    return result


def _maneuvers(fitted_on: str) -> str:
    return {"all": "training maneuvers of both kinds", "stall": "stall training maneuvers",
            "nominal": "nominal training maneuvers (attached-flow parts)"}[fitted_on]


def _check_regimes(campaign: Campaign) -> None:
    """Both regimes in both splits, else one error naming what is missing."""
    for which in REGIMES:
        for split in ("train", "validation"):
            if not any(m.split == split and regime(m.kind) == which for m in campaign.maneuvers):
                raise DataError(f"--by-kind needs {which} maneuvers among the {split} maneuvers and the campaign has "
                                f"none (nominal maneuvers: kind = \"nominal\"; simulate --nominal writes them)",
                                source=str(campaign.directory / "campaign.toml") if campaign.directory
                                else campaign.name, column="kind")
