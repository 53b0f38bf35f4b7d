"""Reading files that anyone may have written: regular files only, bounded in size, decoded strictly, nested
to a bounded depth, and named only inside the directory they belong to.

A FIFO or a device would make a reader wait forever (or read without end), a sparse file of gigabytes would be
read whole, a name like ``../../etc/passwd`` (or a symbolic link to it) would leak another file into the
outputs, and a JSON or TOML document nested a few thousand levels deep ends the parser in a RecursionError.
Every reader of a file a user hands over goes through here and gets one project error naming the file.
"""
from __future__ import annotations

import io
import json
import os
import re
import stat
import tomllib
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import DataError, StructSearchError

MiB = 1 << 20
# The largest file of each kind read (a full flight-test record at 100 Hz is tens of MiB; a spec, a manifest or a
# fit document is kilobytes; a cache entry holds one fit's statistics).
MAX_DOCUMENT_BYTES = 16 * MiB      # TOML and JSON documents, ranking tables
MAX_CACHE_BYTES = 16 * MiB         # one cache entry
MAX_TABLE_BYTES = 1024 * MiB       # one maneuver file
# Nesting of JSON arrays and objects or TOML arrays and tables: the project writes at most a handful.
MAX_NESTING = 64
# The longest excerpt of a file an error line quotes.
EXCERPT = 80

ErrorType = Callable[[str, str], StructSearchError]


def data_error(source: str, message: str) -> StructSearchError:
    return DataError(message, source=source)


def excerpt(text, limit: int = EXCERPT) -> str:
    """At most ``limit`` characters of ``text``, repr'd (an error line never carries a file's megabytes)."""
    text = str(text)
    return repr(text[:limit]) + (f" (and {len(text) - limit} more characters)" if len(text) > limit else "")


def shown(value, limit: int = EXCERPT) -> str:
    """A value read from a file as an error line shows it: a string as :func:`excerpt`, anything else (a table, a
    list, a number) as its repr cut to ``limit`` characters."""
    if isinstance(value, str):
        return excerpt(value, limit)
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def regular_file(path: Path | str, limit: int, error: ErrorType = data_error) -> os.stat_result:
    """The stat of ``path`` (symbolic links followed), refused unless it is a regular file of at most ``limit``
    bytes: checked before anything opens it, so a FIFO never blocks and a huge file is never read."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(str(path), "not found") from None
    except OSError as exc:
        raise error(str(path), f"cannot read it: {exc.strerror}") from None
    _check_stat(st, path, limit, error)
    return st


def _check_stat(st: os.stat_result, path, limit: int, error: ErrorType) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise error(str(path), f"{_kind(st.st_mode)}, not a regular file: only regular files are read")
    if st.st_size > limit:
        raise error(str(path), f"{st.st_size} bytes, more than the {limit // MiB} MiB such a file may have")


def open_regular(path: Path | str, limit: int, error: ErrorType = data_error, no_nul: bool = False) -> "BoundedReader":
    """``path`` opened for reading as a :class:`BoundedReader`: opened without blocking (a FIFO that appeared
    after a stat does not hang the open) and checked again on the open file."""
    regular_file(path, limit, error)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise error(str(path), f"cannot read it: {exc.strerror}") from None
    try:
        _check_stat(os.fstat(fd), path, limit, error)
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return BoundedReader(fd, path, limit, error, no_nul)


class BoundedReader(io.RawIOBase):
    """A file that refuses to give more than ``limit`` bytes (a file that grows while it is read) and, with
    ``no_nul``, any NUL byte (a binary or sparse file), naming the byte offset."""

    def __init__(self, fd: int, path, limit: int, error: ErrorType, no_nul: bool = False):
        super().__init__()
        self._fd, self.path, self.limit, self.error, self.no_nul = fd, path, limit, error, no_nul
        self.offset = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        want = min(len(buffer), self.limit + 1 - self.offset)
        if want <= 0:
            raise self.error(str(self.path), f"more than the {self.limit // MiB} MiB such a file may have "
                                             "(it grew while it was read)")
        chunk = os.read(self._fd, want)
        nul = chunk.find(b"\0") if self.no_nul else -1
        if nul >= 0:
            raise self.error(str(self.path), f"not a text file: a NUL byte at byte offset {self.offset + nul}")
        buffer[:len(chunk)] = chunk
        self.offset += len(chunk)
        return len(chunk)

    def close(self) -> None:
        if not self.closed:
            os.close(self._fd)
        super().close()


def read_bytes(path: Path | str, limit: int = MAX_DOCUMENT_BYTES, error: ErrorType = data_error) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (at most ``limit + 1`` are ever read)."""
    with open_regular(path, limit, error) as raw:
        chunks, size = [], 0
        while True:
            chunk = raw.read(min(MiB, limit + 1 - size) or 1)
            if not chunk:
                return b"".join(chunks)
            chunks.append(chunk)
            size += len(chunk)


