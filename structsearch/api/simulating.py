"""``simulate --jsbsim NAME_OR_DIR [--modify FILE] [--lateral]``: a stall campaign flown in JSBSim
(:mod:`structsearch.foreign.fly`): the aircraft model flown, not a flight."""
from __future__ import annotations

import os
import time

from ..data.campaign import Campaign


def simulate_jsbsim(aircraft: str, *, modify: str | os.PathLike | None = None, seed: int = 0, scale: float = 1.0,
                    out: str | os.PathLike | None = None, format: str = "csv",
                    lateral: bool = False) -> tuple[Campaign, float]:
    """Fly the stall plan in JSBSim with ``aircraft`` (modified by the TOML file ``modify``; with ``lateral`` the
    lateral plan too and the lateral channels recorded); with ``out``, write the campaign there. Returns the
    campaign and the seconds it took."""
    from ..data.campaign import write_campaign
    from ..foreign.fly import fly_campaign
    from ..foreign.modify import read_modify
    started = time.perf_counter()
    modification = read_modify(modify) if modify is not None else None
    campaign = fly_campaign(aircraft, modification, scale=scale, seed=seed, lateral=lateral)
    if out is not None:
        write_campaign(campaign, out, fmt=format)
    return campaign, time.perf_counter() - started
