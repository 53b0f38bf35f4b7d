"""Memory of reading a campaign: the peak a reading process adds, against the size of the data it holds.

Each format is read in a fresh interpreter (the reading's peak resident memory is not mixed with the bench's
own), after importing everything a reading needs, with the kernel's peak counter reset (Linux
``/proc/self/clear_refs``): the figure is the peak ``read_campaign`` itself adds to the resident memory,
against the bytes of the columns it returns (float64 samples). Reading streams a file into those columns; a reader
that held the text, a parsed copy and the columns at once would show 3x and more.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

_CHILD = """
import json, sys
import numpy, pandas
from structsearch.data.campaign import read_campaign
try:
    import pyarrow  # noqa: F401  (imported before the baseline whatever the format)
except ImportError:
    pass

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024

open("/proc/self/clear_refs", "w").write("5")   # the peak resident memory starts again from here
before = status("VmRSS:")
campaign = read_campaign(sys.argv[1])
peak = status("VmHWM:")
data = sum(numpy.asarray(v).nbytes for v in campaign.data.columns.values())
print(json.dumps({"peak_added_bytes": peak - before, "data_bytes": int(data),
                  "samples": int(campaign.data.n_samples), "columns": len(campaign.data.columns)}))
"""


def run_reading(scale: float = 1.0, seed: int = 0, progress=None) -> dict:
    """Per format (csv, parquet): the peak memory a reading adds and its ratio to the data's bytes."""
    from ..data.campaign import write_campaign
    from ..flight.flighttest import build_campaign
    say = progress or (lambda msg: None)
    say(f"simulating the campaign (seed {seed}, scale {scale})")
    campaign = build_campaign(seed=seed, scale=scale)
    out = {"scale": scale, "seed": seed, "formats": {}}
    with tempfile.TemporaryDirectory(prefix="structsearch-reading-") as folder:
        for fmt in ("csv", "parquet"):
            directory = Path(folder) / fmt
            write_campaign(campaign, directory, fmt=fmt)
            size = sum(p.stat().st_size for p in directory.iterdir())
            say(f"reading the {fmt} campaign ({size / 1e6:.1f} MB on disk) in a fresh process")
            proc = subprocess.run([sys.executable, "-c", _CHILD, str(directory)], capture_output=True, text=True,
                                  check=True)
            figures = json.loads(proc.stdout)
            figures["file_bytes"] = size
            figures["ratio"] = figures["peak_added_bytes"] / figures["data_bytes"]
            out["formats"][fmt] = figures
    return out


def reading_markdown(doc: dict, command: str) -> str:
    rows = ["| format | samples | columns | files on disk | data (float64) | peak added by reading | ratio |",
            "|---|---|---|---|---|---|---|"]
    for fmt, f in doc["formats"].items():
        rows.append(f"| {fmt} | {f['samples']} | {f['columns']} | {f['file_bytes'] / 1e6:.1f} MB | "
                    f"{f['data_bytes'] / 1e6:.1f} MB | {f['peak_added_bytes'] / 1e6:.1f} MB | {f['ratio']:.2f} |")
    return "\n".join([
        "# Memory of reading a campaign", "",
        f"Made by `{command}`. The simulated default campaign (seed {doc['seed']}, scale {doc['scale']}) written "
        "in each format and read by `read_campaign` in a fresh interpreter: the peak resident memory the reading "
        "adds (after the imports), against the bytes of the columns it returns.", "", *rows, ""])
