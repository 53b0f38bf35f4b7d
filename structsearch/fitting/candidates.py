"""Candidate model structures and the grids that hold them (declared in model_specs/ or in code)."""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field

from ..data.errors import DeclarationError

# Where a pitch candidate's C_m is taken about (docs/interfaces.md 7.5): the recorded cg, or the fixed
# ``[aircraft] reference_point``, moved to the recorded cg by the known transfer (structsearch.data.moment_transfer).
MOMENT_REFERENCES = ("cg", "fixed")


# a wing state's angle of attack: alpha, plus or minus a number times p* (parsed, never evaluated)
_DRIVE = re.compile(r"\s*alpha\s*([+-])\s*(?:([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*\*\s*pstar|pstar\s*\*\s*"
                    r"([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?))\s*")


def parse_drives(table, where: str) -> tuple[tuple[str, float], ...]:
    """A ``drive`` table (wing state symbol -> "alpha - 0.5*pstar") as (state name, drive) pairs; one error naming
    ``where`` and the state for anything else."""
    if not isinstance(table, dict):
        raise DeclarationError(f"{where}: drive is a table of wing states, such as "
                               "{ X_left = \"alpha - 0.5*pstar\", X_right = \"alpha + 0.5*pstar\" }")
    out = []
    for symbol, text in table.items():
        m = _DRIVE.fullmatch(text) if isinstance(text, str) else None
        if not symbol.startswith("X_") or not symbol[2:].isidentifier() or m is None:
            raise DeclarationError(f"{where}: drive {symbol!r} = {text!r}: a wing state X_<name> read at "
                                   "\"alpha + NUMBER*pstar\" or \"alpha - NUMBER*pstar\" (p* = p b / (2 V))")
        number = float(m[2] or m[3])
        out.append((symbol[2:], number if m[1] == "+" else -number))
    return tuple(out)


def drive_text(drive: float) -> str:
    """The angle of attack a wing state of ``drive`` reads, as a drive table writes it."""
    return f"alpha {'+' if drive >= 0 else '-'} {abs(drive):g}*pstar"