def decode(content: bytes, path, error: ErrorType = data_error) -> str:
    """UTF-8 text (a leading byte-order mark dropped); another encoding is one error naming the byte offset."""
    try:
        return content.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(str(path), f"not UTF-8 text: byte {content[exc.start:exc.start + 1]!r} at byte offset "
                               f"{exc.start} (save it as UTF-8)") from None


def read_text(path: Path | str, limit: int = MAX_DOCUMENT_BYTES, error: ErrorType = data_error) -> str:
    return decode(read_bytes(path, limit, error), path, error)


# What holds no bracket that nests: strings and comments (TOML), strings (JSON). Every pattern matches once it
# has started (an unclosed string runs to the end of its line or of the text), so a substitution is linear in the
# text however many quotes are left open (a pattern that could fail after a long scan would be quadratic).
_TOML_INERT = re.compile(r'"""[\s\S]*?(?:"""|\Z)|\'\'\'[\s\S]*?(?:\'\'\'|\Z)|"(?:[^"\\\n]|\\.)*"?|\'[^\'\n]*\'?|#[^\n]*')
_JSON_INERT = re.compile(r'"(?:[^"\\]|\\.)*"?', re.DOTALL)


def bracket_depth(text: str, inert: re.Pattern) -> int:
    """The deepest nesting of [ and { in ``text`` outside its strings (and comments): counted before a parser
    recurses into it."""
    stripped = inert.sub("", text)
    codes = np.frombuffer(stripped.encode("utf-8", "replace"), np.uint8)
    steps = np.zeros(len(codes), np.int64)
    steps[(codes == ord("[")) | (codes == ord("{"))] = 1
    steps[(codes == ord("]")) | (codes == ord("}"))] = -1
    return int(np.cumsum(steps).max(initial=0))


def value_depth(value) -> int:
    """The nesting depth of parsed lists and tables (TOML's dotted keys nest without brackets), walked
    without recursion."""
    deepest, todo = 0, [(value, 1)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, dict):
            items = item.values()
        elif isinstance(item, list):
            items = item
        else:
            continue
        deepest = max(deepest, depth)
        if depth > MAX_NESTING:
            return depth
        todo.extend((v, depth + 1) for v in items)
    return deepest


def _check_depth(text: str, inert: re.Pattern, path, error: ErrorType) -> None:
    depth = bracket_depth(text, inert)
    if depth > MAX_NESTING:
        raise error(str(path), f"nested {depth} levels deep, more than the {MAX_NESTING} such a file may have")


def parse_toml(text: str, path, error: ErrorType = data_error) -> dict:
    """A TOML document, its nesting bounded before and after parsing."""
    _check_depth(text, _TOML_INERT, path, error)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(str(path), f"not valid TOML: {exc}") from None
    except RecursionError:
        raise error(str(path), f"nested more than the {MAX_NESTING} levels such a file may have") from None
    if value_depth(doc) > MAX_NESTING:
        raise error(str(path), f"nested more than the {MAX_NESTING} levels such a file may have")
    return doc


def parse_json(text: str, path, error: ErrorType = data_error):
    """A JSON document, its nesting bounded before and after parsing."""
    _check_depth(text, _JSON_INERT, path, error)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(str(path), f"not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    except (RecursionError, ValueError) as exc:
        raise error(str(path), f"not valid JSON: {excerpt(exc)}") from None


def load_toml(path: Path | str, error: ErrorType = data_error, limit: int = MAX_DOCUMENT_BYTES) -> dict:
    return parse_toml(read_text(path, limit, error), path, error)


def load_json(path: Path | str, error: ErrorType = data_error, limit: int = MAX_DOCUMENT_BYTES):
    return parse_json(read_text(path, limit, error), path, error)


def inside(directory: Path | str, name: str, source: str, column: str | None = None) -> Path:
    """``directory / name`` when it resolves (symbolic links followed) inside ``directory``: an absolute name, a
    ``..`` or a link that leads elsewhere is refused, and nothing of the file it leads to is read."""
    directory = Path(directory)
    target = directory / name
    try:
        resolved, home = target.resolve(), directory.resolve()
    except (OSError, RuntimeError):   # a loop of symbolic links
        raise DataError(f"{excerpt(name)} cannot be resolved (a loop of symbolic links?)", source=source,
                        column=column) from None
    if Path(name).is_absolute() or not resolved.is_relative_to(home):
        raise DataError(f"{excerpt(name)} leads outside the directory {home} (an absolute path, '..' or a "
                        "symbolic link): only files inside it are read", source=source, column=column)
    return target
