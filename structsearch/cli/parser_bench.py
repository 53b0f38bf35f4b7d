"""The ``bench`` command's options (kept apart from :mod:`.parser`, which stays under the house's module size)."""
from __future__ import annotations

from typing import Callable

from .help import command_parser
from .options import (CG_MOMENTS, PROFILE_CAMPAIGNS, _count, _covariance_kinds, _flight_effects, _fraction,
                      _non_negative, _seed_range)


def _add_bench(sub, handler: Callable) -> None:
    """The ``bench`` command."""
    b = command_parser(sub, "bench")
    b.add_argument("--out", default="results", help="output directory (default: results)")
    b.add_argument("--samples", type=_count, default=250_000, help="samples in the benchmark campaign")
    b.add_argument("--repeats", type=_count, default=3, help="repeats of every single-start timing (every method alike)")
    b.add_argument("--starts", type=_count, default=20, help="random starts for the success rate")
    b.add_argument("--seed", type=_non_negative, default=2025, help="seed of the benchmarks' random draws (default 2025)")
    b.add_argument("--jobs", type=_non_negative, default=2, help="processes for the random starts and the search")
    b.add_argument("--no-search", action="store_true", help="skip the search --grid all benchmark")
    b.add_argument("--staged", type=_count, default=None, metavar="CAMPAIGNS",
                   help="also measure the default fit's success over this many seeded campaigns (50: ~10 min)")
    b.add_argument("--calibration", action="store_true",
                   help="instead: Monte Carlo calibration of the covariances on simulated campaigns "
                        "(writes calibration.md and calibration.json)")
    b.add_argument("--joint", action="store_true",
                   help="instead: a joint fit of the final models against the sequential fits on the default "
                        "campaign (cost, validation MSE, shared parameters; writes joint_bench.md and .json)")
    b.add_argument("--discovery", action="store_true",
                   help="instead: the story with the structure search against the effect library alone, and "
                        "discover --from minimal for each coefficient (writes discovery_bench.md and .json)")
    b.add_argument("--reading", action="store_true",
                   help="instead: the peak memory of reading the default campaign (CSV and Parquet) against the "
                        "size of its data, each in a fresh process (writes reading_bench.md and .json; --scale)")
    b.add_argument("--trace", metavar="FILE", default=None,
                   help="instead: what the task graph of a run recorded with --trace allows: total work, critical "
                        "path, available parallelism, the wall a list schedule predicts at 2, 4, 8, 16, 64 workers "
                        "(writes trace_bench.md and the 'trace' entry of bench.json)")
    b.add_argument("--campaigns", type=_count, default=50,
                   help="--calibration: number of seeded campaigns (seeds 2000 on: held out from the seeds the "
                        "defaults were chosen on)")
    b.add_argument("--seeds", type=_seed_range, default=None, metavar="A:B",
                   help="--calibration: the campaigns' seeds A to B-1 instead (overrides --campaigns)")
    b.add_argument("--scale", type=_fraction, default=0.1, help="--calibration: fraction of the maneuvers flown")
    b.add_argument("--profile-campaigns", type=_non_negative, default=PROFILE_CAMPAIGNS, metavar="N",
                   help=f"--calibration: the first N campaigns also calibrate the profile intervals of the nonlinear "
                        f"parameters beside the Wald ones (default {PROFILE_CAMPAIGNS}, ~12 s each at scale 0.25; "
                        "0: none)")
    b.add_argument("--flight-errors", action="store_true",
                   help="--calibration: fly each campaign on flights of about four maneuvers that share a mass, cg, "
                        "engine-model and vane-calibration error (simulate --flights), and calibrate the "
                        "flight-grouped covariance hac-flight beside the others")
    b.add_argument("--flight-effects", type=_flight_effects, default=(), metavar="NAME[,NAME]",
                   help="--calibration --flight-errors: the final models estimate these per-flight offsets with "
                        "their parameters (x_cg, intercept; fit --flight-effects)")
    b.add_argument("--cg-moment", choices=CG_MOMENTS, default="thesis",
                   help="--calibration: how the simulated truth's C_m depends on the cg (simulate --cg-moment): "
                        "thesis (default; the pitch model calibrated is Cm-XXXIIIr) or transfer (the moment transfer "
                        "about the reference point; the pitch model calibrated is its structure Cm-XXXIIIf, about "
                        "the fixed point)")
    b.add_argument("--kinds", type=_covariance_kinds, default=None, metavar="KIND[,KIND]",
                   help="--calibration: calibrate only these covariance kinds (default: every kind)")
    b.set_defaults(func=handler)
