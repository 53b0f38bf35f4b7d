"""What the commands print: the search's winners, skipped candidates, a report's notes (kept apart from
:mod:`.main`, which runs the commands)."""
from __future__ import annotations


def _truth_words(name: str) -> str:
    """The simulated truth, in words (the default one has no other name than "truth")."""
    return "the default (the thesis' identified models)" if name == "truth" else name


def _parameters(n: int) -> str:
    return f"{n} parameter" + ("" if n == 1 else "s")


def _held_out(s) -> str:
    if s.cv is None:
        return "validation"
    return (f"{s.cv_folds}-fold {'blocked ' if s.cv_scheme == 'blocks' else ''}"
            f"{'one-step ' if s.cv_method == 'one-step' else ''}CV")


def _clip(line: str) -> str:
    from ..fitting.fitter import console_line   # imported late: the command line's start stays light
    return console_line(line)


def _named(names: list[str], shown: int = 3) -> str:
    """Names listed, or the first few and how many more (a long list would make a line of hundreds)."""
    return ", ".join(names) if len(names) <= shown else f"{', '.join(names[:shown])} and {len(names) - shown} more"


def _print_winners(result) -> None:
    from ..grid_search.answer import answer_of
    from ..grid_search.ranking import passed_over
    for grid, ranked in result.grids.items():
        ok = [s for s in ranked if not s.failed]
        skipped = [s for s in ranked if s.not_applicable]
        failed = len(ranked) - len(ok) - len(skipped)
        if not ok:
            print(f"{grid}: every candidate " + ("failed" if failed else "was skipped"))
            _print_skipped(skipped)
            continue
        best, runner_up = ok[0], (ok[1] if len(ok) > 1 else None)
        # without cross-validation the held-out MSE is the validation MSE: said once
        scores = f"{_held_out(best)} MSE {best.comparison.mse:.4g}" + (
            f", validation MSE {best.mse_validation:.4g}" if best.cv is not None else "")
        answer = answer_of(ranked)
        # rank 1 is the answer only when it is admissible and near the best fit: otherwise the line says so first
        no_answer = answer is not None and not answer.answered and best.placement.admissible
        parts = [f"{grid}: " + ("no answer, rank 1 " if no_answer else "")
                 + f"{best.name} ({_parameters(best.n_params)}, {scores})"]
        n_admissible = sum(bool(s.placement.admissible) for s in ok)
        parts.append(f"{n_admissible} of {len(ok)} admissible" if best.placement.admissible else
                     f"NOT admissible (none of {len(ok)} is)")
        # the warnings before the runner-up and the time: a line cut at the console's width loses those last
        if failed:
            parts.append(f"{failed} failed")
        not_converged = [s.name for s in ok if not s.optimizer.converged]
        if not_converged:
            parts.append(f"optimizer did not converge for {_named(not_converged)}")
        if runner_up is not None:
            parts.append(f"next {runner_up.name} ({_parameters(runner_up.n_params)}, gap {_gap(runner_up)})")
        parts.append(f"{result.seconds[grid]:.1f} s")
        print(_clip("; ".join(parts)))
        if answer is not None and not answer.answered:
            # the whole sentence, uncut: it is the search's answer
            print(f"  {grid}: {answer.sentence()}")
        for s in passed_over(ranked)[:3]:
            print(_clip(f"  passed over {s.name} (gap {_gap(s)}): {'; '.join(s.placement.reasons)}"))
        _print_skipped(skipped)


def _print_skipped(skipped) -> None:
    """One line per reason: the candidates the campaign cannot fit by their nature (not failures)."""
    from ..fitting.candidate_result import NOT_APPLICABLE
    by_reason: dict[str, list[str]] = {}
    for s in skipped:
        by_reason.setdefault(s.error[len(NOT_APPLICABLE):], []).append(s.name)
    for reason, names in by_reason.items():
        print(_clip(f"  skipped {_named(names)}: {reason}"))


def _gap(s) -> str:
    """The tables' "gap to best" of ``s`` (its mean per-maneuver relative excess of held-out MSE over the
    ranking's reference), as a signed percentage that never reads "-0.0%": the console and the tables give one
    number for one comparison. "n/a" when the ranking could not measure it."""
    from ..reporting.tables import signed_percent   # "n/a" for NaN
    return signed_percent(float("nan") if s.placement.gap is None else s.placement.gap)


def _print_report(res) -> None:
    for note in res.notes:
        print(f"note: {note}")
    drawn = (f"with {len(res.figures)} figure{'' if len(res.figures) == 1 else 's'} in {res.html.parent / 'figures'}"
             if res.figures else "without figures (the notes above say why)")
    print(f"wrote {res.html} {drawn} ({res.seconds:.0f} s)")
