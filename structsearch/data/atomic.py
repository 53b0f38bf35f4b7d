"""Atomic file output: write to a temporary file beside the target, flush it to disk, then rename.

Files get the mode a plain ``open(path, "w")`` would give (0666 less the umask), not mkstemp's
0600; the directory entry is synced after the rename so a crash leaves the old or the new file.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from pathlib import Path


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# read once at import, before any worker threads exist: setting the umask to read it is process-wide
_UMASK = _read_umask()


def umask() -> int:
    """The process umask (as read at import)."""
    return _UMASK


def sync_path(path: Path) -> None:
    """fsync a written file, or a directory so that a rename inside it survives a crash (best effort:
    some systems cannot fsync what is opened for reading, or a directory at all)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def process_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one of another user counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_orphans(directory: Path, prefix: str, suffix: str = "") -> None:
    """Remove ``prefix<pid>-...suffix`` files and folders in ``directory`` left by processes that no longer run
    (a run killed with -9 cannot remove its temporary files; the next run does)."""
    try:
        entries = list(directory.iterdir())
    except OSError:
        return
    for entry in entries:
        name = entry.name
        if not (name.startswith(prefix) and name.endswith(suffix)):
            continue
        pid = name[len(prefix):].split("-", 1)[0]
        if pid.isdigit() and not process_alive(int(pid)):
            try:
                shutil.rmtree(entry) if entry.is_dir() and not entry.is_symlink() else entry.unlink()
            except OSError:
                pass


def write_bytes(path: Path | str, content: bytes) -> Path:
    """Write ``content`` to ``path`` atomically. An error names ``path`` (not its temporary twin)."""
    path = Path(path)
    prefix = f".{path.name}."
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_orphans(path.parent, prefix, ".tmp")
        fd, tmp = tempfile.mkstemp(prefix=f"{prefix}{os.getpid()}-", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(content)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~umask())
        os.replace(tmp, path)
        sync_path(path.parent)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise
    return path


def write_text(path: Path | str, text: str) -> Path:
    return write_bytes(path, text.encode("utf-8"))


def json_ready(value):
    """``value`` with every non-finite float replaced by None: output is strict JSON, and a number
    that cannot be estimated is null, never 0 and never the non-standard NaN."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    return value


def write_json(path: Path | str, doc, indent: int = 2) -> Path:
    return write_text(path, json.dumps(json_ready(doc), indent=indent, allow_nan=False))


def exchange_directories(new: Path, target: Path) -> bool:
    """Swap two existing directories in one atomic step (Linux renameat2 RENAME_EXCHANGE); False where
    the system cannot, and the caller falls back to two renames."""
    import ctypes
    import sys
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    done = renameat2(at_fdcwd, os.fsencode(new), at_fdcwd, os.fsencode(target), rename_exchange) == 0
    if done:
        sync_path(Path(target).parent)
    return done


def remove_dead_runs(base: Path) -> None:
    """Remove what runs killed with -9 left: their ``structsearch-<pid>-*`` folders in ``base`` and the named
    semaphores their worker pools made (``/dev/shm/sem.loky-<pid>-*``; only of a pid that had such a folder, so
    never another program's)."""
    dead = set()
    for entry in _entries(base):
        pid = entry.name[len("structsearch-"):].split("-", 1)[0]
        if entry.name.startswith("structsearch-") and pid.isdigit() and not process_alive(int(pid)):
            dead.add(pid)
    for pid in sorted(dead):
        for semaphore in _entries(Path("/dev/shm")):
            if semaphore.name.startswith(f"sem.loky-{pid}-"):
                try:
                    semaphore.unlink()
                except OSError:
                    pass
    remove_orphans(base, "structsearch-")


def _entries(directory: Path) -> list[Path]:
    try:
        return list(directory.iterdir())
    except OSError:
        return []
