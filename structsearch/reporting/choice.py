"""Which structures a report shows: the rank-1 lift, drag and pitch structures of the user's own search
(``ranking.csv`` in the output directory, its refined "-auto" structures read back from ``refined_<grid>.toml``),
or the structures named on the command line; the thesis' final structures only where there is neither (a note
says so).

A drag or pitch winner is shown as it was ranked: on the lift model whose separation states it reads. When that
is not the lift winner, the answer shows it with its own lift model (a note names it) and the figures, which draw
one consistent set, draw that lift model with it (issue 43: the thesis' finals were swapped in silently).
"""
from __future__ import annotations

import csv
import dataclasses
import io
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

from ..data.campaign import Campaign
from ..data.coefficients import GRID_OF as _ALL_GRIDS, LIFT, LONGITUDINAL, coefficient
from ..data.errors import DataError, DeclarationError
from ..data.manifest import check_set
from ..data.reading import excerpt, inside, read_text
from ..fitting.candidates import Candidate
from ..fitting.specs import find_candidate, load_grid
from ..flight.reference import FINAL_MODEL_NAMES
from .refined import load_refined

# the report's first screen answers the longitudinal coefficients (the thesis' final structures stand in for one the
# search did not rank): their grids
GRID_OF = MappingProxyType({c: _ALL_GRIDS[c] for c in LONGITUDINAL})
ANSWERS_MAX_BYTES = 1 << 20   # a search's answers are a few hundred bytes a grid


@dataclass(frozen=True)
class Choice:
    """The structure shown per coefficient (``winners``: the answer), the consistent set the figures draw
    (``shown``: drag and pitch on its lift model; the winners themselves when they share the lift winner's
    states), where the winners come from (``source``, in words) and the notes on how they were chosen."""

    winners: Mapping[str, Candidate]
    shown: Mapping[str, Candidate]
    source: str
    notes: tuple[str, ...] = ()
    lifts: Mapping[str, Candidate] = field(default_factory=dict)   # a drag or pitch winner's lift model
    # per coefficient the search's answer (search_answer.json: docs/interfaces.md 8.1) where the winner is its
    # rank 1; absent where the structure was named on the command line or the search wrote no answer
    verdicts: Mapping[str, dict] = field(default_factory=dict)

    @property
    def names(self) -> dict[str, str]:
        return {coef: c.name for coef, c in self.shown.items()}


def resolver(out: Path):
    """A function from a structure's name to its candidate: a shipped one, or one the search in ``out`` reached
    by refinement."""
    refined = load_refined(out)

    def resolve(name: str) -> Candidate:
        if name in refined:
            return refined[name]
        try:
            return find_candidate(name)
        except DeclarationError:
            if name.endswith("-auto"):
                raise DataError(f"the search's {name} is a refined structure, and no refined_<grid>.toml in the "
                                "output directory declares it (a search older than that file): run the search "
                                "again", source=str(Path(out) / "ranking.csv")) from None
            raise
    return resolve


def ranked_rows(out: Path) -> dict[str, list[dict]] | None:
    """The rows of ``out/ranking.csv`` per grid, in rank order (None: there is no ranking)."""
    path = Path(out) / "ranking.csv"
    if not path.exists():
        return None
    # inside ``out`` (a link to elsewhere is refused unread), a regular UTF-8 file of bounded size, before its
    # manifest hashes it
    text = read_text(inside(out, "ranking.csv", str(path)))
    check_set(Path(out), "search", "ranking.csv")
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        missing = [c for c in ("grid", "model", "rank") if c not in (reader.fieldnames or ())]
        if missing:
            raise DataError("a search ranking needs this column", source=str(path), column=missing[0], row=1)
        rows = list(reader)
    except csv.Error as exc:
        raise DataError(f"not a CSV table: {excerpt(exc)}", source=str(path)) from None
    for i, row in enumerate(rows):
        if not all(isinstance(row.get(k), str) for k in ("grid", "model", "rank")):
            raise DataError("a row without its grid, model or rank", source=str(path), row=i + 2)
    by_grid: dict[str, list[dict]] = {}
    for row in rows:
        by_grid.setdefault(row["grid"], []).append(row)
    return {g: sorted(rs, key=lambda r: _rank(r["rank"])) for g, rs in by_grid.items()}


