"""A drag or pitch grid with nothing admissible goes on by structure search too: from the minimal structure, fed the
lift model its best fit is fed (one of the lift grid's), and the admissible structures it fits are ranked beside
the grid as "discovered". A best fit fed a lift model outside the lift grid cannot be searched from: said, and the
ranking is left as it was."""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest
from conftest import fitter_for

from structsearch.api.fallback import discover_beside, needs_discovery
from structsearch.data.campaign import read_campaign
from structsearch.discovery.search_start import with_lift_models
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.specs import load_grid

sys.path.insert(0, str(Path(__file__).parent))
from airfoil_truths import TRUTHS, write_campaign  # noqa: E402


def _drag(lift: str) -> Candidate:
    feed = load_grid("lift")["CL-I"]
    return Candidate("CD-test", "drag", "CD", (("CD0", "1"), ("CD_alpha", "alpha")), feed.states, lift,
                     "a drag structure whose parabola is missing", feed.bounds, feed.forms)


def _fitted(tmp_path, said):
    campaign = read_campaign(write_campaign(TRUTHS["symmetric"], tmp_path / "campaign", seed=11))
    fitter = fitter_for(campaign, tmp_path / "cache", progress=said.append)
    declared = _drag("CL-I")
    fitter = with_lift_models(fitter, declared)
    ranked = [r.placed(admissible=False, reasons=("stated inadmissible for the test",))
              for r in fitter.quiet().fit([declared])]
    return fitter, declared, ranked


def test_a_best_fit_fed_a_lift_model_outside_the_lift_grid_is_not_searched_from_and_says_so(tmp_path):
    said = []
    fitter, declared, ranked = _fitted(tmp_path, said)
    assert needs_discovery(ranked) and not needs_discovery([ranked[0].placed(admissible=True)])
    foreign = [dataclasses.replace(ranked[0], lift="my-own-lift")]
    again, none = discover_beside(fitter, "drag", foreign, [declared], max_steps=1)
    assert again == foreign and none == []
    assert any("needs a lift model of the lift grid" in line and "my-own-lift" in line for line in said)


@pytest.mark.slow
def test_a_drag_grid_with_nothing_admissible_is_searched_on_fed_its_lift_model(tmp_path):
    """(130 s on 2 cores: the lift models fitted, then one step of the search with its floors.)"""
    said = []
    fitter, declared, ranked = _fitted(tmp_path, said)
    grown, found = discover_beside(fitter, "drag", ranked, [declared], max_steps=1)
    lifts = {c.name for c in load_grid("lift").candidates}
    assert found and all(c.coefficient == "CD" and c.lift in lifts and c.name.endswith("-auto") for c in found)
    discovered = [r for r in grown if r.placement.origin == "discovered"]
    assert discovered and all(r.placement.admissible for r in discovered)
    assert any("fed CL-I" in line for line in said)
    # the truth's drag is 0.01 + 0.8 alpha^2: a structure the search finds beats the one without the parabola
    assert min(r.comparison.mse for r in discovered) < ranked[0].comparison.mse

