"""``--modify FILE``: a modification of a JSBSim aircraft, read as data (TOML, never run)::

    [[scale]]
    function = "aero/coefficient/CLq"   # an axis function of the aircraft
    factor = 2.0                        # a finite number: the function is multiplied by it

Each error names the file and the entry.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..data.errors import DeclarationError
from ..data.reading import parse_toml, read_text

KEYS = ("scale",)
SCALE_KEYS = ("function", "factor")


def _refused(source: str, message: str) -> DeclarationError:
    return DeclarationError(f"{source}: {' '.join(message.split())}")


def _not_toml(source: str, message: str) -> DeclarationError:
    return DeclarationError(f"{source}: not a TOML file ({' '.join(message.removeprefix('not valid TOML: ').split())})")


def read_modify(path: str | Path) -> dict[str, float]:
    """The modification in ``path`` as function -> factor."""
    path = Path(path)
    # a file from anyone: a regular file of bounded size, UTF-8, its nesting bounded (structsearch.data.reading)
    try:
        doc = parse_toml(read_text(path, error=_refused), path, _not_toml)
    except OSError as exc:
        raise DeclarationError(f"{path}: cannot read the modification ({exc.strerror})") from None
    unknown = [k for k in doc if k not in KEYS]
    if unknown:
        raise DeclarationError(f"{path}: unknown key {unknown[0]!r} (a modification holds [[scale]] entries)")
    entries = doc.get("scale")
    if not isinstance(entries, list) or not entries:
        raise DeclarationError(f"{path}: no [[scale]] entry (function = \"aero/coefficient/...\", factor = 2.0)")
    out: dict[str, float] = {}
    for i, e in enumerate(entries, 1):
        where = f"{path}: [[scale]] entry {i}"
        if not isinstance(e, dict) or sorted(e) != sorted(SCALE_KEYS):
            raise DeclarationError(f"{where}: give exactly function = \"...\" and factor = NUMBER")
        f, factor = e["function"], e["factor"]
        if not isinstance(f, str) or not f.strip():
            raise DeclarationError(f"{where}: function must be the name of an axis function")
        if isinstance(factor, bool) or not isinstance(factor, (int, float)) or not math.isfinite(factor):
            raise DeclarationError(f"{where}: factor must be a finite number, not {factor!r}")
        if f in out:
            raise DeclarationError(f"{where}: {f} is scaled twice")
        out[f.strip()] = float(factor)
    return out
