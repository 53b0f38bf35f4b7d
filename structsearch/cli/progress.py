"""What a command shows of its progress on stderr: the lines worth keeping (a grid begun, a step of a search, a
warning) as they come, and the candidates of each fit call as a tqdm bar, drawn only on a terminal.

A search fits hundreds of candidates: a line each scrolled the summaries out of sight (issue 43). The fitting
layer tells a meter ``(finished, of, what)`` after each candidate (:data:`structsearch.fitting.fitter.Meter`);
this object is that meter and the command's line sink at once, so that a line printed while a bar is drawn
clears the bar first and redraws it below. Piped into a file or a CI log (not a terminal) there is no bar at
all: a bar's carriage returns are noise there, and the lines alone say what happened.
"""
from __future__ import annotations

import os
import sys
from typing import TextIO

# a fit call shorter than this draws no bar (a structure search makes many calls of a few fits each: bars that
# flash and vanish would only flicker)
BAR_DELAY_S = 0.5


class TerminalProgress:
    """A command's progress on ``stream`` (default stderr). Call it with a line; :meth:`meter` is the fitting
    layer's meter; :meth:`close` removes a bar left open (an interrupted run)."""

    def __init__(self, stream: TextIO | None = None, prefix: str = "", delay: float | None = None):
        self.stream = stream if stream is not None else sys.stderr
        self.prefix = prefix
        self.delay = BAR_DELAY_S if delay is None else delay
        self.draws = _is_terminal(self.stream)
        self._bar = None

    def __call__(self, message: str) -> None:
        self.write(self.prefix + message)

    def write(self, text: str, stream: TextIO | None = None) -> None:
        """``text`` as a line on ``stream`` (default this one's), below the bar if one is drawn."""
        out = stream if stream is not None else self.stream
        if self._bar is not None:
            self._bar.clear()
        print(text, file=out, flush=True)
        if self._bar is not None:
            self._bar.refresh()

    def meter(self, finished: int, of: int, what: str) -> None:
        """Candidate ``finished`` of ``of`` of a fit call is done (``what``: "drag CD-IXr")."""
        if not self.draws:
            return
        bar = self._bar
        if bar is None or finished <= bar.n or of != bar.total:   # a new fit call
            self.close()
            bar = self._bar = _new_bar(self.stream, of, what.split(" ", 1)[0], self.delay)
        bar.set_postfix_str(what, refresh=False)
        bar.update(finished - bar.n)
        if finished >= of:
            self.close()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):   # no isatty, or a closed stream
        return False


def _size(stream) -> dict:
    """The terminal's size for tqdm; 80 x 24 where it says 0 x 0 (a pseudo-terminal nobody sized: tqdm would
    draw nothing); tqdm's own guess for a stream without a descriptor."""
    try:
        size = os.get_terminal_size(stream.fileno())
    except (AttributeError, OSError, ValueError):
        return {}
    return {"ncols": size.columns or 80, "nrows": size.lines or 24}


def _new_bar(stream: TextIO, total: int, desc: str, delay: float):
    from tqdm import tqdm   # here: `structsearch --help` and a piped run import no tqdm
    # leave=False: a finished call's bar is erased, so the summary lines stay together on the screen
    return tqdm(total=total, desc=desc, unit="fit", file=stream, leave=False, delay=delay, mininterval=0.2,
                **_size(stream))
