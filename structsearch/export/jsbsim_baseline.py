"""``diagnose --simulator jsbsim:AIRCRAFT``: a JSBSim aircraft's coefficient at the recorded states, the baseline of
a diagnosis (:mod:`structsearch.diagnosis.offset`).

The aircraft is driven as ``export --check`` drives it (:func:`.check.drive`): loaded, initialised, its
integration suspended, ``structsearch/fill-inputs`` set to 0, and for every sample of every maneuver the inputs
its aerodynamics and separation states read (alpha, alpha_dot, q, V, de, C_T, ... in the campaign's SI units) are
written from the recording and one frame is run; ``structsearch/<coefficient>`` is read back. Its separation
states run along each maneuver from equilibrium at its first sample, as in the fits.

This module drives an aircraft written by ``structsearch export --format jsbsim`` (``AIRCRAFT`` is the export
directory or its ``aircraft/<name>`` directory: :func:`exported_by_structsearch`). Any other aircraft, JSBSim's
bundled ones among them, is evaluated term by term at the recorded states by :mod:`structsearch.foreign.baseline`.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

from ..data.campaign import Campaign
from ..data.errors import DataError, DeclarationError
from ..diagnosis.offset import JSBSIM_PREFIX, SimulatorBaseline, check_values
from .check import drive, load_aircraft, need_jsbsim
from .jsbsim_files import FILL_INPUTS
from .xml_functions import INPUTS, output_property

NEEDS = "diagnose --simulator jsbsim:... evaluates a JSBSim aircraft"


def locate(target: str) -> tuple[Path | None, str]:
    """JSBSim's root directory and the aircraft's name (root None: JSBSim's own aircraft)."""
    path = Path(target)
    if path.is_dir():
        path = path.resolve()
        if (path / f"{path.name}.xml").is_file() and path.parent.name == "aircraft":
            return path.parent.parent, path.name
        found = sorted(d.name for d in (path / "aircraft").glob("*") if (d / f"{d.name}.xml").is_file())
        if len(found) == 1:
            return path, found[0]
        if found:
            raise DeclarationError(f"--simulator jsbsim:{target}: the directory holds the aircraft "
                                   f"{', '.join(found)}: name one (jsbsim:{target}/aircraft/{found[0]})")
        raise DeclarationError(f"--simulator jsbsim:{target}: no JSBSim aircraft here (neither <name>/<name>.xml "
                               "under aircraft/ nor an aircraft directory)")
    if os.sep in target or "/" in target:
        raise DeclarationError(f"--simulator jsbsim:{target}: no such directory")
    return None, target


def exported_by_structsearch(target: str) -> bool:
    """Whether ``jsbsim:TARGET`` is an export directory of ``structsearch export --format jsbsim`` (an xml file of
    its root declares the structsearch namespace's inputs); a name (one of JSBSim's own aircraft) is not."""
    path = Path(target)
    if not path.is_dir():
        return False
    try:
        root, _ = locate(target)
    except DeclarationError:
        return False
    marker = FILL_INPUTS.encode()
    for k, f in enumerate(sorted(Path(root).rglob("*.xml"))):
        if k >= 200:
            break
        try:
            if f.stat().st_size < 5_000_000 and marker in f.read_bytes():
                return True
        except OSError:
            continue
    return False


def jsbsim_baseline(target: str, campaign: Campaign, coefficient: str) -> SimulatorBaseline:
    """The JSBSim aircraft ``target``'s ``coefficient`` at every sample of ``campaign`` (module docstring)."""
    started = time.perf_counter()
    root, name = locate(target)
    fdm = load_aircraft(root, name, NEEDS)
    if fdm is None:
        where = "JSBSim's own aircraft" if root is None else str(root / "aircraft" / name)
        raise DeclarationError(f"--simulator jsbsim:{target}: JSBSim could not load the aircraft {name!r} ({where})")
    manager = fdm.get_property_manager()
    if manager.get_node(FILL_INPUTS, False) is None:
        raise DeclarationError(
            f"--simulator jsbsim:{target}: not an aircraft exported by structsearch (no {FILL_INPUTS} property): "
            "a JSBSim aircraft's own aerodynamics read aero/alpha-rad, aero/alphadot-rad_sec, aero/qbar-psf and "
            "velocities/q-rad_sec, which JSBSim computes from its integrated state and which cannot be set sample by "
            "sample; write its coefficient along the flight into the campaign and give --baseline-column")
    out = output_property(coefficient)
    if manager.get_node(out, False) is None:
        raise DeclarationError(f"--simulator jsbsim:{target}: the aircraft {name} does not model {coefficient} (no "
                               f"{out} property): export the model of {coefficient} with it")
    columns = [c for c, i in INPUTS.items() if manager.get_node(i.property, False) is not None]
    for c in columns:
        if c not in campaign.data:
            source = str(campaign.directory / "campaign.toml") if campaign.directory is not None else campaign.name
            raise DataError(f"the aircraft {name} reads this column ({INPUTS[c].property}), which the campaign lacks",
                            source=source, column=c)
    values = check_values(campaign, drive(fdm, campaign.data, columns, [out])[0], f"{JSBSIM_PREFIX}{name} {out}")
    detail = {"aircraft": name, "root": None if root is None else str(root), "property": out,
              "inputs": columns, "jsbsim_version": need_jsbsim(NEEDS).__version__,
              "seconds": round(time.perf_counter() - started, 2)}
    return SimulatorBaseline(coefficient, f"{JSBSIM_PREFIX}{name}", "jsbsim", values, detail)
