"""Two output directories of the same command compared as answers, not as bytes.

The same command on another machine (another processor, BLAS kernel or thread count) must give the same
decisions: the rankings (order, admissible set, within-noise flags), the chosen, refined and discovered
structures, the story's moves and verdicts. Its numbers agree within tolerances, not to the bit: a fit stops
when its cost changes by less than the solver's tolerance, and another kernel's rounding moves the point
where it stops within that.

Every CSV and JSON file of the first directory is read with its twin in the second. Text, booleans and
integers must be equal; a text's numbers (a reason "|rho| = 0.952 > 0.95") are compared as numbers, the
rest of it as text. Floating-point numbers must agree within ``rtol`` of the larger magnitude, or within
``atol_fraction`` of the largest magnitude of their column (CSV) or list (JSON), or within ``atol``, so that
a number that is zero up to rounding (a gap of 1e-17) does not count as a relative difference. Fields that describe the
run rather than the answer (wall times, evaluation counts, the optimizer's stopping message) are skipped.
"""
from __future__ import annotations

import csv
import io
import dataclasses
import math
import re
from dataclasses import dataclass
from pathlib import Path

from ..data.reading import inside, parse_json, read_text

# Fields that describe how a run went, not what it found: they differ between machines by design.
RUN_FIELDS = frozenset({"seconds", "wall_seconds", "elapsed", "nfev", "evaluations", "njev", "message",
                        "n_reached_best",
                        "timings", "time", "duration", "version", "command", "cached"})
# Files that are measurements of the machine (benchmarks), not answers; directories that hold inputs and
# internal state (the simulated campaign, the fit cache, whose file names carry digests of the data's bits).
MACHINE_FILES = ("bench.json", "bench.csv")
SKIPPED_DIRECTORIES = ("cache", "campaign")
_INTEGER = re.compile(r"^[-+]?\d+$")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


@dataclass(frozen=True)
class Tolerances:
    """How close two numbers of an answer must be.

    ``rtol`` 1e-3. A fit stops where its cost changes by less than 1e-10 of itself; a parameter can still move
    along a poorly determined direction by up to about sqrt(1e-10 * samples) of its standard error, and a
    fold's refit of a poorly fitting candidate, warm started, can stop elsewhere in a flat valley. Measured
    between OpenBLAS's Haswell and SandyBridge kernels on the demo at scale 0.2: the rankings' MSEs,
    parameters and R^2 within 3e-6, one cross-validation MSE 1.4e-4 apart (X_ss/X_w Q/U, 44 % above the best
    candidate). The decisions (ranks, admissible sets, structures, moves, verdicts) are compared exactly.
    """

    rtol: float = 1e-3
    # per field, a looser relative tolerance: the permutation importances of the diagnosis' boosted-tree model
    # of a residual (its splits follow the residual's last digits; measured 7 % apart between two kernels on
    # the demo); the order of the signals they rank is compared exactly
    fields: tuple[tuple[str, float], ...] = (("importance", 0.25),)
    atol_fraction: float = 1e-9
    # the answers' numbers are coefficients and parameters (order 1), MSEs (1e-6 and up) and their gaps: a
    # difference below 1e-12 is rounding of a number that is zero (a gap of the best to itself, 1e-17)
    atol: float = 1e-12


@dataclass(frozen=True)
class Difference:
    """One disagreement: the file, where in it, both values and whether it is a decision or a number."""

    file: str
    where: str
    first: str
    second: str
    kind: str          # "decision" (text, flag, count, a missing file or field) or "number"

    def line(self) -> str:
        return f"{self.file}: {self.where}: {self.first} vs {self.second} ({self.kind})"


@dataclass(frozen=True)
class OutputComparison:
    """What :func:`compare_outputs` found."""

    first: str
    second: str
    files: tuple[str, ...]
    differences: tuple[Difference, ...]
    tolerances: Tolerances

    @property
    def same(self) -> bool:
        return not self.differences

    @property
    def decisions(self) -> tuple[Difference, ...]:
        return tuple(d for d in self.differences if d.kind == "decision")

    def to_dict(self) -> dict:
        return {"first": self.first, "second": self.second, "files": list(self.files), "same": self.same,
                "rtol": self.tolerances.rtol, "field_rtol": dict(self.tolerances.fields), "atol_fraction": self.tolerances.atol_fraction,
                "atol": self.tolerances.atol,
                "differences": [d.__dict__ for d in self.differences]}

    def summary(self) -> str:
        head = (f"{len(self.files)} files compared: "
                + ("the same answers" if self.same else
                   f"{len(self.decisions)} decisions and {len(self.differences) - len(self.decisions)} numbers differ"))
        return "\n".join([head] + [d.line() for d in self.differences[:50]]
                         + ([f"... and {len(self.differences) - 50} more"] if len(self.differences) > 50 else []))


