"""The files one run writes, as a set: a manifest written before and after them.

A run that is killed between two of its files (a new ``ranking.csv`` beside the previous run's tables) must
not pass for a whole one. Before its first file a writer records the run as incomplete; after its last it
records every file's sha256. A reader of those files asks :func:`check_set`: a set left incomplete, or a file
whose content is not the one its run recorded, is named, never read as if it belonged to the others.
"""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Iterable

from .atomic import write_json
from .errors import DataError
from .reading import MAX_TABLE_BYTES, excerpt, load_json, open_regular, shown


def manifest_path(out: Path, name: str) -> Path:
    return Path(out) / f"{name}_manifest.json"


def begin_set(out: Path, name: str) -> None:
    """Record that a run writing set ``name`` in ``out`` has started (and not finished)."""
    write_json(manifest_path(out, name), {"set": name, "complete": False, "files": {}})


def finish_set(out: Path, name: str, paths: Iterable[Path]) -> None:
    """Record the set ``name`` complete, with the sha256 of each of its files. Nothing of the run's time or
    process is written: the same run gives a byte-identical manifest."""
    out = Path(out)
    files = {Path(p).resolve().relative_to(out.resolve()).as_posix(): _sha256(Path(p)) for p in paths}
    write_json(manifest_path(out, name), {"set": name, "complete": True, "files": dict(sorted(files.items()))})


def listed_files(out: Path, name: str) -> set[str] | None:
    """The files the manifest of set ``name`` in ``out`` lists (None: no manifest, as for outputs written by hand
    or before manifests existed)."""
    path = manifest_path(out, name)
    if not path.exists():
        return None
    return set(_read(path, name)[1])


def _read(path: Path, name: str) -> tuple[bool, dict]:
    """A manifest's verdict and files; what is wrong with one is one error naming the file and its key (the
    reader's own errors, a FIFO, NUL bytes or a file too large, say theirs)."""
    doc = load_json(path)
    again = f"run the {name} again"
    if not isinstance(doc, dict):
        raise DataError(f"the {name} manifest is not a JSON object: {again}", source=str(path))
    for key, kind in (("complete", bool), ("files", dict)):
        if not isinstance(doc.get(key), kind):
            raise DataError(f"the {name} manifest's {key!r} is not a {'boolean' if kind is bool else 'table'}: "
                            f"{again}", source=str(path), column=key)
    for file, digest in doc["files"].items():
        if not isinstance(digest, str) or Path(file).is_absolute() or ".." in Path(file).parts:
            raise DataError(f"the {name} manifest lists {excerpt(file)} with {shown(digest)}, not a file of its "
                            f"directory with its digest: {again}", source=str(path), column="files")
    return doc["complete"], dict(doc["files"])


def check_set(out: Path, name: str, file: str) -> None:
    """Raise a DataError when ``out/file`` is part of an interrupted run of set ``name``, or not the file its run
    wrote. Outputs without a manifest (written by hand, or before manifests existed) pass."""
    path = manifest_path(out, name)
    if not path.exists():
        return
    complete, files = _read(path, name)
    target = Path(out) / file
    if not complete:
        raise DataError(f"written by a {name} that did not finish: run the {name} again to complete its files",
                        source=str(target))
    if file in files and target.exists() and _sha256(target) != files[file]:
        raise DataError(f"not the file the last {name} wrote (changed since, or written by another run): "
                        f"run the {name} again", source=str(target))


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open_regular(path, MAX_TABLE_BYTES) as f:   # a FIFO put in a file's place is refused, never waited on
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