def _rank(text: str) -> float:
    try:
        return float(text)
    except ValueError:   # a failed candidate has no rank: last
        return float("inf")


def chosen_models(out: Path, overrides: tuple[str, ...] = (), searched: str | None = None,
                  campaign: Campaign | None = None) -> Choice:
    """The structures a report in ``out`` shows (module docstring); ``overrides`` (structure names) replace the
    winner of their coefficient; ``searched``: how the ranking came about, in words (default: the user's search);
    ``campaign``: replace a structure that needs a column it lacks (:func:`applicable_models`)."""
    resolve = resolver(out)
    rows = ranked_rows(out)
    notes: list[str] = []
    if rows is None:
        winners = {coef: find_candidate(n) for coef, n in FINAL_MODEL_NAMES.items()}
        source = "the thesis' final structures (no search ranking in the output directory)"
        if not overrides:
            notes.append(f"No {Path(out) / 'ranking.csv'}: the thesis' final structures are shown (run a search "
                         "to rank your own).")
    else:
        winners = {coef: resolve(rows[grid][0]["model"]) if grid in rows else find_candidate(FINAL_MODEL_NAMES[coef])
                   for coef, grid in GRID_OF.items()}
        source = searched or f"ranked first by the search in {Path(out) / 'ranking.csv'}"
        notes += [f"No {grid} grid in the ranking: the report shows the thesis' {FINAL_MODEL_NAMES[coef]}."
                  for coef, grid in GRID_OF.items() if grid not in rows]
    if overrides:
        chosen = [resolve(n) for n in overrides]
        winners.update({c.coefficient: c for c in chosen})
        source = "named on the command line (--model)" + (f"; the others {source}" if len(chosen) < 3 else "")
        notes.append(f"Models chosen on the command line: {', '.join(overrides)}.")
    if campaign is not None:
        # a coefficient the search did not rank shows the thesis' structure; a campaign that cannot fit it
        # (a wind-tunnel airfoil has no thrust coefficient) leaves it out instead
        unranked = set(GRID_OF) if rows is None else {coef for coef, grid in GRID_OF.items() if grid not in rows}
        winners = applicable_models(winners, campaign, notes, optional=unranked - set(overrides_of(overrides)))
        notes = [n for n in notes if not any(n.startswith(f"No {GRID_OF[coef]} grid in the ranking")
                                             for coef in set(GRID_OF) - set(winners))]
    choice = consistent(winners, rows or {}, resolve, source, notes)
    verdicts = search_answers(out) if rows is not None else {}
    return dataclasses.replace(choice, verdicts={coef: verdicts[GRID_OF[coef]] for coef, c in winners.items()
                                                 if GRID_OF.get(coef) in verdicts
                                                 and verdicts[GRID_OF[coef]].get("best_admissible", c.name) in
                                                 (c.name, None) and rows[GRID_OF[coef]][0]["model"] == c.name})


def search_answers(out: Path) -> dict[str, dict]:
    """Per grid the search's answer in ``out/search_answer.json`` ({} when the search wrote none)."""
    from ..data.reading import load_json
    path = Path(out) / "search_answer.json"
    if not path.exists():
        return {}
    doc = load_json(path, limit=ANSWERS_MAX_BYTES)   # regular, bounded, UTF-8, nesting bounded
    answers = doc.get("answers") if isinstance(doc, dict) else None
    if not isinstance(answers, dict) or not all(isinstance(a, dict) and isinstance(a.get("status"), str)
                                                for a in answers.values()):
        raise DataError("a search's answers: {\"answers\": {grid: {\"status\": ..., ...}}}", source=str(path))
    return answers