def answer_files(directory: Path) -> list[str]:
    """The CSV and JSON files under ``directory`` that hold answers (relative paths, sorted)."""
    found = []
    for p in sorted(directory.rglob("*")):
        relative = p.relative_to(directory)
        if (p.suffix in (".csv", ".json") and p.is_file() and p.name not in MACHINE_FILES
                and not p.name.endswith("_manifest.json")
                and not set(relative.parts[:-1]) & set(SKIPPED_DIRECTORIES)):
            found.append(relative.as_posix())
    return found


def compare_outputs(first: str | Path, second: str | Path, tolerances: Tolerances = Tolerances()) -> OutputComparison:
    """Compare every answer file of ``first`` with the same file of ``second`` (module docstring)."""
    a, b = Path(first), Path(second)
    files = answer_files(a)
    differences: list[Difference] = []
    for name in files:
        if not (b / name).is_file():
            differences.append(Difference(name, "file", "present", "missing", "decision"))
            continue
        compare = _compare_csv if name.endswith(".csv") else _compare_json
        differences.extend(compare(name, _text(a, name), _text(b, name), tolerances))
    for name in answer_files(b):
        if name not in files:
            differences.append(Difference(name, "file", "missing", "present", "decision"))
    return OutputComparison(str(a), str(b), tuple(files), tuple(differences), tolerances)


OUTPUT_DIRECTORY = "<output directory>"


def _text(root: Path, name: str) -> str:
    """A file's text with the paths into its output directory written relative to it, after a placeholder: a path
    a run writes into its own output (a discovered structure's spec file) names where it ran (relative to the
    working directory of the run, or absolute), not what it found, and the directory may be named here either
    way."""
    text = read_text(inside(root, name, str(root)))   # regular, bounded, UTF-8, and inside the directory
    text = text.replace(str(root.resolve()), OUTPUT_DIRECTORY)
    if not root.is_absolute() and str(root) != ".":
        text = text.replace(str(root) + "/", OUTPUT_DIRECTORY + "/")
    return _PATH.sub(lambda m: _under(root, m[0]), text)


# a token with a slash that may be a path (no spaces: the stored paths of a run's own files have none), not one
# that already follows the placeholder
_PATH = re.compile(r"(?<![\w.~/>-])[\w.~-]*(?:/[\w.~-]+)+")


def _under(root: Path, token: str) -> str:
    """``token`` as ``<output directory>/TAIL`` when its longest tail of path parts names something under ``root``
    (the part before the tail is where the run was made from), else unchanged."""
    parts = token.split("/")
    for i in range(len(parts)):
        tail = parts[i:]
        if tail and all(tail) and ".." not in tail and (root / Path(*tail)).exists():
            return OUTPUT_DIRECTORY + "/" + "/".join(tail)
    return token


def _compare_csv(name: str, a: str, b: str, tol: Tolerances) -> list[Difference]:
    rows_a, rows_b = _read_csv(a), _read_csv(b)
    if len(rows_a) != len(rows_b):
        return [Difference(name, "rows", str(len(rows_a)), str(len(rows_b)), "decision")]
    if not rows_a:
        return []
    header, header_b = rows_a[0], rows_b[0]
    if header != header_b:
        return [Difference(name, "columns", ",".join(header), ",".join(header_b), "decision")]
    width = len(header)
    body = [r + [""] * (width - len(r)) for r in rows_a[1:]]
    scales = [max((abs(v) for r in body for v in [_as_float(r[k])] if v is not None and math.isfinite(v)),
                  default=0.0) for k in range(width)]
    label_column = next((header.index(k) for k in ("model", "name", "parameter") if k in header), None)
    out = []
    for i, (ra, rb) in enumerate(zip(rows_a[1:], rows_b[1:])):
        label = ra[label_column] if label_column is not None and label_column < len(ra) else str(i + 1)
        if len(ra) != len(rb):
            out.append(Difference(name, f"row {i + 1} ({label}) length", str(len(ra)), str(len(rb)), "decision"))
            continue
        for k, (u, v) in enumerate(zip(ra, rb)):
            column = header[k] if k < width else f"column {k + 1}"
            if column not in RUN_FIELDS:
                out.extend(_compare_values(name, f"row {i + 1} ({label}), {column}", u, v,
                                           scales[k] if k < width else 0.0, tol))
    return out


