"""``structsearch export``: a fitted model handed to a simulator (docs/interfaces.md 7.6).

The model comes from a fit directory (its ``fit.json``, single or joint, and the campaign it names) or is fitted
here as ``fit`` fits it (``--data DIR --model NAME[,NAME...]``; a drag or pitch model brings the lift model it
reads). :mod:`structsearch.export` renders it; ``check=True`` drives JSBSim with the campaign's maneuvers and
compares with structsearch's own prediction of the same fit (:func:`structsearch.fitting.models.predict_candidate`).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..data.campaign import Campaign, read_campaign
from ..data.coefficients import coefficient as coefficient_record
from ..data.errors import DataError, DeclarationError
from ..engine.separation import SeparationState, evaluate_state
from ..export.card import (CoefficientModel, ExportedModel, StateModel, aircraft_record, ordered, validity)
from ..fitting.candidates import Candidate
from ..fitting.lift_fit import LiftAt
from ..data.reading import inside, shown
from .fit_document import Fields, read_fit_json
from .results import campaign_record
from .settings import Settings, command_fitter


@dataclass(frozen=True)
class Fitted:
    """One fitted structure as an export reads it: its candidate, every parameter's value (a drag or pitch
    model's own, its states' come from the lift), standard deviations, covariance (None: not recorded, with
    ``note``) and residual standard deviation on the training maneuvers."""

    candidate: Candidate
    params: Mapping[str, float]
    stderr: Mapping[str, float | None]
    covariance_names: tuple[str, ...] = ()
    covariance: np.ndarray | None = None
    residual_sd: float | None = None
    note: str = ""


@dataclass(frozen=True)
class ExportOutcome:
    """What ``export`` wrote: the model, the files and (``check=True``) the JSBSim check."""

    model: ExportedModel
    written: tuple[Path, ...]
    check: object | None = None      # structsearch.export.check.CheckReport


# ----- where the model comes from --------------------------------------------------------------------------
def _model_names(models: str | Sequence[str]) -> list[Candidate]:
    from ..fitting.specs import resolve_candidate
    names = [n.strip() for n in (models.split(",") if isinstance(models, str) else models) if n.strip()]
    if not names:
        raise DeclarationError("--model: name at least one model (CL-VI or CL-VI,CD-IXr,Cm-XXXIIIr)")
    candidates = [resolve_candidate(n) for n in names]
    coefficients = [c.coefficient for c in candidates]
    for c in candidates:
        if coefficients.count(c.coefficient) > 1:
            raise DeclarationError(f"--model: two models of {c.coefficient} ({', '.join(names)})")
    return candidates


def _lift_of(candidates: Sequence[Candidate]) -> Candidate:
    """The lift structure of an export: the one named, else the one drag and pitch read (the same for both)."""
    from ..fitting.specs import load_grid
    named = [c for c in candidates if coefficient_record(c.coefficient).owns_states]
    read = {c.lift for c in candidates if c.lift}
    if len(read) > 1:
        raise DeclarationError(f"--model: the drag and pitch models read different lift models ({', '.join(sorted(read))}); "
                               "an export has one lift model")
    if named and read and named[0].name not in read:
        raise DeclarationError(f"--model: {next(c.name for c in candidates if c.lift)} reads the lift model "
                               f"{read.pop()}, not {named[0].name}")
    return named[0] if named else load_grid("lift")[read.pop()]


def _from_result(candidate: Candidate, result) -> Fitted:
    e = result.estimates
    return Fitted(candidate, dict(e.params), dict(e.stderr), tuple(e.names), np.asarray(e.covariance, float),
                  math.sqrt(result.mse_train) if np.isfinite(result.mse_train) else None)


def fitted_from_data(campaign: Campaign, candidates: Sequence[Candidate], settings: Settings) -> list[Fitted]:
    """Fit the lift model and then the drag and pitch models on the training maneuvers, as ``fit`` does."""
    from ..fitting.lift_fit import LiftFit
    from ..fitting.options import check_box_names
    from .settings import fit_options
    lift = _lift_of(candidates)
    others = [c for c in candidates if c.coefficient != "CL"]
    check_box_names(fit_options("fit", settings, campaign).parameter_boxes, [lift, *others])
    with command_fitter("fit", campaign, settings) as fitter:
        lift_result = fitter.fit_one(lift)
        if lift_result.failed:
            raise DeclarationError(f"fitting {lift.name} failed: {lift_result.error}")
        out = [_from_result(lift, lift_result)]
        with_lift = fitter.with_lifts({lift.name: LiftFit(lift, lift_result)})
        for c in others:
            result = with_lift.fit_one(c)
            if result.failed:
                raise DeclarationError(f"fitting {c.name} failed: {result.error}")
            out.append(_from_result(c, result))
    return out


def read_fit_directory(directory: str | os.PathLike) -> tuple[list[Fitted], dict]:
    """The structures of a fit directory's ``fit.json`` (single or joint) and its ``data`` record, every field
    checked for its type (:mod:`.fit_document`)."""
    path = Path(directory) / "fit.json"
    if not os.path.lexists(path):
        raise DataError("no fit.json here: --fit takes the --out directory of `structsearch fit`",
                        source=str(path))
    doc = read_fit_json(inside(directory, "fit.json", str(path)))   # a link out of the directory is refused unread
    if not isinstance(doc, dict):
        raise DataError(f"not a fit document (a JSON object), but {shown(doc)}", source=str(path))
    fields = Fields(path)
    fitted = _joint_fitted(doc, fields) if doc.get("joint") else _single_fitted(doc, fields)
    data = doc.get("data")
    if not isinstance(data, dict) or not data.get("source"):
        raise DataError("fit.json does not name the campaign it was fitted on (a fit of an older version, or of a "
                        "campaign in memory): export with --data DIR --model NAME", source=str(path))
    fields.string(data, "source", "data.")
    if data.get("digest") is not None:
        fields.string(data, "digest", "data.")
    for f in fitted:
        _complete(f, fields)
    return fitted, data


def _complete(f: Fitted, fields: Fields) -> None:
    """Every parameter an export writes is in the document: each regressor's, and a lift model's states'."""
    needed = [name for name, _ in f.candidate.regressors]
    if coefficient_record(f.candidate.coefficient).owns_states:
        needed += list(f.candidate.state_parameters)
    missing = [p for p in needed if p not in f.params]
    if missing:
        fields.fail(f"params.{missing[0]}", f"missing: {f.candidate.name} has the parameter {missing[0]!r}")


