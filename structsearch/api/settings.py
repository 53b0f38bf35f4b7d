"""The settings every fitting command shares (``--starts``, ``--seed``, ``--covariance``, ``--bound``, ``--jobs``,
``--backend``, ``--segment``, the cache and where progress goes), as one value made once, and each command's
differences from the fit options' defaults, stated here and nowhere else. :func:`command_fitter` turns them into
the :class:`~structsearch.fitting.fitter.Fitter` the command fits with."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping

from ..data.campaign import Campaign, read_campaign
from ..data.errors import DeclarationError
from ..engine.statistics import DEFAULT_COVARIANCE
from ..data.atomic import write_json
from ..fitting.fitter import Fitter, Meter, RunConfig
from ..fitting.trace import Trace
from ..fitting.options import FitOptions, command_options

Progress = Callable[[str], None] | None
Bounds = Mapping[str, tuple[float, float]] | Iterable[tuple[str, tuple[float, float]]] | None

@dataclass(frozen=True)
class Settings:
    """How a command fits: ``starts`` (None: the command's own default,
    :data:`structsearch.fitting.options.COMMAND_OPTIONS`), ``seed``,
    ``covariance``, ``bounds`` (``--bound NAME=LO:HI``: a mapping or pairs, the last box of a name winning),
    ``jobs`` worker processes (0: every core) of ``backend``, ``segment`` ("cycles" fits a periodic record's
    cycles as maneuvers), ``cache`` (the directory whose ``cache/`` holds the fits; default the command's
    ``out``, else a temporary directory), ``progress`` (receives the lines the command writes to stderr), ``meter``
    (told ``(finished, of, what)`` after each candidate a fit call fitted: the command line's progress bar) and
    ``trace`` (a file the command writes its tasks to, as Chrome trace-event JSON: ``--trace FILE``);
    ``moment_reference`` ("cg" or "fixed": every pitch structure the command starts from takes C_m about it; None:
    as each declares) and ``reference_point`` (the fixed station [m], replacing the manifest's; None: the
    manifest's)."""

    starts: int | None = None
    seed: int = 0
    covariance: str = DEFAULT_COVARIANCE
    bounds: Bounds = None
    jobs: int = 0
    backend: str = "loky"
    segment: str | None = None
    cache: str | os.PathLike | None = None
    progress: Progress = None
    trace: str | os.PathLike | None = None
    meter: Meter | None = None
    # per-flight nuisance parameters every candidate estimates (``--flight-effects x_cg,intercept``;
    # structsearch.fitting.flight_effects)
    flight_effects: tuple[str, ...] = ()
    moment_reference: str | None = None
    reference_point: float | None = None

    @property
    def processes(self) -> int:
        """``jobs`` as a process count: 0 means every core (the commands' ``--jobs``)."""
        return self.jobs or os.cpu_count() or 1

    def boxes(self) -> tuple:
        """``bounds`` as FitOptions' sorted boxes, the last box of a name winning."""
        b = self.bounds
        pairs = dict(b.items() if isinstance(b, Mapping) else (b or ()))
        return tuple(sorted((name, (float(lo), float(hi))) for name, (lo, hi) in pairs.items()))


def fit_options(command: str, settings: Settings, campaign: Campaign | None = None, **changes) -> FitOptions:
    """``command``'s FitOptions under ``settings``; with the ``campaign``, its cross-validation folds leave one
    cycle out when its training maneuvers are cycles of periodic records
    (:func:`structsearch.fitting.folds.fold_size_for`), and blocked folds last at least the campaign's shortest
    maneuver worth fitting (:func:`structsearch.fitting.folds.block_convective_times`)."""
    values = {"seed": settings.seed, "covariance": settings.covariance, "parameter_boxes": settings.boxes()}
    if settings.flight_effects:
        from ..fitting.flight_effects import parse_effects
        values["flight_effects"] = parse_effects(list(settings.flight_effects), "flight effects")
    if settings.starts is not None:
        values["n_starts"] = settings.starts
    if campaign is not None:
        from ..fitting.folds import block_convective_times, fold_size_for
        values["cv_fold_size"] = fold_size_for(campaign.maneuvers)
        values["cv_block_convective_times"] = block_convective_times(campaign)
    return command_options(command, **{**values, **changes})


@contextmanager
def cache_directory(cache: str | os.PathLike | None) -> Iterator[Path]:
    """``cache`` as a Path, or a temporary directory (removed afterwards) when it is None."""
    if cache is not None:
        yield Path(cache)
        return
    with tempfile.TemporaryDirectory(prefix=f"structsearch-{os.getpid()}-") as tmp:
        yield Path(tmp)


@contextmanager
def command_fitter(command: str, campaign: Campaign, settings: Settings, out: str | os.PathLike | None = None,
                   **option_changes) -> Iterator[Fitter]:
    """The fitter of ``command``: its options (:func:`fit_options`, with ``option_changes``), its cache
    (``settings.cache``, else ``out``, else a temporary directory), workers (on ``backend="dask"``, the client the
    caller opened, else a local cluster of ``jobs`` workers), progress and meter; with ``settings.trace``, every task
    it ran is written there when it ends (also when it fails: the trace shows how far it got)."""
    options = fit_options(command, settings, campaign, **option_changes)
    trace = Trace() if settings.trace is not None else None
    with cache_directory(settings.cache if settings.cache is not None else out) as where, \
            _dask_client(settings) as _:
        try:
            yield Fitter(RunConfig(campaign, where, options, settings.processes, settings.backend, settings.progress,
                                   trace, settings.meter))
        finally:
            if trace is not None:
                write_json(Path(settings.trace), trace.to_chrome())


def _current_dask_client():
    """The dask client the caller opened, or None."""
    try:
        from dask.distributed import get_client
        return get_client()
    except (ImportError, ValueError):
        return None


@contextmanager
def _dask_client(settings: Settings):
    """The dask client a command's tasks run on: the caller's, else a local cluster closed afterwards."""
    if settings.backend != "dask":
        yield None
        return
    # looked up before the command runs: an error inside the command must not be taken for "no client"
    existing = _current_dask_client()
    if existing is not None:
        yield existing
        return
    client = dask_client(None, settings.processes)
    try:
        yield client
    finally:
        client.close()


def dask_client(scheduler: str | None, jobs: int):
    """A dask.distributed Client: the given scheduler, else a local cluster of ``jobs`` single-threaded workers."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DeclarationError("--backend dask needs the optional dependency dask.distributed "
                               "(pip install 'structsearch[dask]')") from None
    if scheduler:
        return Client(scheduler)
    return Client(LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None))


@dataclass(frozen=True)
class FlightTestPlan:
    """What a simulated campaign flies besides its seed and scale (``structsearch simulate``'s other options):
    the ``aircraft`` ("citation" or "transport"), effects of the truth to ``withhold``, an ``anomaly`` outside the
    diagnosis' library, ``extras`` maneuvers, ``raw`` channels instead of coefficients, the scale of the slow
    reconstruction errors, ``flights`` = N > 0: the maneuvers flown on N flights that share errors, ``nominal``:
    nominal (attached-flow) maneuvers across the envelope besides the stall maneuvers; ``cg_spread`` [m]: the width
    of the band each loading's cg is drawn from (None: the default band); ``cg_moment``: how the truth's C_m depends
    on the cg ("thesis" or "transfer")."""

    aircraft: str = "citation"
    withhold: tuple[str, ...] = ()
    anomaly: str | None = None
    extras: bool = False
    raw: bool = False
    slow_errors: float = 1.0
    flights: int = 0
    nominal: bool = False
    cg_spread: float | None = None
    cg_moment: str = "thesis"


def as_campaign(campaign: Campaign | str | os.PathLike, segment: str | None = None,
                reference_point: float | None = None) -> Campaign:
    """``campaign`` itself, or the standard campaign read from that directory. ``segment`` (``--segment``):
    "cycles" cuts every record into its cycles, "none" keeps each whole, None as campaign.toml says
    (:mod:`structsearch.data.records`; a campaign in memory: :func:`structsearch.data.cycles.segmented`).
    ``reference_point`` (``--reference-point``): the fixed moment reference point [m], replacing the manifest's."""
    if isinstance(campaign, Campaign):
        from ..data.cycles import segmented
        campaign = segmented(campaign, segment)
    else:
        campaign = read_campaign(campaign, segment=segment)
    if reference_point is not None:
        from ..data.campaign import with_reference_point
        campaign = with_reference_point(campaign, reference_point)
    return campaign
