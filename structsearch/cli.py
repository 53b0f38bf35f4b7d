"""Command line: ``structsearch <command>`` (also ``python -m structsearch``)."""
from __future__ import annotations

import os

# One BLAS thread per process: the products here are tall and skinny (m x ~10), where
# threading costs more than it gains, and parallelism comes from joblib processes.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402


def _bench(args) -> int:
    from .bench import BenchConfig, run, write
    config = BenchConfig(samples=args.samples, repeats=args.repeats, random_starts=args.starts,
                         seed=args.seed, n_jobs=args.jobs)
    fig = run(config, progress=lambda msg: print(f"bench: {msg}", file=sys.stderr, flush=True))
    md, js = write(fig, Path(args.out))
    o, r = fig["one_start"], fig["random_starts"]
    print(f"one start: SNLS {o['snls_median_s']:.3f} s ({o['snls_nfev']} evaluations), full NLS "
          f"{o['full_median_s']:.3f} s ({o['speedup']:.1f}x), full NLS with finite differences "
          f"{o['fd_median_s']:.3f} s ({o['fd_speedup']:.1f}x); random starts reaching the best: SNLS "
          f"{r['snls_success']}/{r['n']}, full NLS {r['full_success']}/{r['n']}, finite differences "
          f"{r['fd_success']}/{r['n']}; peak memory "
          f"{fig['memory'][0]['peak_mb']:.0f} MB -> {fig['memory'][1]['peak_mb']:.0f} MB at 2x samples")
    print(f"wrote {md} and {js}")
    return 0


def _simulate(args) -> int:
    from .campaign import write_campaign
    from .flighttest import build_campaign
    campaign = build_campaign(seed=args.seed, withhold=args.withhold or (), scale=args.scale,
                              extras=args.extras)
    out = write_campaign(campaign, Path(args.out), fmt=args.format)
    d = campaign.data
    n_val = sum(m.split == "validation" for m in campaign.maneuvers)
    print(f"wrote {out}: {len(campaign.maneuvers)} maneuvers ({n_val} validation), {d.n_samples} samples; "
          f"truth: {campaign.extra['truth']}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="structsearch", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("bench", help="measure speed, robustness and memory of the SNLS engine")
    b.add_argument("--out", default="results", help="output directory (default: results)")
    b.add_argument("--samples", type=int, default=250_000, help="samples in the benchmark campaign")
    b.add_argument("--repeats", type=int, default=5, help="repeats of the single-start timing")
    b.add_argument("--starts", type=int, default=20, help="random starts for the success rate")
    b.add_argument("--seed", type=int, default=2025)
    b.add_argument("--jobs", type=int, default=2, help="processes for the random starts")
    b.set_defaults(func=_bench)

    from .aero import WITHHOLDABLE
    s = sub.add_parser("simulate", help="simulate the Citation II flight-test campaign (thesis Table 4)")
    s.add_argument("--out", required=True, help="campaign directory to write")
    s.add_argument("--seed", type=int, default=0, help="random seed (same seed, same campaign bit for bit)")
    s.add_argument("--withhold", action="append", choices=sorted(WITHHOLDABLE), metavar="EFFECT",
                   help="remove an effect from the truth model (repeatable): " + ", ".join(WITHHOLDABLE))
    s.add_argument("--scale", type=float, default=1.0,
                   help="fraction of the maneuvers of each kind to fly (small test campaigns)")
    s.add_argument("--extras", action="store_true", help="add pullups, pushovers and phugoids")
    s.add_argument("--format", choices=("csv", "parquet"), default="csv")
    s.set_defaults(func=_simulate)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from .errors import StructSearchError
    try:
        return args.func(args)
    except StructSearchError as exc:
        print(f"structsearch {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"structsearch {args.command}: error: {exc}", file=sys.stderr)
        return 2
