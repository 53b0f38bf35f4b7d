"""The one object every command fits candidates with: a :class:`RunConfig` (the campaign, the fit options, the
cache, the workers, where progress goes), made once by the API, and the lift models drag and pitch candidates
read. The search, its refinement, the structure search, the diagnosis, the study and the report take a
:class:`Fitter` instead of threading those settings through every call, so a command's fits are made alike
everywhere it fits (and one cache serves them)."""
from __future__ import annotations

import dataclasses
import os
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping, Sequence

from ..data.campaign import Campaign
from ..data.flightdata import FlightData
from .candidate_result import CandidateResult
from .candidates import Candidate
from .lift_fit import LiftFit
from .options import FitOptions
from .trace import Trace

Progress = Callable[[str], None]
# (finished, of, what): told after each candidate a fit call fitted ("drag CD-IXr"); the command line draws a bar
# from it on a terminal, in place of a line per candidate (a search fits hundreds)
Meter = Callable[[int, int, str], None]


# A console line at most (a terminal's width, roughly twice): the tables, story.md and the JSON hold long texts whole.
CONSOLE_WIDTH = 160


def console_line(line: str, width: int = CONSOLE_WIDTH) -> str:
    """``line`` wrapped at ``width`` characters on word boundaries, nothing cut: the lines after the first indented
    four spaces more than it (joined by newlines; a line that fits is returned as it is)."""
    if len(line) <= width:
        return line
    import textwrap
    indent = " " * (len(line) - len(line.lstrip(" ")))
    return "\n".join(textwrap.wrap(line, width, subsequent_indent=indent + "    ", break_long_words=False,
                                    break_on_hyphens=False))


def _silent(message: str) -> None:
    """Progress that goes nowhere (a run nobody watches)."""


@dataclass(frozen=True)
class RunConfig:
    """Where and how a command fits: ``campaign`` (split into training and validation maneuvers by its
    manifest), ``options`` (starts, seed, covariance, cross-validation, boxes), ``cache_dir`` (whose ``cache/``
    holds every fit, keyed by what it depends on), ``n_jobs`` worker processes of ``backend`` (joblib's, or
    "dask" on a client the caller opened), ``progress`` (the lines a command prints to stderr), ``meter`` (told of
    each candidate fitted: :data:`Meter`; None: nobody) and ``trace`` (where every task is recorded, for
    ``--trace``; None: nowhere)."""

    campaign: Campaign
    cache_dir: Path
    options: FitOptions = FitOptions()
    n_jobs: int = 1
    backend: str = "loky"
    progress: Progress = _silent
    trace: Trace | None = None
    meter: Meter | None = None

    def __post_init__(self):
        object.__setattr__(self, "cache_dir", Path(self.cache_dir))
        if self.progress is None:
            object.__setattr__(self, "progress", _silent)


@dataclass(frozen=True)
class Fitter:
    """Fits candidates as a command's :class:`RunConfig` says: cached, on its workers, each staged from the
    candidates nested in it that were fitted before (``donors``, and earlier waves of the same call). Drag and
    pitch candidates read the lift model their ``lift`` names from ``lifts``."""

    config: RunConfig
    lifts: Mapping[str, LiftFit] = field(default_factory=dict)

    # ----- what it fits on -------------------------------------------------------------------------------
    @property
    def campaign(self) -> Campaign:
        return self.config.campaign

    @property
    def options(self) -> FitOptions:
        return self.config.options

    @property
    def say(self) -> Progress:
        return self.config.progress

    def splits(self) -> tuple[FlightData, FlightData]:
        """The training and the validation maneuvers."""
        return self.campaign.split("train"), self.campaign.split("validation")

    def lift_of(self, candidate: Candidate) -> LiftFit | None:
        """The lift model ``candidate`` reads (None for a lift or separation candidate, or one not fitted)."""
        return self.lifts.get(candidate.lift) if candidate.lift else None

    # ----- fitting ---------------------------------------------------------------------------------------
    def fit(self, candidates: Sequence[Candidate],
            donors: Iterable[tuple[Candidate, CandidateResult]] = (), *, staged: bool = True) -> list[CandidateResult]:
        """Every candidate's result, in order (a failed one carries its reason); ``staged`` False: none starts
        from another of ``candidates`` (each fitted as it would be alone)."""
        from .runner import run
        if not candidates:
            return []
        c = self.config
        return run(list(candidates), c.campaign, c.cache_dir, lifts=dict(self.lifts), options=c.options,
                   n_jobs=c.n_jobs, backend=c.backend, progress=c.progress, fitted_before=list(donors),
                   trace=c.trace, meter=c.meter, staged=staged)

    def fit_one(self, candidate: Candidate,
                donors: Iterable[tuple[Candidate, CandidateResult]] = ()) -> CandidateResult:
        return self.fit([candidate], donors)[0]

    # ----- variants (each a new fitter; the config is never changed in place) ----------------------------
    def with_lifts(self, lifts: Mapping[str, LiftFit]) -> "Fitter":
        """This fitter with ``lifts`` added to (and replacing) its lift models."""
        return dataclasses.replace(self, lifts={**self.lifts, **lifts})

    def with_options(self, **changes) -> "Fitter":
        """This fitter with some fit options changed (a screening fit's ``scores_only``, ...)."""
        return self._with(options=dataclasses.replace(self.config.options, **changes))

    def with_progress(self, progress: Progress) -> "Fitter":
        """This fitter telling its progress to ``progress``."""
        return self._with(progress=progress)

    def quiet(self) -> "Fitter":
        """This fitter without progress lines (its meter still counts the candidates: a structure search that
        says one line a step is long, and the bar is all a terminal shows of it)."""
        return self._with(progress=_silent)

    def serial(self) -> "Fitter":
        """This fitter on one process (one candidate at a time: a refinement's steps)."""
        return self._with(n_jobs=1)

    def _with(self, **changes) -> "Fitter":
        return dataclasses.replace(self, config=dataclasses.replace(self.config, **changes))


@contextmanager
def temporary_fitter(campaign: Campaign, options: FitOptions = FitOptions(), **config) -> Iterator[Fitter]:
    """A fitter whose cache is a temporary directory, removed afterwards (a run that keeps nothing: a benchmark,
    a test); ``config``: the other fields of :class:`RunConfig`."""
    with tempfile.TemporaryDirectory(prefix=f"structsearch-{os.getpid()}-") as tmp:
        yield Fitter(RunConfig(campaign, Path(tmp), options, **config))