def consistent(winners: Mapping[str, Candidate], rows: Mapping[str, list[dict]], resolve, source: str,
               notes: list[str]) -> Choice:
    """The Choice of ``winners``: the figures' set on the lift model the drag and pitch winners read."""
    lifts = {coef: resolve(winners[coef].lift) for coef in ("CD", "Cm") if coef in winners and winners[coef].lift}
    shown = dict(winners)
    other = {coef: c for coef, c in lifts.items() if c.name != winners["CL"].name}
    for coef, lift in other.items():
        notes.append(f"The {GRID_OF[coef]} winner {winners[coef].name} takes its separation states from {lift.name}, "
                     f"not from the lift winner {winners['CL'].name}: it is shown with {lift.name}, fitted too.")
    if other:
        pitch_lift = lifts.get("Cm", winners["CL"])
        shown["CL"] = pitch_lift
        if "CD" in winners and winners["CD"].lift and winners["CD"].lift != pitch_lift.name:
            shown["CD"] = _reading(pitch_lift, rows.get("drag", []), resolve)
            notes.append(f"The figures draw one set on one lift model's states, {pitch_lift.name} (the pitch "
                         f"winner's); its drag model there is {shown['CD'].name}, the best-ranked drag structure "
                         f"on {pitch_lift.name}.")
        else:
            notes.append(f"The figures draw {pitch_lift.name} with {shown['CD'].name} and {shown['Cm'].name} (one "
                         "set on one lift model's states).")
    return Choice(winners, shown, source, tuple(notes), lifts)


def _reading(lift: Candidate, drag_rows: list[dict], resolve) -> Candidate:
    """The best-ranked drag structure that reads ``lift``'s states (the shipped grid's first when none is
    ranked)."""
    for row in drag_rows:
        if row.get("lift") == lift.name and _rank(row["rank"]) < float("inf"):
            return resolve(row["model"])
    grid = load_grid("drag", load_grid("lift"))
    found = next((c for c in grid.candidates if c.lift == lift.name), None)
    if found is None:
        raise DataError(f"no drag structure reads the states of {lift.name}: the report cannot draw one set")
    return found


def missing_columns(candidate: Candidate, campaign: Campaign) -> list[str]:
    """Data columns a candidate's regressors read that the campaign lacks (x_cg, for one)."""
    from ..engine.regressors import symbol_names
    have = set(campaign.data.columns) | set(campaign.data.constants)
    used = {n for _, text in candidate.regressors for n in symbol_names(text)}
    states = {n for n in used if n == "X" or n.startswith("X_")}
    return sorted(used - states - have)


def overrides_of(names: tuple[str, ...]) -> set[str]:
    """The coefficients the structures named on the command line model."""
    return {find_candidate(n).coefficient for n in names if not n.endswith("-auto")}


def applicable_models(winners: Mapping[str, Candidate], campaign: Campaign, notes: list[str],
                      optional: set[str] = frozenset()) -> dict[str, Candidate]:
    """``winners`` with every structure that needs a column the campaign lacks replaced by the first structure of
    its grid that needs none (and takes its states from the same lift model), with a note each in ``notes``; a
    coefficient of ``optional`` that none fits is left out (a note says so)."""
    out = dict(winners)
    lift_grid = load_grid("lift")
    for coef, c in winners.items():
        missing = missing_columns(c, campaign)
        if not missing:
            continue
        owns = coefficient(coef).owns_states
        grid = lift_grid if owns else load_grid(GRID_OF[coef], lift_grid)
        lift = None if owns else (c.lift or out[LIFT.name].name)
        substitute = next((s for s in grid.candidates
                           if not missing_columns(s, campaign) and (lift is None or s.lift == lift)), None)
        if substitute is None and coef in optional:
            del out[coef]
            notes.append(f"No {GRID_OF[coef]} structure is shown: the search ranked none, and {c.name} (the thesis') "
                         f"needs {', '.join(missing)}, which the campaign does not have; so does every structure of "
                         f"the {GRID_OF[coef]} grid on {lift}.")
            continue
        if substitute is None:
            raise DataError(f"no {GRID_OF[coef]} structure can be shown: {c.name} needs column {missing[0]} and "
                            "every other one needs a column the campaign lacks too", source=str(campaign.directory),
                            column=missing[0])
        out[coef] = substitute
        notes.append(f"{c.name} needs {', '.join(missing)}, which the campaign does not have; the report shows "
                     f"{substitute.name}, the first {GRID_OF[coef]} structure that does not.")
    return out
