"""The documentation: the site builds without a warning, the README stays short, and every code block of
README.md and docs/**/*.md runs.

Code blocks are read by their language tag:

* ``python``: executed, the page's blocks in order in one namespace and one working directory;
* ``console`` (commands after ``$ ``, other lines are output) and ``bash``: every command must be a
  ``structsearch`` command (``.venv/bin/structsearch`` too) and runs as ``python -m structsearch ...`` in the
  page's working directory. The lines after a command in a console block quote its output: each must be a line
  the command prints (stdout or stderr), in the order quoted, words equal and numbers within one unit of their
  last quoted digit (or the relative tolerance ``<!-- output: rtol R -->`` before the fence states); ``...`` in
  a quoted line stands for any text (a wall time). A quoted line the run does not print fails the test;
* ``toml``: parsed; with ``<!-- file: NAME -->`` right before the fence it is also written to NAME in the
  page's working directory, where later blocks use it (a grid spec is then searched, a term library loaded);
* ``text``, ``csv``, ``json``: listings, not run (``json`` is parsed when it is a whole document). A ``text``
  block that quotes what the program printed or wrote is marked ``<!-- output: printed -->`` (the output of the
  page's block run just before it: a python block's standard output, a shell block's commands' outputs) or
  ``<!-- output: file PATH -->`` (a file the page's runs wrote, an HTML page read as its text), optionally with
  ``, rtol R``; its lines are then checked as a console block's quoted lines are. A text block that quotes an
  error line (``structsearch ...: error: ...``) must be so marked.

An HTML comment on the line before a fence marks a block: ``<!-- test: slow -->`` runs it only in the slow set
(with the rest of its page, in order), ``<!-- test: skip (REASON) -->`` never runs it (an installation, the test
command itself) and must give a reason, ``<!-- test: exit N -->`` (or ``slow, exit N``) expects each command of a
console block to end with exit status N (an error the page shows, its quoted lines checked). A block without a
known tag fails the test, so none is skipped silently.

Examples use the small campaign ``structsearch simulate --out camp --scale 0.05``; it is flown once per test
module and copied where a page asks for it (the same command and seed give the same campaign bit for bit).
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))
SMALL_CAMPAIGN = "structsearch simulate --out camp --scale 0.05"

RUN_PYTHON = {"python"}
RUN_SHELL = {"console", "bash"}
LISTINGS = {"text", "csv", "json", "toml"}

FENCE = re.compile(r"^(?P<indent>[ ]*)```(?P<lang>[\w-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```[ ]*$", re.M | re.S)
MARKER = re.compile(r"<!--\s*(test|file|output):\s*(.*?)\s*-->\s*$")
ISSUE = re.compile(r"\bissues? #?\d+|\(#\d+\)", re.I)


@dataclass
class Block:
    page: Path
    line: int
    lang: str
    body: str
    marker: str = ""        # "slow", "skip (...)", "exit N", "slow, exit N" or ""
    file: str = ""          # <!-- file: NAME -->
    output: str = ""        # <!-- output: [printed | file PATH][, ]rtol R -->: what a quote quotes, how closely

    @property
    def slow(self) -> bool:
        return self.marker.split(",")[0].strip() == "slow"

    @property
    def skipped(self) -> bool:
        return self.marker.startswith("skip")

    @property
    def exit_status(self) -> int:
        """The exit status each command of the block must end with (``<!-- test: exit N -->``; 0 otherwise)."""
        m = re.search(r"(?:^|,\s*)exit (\d+)$", self.marker)
        return int(m[1]) if m else 0

    @property
    def quotes(self) -> str:
        """What a text block quotes: "printed", "file PATH", or "" (a listing)."""
        return re.sub(r",?\s*rtol [0-9.eE+-]+$", "", self.output).strip()

    @property
    def where(self) -> str:
        page = self.page.relative_to(ROOT) if self.page.is_relative_to(ROOT) else self.page
        return f"{page}:{self.line}"


def blocks(page: Path) -> list[Block]:
    text = page.read_text()
    found = []
    for match in FENCE.finditer(text):
        start = text.count("\n", 0, match.start())
        block = Block(page, start + 1, match["lang"], "\n".join(line[len(match["indent"]):]
                                                               for line in match["body"].splitlines()))
        lines = text.splitlines()[:start]
        while lines and not lines[-1].strip():
            lines.pop()
        while lines and MARKER.search(lines[-1].strip()):     # the comments right before the fence
            marker = MARKER.search(lines.pop().strip())
            if marker[1] == "test":
                block.marker = marker[2]
            elif marker[1] == "output":
                block.output = marker[2]
            else:
                block.file = marker[2]
        found.append(block)
    return found


def commands(block: Block) -> list[str]:
    """The commands of a shell block: ``$ `` lines of a console block (continued by a trailing backslash),
    every line of a bash block that is not a comment."""
    lines, out = block.body.splitlines(), []
    pending = None
    for line in lines:
        if pending is not None:
            pending += " " + line.strip()
        elif block.lang == "console" and line.startswith("$ "):
            pending = line[2:].strip()
        elif block.lang == "bash" and line.strip() and not line.lstrip().startswith("#"):
            pending = line.strip()
        else:
            continue
        if pending.endswith("\\"):
            pending = pending[:-1].rstrip()
            continue
        out.append(pending)
        pending = None
    return out


def quoted_outputs(block: Block) -> list[list[str]]:
    """Per command of a console block (in :func:`commands`' order) the output lines quoted after it."""
    if block.lang != "console":
        return [[] for _ in commands(block)]
    out: list[list[str]] = []
    continued = False
    for line in block.body.splitlines():
        if line.startswith("$ "):
            out.append([])
            continued = line.rstrip().endswith("\\")
        elif continued:
            continued = line.rstrip().endswith("\\")
        elif out and line.strip():
            out[-1].append(line)
    return out


NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _line_pattern(quoted: str) -> re.Pattern:
    """A quoted output line as a pattern: its words literal, each number a group, ``...`` any text."""
    parts = []
    for i, piece in enumerate(quoted.strip().split("...")):
        if i:
            parts.append(".*?")
        last = 0
        for m in NUMBER.finditer(piece):
            parts.append(re.escape(piece[last:m.start()]))
            parts.append(r"([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?)")
            last = m.end()
        parts.append(re.escape(piece[last:]))
    return re.compile("".join(parts))


def _close(quoted: str, printed: str, rtol: float | None) -> bool:
    """``printed`` within one unit of ``quoted``'s last digit, or within ``rtol`` of it."""
    x, y = float(quoted), float(printed)
    if rtol is not None and abs(x - y) <= rtol * max(abs(x), abs(y)):
        return True
    mantissa, _, exponent = quoted.lower().partition("e")
    digits = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return abs(x - y) <= 1.0001 * 10.0 ** (int(exponent or 0) - digits)


def quoted_output_problem(quoted: list[str], printed: str, rtol: float | None = None) -> str | None:
    """None when every quoted line is a line of ``printed`` (in order; numbers within tolerance), else which
    quoted line the run did not print."""
    lines = printed.splitlines()
    at = 0
    for q in quoted:
        pattern = _line_pattern(q)
        for k in range(at, len(lines)):
            m = pattern.search(lines[k])
            if m and all(_close(a, b, rtol) for a, b in zip(NUMBER.findall(q.replace("...", " ")), m.groups())):
                at = k + 1
                break
        else:
            return f"the quoted output line {q.strip()!r} is not printed (in this order); the run printed:\n{printed}"
    return None


def _rtol(block: Block) -> float | None:
    if not block.output or block.output == block.quotes:
        return None
    m = re.search(r"rtol ([0-9.eE+-]+)$", block.output)
    assert m, f"{block.where}: <!-- output: rtol R --> expected, not {block.output!r}"
    return float(m[1])


class _HtmlText(HTMLParser):
    """An HTML page's text as a reader sees it: a line per block element, a formula's MathML skipped (the page
    also writes each formula as text)."""
    BLOCKS = {"p", "div", "h1", "h2", "h3", "h4", "li", "tr", "br", "pre", "table", "section", "caption", "dt", "dd"}
    CELLS = {"td", "th"}          # a table's cells: words apart on the row's line

    def __init__(self):
        super().__init__()
        self.parts: list[str] = []
        self.hidden = 0
        self.pre = 0

    def handle_starttag(self, tag, attrs):
        self.hidden += tag in ("math", "script", "style")
        self.pre += tag == "pre"
        if tag in self.BLOCKS:
            self.parts.append("\n")
        elif tag in self.CELLS:
            self.parts.append(" ")

    def handle_endtag(self, tag):
        self.hidden -= tag in ("math", "script", "style")
        self.pre -= tag == "pre"
        if tag in self.BLOCKS:
            self.parts.append("\n")

    def handle_data(self, data):
        if not self.hidden:
            self.parts.append(data if self.pre else data.replace("\n", " "))   # a source line break is a space

    def text(self) -> str:
        return "\n".join(" ".join(line.split()) for line in "".join(self.parts).splitlines() if line.strip())


def written_text(path: Path) -> str:
    """A file the page's runs wrote, as text (an HTML page as its reader's text)."""
    if path.suffix == ".html":
        parser = _HtmlText()
        parser.feed(path.read_text(encoding="utf-8"))
        return parser.text()
    return path.read_text(encoding="utf-8")


ERROR_LINE = re.compile(r"^\s*structsearch[\w -]*: error:", re.M)


def quoted_text_problem(block: Block, printed: str, workdir: Path) -> str | None:
    """Whether a text block marked as quoting an output quotes it (None) or what it quotes that was not printed."""
    if block.quotes == "printed":
        return quoted_output_problem(block.body.splitlines(), printed, _rtol(block))
    path = workdir / block.quotes.removeprefix("file ").strip()
    if not path.is_file():
        return f"the quoted file {path} was not written"
    return quoted_output_problem(block.body.splitlines(), written_text(path), _rtol(block))


def pages_with(predicate) -> list[Path]:
    return [page for page in PAGES if any(predicate(b) for b in blocks(page))]


def _ids(pages):
    return [str(p.relative_to(ROOT)) for p in pages]


@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory):
    where = tmp_path_factory.mktemp("campaign")
    _structsearch(shlex.split(SMALL_CAMPAIGN)[1:], where)
    return where / "camp"


