"""Writing a campaign: ``campaign.toml`` and one file per maneuver, atomically (a temporary directory that replaces
the target, exchanged with it where the system can)."""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from .atomic import exchange_directories, remove_orphans, sync_path, umask
from .campaign_checks import AIRCRAFT_KEYS, REQUIRED
from .errors import DataError
from .reading import shown

if TYPE_CHECKING:   # annotations only: data.campaign imports this module to keep write_campaign its name
    from .campaign import Campaign, Maneuver


def _toml_value(v) -> str:
    if isinstance(v, Mapping):   # an inline table (the [source] of a campaign flown in a simulator)
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(int(v))
    return repr(float(v))


def write_campaign(campaign: Campaign, directory: Path | str, fmt: str = "csv") -> Path:
    """Write a campaign atomically: everything goes to a temporary directory that replaces the target."""
    if fmt not in ("csv", "parquet"):
        raise DataError(f"unknown campaign file format {shown(fmt)} (csv or parquet)")
    directory = Path(directory).resolve()   # a symbolic link: replace what it points to
    if directory.parent == directory:
        raise DataError("cannot write a campaign as the file-system root", source=str(directory))
    if directory.exists() and (not directory.is_dir() or (any(directory.iterdir())
                                                          and not (directory / "campaign.toml").exists())):
        raise DataError("refusing to replace it: it exists and is not a campaign directory (no campaign.toml)",
                        source=str(directory))
    directory.parent.mkdir(parents=True, exist_ok=True)
    # named after this process: a run killed (-9) while writing leaves it, and the next writer removes it
    remove_orphans(directory.parent, f".{directory.name}.")
    tmp = Path(tempfile.mkdtemp(prefix=f".{directory.name}.{os.getpid()}-", dir=directory.parent))
    os.chmod(tmp, 0o777 & ~umask())
    try:
        lines = _manifest_head(campaign)
        for m, sl in zip(campaign.maneuvers, campaign.data.segment_slices()):
            lines += _maneuver_entry(m, f"{m.id}.{fmt}")
            _write_maneuver_file(campaign, sl, tmp / f"{m.id}.{fmt}", fmt)
        (tmp / "campaign.toml").write_text("\n".join(lines) + "\n", encoding="utf-8")
        for written in tmp.iterdir():   # flush the files before they become the campaign
            sync_path(written)
        sync_path(tmp)
        _put_in_place(tmp, directory)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return directory


def _manifest_head(campaign: Campaign) -> list[str]:
    """campaign.toml's lines before its maneuvers: the name, free metadata, the aircraft and the length rules."""
    lines = [f"name = {_toml_value(campaign.name)}", "", "[aircraft]"]
    lines += [f"{k} = {_toml_value(campaign.aircraft[k])}" for k in AIRCRAFT_KEYS]
    lines += [f"{k} = {_toml_value(v)}" for k, v in campaign.aircraft.items() if k not in AIRCRAFT_KEYS]
    for key, value in campaign.extra.items():
        lines.insert(1, f"{key} = {_toml_value(value)}")
    if not campaign.length_rules.is_default:
        lines += ["", "[min_convective_times]"] + [f"{k} = {_toml_value(v)}"
                                                   for k, v in campaign.length_rules.as_table().items()]
    if campaign.cutoffs_hz:
        lines += ["", "[cutoffs]"] + [f"{k} = {_toml_value(v)}" for k, v in campaign.cutoffs_hz.items()]
    return lines


def _maneuver_entry(m: Maneuver, file: str) -> list[str]:
    lines = ["", "[[maneuver]]", f"id = {_toml_value(m.id)}", f"file = {_toml_value(file)}",
             f"kind = {_toml_value(m.kind)}", f"split = {_toml_value(m.split)}"]
    if m.flight is not None:
        lines.append(f"flight = {_toml_value(m.flight)}")
    if m.record:
        lines.append(f"record = {_toml_value(m.record)}")
    if m.periodic:
        lines.append("periodic = true")
    if m.frequency is not None:
        lines.append(f"frequency = {_toml_value(m.frequency)}")
    if m.steady:
        lines.append("steady = true")
    return lines


def _write_maneuver_file(campaign: Campaign, rows: slice, path: Path, fmt: str) -> None:
    """One maneuver's rows, the required columns first, every float to its last bit (``%.17g``)."""
    import pandas as pd
    frame = pd.DataFrame({k: v[rows] for k, v in campaign.data.columns.items()})
    ordered = [c for c in ("t",) + REQUIRED[1:] if c in frame] + sorted(c for c in frame if c not in REQUIRED)
    frame = frame[ordered]
    if fmt == "csv":
        frame.to_csv(path, index=False, float_format="%.17g")
        return
    try:
        frame.to_parquet(path, index=False)
    except ImportError:
        raise DataError("writing Parquet needs the optional dependency pyarrow") from None


def _put_in_place(tmp: Path, directory: Path) -> None:
    """The written campaign ``tmp`` becomes ``directory`` (atomically where the system can exchange them)."""
    if directory.exists() and exchange_directories(tmp, directory):
        shutil.rmtree(tmp)          # the old campaign, now under the temporary name
    elif directory.exists():        # no atomic exchange here: a short window between two renames
        old = directory.with_name(f".{directory.name}.old")
        if old.exists():
            shutil.rmtree(old)
        os.replace(directory, old)
        os.replace(tmp, directory)
        shutil.rmtree(old)
    else:
        os.replace(tmp, directory)
    sync_path(directory.parent)