@dataclass(frozen=True)
class Candidate:
    """One model structure of a grid.

    ``forms``: the static separation curve of each state that does not have the default tanh ((state name,
    form) pairs, :mod:`structsearch.engine.static_forms`); kept in the order of ``states``, without the tanh
    and without a state the candidate does not have (a move that removes a state drops its form).
    """

    name: str
    grid: str
    coefficient: str
    regressors: tuple[tuple[str, str], ...]
    states: tuple[tuple[str, str], ...] = ()
    lift: str | None = None
    note: str = ""
    bounds: tuple[tuple[str, tuple[float, float]], ...] = ()
    forms: tuple[tuple[str, str], ...] = ()
    # per-flight nuisance parameters estimated with it (.flight_effects.EFFECTS; docs/interfaces.md 7.5)
    flight_effects: tuple[str, ...] = ()
    moment_reference: str = "cg"   # MOMENT_REFERENCES; "fixed" for a pitch candidate only
    # known terms (name, expression) added to the output with their coefficient fixed at 1, never estimated (a
    # simulator's term taken out of a fixed offset: structsearch.diagnosis.offset)
    known: tuple[tuple[str, str], ...] = ()
    # a lift-fed structure's wing states (name, drive): each the lift model's wing state (its only state, or its
    # "w") at the wing's own angle of attack alpha + drive p* (structsearch.engine.separation.SeparationState)
    wings: tuple[tuple[str, float], ...] = ()

    def __post_init__(self):
        given = dict(self.forms)
        kept = tuple((n, given[n]) for n, _ in self.states if given.get(n, "tanh") != "tanh")
        if kept != self.forms:
            object.__setattr__(self, "forms", kept)
        if self.moment_reference not in MOMENT_REFERENCES:
            raise DeclarationError(f"candidate {self.name!r}: moment_reference must be one of "
                                   f"{', '.join(MOMENT_REFERENCES)}, not {self.moment_reference!r}")
        if self.moment_reference == "fixed" and self.coefficient != "Cm":
            raise DeclarationError(f"candidate {self.name!r}: moment_reference = \"fixed\" is for a pitch (Cm) "
                                   f"candidate, not a {self.coefficient} one")

    def form_of(self, state: str) -> str:
        """The static separation form of state ``state`` ("tanh" unless declared otherwise)."""
        return dict(self.forms).get(state, "tanh")

    @property
    def separation_states(self):
        """Its own states as :class:`~structsearch.engine.separation.SeparationState` (kind and form)."""
        from ..engine.separation import SeparationState
        return tuple(SeparationState(n, k, self.form_of(n)) for n, k in self.states)

    @property
    def n_linear(self) -> int:
        return len(self.regressors)

    @property
    def state_parameters(self) -> tuple[str, ...]:
        """The separation parameters of its own states (a drag or pitch candidate's come from its lift)."""
        return tuple(p for s in self.separation_states for p in s.parameters)

    def with_bounds(self, overrides) -> "Candidate":
        """The same candidate with the search boxes in ``overrides`` ((name, (lo, hi)) pairs) that concern
        its own separation parameters replacing the declared ones (the command line wins)."""
        mine = {k: tuple(v) for k, v in overrides if k in self.state_parameters}
        if not mine:
            return self
        merged = {**dict(self.bounds), **mine}
        return dataclasses.replace(self, bounds=tuple(sorted(merged.items())))

    def with_moment_reference(self, reference: str | None) -> "Candidate":
        """This candidate with C_m taken about ``reference`` ("cg" or "fixed"; ``--moment-reference``): a pitch
        candidate's changes, any other's and None leave it as declared."""
        if reference is None or self.coefficient != "Cm" or reference == self.moment_reference:
            return self
        return dataclasses.replace(self, moment_reference=reference)

    def to_dict(self) -> dict:
        """Its fields as JSON; ``x0`` (state -> form) only when a state has a form other than the tanh,
        ``flight_effects`` only when it has some and ``moment_reference`` only when it is not the cg, so that a
        structure without them writes what it wrote (and keeps the cache key it had) before they existed."""
        out = {"name": self.name, "grid": self.grid, "coefficient": self.coefficient,
               "regressors": dict(self.regressors), "states": dict(self.states), "lift": self.lift,
               "note": self.note, "bounds": {k: list(v) for k, v in self.bounds}}
        if self.forms:
            out["x0"] = dict(self.forms)
        if self.flight_effects:
            out["flight_effects"] = list(self.flight_effects)
        if self.moment_reference != "cg":
            out["moment_reference"] = self.moment_reference
        if self.known:
            out["known"] = dict(self.known)
        if self.wings:
            out["drive"] = {f"X_{n}": drive_text(d) for n, d in self.wings}
        return out

    @classmethod
    def from_dict(cls, d) -> "Candidate":
        """The candidate of :meth:`to_dict` (an exact round trip; without ``x0`` every state is a tanh)."""
        return cls(d["name"], d["grid"], d["coefficient"], tuple(d["regressors"].items()), tuple(d["states"].items()),
                   d["lift"], d.get("note", ""), tuple((k, tuple(v)) for k, v in d.get("bounds", {}).items()),
                   tuple(d.get("x0", {}).items()), flight_effects=tuple(d.get("flight_effects", ())),
                   moment_reference=d.get("moment_reference", "cg"), known=tuple(d.get("known", {}).items()),
                   wings=parse_drives(d.get("drive", {}), f"candidate {d['name']!r}"))


@dataclass(frozen=True)
class Grid:
    name: str
    coefficient: str
    candidates: tuple[Candidate, ...]
    source: str = ""
    lift_grid: "Grid | None" = field(default=None, repr=False)

    def __getitem__(self, name: str) -> Candidate:
        for c in self.candidates:
            if c.name == name:
                return c
        raise DeclarationError(f"grid {self.name!r} has no candidate {name!r}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.candidates)


_ROMAN = [(1000, "M"), (900, "CM"), (500, "D"), (400, "CD"), (100, "C"), (90, "XC"), (50, "L"),
          (40, "XL"), (10, "X"), (9, "IX"), (5, "V"), (4, "IV"), (1, "I")]


def roman(n: int) -> str:
    out = ""
    for value, letters in _ROMAN:
        while n >= value:
            out += letters
            n -= value
    return out


def from_roman(text: str) -> int | None:
    values = {"I": 1, "V": 5, "X": 10, "L": 50, "C": 100, "D": 500, "M": 1000}
    if not text or any(ch not in values for ch in text):
        return None
    total = 0
    for a, b in zip(text, text[1:] + " "):
        v = values[a]
        total += -v if b != " " and values.get(b, 0) > v else v
    return total if roman(total) == text else None
