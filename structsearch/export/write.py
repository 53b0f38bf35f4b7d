"""The files of ``structsearch export`` (docs/interfaces.md 7.6), written atomically."""
from __future__ import annotations

from pathlib import Path

from ..data.atomic import write_json, write_text
from ..data.errors import DeclarationError
from .aircraft import ENGINE, aircraft_name, aircraft_xml, direct_thruster_xml, engine_xml, fly_stall_script
from .card import ExportedModel
from .jsbsim_files import SYSTEM_NAME, aerodynamics_xml, system_xml

FORMATS = ("jsbsim", "json")


def write_export(model: ExportedModel, fmt: str, out: Path) -> list[Path]:
    """Write ``model`` in ``fmt`` under ``out``; the paths written. Everything is rendered before the first file
    is written, so an unmappable term leaves no half export behind."""
    out = Path(out)
    if fmt == "json":
        return [write_json(out / "model.json", model.to_dict())]
    if fmt != "jsbsim":
        raise DeclarationError(f"--format {fmt!r}: one of {', '.join(FORMATS)}")
    name = aircraft_name(model)
    files = {
        out / "aerodynamics.xml": aerodynamics_xml(model),
        out / "systems" / f"{SYSTEM_NAME}.xml": system_xml(model),
        out / "aircraft" / name / f"{name}.xml": aircraft_xml(model, name),
        out / "engine" / f"{ENGINE}.xml": engine_xml(float(model.aircraft["max_thrust_N"])),
        out / "engine" / "direct.xml": direct_thruster_xml(),
        out / "fly_stall.py": fly_stall_script(model, name),
    }
    return [write_text(path, text) for path, text in files.items()]
