"""Issue 43: a long run shows a progress bar on a terminal in place of a line per candidate, and nothing of it
when stderr is not a terminal (a log file, a CI job): the summary lines stay."""
import io
import re

import pytest

from structsearch.cli.progress import TerminalProgress

# what a line per candidate used to look like ("[3/12] separation X S: 0.6 s (14 s elapsed)")
PER_CANDIDATE = re.compile(r"^\[\d+/\d+\] ", re.M)


@pytest.fixture(scope="module")
def tiny(campaign_on_disk):
    return campaign_on_disk(seed=1, scale=0.05, slow_errors=0.0)


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


def _fit_call(progress, n=12, grid="separation"):
    """What the fitting layer tells in one fit call of ``n`` candidates: a summary line, then the meter."""
    progress(f"grid {grid}: {n} candidates")
    for k in range(1, n + 1):
        progress.meter(k, n, f"{grid} C-{k}")


def test_a_stream_that_is_not_a_terminal_gets_the_lines_and_no_bar():
    stream = io.StringIO()
    progress = TerminalProgress(stream, delay=0)
    _fit_call(progress)
    _fit_call(progress, 5, "lift")
    progress.close()
    text = stream.getvalue()
    assert text == "grid separation: 12 candidates\ngrid lift: 5 candidates\n"
    assert "\r" not in text and "|" not in text and not PER_CANDIDATE.search(text)


def test_a_terminal_gets_a_bar_that_is_erased_when_the_call_ends():
    stream = FakeTerminal()
    progress = TerminalProgress(stream, delay=0)
    _fit_call(progress)
    text = stream.getvalue()
    assert "grid separation: 12 candidates\n" in text
    assert "\r" in text and "separation:" in text and "fit" in text and re.search(r"\d+/12", text)
    assert not PER_CANDIDATE.search(text)
    # leave=False: the finished bar is cleared, its line ends blank
    assert text.rstrip(" ").endswith("\r")


def test_a_line_said_while_a_bar_is_drawn_is_written_whole():
    stream = FakeTerminal()
    progress = TerminalProgress(stream, delay=0)
    progress.meter(1, 3, "drag CD-I")
    progress("warning: something worth a line")
    progress.meter(2, 3, "drag CD-II")
    progress.close()
    assert "\nwarning: something worth a line\n" in stream.getvalue().replace("\r", "\n")


def test_a_new_fit_call_starts_a_new_bar():
    stream = FakeTerminal()
    progress = TerminalProgress(stream, delay=0)
    progress.meter(1, 4, "pitch Cm-I")
    first = progress._bar
    progress.meter(1, 2, "drag CD-I")      # another call began before the first ended (an interrupted one)
    assert progress._bar is not first and progress._bar.total == 2
    progress.close()
    assert progress._bar is None


@pytest.mark.parametrize("tty", [False, True])
def test_the_command_line_passes_the_bar_to_the_fitter_as_its_meter(tty, tiny, tmp_path, monkeypatch, capsys):
    """``structsearch search`` end to end on a tiny campaign: its stderr holds the grid's summary line; a bar
    only on a terminal; never a line per candidate."""
    import sys

    from structsearch.cli import progress as cli_progress
    from structsearch.cli import main
    stream = FakeTerminal() if tty else io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    monkeypatch.setattr(cli_progress, "BAR_DELAY_S", 0.0)
    code = main(["search", "--data", str(tiny.directory), "--grid", "lift", "--starts", "1", "--jobs", "1",
                 "--out", str(tmp_path)])
    assert code == 0
    err = stream.getvalue()
    assert "grid lift: 6 candidates" in err and not PER_CANDIDATE.search(err)
    assert ("\r" in err) == tty and (re.search(r"\d+/\d+ \[", err) is not None) == tty
    assert "lift: CL-" in capsys.readouterr().out


def test_a_pseudo_terminal_nobody_sized_still_gets_a_bar():
    """A pseudo-terminal of 0 x 0 (script(1), some CI runners) made tqdm draw nothing: it is taken for 80 x 24."""
    import os
    pty = pytest.importorskip("pty")
    master, slave = pty.openpty()
    with open(slave, "w", encoding="utf-8", closefd=True) as stream:
        assert stream.isatty() and os.get_terminal_size(slave).columns == 0
        progress = TerminalProgress(stream, delay=0)
        for k in range(1, 4):
            progress.meter(k, 3, f"drag CD-{k}")
        stream.flush()
        drawn = os.read(master, 65536).decode("utf-8", "replace")
    os.close(master)
    assert "drag:" in drawn and "/3 [" in drawn
