"""Issue 43: every command's --help says what it does, what it reads and writes, and shows a runnable example;
the top-level --help lists every command with a one-line summary."""
import argparse
import contextlib
import io
import shlex

import pytest

from structsearch.cli import build_parser


def _subparsers():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub


def _examples(subparser) -> list[str]:
    """The example command lines of a subparser's epilog (after "examples:"), their comments cut."""
    lines = subparser.epilog.split("examples:", 1)[1].strip().splitlines()
    return [line.split("#", 1)[0].strip() for line in lines if line.strip()]


def test_every_command_has_a_description_and_an_example():
    _, sub = _subparsers()
    for name, subparser in sub.choices.items():
        assert subparser.description and len(subparser.description) > 150, name
        assert "writes" in subparser.description or "Writes" in subparser.description, name
        assert subparser.epilog and "examples:" in subparser.epilog, name
        examples = _examples(subparser)
        assert examples and all(e.startswith(f"structsearch {name}") for e in examples), (name, examples)


def test_every_example_parses_with_the_options_it_names():
    """An example is runnable as written: its options are the command's, its values valid."""
    parser, sub = _subparsers()
    for name, subparser in sub.choices.items():
        for example in _examples(subparser):
            args = parser.parse_args(shlex.split(example)[1:])
            assert args.command == name, example


def test_the_top_level_help_lists_every_command_on_one_line():
    parser, sub = _subparsers()
    text = parser.format_help()
    summaries = {a.dest: a.help for a in sub._choices_actions}
    assert set(summaries) == set(sub.choices)
    for name, summary in summaries.items():
        assert summary and "\n" not in summary and len(summary) <= 64, name
        assert summary in text, name


@pytest.mark.parametrize("name", ["search", "demo", "grids"])
def test_a_command_help_prints_the_example_as_written(name, capsys):
    """The epilog keeps its lines (an example is not re-flowed into the paragraph)."""
    with pytest.raises(SystemExit), contextlib.redirect_stdout(io.StringIO()) as out:
        build_parser().parse_args([name, "--help"])
    assert f"\nexamples:\n  structsearch {name}" in out.getvalue()


def test_the_consoles_gap_is_the_tables_gap_to_best_and_never_reads_minus_zero():
    """The console's "next" and "passed over" figures are the ranking's gap to best (the tables' column), not
    a ratio of pooled MSEs: one comparison, one number."""
    from types import SimpleNamespace
    from structsearch.cli import _gap
    gaps = (0.0, -0.00012, 0.0004, -0.001, 0.107, float("nan"), None)
    assert [_gap(SimpleNamespace(placement=SimpleNamespace(gap=x))) for x in gaps] == \
        ["0%", "-0.012%", "+0.04%", "-0.1%", "+10.7%", "n/a", "n/a"]
