"""``structsearch bench``: speed, robustness and memory of structsearch, measured side by side.

* :mod:`.bench_engine`: the SNLS engine against a numpy/scipy prototype and full NLS on a synthetic
  ~250,000-sample campaign (like for like over the same random starts, one start, memory);
* :mod:`.bench_process`: the whole ``structsearch fit`` process against an independent numpy/scipy
  script's whole process (``reference_vp_script.py``), alternated, in the same run;
* :mod:`.bench_search` (``run_search``): ``search --grid all`` against a naive fan-out of the same
  candidates and against its own critical path, both measured in the same run;
* :mod:`.bench_staged` (``run_staged``): the default fit against the best admissible solution of 64
  random starts on seeded campaigns;
* :mod:`.bench_report`: ``bench.md`` and ``bench.json``.
"""
from __future__ import annotations

from .bench_engine import BenchConfig, bench_data, prototype_vp, run_engine
from .bench_process import run_process
from .bench_report import to_markdown, write
from .bench_search import critical_path, naive_fan_out, one_start_unit, ranking_agreement, run_search
from .bench_staged import run_staged

__all__ = ["BenchConfig", "bench_data", "critical_path", "naive_fan_out", "one_start_unit", "prototype_vp",
           "ranking_agreement", "run", "run_engine", "run_process", "run_search", "run_staged", "to_markdown",
           "write"]


# The default simulated campaign's size, and the smallest fraction of it the whole-process comparison flies
DEFAULT_CAMPAIGN_SAMPLES = 250_000
PROCESS_MIN_SCALE = 0.05


def run(config: BenchConfig = BenchConfig(), progress=None) -> dict:
    """The engine figures and, unless ``config.processes`` is off, the whole-process ``fit`` comparison."""
    fig = run_engine(config, progress)
    if config.processes:
        # as many alternated repeats as every other timing; the simulated campaign flown at the size asked for (--samples; the default campaign has ~258,000)
        scale = min(1.0, max(PROCESS_MIN_SCALE, config.samples / DEFAULT_CAMPAIGN_SAMPLES))
        fig["processes"] = run_process(repeats=config.repeats, random_starts=config.random_starts,
                                       n_jobs=config.n_jobs, progress=progress, scale=scale)
    return fig
