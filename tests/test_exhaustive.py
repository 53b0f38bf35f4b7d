"""``discover --exhaustive``: every structure of the term library up to a number of terms, fitted as one grid.
Its size is what the binomial sums say; a structure has a state exactly when a term reads it; drag and pitch
structures are fed a lift model; on a pitching section whose truth is one lagged state without a constant
(simulated by scipy's Runge-Kutta, not by the engine), the truth's structure ranks first and no structure fits
worse than one it contains."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

from structsearch.data.errors import DeclarationError
from structsearch.discovery.exhaustive import count, library_terms, name_of, structures
from structsearch.discovery.terms import TermLibrary, shipped_terms
from structsearch.fitting.specs import load_grid

sys.path.insert(0, str(Path(__file__).parent))
from airfoil_truths import TRUTHS, write_campaign  # noqa: E402
from test_measured_data import assert_no_structure_fits_worse_than_one_it_contains  # noqa: E402


def test_the_grid_is_every_subset_of_the_library_up_to_its_size_with_every_kind_of_its_states():
    library = TermLibrary("CL", tuple(shipped_terms("CL")))
    terms = library_terms(library, None)
    assert len(terms) == 10                            # 8 templates, two of them on each of two states
    # 4 terms read X_ss (K_L, X*de) or X_w: a subset's structures are 3^(states it reads)
    on = {s: [t for t in terms if f"X_{s}" in t[1]] for s in ("ss", "w")}
    assert len(on["ss"]) == len(on["w"]) == 2
    one = 6 + 4 * 3
    assert count(terms, 1) == one
    grid = structures(library, 3)
    assert len(grid) == count(terms, 3) == len({c.name for c in grid})
    assert count(terms, 10, fed=True) == 2 ** 10 - 1
    for c in grid:
        read = {s for s in ("ss", "w") if any(f"X_{s}" in e for _, e in c.regressors)}
        assert {s for s, _ in c.states} == read and all(k in "SQU" for _, k in c.states)
        assert {n for n, _ in c.bounds} == {f"a_star_{s}" for s in read}
    kinds = {tuple(c.states) for c in grid if [n for n, _ in c.regressors] == ["CL_KL_ss", "CL_KL_w"]}
    assert len(kinds) == 9
    assert name_of("CL", (("CL0", "1"), ("CL_KL_w", "K_L(X_w)")), (("w", "U"),)) == "CL-E(CL0, CL_KL_w; X_w U)"


def test_drag_and_pitch_structures_are_fed_a_lift_model_and_lift_ones_are_not():
    lift = load_grid("lift")["CL-VI"]
    drag = structures(TermLibrary("CD", tuple(shipped_terms("CD"))), 2, lift)
    n = len(library_terms(TermLibrary("CD", tuple(shipped_terms("CD"))), lift))
    assert len(drag) == n + math.comb(n, 2)
    assert all(c.lift == "CL-VI" and c.states == lift.states for c in drag)
    with pytest.raises(DeclarationError, match="a lift model must feed"):
        structures(TermLibrary("CD", tuple(shipped_terms("CD"))), 2)
    with pytest.raises(DeclarationError, match="own their states"):
        structures(TermLibrary("CL", tuple(shipped_terms("CL"))), 2, lift)
    with pytest.raises(DeclarationError, match="at least 1"):
        structures(TermLibrary("CL", tuple(shipped_terms("CL"))), 0)


def test_the_truths_structure_ranks_first_and_none_fits_worse_than_one_it_contains(tmp_path, run_cli):
    data = write_campaign(TRUTHS["symmetric"], tmp_path / "campaign", seed=11)
    out = tmp_path / "exhaustive"
    done = run_cli("discover", "--data", data, "--coefficient", "CL", "--exhaustive", "--max-terms", "2",
                   "--out", out, "--jobs", "1", timeout=900)
    assert done.returncode == 0, done.stderr
    # no CT column: 9 terms; 5 read no state, 4 one state (3 kinds each); pairs: 10 of none, 20 x 3, 6 x 3 (same state
    # twice: K_L(X_ss) and X_ss de) and 4 x 9 (one term on each state)
    n = 5 + 4 * 3 + 10 + 20 * 3 + 2 * 3 + 4 * 9
    assert f"{n} structures of 1 to 2 of 9 terms" in done.stderr + done.stdout
    spec = out / "exhaustive_CL.toml"
    grid = load_grid(str(spec))
    assert len(grid.candidates) == n
    from structsearch.api import search
    from structsearch.api.settings import Settings
    ranked = search(data, str(spec), settings=Settings(jobs=1), out=out, refine=False).grids[grid.name]
    # the truth: C_L = CL_KL K_L(X), one U state breaking at 0.30 rad (inside X_w's box, not X_ss's)
    assert ranked[0].name == "CL-E(CL_KL_w; X_w U)" and ranked[0].placement.admissible
    assert assert_no_structure_fits_worse_than_one_it_contains(ranked, out, spec) > 0
    refused = run_cli("discover", "--data", data, "--coefficient", "CL", "--exhaustive", "--beam", "2",
                      "--out", tmp_path / "x")
    assert refused.returncode != 0 and "--beam belongs to the search move by move" in refused.stderr