def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def _structsearch(argv: list[str], cwd: Path, where: str = "", status: int = 0) -> str:
    """Run ``structsearch ARGV`` in ``cwd``, which must end with exit ``status``; what it printed, stdout and
    stderr interleaved as on a console."""
    proc = subprocess.run([sys.executable, "-m", "structsearch", *argv], cwd=cwd, env={**_env(), "PYTHONUNBUFFERED": "1"},
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=3600)
    assert proc.returncode == status, \
        f"{where}: structsearch {' '.join(argv)} ended with exit {proc.returncode}, not {status}:\n{proc.stdout[-4000:]}"
    return proc.stdout


def run_page(page: Path, workdir: Path, small_campaign_dir, include_slow: bool, monkeypatch) -> int:
    """Run the page's blocks in order in ``workdir``; return how many ran."""
    namespace: dict = {"__name__": "__docs__"}
    monkeypatch.chdir(workdir)
    if not (workdir / "examples").exists():       # the pages run from a checkout's root, where examples/ is
        (workdir / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    ran, printed, skipped_a_run = 0, "", False
    for block in blocks(page):
        if block.skipped or (block.slow and not include_slow):
            skipped_a_run |= _prints(block)
            continue
        if block.lang == "text" and block.quotes:
            if skipped_a_run and (block.quotes == "printed"
                                  or not (workdir / block.quotes.removeprefix("file ").strip()).exists()):
                continue         # it quotes what a block that did not run in this set printed or wrote
            problem = quoted_text_problem(block, printed, workdir)
            assert problem is None, f"{block.where}: {problem}"
            continue
        if _prints(block):
            skipped_a_run = False
        if block.lang == "toml":
            tomllib.loads(block.body)
            if block.file:
                (workdir / block.file).parent.mkdir(parents=True, exist_ok=True)
                (workdir / block.file).write_text(block.body + "\n")
        elif block.lang in RUN_PYTHON:
            with contextlib.redirect_stdout(io.StringIO()) as stdout:
                try:
                    exec(compile(block.body, block.where, "exec"), namespace)
                except Exception as error:      # noqa: BLE001 - name the block that failed
                    raise AssertionError(f"{block.where}: the python block failed: {error!r}") from error
            printed = stdout.getvalue()
        elif block.lang in RUN_SHELL:
            printed = ""
            for command, quoted in zip(commands(block), quoted_outputs(block)):
                argv = shlex.split(command)
                if command == SMALL_CAMPAIGN and not (workdir / "camp").exists() and not quoted:
                    shutil.copytree(small_campaign_dir(), workdir / "camp")
                    continue
                output = _structsearch(argv[1:], workdir, block.where, block.exit_status)
                printed += output
                problem = quoted_output_problem(quoted, output, _rtol(block))
                assert problem is None, f"{block.where}: {command}: {problem}"
        else:
            continue
        ran += 1
    return ran


# ---------------------------------------------------------------- the site and the pages' text

def test_the_site_builds_strictly_without_a_warning(tmp_path):
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output
    assert "WARNING" not in output, output
    assert (tmp_path / "site" / "reference" / "api" / "index.html").exists()


def test_the_readme_is_short_and_names_no_issue():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) < 200
    assert ISSUE.findall(readme) == []


