"""``structsearch discover`` as a Python function (the run itself is :mod:`structsearch.diagnosis.discover`)."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from ..data.campaign import Campaign
from .settings import Settings, command_fitter


def discover(campaign: Campaign | str | os.PathLike, coefficient: str, *, settings: Settings = Settings(),
             start: str = "minimal", lifts: Iterable[str] = (), terms: str | os.PathLike | None = None,
             beam: int | None = None, max_steps: int | None = None, out: str | os.PathLike | None = None,
             command: str | None = None, kinds: Iterable[str] | None = None):
    """Search structures for ``coefficient`` from ``start`` ("minimal", a candidate name or a spec file) as
    ``structsearch discover`` does; with ``out``, write discover.json, discover.md, path.csv and the final
    structure's spec file there (fits cached in ``out/cache``). Returns the typed
    :class:`~structsearch.discovery.discovered.Discovery`. ``kinds``: the moves it makes (default every kind of
    :data:`~structsearch.discovery.moves.MOVE_KINDS`; without ``"form"`` every state keeps its static curve)."""
    from ..diagnosis.discover import discover_structures
    from ..discovery.search_setting import DISCOVER
    from .settings import as_campaign
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    with command_fitter("discover", campaign, settings, out) as fitter:
        setting = DISCOVER.but(beam=beam, max_rounds=max_steps, kinds=kinds)
        found = discover_structures(fitter, coefficient, setting, start=start, lifts=lifts, terms=terms,
                                    moment_reference=settings.moment_reference)
    if out is None:
        return found
    from ..reporting.discovery_doc import write_discovery
    return write_discovery(found, Path(out), command or "")


def discover_exhaustive(campaign: Campaign | str | os.PathLike, coefficient: str, *, out: str | os.PathLike,
                        settings: Settings = Settings(), max_terms: int = 3, lift: str | None = None,
                        terms: str | os.PathLike | None = None):
    """``structsearch discover --exhaustive``: every structure of the term library (the shipped templates the
    campaign can evaluate, and ``terms``) of 1 to ``max_terms`` terms (:mod:`structsearch.discovery.exhaustive`),
    written to ``out/exhaustive_<coefficient>.toml`` and searched as that grid, without refinement (every
    smaller structure is in it); a drag or pitch structure is fed ``lift`` (default the thesis' CL-VI). Returns the
    :class:`~structsearch.api.results.Ranking` (``ranking.csv`` and the tables written to ``out``)."""
    from ..data.atomic import write_text
    from ..data.coefficients import coefficient as coefficient_record
    from ..discovery.exhaustive import count, library_terms, structures
    from ..discovery.spec_file import grid_text
    from ..discovery.terms import library_for
    from ..fitting.specs import load_grid
    from ..flight.reference import FINAL_MODEL_NAMES
    from .commands import search
    from .settings import as_campaign
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    library = library_for(coefficient_record(coefficient).name, campaign.data, terms)
    fed = None if coefficient_record(coefficient).owns_states else load_grid("lift")[lift or FINAL_MODEL_NAMES["CL"]]
    terms = library_terms(library, fed)
    candidates = structures(library, max_terms, fed)
    if settings.progress is not None:
        settings.progress(f"discover --exhaustive: {len(candidates)} structures of 1 to {min(max_terms, len(terms))} "
                          f"of {len(terms)} terms ({count(terms, len(terms), fed is not None)} with every number of "
                          "terms)" + (f", fed {fed.name}" if fed is not None else ", each state S, Q or U"))
    Path(out).mkdir(parents=True, exist_ok=True)
    spec = Path(out) / f"exhaustive_{coefficient}.toml"
    write_text(spec, grid_text(candidates, f"written by structsearch discover --exhaustive (up to {max_terms} terms)"))
    return search(campaign, str(spec), settings=settings, out=out, refine=False)
