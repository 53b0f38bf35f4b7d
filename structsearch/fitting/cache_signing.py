"""Signatures of cache entries: who wrote an entry, not only that it is whole.

A cache entry's digest proves that its content is the one written with it, but anyone can edit the numbers and
compute the digest again: a cache directory received from elsewhere would then change a ranking silently. Each
entry is therefore signed with an HMAC-SHA256 under a key that lives outside every output directory, in the
user's cache folder (``$STRUCTSEARCH_CACHE_KEY_FILE``, else ``$XDG_CACHE_HOME/structsearch/cache.key``, else
``~/.cache/structsearch/cache.key``), made with mode 0600 on first use. An entry not signed under this key (an
edited one, or one from another user or machine) is refitted, never served.

Where no key can be kept or read (a read-only home, a key file of the wrong size), a key of this process only is
used: the run's own entries are served to itself, none of an earlier run.
"""
from __future__ import annotations

import hashlib
import hmac
import os
import secrets
from functools import lru_cache
from pathlib import Path

KEY_FILE_VARIABLE = "STRUCTSEARCH_CACHE_KEY_FILE"
KEY_BYTES = 32


def key_file() -> Path:
    """Where the signing key is kept."""
    if os.environ.get(KEY_FILE_VARIABLE):
        return Path(os.environ[KEY_FILE_VARIABLE])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "structsearch" / "cache.key"


@lru_cache(maxsize=4)
def _key(path: Path) -> bytes:
    try:
        return _read_key(path)
    except FileNotFoundError:
        pass
    except OSError:   # not a key (another size, a FIFO) or unreadable: this process's own, trusting no file
        return secrets.token_bytes(KEY_BYTES)
    try:
        return _create_key(path)
    except FileExistsError:       # another process made it first: use theirs
        return _read_key(path)
    except OSError:
        return secrets.token_bytes(KEY_BYTES)


def _read_key(path: Path) -> bytes:
    import stat
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size != KEY_BYTES:
            raise OSError(f"{path}: not a signing key of {KEY_BYTES} bytes")
        return os.read(fd, KEY_BYTES)
    finally:
        os.close(fd)


def _create_key(path: Path) -> bytes:
    """A new random key, written whole under a temporary name then linked to ``path`` (which fails if another
    process linked its key first): a reader never sees a half-written key."""
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    key = secrets.token_bytes(KEY_BYTES)
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        os.write(fd, key)
        os.fsync(fd)
    finally:
        os.close(fd)
    try:
        os.link(tmp, path)
    finally:
        os.unlink(tmp)
    return key


def signing_key() -> bytes:
    return _key(key_file())


def signature(question: str, digest: str) -> str:
    """The HMAC-SHA256 of an entry's question (its key) and content digest."""
    return hmac.new(signing_key(), f"{question}\n{digest}".encode(), hashlib.sha256).hexdigest()


def signed(question: str, digest: str, claimed) -> bool:
    return isinstance(claimed, str) and hmac.compare_digest(signature(question, digest), claimed)