def test_the_readme_links_to_files_that_exist():
    """The README is not part of the site (strict mode does not see it): its relative links are checked here."""
    readme = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    assert len(targets) > 20
    missing = [t for t in targets if not t.startswith(("http://", "https://")) and not (ROOT / t).exists()]
    assert missing == []


@pytest.mark.parametrize("page", PAGES, ids=_ids(PAGES))
def test_no_page_narrates_issues(page):
    """The changelog (CHANGELOG.md at the root, included in the site) is where history lives."""
    assert ISSUE.findall(page.read_text()) == [], page


@pytest.mark.parametrize("page", PAGES, ids=_ids(PAGES))
def test_every_block_has_a_known_tag_and_markers_are_well_formed(page):
    for block in blocks(page):
        assert block.lang in RUN_PYTHON | RUN_SHELL | LISTINGS, f"{block.where}: a block tagged {block.lang!r}"
        assert re.fullmatch(r"(slow)?|(slow, )?exit \d+|skip \(.+\)", block.marker), block.where
        assert not block.exit_status or block.lang == "console", block.where
        assert not block.output or (block.lang == "console" and not block.quotes and _rtol(block) is not None) \
            or (block.lang == "text" and re.fullmatch(r"printed|file \S+", block.quotes)), block.where
        assert block.lang != "text" or block.quotes or block.skipped or not ERROR_LINE.search(block.body), \
            f"{block.where}: a text block quotes an error line: mark it <!-- output: printed --> after the block " \
            "that prints it (a console block marked <!-- test: exit 2 -->)"
        if block.lang == "json" and block.body.lstrip().startswith("{") and "..." not in block.body:
            json.loads(block.body)
        if block.lang in RUN_SHELL and not block.marker.startswith("skip"):
            assert commands(block), f"{block.where}: a shell block without a command"
            for command in commands(block):
                assert shlex.split(command)[0] in ("structsearch", ".venv/bin/structsearch"), \
                    f"{block.where}: only structsearch commands run ({command!r}); mark the block skip with a reason"