def _candidate(entry: Mapping, fields: Fields, where: str = "") -> Candidate:
    from ..fitting.specs import resolve_candidate
    if entry.get("structure"):
        return fields.structure(entry, where)
    return resolve_candidate(fields.string(entry, "model", where))


def _single_fitted(doc: Mapping, fields: Fields) -> list[Fitted]:
    c = _candidate(doc, fields)
    names, matrix = fields.covariance(doc)
    own = Fitted(c, fields.numbers(doc, "params"), fields.optional_numbers(doc, "stderr"), names, matrix,
                 _sd(fields.number(doc.get("mse", {}).get("train") if isinstance(doc.get("mse"), dict) else None,
                                   "mse.train")),
                 "" if matrix is not None else "fit.json records no covariance matrix (a fit of an older version)")
    if coefficient_record(c.coefficient).owns_states or not doc.get("lift"):
        return [own]
    lift = fields.table(doc, "lift")
    lift_c = _candidate(lift, fields, "lift.")
    return [Fitted(lift_c, fields.numbers(lift, "params", "lift."), {},
                   note=f"the fit of {c.name} records its lift model's estimates only: fit the lift model for its "
                        "statistics"), own]


def _joint_fitted(doc: Mapping, fields: Fields) -> list[Fitted]:
    from ..fitting.specs import resolve_candidate
    names, matrix = fields.covariance(doc)
    out = []
    for coef, entry in fields.table(doc, "coefficients").items():
        where = f"coefficients.{coef}."
        if not isinstance(entry, dict):
            fields.fail(where[:-1], f"must be a table, not {shown(entry)}")
        c = resolve_candidate(fields.string(entry, "model", where))
        params = fields.numbers(entry, "parameters", where)
        keep = [i for i, n in enumerate(names) if n in params]
        mse = fields.table(entry, "mse", where)
        out.append(Fitted(c, params, fields.optional_numbers(entry, "stderr", where), tuple(names[i] for i in keep),
                          None if matrix is None else matrix[np.ix_(keep, keep)],
                          _sd(fields.number(mse.get("train"), f"{where}mse.train")),
                          "" if matrix is not None else "fit.json records no covariance matrix (a fit of an older "
                                                        "version)"))
    return out


