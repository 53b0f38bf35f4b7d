"""Exceptions raised by structsearch.

Every error a user can provoke with bad input or a bad declaration derives from
:class:`StructSearchError` (a :class:`ValueError`), so callers can catch one type
and the CLI can print one line.
"""
from __future__ import annotations


class StructSearchError(ValueError):
    """Base class of every user-facing error."""


class DeclarationError(StructSearchError):
    """A model, regressor or parameter declaration is inconsistent."""


class DataError(StructSearchError):
    """Input data is unusable; names the source, the column and the row."""

    def __init__(self, message: str, *, source: str | None = None,
                 column: str | None = None, row: int | None = None):
        self.source = source
        self.column = column
        self.row = row
        where = []
        if source is not None:
            where.append(f"file {source}")
        if column is not None:   # a column's name may come from a file: at most 80 characters of it
            where.append(f"column {column[:80]!r}" if isinstance(column, str) else f"column {column!r}")
        if row is not None:
            where.append(f"row {row}")
        prefix = (", ".join(where) + ": ") if where else ""
        super().__init__(prefix + message)


class FitError(StructSearchError):
    """The optimiser could not produce a usable fit."""
