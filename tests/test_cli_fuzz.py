"""CLI fuzzing (issue 13): every subcommand, each option given an empty, negative, zero, huge, non-finite or
misspelled value, ends in one line on stderr and exit status 0 or 2, never a traceback.

Run it alone with ``python -m pytest -q tests/test_cli_fuzz.py -s`` (prints the number of cases). A valid
value is executed only where the command then stops on the missing campaign (so the fuzz never starts a
simulation or a search); otherwise parsing it is the case.
"""
import argparse
import contextlib
import io

import pytest

from structsearch.cli import build_parser, main

MISSING = "/nonexistent/structsearch-fuzz-campaign"
VALUES = ("", "-1", "0", "1e400", "nan", "-inf", "abc", "tau2_ss=1:0", "CL-XXX")
# what each subcommand needs so that only the fuzzed option is wrong
REQUIRED = {"fit": ["--data", MISSING, "--model", "CL-VI"], "search": ["--data", MISSING, "--grid", "lift"],
            "diagnose": ["--data", MISSING, "--model", "CL-VI"], "report": ["--data", MISSING],
            "export": ["--data", MISSING, "--model", "CL-VI", "--format", "json"]}
# subcommands whose valid options lead straight to reading the (missing) campaign
STOPS_ON_DATA = {"fit", "search", "diagnose", "report", "export"}


def _cases():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for command, subparser in sub.choices.items():
        for action in subparser._actions:
            if not action.option_strings or action.nargs == 0 or action.dest == "help":
                continue
            option = action.option_strings[0]
            for value in VALUES:
                base = list(REQUIRED.get(command, []))
                if option in base:   # fuzz a required option itself
                    i = base.index(option)
                    base = base[:i] + base[i + 2:]
                yield [command, *base, option, value]


CASES = list(_cases())


def _run(argv, tmp_path):
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:
            return int(exc.code or 0), err.getvalue(), False
        if args.command not in STOPS_ON_DATA or (args.command == "diagnose" and args.benchmark):
            return 0, "", False            # a valid value of a command that would start real work
        if hasattr(args, "out") and argv.count("--out") == 0:
            argv = argv + ["--out", str(tmp_path / "out")]
        try:
            code = main(argv)
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, err.getvalue(), True


def test_fuzzing_the_cli_gives_one_line_errors(tmp_path):
    executed = 0
    for argv in CASES:
        code, err, ran = _run(argv, tmp_path)
        executed += ran
        assert code in (0, 2), (argv, code, err)
        if code == 2:
            assert err.count("\n") == 1 and err.startswith("structsearch"), (argv, err)
            assert "Traceback" not in err
    print(f"\nCLI fuzz: {len(CASES)} cases, {executed} executed up to the campaign reader")
    assert len(CASES) > 300 and executed > 50


