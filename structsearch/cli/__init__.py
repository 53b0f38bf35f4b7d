"""The command line: ``structsearch COMMAND`` (:mod:`.main` runs it, :mod:`.parser` declares its options with
:mod:`.options` and :mod:`.help`, :mod:`.progress` shows progress, :mod:`.grids` and :mod:`.bench` run the commands
of those names). It parses, calls the public API (:mod:`structsearch.api`) and prints; it computes nothing itself."""
from .main import _gap, build_parser, main  # noqa: F401  (the entry point and what the tests drive)