def _read_csv(text: str) -> list[list[str]]:
    # a leading "# command: ..." line records how the file was made (its paths differ between runs)
    return [row for row in csv.reader(io.StringIO(text, newline="")) if row and not row[0].startswith("#")]


def _as_float(text: str) -> float | None:
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def _compare_json(name: str, a: str, b: str, tol: Tolerances) -> list[Difference]:
    out: list[Difference] = []
    _walk(name, "", parse_json(a, name), parse_json(b, name), 0.0, tol, out)   # nesting bounded: _walk recurses
    return out


def _walk(name: str, where: str, x, y, scale: float, tol: Tolerances, out: list[Difference]) -> None:
    if isinstance(x, dict) and isinstance(y, dict):
        for k in sorted(set(x) | set(y)):
            if k in RUN_FIELDS:
                continue
            if k not in x or k not in y:
                out.append(Difference(name, f"{where}/{k}", "absent" if k not in x else "present",
                                      "absent" if k not in y else "present", "decision"))
            else:
                loose = dict(tol.fields).get(k)
                inner = dataclasses.replace(tol, rtol=loose) if loose is not None else tol
                _walk(name, f"{where}/{k}", x[k], y[k], _scale_of(x[k]), inner, out)
    elif isinstance(x, list) and isinstance(y, list):
        if len(x) != len(y):
            out.append(Difference(name, f"{where} (length)", str(len(x)), str(len(y)), "decision"))
            return
        inner = _scale_of(x)
        for i, (u, v) in enumerate(zip(x, y)):
            _walk(name, f"{where}[{i}]", u, v, inner, tol, out)
    else:
        out.extend(_compare_values(name, where or "/", x, y, scale, tol))


def _scale_of(value) -> float:
    """The largest finite magnitude among a list's numbers (0 for anything else)."""
    if isinstance(value, list):
        return max((abs(v) for v in value if _is_float(v) and math.isfinite(v)), default=0.0)
    return abs(value) if _is_float(value) and math.isfinite(value) else 0.0


def _is_float(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _compare_values(name: str, where: str, x, y, scale: float, tol: Tolerances) -> list[Difference]:
    if isinstance(x, float) or isinstance(y, float) or (isinstance(x, str) and isinstance(y, str)):
        return _compare_text_or_number(name, where, x, y, scale, tol)
    if x != y:
        return [Difference(name, where, repr(x), repr(y), "decision")]
    return []


def _compare_text_or_number(name: str, where: str, x, y, scale: float, tol: Tolerances) -> list[Difference]:
    """Numbers within tolerance; in text, the numbers within tolerance and the words equal."""
    if _is_float(x) and _is_float(y):
        return [] if _close(float(x), float(y), scale, tol) else [Difference(name, where, repr(x), repr(y), "number")]
    sx, sy = str(x), str(y)
    if _INTEGER.match(sx) and _INTEGER.match(sy):   # a rank, a count: a decision
        return [] if sx == sy else [Difference(name, where, sx, sy, "decision")]
    fx, fy = _as_float(sx), _as_float(sy)
    if fx is not None and fy is not None:
        return [] if _close(fx, fy, max(scale, 0.0), tol) else [Difference(name, where, sx, sy, "number")]
    if _NUMBER.sub("#", sx) != _NUMBER.sub("#", sy):
        return [Difference(name, where, sx, sy, "decision")]
    for u, v in zip(_NUMBER.findall(sx), _NUMBER.findall(sy)):
        if not _close_printed(u, v, tol):
            return [Difference(name, where, sx, sy, "number")]
    return []


def _close(x: float, y: float, scale: float, tol: Tolerances) -> bool:
    if math.isnan(x) or math.isnan(y):
        return math.isnan(x) and math.isnan(y)
    if math.isinf(x) or math.isinf(y):
        return x == y
    return abs(x - y) <= max(tol.rtol * max(abs(x), abs(y)), tol.atol_fraction * scale, tol.atol)


def _close_printed(u: str, v: str, tol: Tolerances) -> bool:
    """Two numbers as printed in a sentence: equal within ``rtol`` or within one unit of their last digit
    (a value on a rounding boundary prints as 0.952 on one machine and 0.953 on another)."""
    x, y = float(u), float(v)
    if not (math.isfinite(x) and math.isfinite(y)):
        return u == v
    digits = len(u.split(".")[1].lower().split("e")[0]) if "." in u else 0
    exponent = int(u.lower().split("e")[1]) if "e" in u.lower() else 0
    unit = 10.0 ** max(min(exponent - digits, 300), -300)
    return abs(x - y) <= max(tol.rtol * max(abs(x), abs(y)), 1.0001 * unit)