@pytest.mark.parametrize("page", PAGES, ids=_ids(PAGES))
def test_a_quote_of_printed_output_follows_a_block_that_runs(page):
    """A quote of what was printed is checked against the block run before it, so that block must run."""
    before = None
    for block in blocks(page):
        if block.lang == "text" and block.quotes:
            # a quote is checked where the page runs: a marker of its own would set it apart from what it quotes
            assert not block.marker, f"{block.where}: a quote takes no test marker ({block.marker!r})"
        if block.lang == "text" and block.quotes == "printed":
            assert before is not None and not before.skipped, \
                f"{block.where}: it quotes the output of a block that never runs ({before and before.where})"
        elif _prints(block):
            before = block


TUTORIAL_RUN = """\
grid lift: 6 candidates
grid lift: refined CL-VI; stopped: dropping CL_qstar (t-test accepts 0, p = 0.63) raises the held-out MSE by 1.2%; 1 more move refused
lift: CL-VI (11 parameters, validation MSE 0.003777); NOT admissible (none of 6 is); next CL-V (10 parameters, +1.2%); 4.8 s
wrote first-search/ranking.csv and the tables of each grid
"""


def test_a_quoted_output_the_run_does_not_print_fails():
    """The first-search tutorial once quoted "lift: CL-VI (NOT admissible: no candidate is)", a line the search
    never printed; a quoted line must be one the run prints, its numbers within their last digit."""
    printed = TUTORIAL_RUN
    assert quoted_output_problem(["lift: CL-VI (NOT admissible: no candidate is)"], printed) is not None
    assert quoted_output_problem(["lift: CL-VI (11 parameters, validation MSE 0.003777); NOT admissible (none of 6 "
                                  "is); next CL-V (10 parameters, +1.2%); ..."], printed) is None
    assert quoted_output_problem(["lift: CL-VI (11 parameters, validation MSE 0.00378); ..."], printed) is None
    assert quoted_output_problem(["lift: CL-VI (11 parameters, validation MSE 0.00390); ..."], printed) is not None
    assert quoted_output_problem(["lift: CL-VI (11 parameters, validation MSE 0.0039); ..."], printed, 0.05) is None
    assert quoted_output_problem(["lift: CL-VI (11 parameters, validation MSE 0.0040); ..."], printed, 0.05) \
        is not None
    assert quoted_output_problem(["wrote first-search/ranking.csv ...", "grid lift: 6 candidates"], printed) \
        is not None                                                       # the order counts
    console = Block(ROOT / "README.md", 1, "console", "$ structsearch search \\\n  --grid lift\nout 1\n\nout 2\n"
                    "$ structsearch grids\n")
    assert commands(console) == ["structsearch search --grid lift", "structsearch grids"]
    assert quoted_outputs(console) == [["out 1", "out 2"], []]


