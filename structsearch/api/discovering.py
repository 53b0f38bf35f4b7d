"""``structsearch discover`` as a Python function (the run itself is :mod:`structsearch.discovery.discover`)."""
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
    from ..diagnosis.diagnose import diagnose_search
    from ..discovery.discover import discover_structures
    from .settings import as_campaign
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    with command_fitter("discover", campaign, settings, out) as fitter:
        found = discover_structures(fitter, coefficient, diagnose_search, start=start, lifts=lifts, terms=terms,
                                    beam=beam, max_steps=max_steps, moment_reference=settings.moment_reference,
                                    **({} if kinds is None else {"kinds": tuple(kinds)}))
    if out is None:
        return found
    from ..reporting.discovery_doc import write_discovery
    return write_discovery(found, Path(out), command or "")