def _sd(mse) -> float | None:
    return math.sqrt(mse) if mse is not None and math.isfinite(mse) and mse >= 0 else None


def _campaign_of(data: Mapping, settings: Settings) -> Campaign:
    """The campaign a fit directory's ``data`` names, checked against its digest."""
    from ..fitting.runner import campaign_fingerprint
    source = data["source"]
    if not Path(source).is_dir():
        raise DataError("the campaign this fit was fitted on is not there any more", source=source)
    campaign = read_campaign(source, segment=settings.segment)
    if data.get("digest") and campaign_fingerprint(campaign) != data["digest"]:
        raise DataError("the campaign has changed since the fit (its digest differs): fit again", source=source)
    return campaign


# ----- the exported model ------------------------------------------------------------------------------------
def exported_model(fitted: Sequence[Fitted], campaign: Campaign, data: Mapping) -> ExportedModel:
    """The :class:`ExportedModel` of ``fitted`` (the lift model first) on ``campaign``."""
    from ..fitting.models import used_states
    for f in fitted:
        _check_exportable(f.candidate)
    lift = next(f for f in fitted if coefficient_record(f.candidate.coefficient).owns_states)
    states = tuple(StateModel(n, k, {p: lift.params[p] for p in SeparationState(n, k, lift.candidate.form_of(n)).parameters},
                              lift.candidate.form_of(n))
                   for n, k in lift.candidate.states)
    coefficients = []
    for f in fitted:
        linear = dict(f.candidate.regressors)
        symbols = tuple(SeparationState(n, k).symbol for n, k in
                        (f.candidate.states if coefficient_record(f.candidate.coefficient).owns_states
                         else used_states(f.candidate).items()))
        cov = None if f.covariance is None else tuple(tuple(float(v) for v in row) for row in f.covariance)
        coefficients.append(CoefficientModel(
            f.candidate.coefficient, f.candidate.name, tuple(linear.items()), {p: f.params[p] for p in linear},
            {p: _finite(f.stderr.get(p)) for p in f.params}, f.covariance_names, cov, f.note, f.residual_sd,
            symbols))
    train = campaign.split("train")
    return ExportedModel(ordered(coefficients), states, aircraft_record(campaign.aircraft, train),
                         validity(train), dict(data))


def _check_exportable(c: Candidate) -> None:
    """What an export cannot write yet is one error naming it, never a model that computes something else: a
    pitch model about a fixed reference point (its known transfer term reads the measured C_D) and a model with
    per-flight offsets (a simulator flies no recorded flight), and a lateral coefficient (C_Y is a body-axis force
    where JSBSim's SIDE axis is a wind axis, and the export writes the LIFT, DRAG and PITCH axes)."""
    if coefficient_record(c.coefficient).lateral:
        raise DeclarationError(f"{c.name}: {c.coefficient} is a lateral coefficient; export --format jsbsim writes the "
                               "LIFT, DRAG and PITCH axes (C_L, C_D, C_m) only")
    if c.moment_reference != "cg":
        raise DeclarationError(f"{c.name}: C_m about a fixed reference point cannot be exported yet (its transfer "
                               "term Cm_transfer is not written); export a model about the cg")
    if c.flight_effects:
        raise DeclarationError(f"{c.name}: per-flight offsets ({', '.join(c.flight_effects)}) belong to the "
                               "recorded flights, not to a simulator; export the model fitted without them")


def _finite(v) -> float | None:
    return None if v is None or not math.isfinite(float(v)) else float(v)


