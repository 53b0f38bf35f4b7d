"""Stored values of the simulator, compared with a tolerance (not bit digests, which pin one BLAS kernel).

``python tests/reference_values.py`` rewrites ``tests/data/reference/simulator.json`` after a deliberate change of
the simulator (the flying, the aircraft, the noise): say why in the commit. The file holds, per column of the
seed-0 campaign at scale 0.05, the column's length, mean, standard deviation and 64 samples at fixed indices.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

REFERENCE = Path(__file__).parent / "data" / "reference" / "simulator.json"
SEED, SCALE, N_SAMPLES = 0, 0.05, 64


def summary(campaign) -> dict:
    """What the reference file stores of a campaign."""
    data = campaign.data
    n = len(data.columns["t"])
    idx = np.linspace(0, n - 1, N_SAMPLES).round().astype(int)
    columns = {}
    for k in sorted(data.columns):
        x = np.asarray(data.columns[k], float)
        columns[k] = {"mean": float(x.mean()), "std": float(x.std()), "samples": x[idx].tolist()}
    return {"seed": SEED, "scale": SCALE, "n": n, "starts": [int(s) for s in data.starts],
            "indices": idx.tolist(), "columns": columns}


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from structsearch.flight.flighttest import build_campaign
    REFERENCE.write_text(json.dumps(summary(build_campaign(seed=SEED, scale=SCALE)), indent=1) + "\n")
    print(f"wrote {REFERENCE}")
