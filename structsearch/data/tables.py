"""One maneuver file's columns: CSV, Parquet (optional ``pyarrow``) or MATLAB ``.mat``.

A CSV file's data rows carry their file lines (:class:`CsvLines`) for the error messages that name one.
"""
from __future__ import annotations

import functools
import io
from pathlib import Path

import numpy as np

from .errors import DataError, StructSearchError
from .reading import MAX_TABLE_BYTES, excerpt, open_regular, read_bytes, regular_file


def read_table(path: Path) -> dict[str, np.ndarray]:
    """The columns of one maneuver file by name (a CSV file's also its rows' file lines under LINE_KEY)."""
    suffix = path.suffix.lower()
    if not path.exists():
        raise DataError("maneuver file not found", source=str(path))
    regular_file(path, MAX_TABLE_BYTES)   # a FIFO, a device or a huge (sparse) file is refused before it is opened
    import pandas as pd
    if suffix == ".csv":
        header = csv_header(path)
        try:   # read through a reader that stops at the size bound and at a NUL byte, wherever they come
            with io.BufferedReader(open_regular(path, MAX_TABLE_BYTES, no_nul=True)) as raw:
                frame = pd.read_csv(raw)
        except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
            if isinstance(exc, StructSearchError):
                raise
            raise DataError(f"cannot read CSV: {excerpt(' '.join(str(exc).split()), 200)}", source=str(path)) from None
        frame.columns = header if len(header) == len(frame.columns) else frame.columns
    elif suffix == ".parquet":
        try:
            frame = pd.read_parquet(path)
        except (ValueError, OSError) as exc:  # pyarrow's ArrowInvalid is a ValueError
            raise DataError(f"cannot read Parquet: {excerpt(' '.join(str(exc).split()), 200)}",
                            source=str(path)) from None
        except ImportError:
            raise DataError("reading Parquet needs the optional dependency pyarrow "
                            "(pip install 'structsearch[parquet]')", source=str(path)) from None
        _unique_names([str(c) for c in frame.columns], path)
    elif suffix == ".mat":
        return read_mat(path)
    else:
        raise DataError(f"unsupported maneuver file type {suffix!r} (csv, parquet, mat)", source=str(path))
    out = {}
    lines = CsvLines(path, len(frame)) if suffix == ".csv" else None
    for col in frame.columns:
        values = frame[col]
        if pd.api.types.is_bool_dtype(values):
            raise DataError("holds booleans (true/false), not numbers", source=str(path), column=str(col))
        if not pd.api.types.is_numeric_dtype(values):
            numeric = pd.to_numeric(values.astype(object), errors="coerce")
            bad = np.flatnonzero(numeric.isna() & values.notna())
            if bad.size:
                where = f" (line {int(lines[bad[0]])})" if lines is not None and len(lines) else ""
                raise DataError(f"value {excerpt(values.iloc[bad[0]])} is not a number{where}", source=str(path),
                                column=str(col), row=int(bad[0]))
            values = numeric
        out[str(col)] = values.to_numpy(dtype=float)
    if lines is not None:
        out[LINE_KEY] = lines
    return out


# How much of a CSV file is read before it is known to be text with a header line.
SNIFF_BYTES = 64 * 1024


def csv_header(path: Path) -> list[str]:
    """The column names of a CSV file's first line, after checking from its first kilobytes that it is text
    (no NUL byte, UTF-8) whose first line is a header of distinct names, not numbers: a binary or huge file is
    refused before it is read whole."""
    with open_regular(path, MAX_TABLE_BYTES) as f:
        head = f.read(SNIFF_BYTES)
    if b"\0" in head:
        raise DataError("cannot read CSV: not a text file (it holds NUL bytes): a maneuver file is CSV text", source=str(path))
    first, newline, _ = head.partition(b"\n")
    if not newline and len(head) == SNIFF_BYTES:
        raise DataError(f"cannot read CSV: the first line is longer than {SNIFF_BYTES // 1024} KiB: not a CSV header",
                        source=str(path))
    try:
        text = first.decode("utf-8-sig").strip("\r")
    except UnicodeDecodeError:
        raise DataError("cannot read CSV: the first line is not UTF-8 text", source=str(path)) from None
    import csv
    names = next(csv.reader([text]), [])
    if not names or not any(n.strip() for n in names):
        raise DataError("cannot read CSV: the first line is empty: it must name the columns (t,alpha,q,V,de,...)", source=str(path))
    numeric = [n for n in names if _is_number(n)]
    if len(numeric) == len(names):
        raise DataError(f"cannot read CSV: the first line {text[:60]!r} holds numbers, not column names (t,alpha,q,V,de,...)",
                        source=str(path))
    _unique_names(names, path)
    return names


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _unique_names(names: list[str], path: Path) -> None:
    seen = set()
    for n in names:
        if n in seen:
            raise DataError("column appears twice", source=str(path), column=n)
        seen.add(n)


# Not a column: the CSV line of each row (pandas skips blank lines, so row + 2 is not always the line).
LINE_KEY = "__line__"


class CsvLines:
    """The 1-based file line of each data row of a CSV file, found when an error message asks for one
    (reading the file again costs a third of reading a campaign; a valid campaign never needs it). Empty
    (no line numbers rather than wrong ones) when :func:`_csv_lines` cannot tell them."""

    def __init__(self, path: Path, n_rows: int):
        self.path, self.n_rows = path, n_rows

    @functools.cached_property
    def lines(self) -> np.ndarray:
        found = _csv_lines(self.path, self.n_rows)
        return found if found is not None else np.empty(0)

    def __len__(self) -> int:
        return len(self.lines)

    def __getitem__(self, row):
        return self.lines[row]


def _csv_lines(path: Path, n_rows: int) -> np.ndarray | None:
    """1-based file line of each data row: the non-blank lines after the header; None (no line numbers
    rather than wrong ones) when they do not match the rows pandas read one to one (quoted newlines,
    form feeds, lone carriage returns)."""
    raw_lines = read_bytes(path, MAX_TABLE_BYTES).split(b"\n")
    if any(b"\r" in raw.rstrip(b"\r") or b'"' in raw for raw in raw_lines):
        return None
    filled = [i + 1 for i, raw in enumerate(raw_lines) if raw.strip(b" \t\r")]
    if len(filled) != n_rows + 1:
        return None
    return np.asarray(filled[1:], float)


def read_mat(path: Path | str) -> dict[str, np.ndarray]:
    """Columns of a MATLAB maneuver file: top-level variables, or the fields of its only struct."""
    from scipy.io import loadmat
    path = Path(path)
    regular_file(path, MAX_TABLE_BYTES)
    try:
        raw = loadmat(path, squeeze_me=True, struct_as_record=False)
    except (ValueError, OSError, NotImplementedError) as exc:
        raise DataError(f"cannot read MATLAB file: {excerpt(exc, 200)}", source=str(path)) from None
    variables = {k: v for k, v in raw.items() if not k.startswith("__")}
    if len(variables) == 1:
        (only,) = variables.values()
        if hasattr(only, "_fieldnames"):
            variables = {f: getattr(only, f) for f in only._fieldnames}
    out = {}
    for name, value in variables.items():
        arr = np.asarray(value)
        if arr.dtype.kind not in "fiu" or arr.ndim > 1:
            continue  # strings, nested structs and matrices are not sample columns
        out[name] = np.atleast_1d(arr).astype(float)
    lengths = {len(v) for v in out.values() if len(v) > 1}
    if len(lengths) > 1:
        raise DataError(f"columns have different lengths {sorted(lengths)}", source=str(path))
    return {k: v for k, v in out.items() if len(v) > 1}
