"""The ``grids`` command: the shipped grids (or a grid spec file, or one candidate) with their equations."""
from __future__ import annotations


def _grids(args) -> int:
    from ..data.errors import DeclarationError
    from ..fitting.specs import BUILTIN_GRIDS, find_candidate, load_grid
    from ..grid_search.pipeline import grids_for
    from ..reporting.equations import equations, model_equation
    name = args.name
    if name is None:
        for grid in grids_for("all") + grids_for("lateral"):
            what = {c.coefficient for c in grid.candidates}
            print(f"{grid.name}: {len(grid.candidates)} candidates of {', '.join(sorted(what))} "
                  f"(structsearch grids {grid.name}: their states too)")
            for c in grid.candidates:
                states = ", ".join((f"X_{n}: {k}" if n else f"X: {k}") + ("" if c.form_of(n) == "tanh" else
                                                                         f" {c.form_of(n)}") for n, k in c.states)
                print(f"  {c.name}: {model_equation(c)}" + (f"  [{states}]" if states and not c.lift else ""))
        return 0
    if name in BUILTIN_GRIDS or name.endswith(".toml"):
        shipped = {g.name: g for g in grids_for("all") + grids_for("lateral")}
        shown = shipped[name] if name in BUILTIN_GRIDS else load_grid(name)
        candidates = list(shown.candidates)
    else:
        try:
            candidates = [find_candidate(name)]
        except DeclarationError as exc:
            raise DeclarationError(f"grids {name}: not a grid ({', '.join(BUILTIN_GRIDS)}), a grid spec file or a "
                                   f"candidate of the shipped grids ({exc})") from None
    for c in candidates:
        print(f"{c.grid} {c.name}" + (f" (on the lift model {c.lift})" if c.lift else "") + (f": {c.note}" if c.note else ""))
        for line in equations(c):
            print(f"    {line}")
    return 0
