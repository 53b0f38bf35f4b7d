"""The thesis' comparison tables regenerated on a campaign (issue 16): the legacy estimator against SNLS on Van
Ingen's structures (Table 7), final models against Van Ingen's (as published and refitted), the dynamic-stall identifiability study, the separation grid as a 3 x 3 matrix, the
final lift model's derived quantities and the collinearity of its regressors, and the final structures fitted
jointly against sequentially (issue 29). Numerics only; the tables are
rendered by :mod:`structsearch.reporting.study_doc`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from ..flight.reference import FINAL_MODEL_NAMES, VAN_INGEN_LIFT, VAN_INGEN_MODEL_NAMES, van_ingen_lift_model
from ..fitting.models import build_model
from ..fitting.fitter import Fitter
from ..fitting.specs import load_grid
from .comparison import CoefficientScores, score_set
from .derived import Collinearity, DerivedQuantity, collinearity, physical_quantities, separation_matrix
from .dynamic_stalls import DynamicStallStudy, dynamic_stall_study
from .joint_comparison import JointComparison, compare_joint
from .legacy import EstimatorComparison, compare_estimators
from .search_tables import ThesisTable, thesis_table
from .model_set import fit_model_set

FINAL = "final"
VAN_INGEN_REFITTED = "Van Ingen (refitted)"
VAN_INGEN_PUBLISHED = "Van Ingen (published)"


@dataclass(frozen=True)
class Study:
    models: Mapping[str, Mapping[str, str]]        # label -> coefficient -> structure
    scores: tuple[CoefficientScores, ...]
    dynamic_stalls: DynamicStallStudy
    separation_kinds: tuple[str, ...]
    separation_mse: tuple[tuple[float, ...], ...]   # rows X_ss kind, columns X_w kind (training MSE)
    derived: tuple[DerivedQuantity, ...]
    collinearity: Collinearity
    estimators: EstimatorComparison
    search_tables: tuple[ThesisTable, ...]
    joint: JointComparison | None = None     # the final structures fitted jointly against sequentially

    def to_dict(self) -> dict:
        """Everything the study holds as plain JSON values (NaN where a number could not be computed; write it
        through ``structsearch.data.atomic.json_ready`` for null)."""
        return {"models": {label: dict(m) for label, m in self.models.items()},
                "scores": [s.to_dict() for s in self.scores],
                "dynamic_stalls": self.dynamic_stalls.to_dict(),
                "separation": {"kinds": list(self.separation_kinds),
                               "training_mse": [list(row) for row in self.separation_mse]},
                "derived": [d.to_dict() for d in self.derived],
                "collinearity": self.collinearity.to_dict(),
                "estimators": self.estimators.to_dict(),
                "search_tables": [t.to_dict() for t in self.search_tables],
                "joint": None if self.joint is None else self.joint.to_dict()}


def run_study(fitter: Fitter) -> Study:
    """Everything the study tables hold; fits go through ``fitter``'s cache (a search of the same campaign with
    the same options makes them instant)."""
    campaign, options, say = fitter.campaign, fitter.options, fitter.say
    say("study: the final model set")
    final = fit_model_set(FINAL, FINAL_MODEL_NAMES, fitter)
    say("study: the final structures fitted jointly")
    joint = compare_joint(final, campaign, options)
    say("study: Van Ingen's structures refitted")
    refitted = fit_model_set(VAN_INGEN_REFITTED, VAN_INGEN_MODEL_NAMES, fitter)
    published = van_ingen_lift_model()
    scores = (score_set(FINAL, lambda c, d: final.predict(c, d), campaign)
              + score_set(VAN_INGEN_REFITTED, lambda c, d: refitted.predict(c, d), campaign)
              # only the lift model's values are published (docs/catalogue.md section 6)
              + score_set(VAN_INGEN_PUBLISHED,
                          lambda c, d: published.predict(d, VAN_INGEN_LIFT) if c == "CL" else None, campaign))
    say("study: the separation grid")
    separation = fitter.fit(load_grid("separation").candidates)
    kinds, matrix = separation_matrix(separation)
    say("study: the lift, drag and pitch grids in the thesis' layout")
    lift_grid = load_grid("lift")
    tables = []
    for name in ("lift", "drag", "pitch"):
        grid = lift_grid if name == "lift" else load_grid(name, lift_grid)
        # the grid's candidates take the final lift model's states, Van Ingen's drag and pitch his lift's
        lifts = {ms.candidates["CL"].name: ms.lift for ms in (final, refitted)}
        results = (fitter.with_lifts(lifts) if name != "lift" else fitter).fit(grid.candidates)
        coefficient = grid.candidates[0].coefficient
        tables.append(thesis_table(name, grid.candidates, results, refitted.summaries[coefficient]))
    say("study: CL-VI with and without the dynamic stalls")
    dynamic = dynamic_stall_study(campaign, FINAL_MODEL_NAMES["CL"], options)
    train = campaign.split("train")
    lift = final.summaries["CL"]
    derived = physical_quantities(dict(lift.estimates.params), train)
    coll = collinearity(build_model(final.candidates["CL"]), dict(lift.estimates.params), train)
    estimators = compare_estimators(campaign, dict(VAN_INGEN_MODEL_NAMES), n_starts=options.n_starts,
                                    seed=options.seed, progress=say)
    models = {FINAL: dict(FINAL_MODEL_NAMES), VAN_INGEN_REFITTED: dict(VAN_INGEN_MODEL_NAMES),
              VAN_INGEN_PUBLISHED: {"CL": VAN_INGEN_MODEL_NAMES["CL"]}}
    return Study(models, tuple(scores), dynamic, kinds, matrix, tuple(derived), coll, estimators, tuple(tables),
                 joint)
