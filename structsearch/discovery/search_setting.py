"""One structure search, two settings: what ``diagnose`` and ``discover`` differ in, made once and passed as
one object (:class:`SearchSetting`). Both run the same search over moves (:mod:`.explore`) judged against the
noise floor (:func:`structsearch.diagnosis.diagnose.diagnose_search`); a diagnosis adopts moves that close the
gap and leaves the static separation forms alone, ``discover`` makes every kind of move and also adopts moves
that only simplify within one standard error."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..data.errors import DeclarationError
from .adoption import DEFAULT_ALPHA
from .explore import DEFAULT_BEAM, DEFAULT_MAX_STEPS
from .moves import DIAGNOSE_KINDS, DISCOVER_KINDS, MOVE_KINDS


@dataclass(frozen=True)
class SearchSetting:
    """How a structure search runs: the move ``kinds`` it makes (names of :data:`~.moves.MOVE_KINDS`),
    whether it adopts moves that only ``simplify``, whether the diagnosis compares the separation state with the
    baseline's (``state_level``), the ``beam`` width, the most ``max_rounds`` and the adoption test's ``alpha``."""

    kinds: tuple[str, ...]
    simplify: bool
    state_level: bool
    beam: int = DEFAULT_BEAM
    max_rounds: int = DEFAULT_MAX_STEPS
    alpha: float = DEFAULT_ALPHA

    def __post_init__(self):
        unknown = [k for k in self.kinds if k not in MOVE_KINDS]
        if unknown or not self.kinds:
            raise DeclarationError(f"move kinds {', '.join(map(repr, unknown)) or '(none)'}: each one of "
                                   f"{', '.join(MOVE_KINDS)}")
        if self.max_rounds < 1:
            raise DeclarationError(f"a structure search needs at least one round, not {self.max_rounds}")
        if self.beam < 1:
            raise DeclarationError(f"a structure search needs a beam of at least 1, not {self.beam}")

    def but(self, **changes) -> "SearchSetting":
        """This setting with ``changes``; a change given as None keeps this setting's value (a command's
        option left out)."""
        kept = {k: (tuple(v) if k == "kinds" else v) for k, v in changes.items() if v is not None}
        return dataclasses.replace(self, **kept)


DIAGNOSE = SearchSetting(kinds=DIAGNOSE_KINDS, simplify=False, state_level=True)
DISCOVER = SearchSetting(kinds=DISCOVER_KINDS, simplify=True, state_level=False)
