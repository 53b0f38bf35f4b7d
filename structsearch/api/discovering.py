"""``structsearch discover`` as a Python function (the run itself is :mod:`structsearch.thesis_study.structure_discovery`)."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable, Iterable

from ..data.campaign import Campaign

Progress = Callable[[str], None] | None


def discover(campaign: Campaign | str | os.PathLike, coefficient: str, *, start: str = "minimal",
             lifts: Iterable[str] = (), terms: str | os.PathLike | None = None, beam: int | None = None,
             max_steps: int | None = None, starts: int = 2, seed: int = 0, covariance: str | None = None,
             bounds=None, jobs: int = 0, backend: str = "loky", out: str | os.PathLike | None = None,
             progress: Progress = None, command: str | None = None, segment: str | None = None):
    """Search structures for ``coefficient`` from ``start`` ("minimal", a candidate name or a spec file) as
    ``structsearch discover`` does; with ``out``, write discover.json, discover.md, path.csv and the final
    structure's spec file there (fits cached in ``out/cache``). Returns the typed :class:`Discovery`."""
    import tempfile
    from ..engine.statistics import DEFAULT_COVARIANCE
    from ..thesis_study.structure_discovery import discover_structures
    from .commands import as_campaign, fit_options, process_count
    campaign = as_campaign(campaign, segment)
    # structures with separation parameters are cross-validated by one-step folds in a structure search
    options = dataclasses.replace(fit_options(starts, seed, covariance or DEFAULT_COVARIANCE, bounds, campaign),
                                  cv_method="one-step")
    kw = dict(start=start, lifts=lifts, terms=terms, beam=beam, max_steps=max_steps, options=options,
              n_jobs=process_count(jobs), backend=backend, progress=progress)
    if out is None:
        with tempfile.TemporaryDirectory(prefix="structsearch-discover-") as tmp:
            return discover_structures(campaign, coefficient, cache_dir=Path(tmp), **kw)
    found = discover_structures(campaign, coefficient, cache_dir=Path(out), **kw)
    from ..reporting.discovery_doc import write_discovery
    return write_discovery(found, Path(out), command or "")