def test_a_printed_quote_is_checked_against_the_block_that_printed_it(tmp_path, monkeypatch):
    """A listing between a slow block and its quote does not make the fast set check the quote against an older
    block's output; the slow set checks it against the slow block's, and a wrong quote fails there."""
    page = tmp_path / "page.md"
    quote = "<!-- output: printed -->\n```text\nx = {}\n```\n"
    body = ("```python\nprint('x = 1')\n```\n\n<!-- test: slow -->\n```python\nprint('x = 5')\n```\n\n"
            "```csv\na,b\n```\n\n")
    page.write_text(body + quote.format(5))
    work = tmp_path / "work"
    work.mkdir()
    assert run_page(page, work, None, False, monkeypatch) == 1
    assert run_page(page, work, None, True, monkeypatch) == 2
    page.write_text(body + quote.format(9))
    assert run_page(page, work, None, False, monkeypatch) == 1
    with pytest.raises(AssertionError, match="x = 9"):
        run_page(page, work, None, True, monkeypatch)


def test_an_html_page_is_quoted_as_its_text(tmp_path):
    page = tmp_path / "report.html"
    page.write_text("<html><style>p {}</style><h2>Lift, C_L: CL-VI</h2><p>Validation R<sup>2</sup> 0.9052;\n"
                    "  held-out MSE 0.003171</p><math><mi>CL</mi></math><p>CL = 0.223</p>"
                    "<table><tr><td>CL</td><td>0.9052</td><td>0.003171</td></tr></table></html>", encoding="utf-8")
    assert written_text(page).splitlines() == ["Lift, C_L: CL-VI", "Validation R2 0.9052; held-out MSE 0.003171",
                                               "CL = 0.223", "CL 0.9052 0.003171"]
    quote = Block(ROOT / "README.md", 1, "text", "Lift, C_L: CL-VI\nCL = 0.223", output="file report.html")
    assert quoted_text_problem(quote, "", tmp_path) is None
    wrong = Block(ROOT / "README.md", 1, "text", "Lift, C_L: CL-VI\nCL = 0.300", output="file report.html")
    assert quoted_text_problem(wrong, "", tmp_path) is not None
    missing = Block(ROOT / "README.md", 1, "text", "CL", output="file nowhere.html")
    assert "was not written" in quoted_text_problem(missing, "", tmp_path)


def test_markers_are_found():
    readme = blocks(ROOT / "README.md")
    assert any(b.marker == "slow" for b in readme) and any(b.marker.startswith("skip") for b in readme)
    assert any(b.lang == "python" and not b.marker for b in readme)


# ---------------------------------------------------------------- the code runs

def _runs(block: Block) -> bool:
    return block.lang in RUN_PYTHON | RUN_SHELL or bool(block.file)


def _prints(block: Block) -> bool:
    """A block whose output a quote may quote (a toml file block runs but prints nothing)."""
    return block.lang in RUN_PYTHON | RUN_SHELL


FAST = pages_with(lambda b: _runs(b) and not b.slow and not b.skipped)
SLOW = pages_with(lambda b: _runs(b) and b.slow)


@pytest.mark.parametrize("page", FAST, ids=_ids(FAST))
def test_the_code_of_a_page_runs(page, tmp_path, request, monkeypatch):
    """Every block not marked slow, in order, in one directory (the fast set)."""
    assert run_page(page, tmp_path, lambda: request.getfixturevalue("small_campaign"), False, monkeypatch) > 0


@pytest.mark.slow
@pytest.mark.parametrize("page", SLOW, ids=_ids(SLOW))
def test_the_code_of_a_page_runs_in_full(page, tmp_path, request, monkeypatch):
    """Every block of the page, the slow ones too, in order, in one directory."""
    assert run_page(page, tmp_path, lambda: request.getfixturevalue("small_campaign"), True, monkeypatch) > 0