@pytest.mark.parametrize("argv,message", [
    (["fit", "--data", "x", "--model", "CL-VI", "--starts", "0"], "--starts: must be at least 1"),
    (["search", "--data", "x", "--grid", "lift", "--jobs", "-2"], "--jobs: must be 0 or more"),
    (["simulate", "--out", "x", "--scale", "2"], "--scale: must lie in (0, 1]"),
    (["bench", "--calibration", "--campaigns", "0"], "--campaigns: must be at least 1"),
    (["demo", "--max-correlation", "1.5"], "--max-correlation: must lie in (0, 1]"),
])
def test_bad_counts_and_ranges_are_named(argv, message, capsys):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_every_option_of_every_command_says_what_it_does():
    """Issue 31: `structsearch demo --help` showed `--starts` and `--quiet` without a word."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    silent = [f"{command} {action.option_strings[0]}" for command, subparser in sub.choices.items()
              for action in subparser._actions if action.option_strings and action.dest != "help" and not action.help]
    assert silent == []


@pytest.mark.parametrize("argv,hint", [
    (["search", "--data", MISSING, "--grid", "lifts"], "did you mean 'lift'?"),
    (["fit", "--data", MISSING, "--model", "CL-VIj"], "did you mean 'CL-VI'?"),
    (["fit", "--data", MISSING, "--model", "Cl-VIj"], "did you mean 'Cl-VI'?"),
    (["fit", "--data", MISSING, "--model", "cd-ixr"], "did you mean 'CD-IXr'?"),
])
def test_a_misspelled_grid_or_model_gets_the_close_match(argv, hint, tmp_path, capsys):
    """Issue 31: a misspelled name is answered with the shipped name it is closest to (the names are resolved
    before the campaign is read: the campaign here does not exist)."""
    code = main(argv + ["--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and hint in err and err.count("\n") == 1


def test_a_name_far_from_every_shipped_one_gets_no_guess(tmp_path, capsys):
    code = main(["fit", "--data", MISSING, "--model", "xyz", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "no candidate named 'xyz'" in err and "did you mean" not in err


def _synopsis():
    """(command, option, bracketed) for every option of the synopsis of the command-line reference
    (docs/reference/cli.md, section "Synopsis")."""
    import re
    from pathlib import Path
    page = (Path(__file__).resolve().parent.parent / "docs" / "reference" / "cli.md").read_text()
    block = page.split("## Synopsis", 1)[1].split("```text\n", 1)[1].split("```", 1)[0]
    entries, command = [], None
    for line in block.splitlines():
        text = line.strip()
        if text.startswith("structsearch "):
            command = text.split()[1]
            text = text[len("structsearch " + command):]
        depth = 0
        for token in re.findall(r"\[|\]|--[a-z][a-z-]*", text):
            depth += {"[": 1, "]": -1}.get(token, 0)
            if token.startswith("--"):
                entries.append((command, token, depth > 0))
    return entries


# required by the command unless another mode is chosen (diagnose --benchmark): checked when it runs
# (bench --trace FILE chooses its mode with a value: written bare on its own synopsis line)
# (export --model goes with its --data mode)
# (diagnose's simulator baseline, --baseline-column or --simulator, is a mode of its own; so is simulate --jsbsim)
REQUIRED_UNLESS_MODE = {("diagnose", "--data"), ("diagnose", "--model"), ("bench", "--trace"), ("export", "--model"),
                        ("diagnose", "--baseline-column"), ("diagnose", "--simulator"), ("simulate", "--jsbsim")}
# optional in one mode and required in another (diagnose --coefficient: a check with --model, the coefficient
# diagnosed with a simulator baseline): either way is right, per synopsis line
REQUIRED_IN_ONE_MODE = {("diagnose", "--coefficient")}


def test_the_synopsis_brackets_exactly_the_optional_options():
    """Issue 31: the synopsis wrote `--out DIR` as required where it has a default. An option is bracketed in
    the synopsis exactly when the parser does not require it (flags that choose a mode, such as `bench
    --discovery`, are written bare)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    entries = _synopsis()
    assert len(entries) > 40 and ("demo", "--out", True) in entries
    wrong = []
    for command, option, bracketed in entries:
        subparser = sub.choices[command]
        action = next((a for a in subparser._actions if option in a.option_strings), None)
        # one of a required group of alternatives (fit --model | --joint) is written bare, as a mode
        chosen = any(action in g._group_actions and g.required for g in subparser._mutually_exclusive_groups)
        required = action is not None and (action.required or chosen or (command, option) in REQUIRED_UNLESS_MODE)
        if action is None:
            wrong.append(f"{command} {option}: no such option")
        elif (command, option) in REQUIRED_IN_ONE_MODE:
            continue
        elif (bracketed and required) or (not bracketed and not required and action.nargs != 0):
            wrong.append(f"{command} {option}: {'bracketed' if bracketed else 'bare'} but "
                         f"{'required' if required else 'optional'}")
    assert wrong == []
