import os

# one BLAS thread, as the CLI uses; keeps timings of the suite stable on small machines
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from structsearch.flight.reference import FINAL_LIFT, final_lift_model  # noqa: E402
from structsearch.flight.synthetic import campaign, with_coefficient  # noqa: E402


@pytest.fixture(scope="session")
def small_campaign():
    """Six 30 s maneuvers at 100 Hz (quasi-steady, dynamic, deep dynamic)."""
    return campaign({"quasi-steady": 2, "dynamic": 2, "deep-dynamic": 2}, duration=30.0, seed=11)


@pytest.fixture(scope="session")
def noise_free_lift(small_campaign):
    model = final_lift_model()
    return model, with_coefficient(small_campaign, model, FINAL_LIFT)


def central_difference(fun, x, rel=1e-6):
    """Central finite differences of a vector function, one column per parameter."""
    x = np.asarray(x, float)
    cols = []
    for i in range(len(x)):
        h = rel * max(abs(x[i]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        cols.append((fun(xp) - fun(xm)) / (2 * h))
    return np.column_stack(cols)