def _with_residual_sd(f: Fitted, fitted: Sequence[Fitted], campaign: Campaign) -> Fitted:
    """``f`` with its residual standard deviation on the training maneuvers computed from its estimates where its
    fit did not record one (the lift model a drag or pitch fit directory carries)."""
    if f.residual_sd is not None:
        return f
    import dataclasses
    train = campaign.split("train")
    if f.candidate.coefficient not in train:
        return f
    residual = train[f.candidate.coefficient] - _predictor(fitted, None)(train)[f.candidate.coefficient]
    return dataclasses.replace(f, residual_sd=float(np.sqrt(np.mean(residual ** 2))),
                               note=f.note + "; its residual standard deviation is recomputed on the training "
                                             "maneuvers from these estimates")


def _predictor(fitted: Sequence[Fitted], model: ExportedModel):
    """structsearch's own prediction of the fit: each coefficient by :func:`predict_candidate` (drag and pitch
    reading the lift model's output and states) and each state by the engine."""
    from ..fitting.models import predict_candidate
    lift = next(f for f in fitted if coefficient_record(f.candidate.coefficient).owns_states)
    lift_at = LiftAt(lift.candidate, dict(lift.params))

    def predict(data) -> dict[str, np.ndarray]:
        out = {}
        for f in fitted:
            out[f.candidate.coefficient] = predict_candidate(f.candidate, {**lift.params, **f.params}, data,
                                                             None if f is lift else lift_at)
        t, alpha, alpha_dot = data["t"], data["alpha"], data["alpha_dot"]
        for s in (model.states if model is not None else ()):
            out[s.symbol] = evaluate_state(SeparationState(s.name, s.kind), s.base(), alpha, alpha_dot, t,
                                           data.bounds, sensitivities=False)[0]
        return out
    return predict


def export(*, fit_dir: str | os.PathLike | None = None, campaign: Campaign | str | os.PathLike | None = None,
           models: str | Sequence[str] | None = None, fmt: str = "json", out: str | os.PathLike = "export",
           check: bool = False, settings: Settings = Settings()) -> ExportOutcome:
    """Export a fitted model as ``structsearch export`` does: from ``fit_dir`` (a fit's --out directory), or
    ``models`` fitted on ``campaign``; ``fmt`` "json" (model.json) or "jsbsim" (the JSBSim files); ``check``
    (jsbsim only) also writes check.json, JSBSim against structsearch on every maneuver and on static points."""
    from ..export.write import FORMATS, write_export
    if fmt not in FORMATS:
        raise DeclarationError(f"--format {fmt!r}: one of {', '.join(FORMATS)}")
    if check and fmt != "jsbsim":
        raise DeclarationError("--check drives the exported JSBSim files: it goes with --format jsbsim")
    if (fit_dir is None) == (campaign is None):
        raise DeclarationError("export takes either --fit DIR or --data DIR --model NAME")
    if check:
        from ..export.check import need_jsbsim
        need_jsbsim()
    if fit_dir is not None:
        if models is not None:
            raise DeclarationError("--model goes with --data (a fit directory names its own models)")
        fitted, data = read_fit_directory(fit_dir)
        the_campaign = _campaign_of(data, settings)
    else:
        if models is None:
            raise DeclarationError("--data needs --model NAME[,NAME...]")
        candidates = _model_names(models)    # a misspelled name is answered before the campaign is read
        from .settings import as_campaign
        the_campaign = as_campaign(campaign, settings.segment)
        fitted = fitted_from_data(the_campaign, candidates, settings)
        data = campaign_record(the_campaign)
    fitted = [_with_residual_sd(f, fitted, the_campaign) for f in fitted]
    model = exported_model(fitted, the_campaign, data)
    written = write_export(model, fmt, Path(out))
    report = None
    if check:
        from ..data.atomic import write_json
        from ..export.aircraft import aircraft_name
        from ..export.check import check as run_check
        report = run_check(model, Path(out).resolve(), aircraft_name(model), the_campaign.data,
                           _predictor(fitted, model))
        written.append(write_json(Path(out) / "check.json", report.to_dict()))
    return ExportOutcome(model, tuple(written), report)
