"""A demo run over earlier results (a checkout's committed results/) keeps every file whose answers did not change,
byte for byte, and says so in one line; a file with another answer is rewritten and named. The earlier results
here are the committed tables themselves; the "new run" rewrites them with last-digit changes (3e-9 relative, as
another BLAS kernel gives: docs/reproducibility.md) or with a changed decision."""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from structsearch.data.manifest import check_set, finish_set
from structsearch.experiments.unchanged import keep_unchanged, snapshot

ROOT = Path(__file__).resolve().parents[1]
FILES = ("ranking.csv", "lift.md", "lift.tex", "pitch_best_parameters.md", "refined_pitch.toml",
         "discover_CL/discover.json", "figures/lift_static.png")


@pytest.fixture
def earlier(tmp_path):
    out = tmp_path / "results"
    for name in FILES:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / "results" / name, out / name)
    finish_set(out, "search", [out / n for n in FILES[:5]])
    return out


def _last_digits(text: str, printed: bool = False) -> str:
    """Every number of 6 or more significant digits moved by 3e-9 of itself (a CSV's or JSON's full precision);
    in a table a person reads (``printed``) one printed to fewer moved by one unit of its last digit (a value on a
    rounding boundary)."""
    def moved(m):
        digits = m[1].lstrip("-").replace(".", "").lstrip("0")
        if len(digits) >= 6:
            return repr(float(m[0]) * (1 + 3e-9))
        if printed and len(digits) >= 3 and m[1][-1] in "012345678":
            return m[1][:-1] + str(int(m[1][-1]) + 1) + (m[2] or "")
        return m[0]
    return re.sub(r"(-?\d+\.\d+)(e[-+]?\d+)?", moved, text)


def _rerun(out: Path, change=None) -> None:
    """A new run writing every file again with other last digits (and the manifest of what it wrote)."""
    for name in FILES:
        if name.endswith(".png"):
            continue
        path = out / name
        text = path.read_text()
        path.write_text(_last_digits(text, name.endswith((".md", ".tex"))) if change is None else change(text))
    finish_set(out, "search", [out / n for n in FILES[:5]])


def test_the_same_answers_keep_every_file_byte_for_byte(earlier):
    before = {n: (earlier / n).read_bytes() for n in FILES + ("search_manifest.json",)}
    aside = snapshot(earlier)
    _rerun(earlier)
    assert all((earlier / n).read_bytes() != before[n] for n in ("ranking.csv", "lift.md", "lift.tex"))  # other digits
    found = keep_unchanged(earlier, aside)
    assert {n: (earlier / n).read_bytes() for n in before} == before
    assert not found.changed and set(found.kept) == set(FILES) and not aside.exists()
    assert set(found.put_back) == set(FILES) - {"figures/lift_static.png", "refined_pitch.toml"}  # rewritten: no figure, no toml (no long numbers)
    assert "the same answers as the results already there" in found.line(earlier)
    assert "5 rewritten with other last digits and put back" in found.line(earlier)
    check_set(earlier, "search", "ranking.csv")                                # the manifest proves the files


def test_another_answer_is_rewritten_and_named(earlier):
    aside = snapshot(earlier)
    _rerun(earlier, lambda text: text.replace("CL-VI,1,", "CL-VI,2,", 1))
    found = keep_unchanged(earlier, aside)
    assert [d.file for d in found.changed] == ["ranking.csv"] and found.changed[0].kind == "decision"
    assert "CL-VI,2," in (earlier / "ranking.csv").read_text()
    assert "1 files hold other answers" in found.line(earlier) and "ranking.csv" in found.line(earlier)
    check_set(earlier, "search", "ranking.csv")                                # recomputed for the new file


def test_a_changed_word_in_a_table_is_another_answer(earlier):
    aside = snapshot(earlier)
    _rerun(earlier, lambda text: text.replace("CL-VI", "CL-V", 1) if "|" in text else text)
    found = keep_unchanged(earlier, aside)
    assert {d.file for d in found.changed} >= {"lift.md"}


def test_no_earlier_results_no_snapshot(tmp_path):
    assert snapshot(tmp_path / "nowhere") is None
    (tmp_path / "empty" / "cache").mkdir(parents=True)
    (tmp_path / "empty" / "cache" / "fit.json").write_text(json.dumps({}))
    assert snapshot(tmp_path / "empty") is None                                # a cache alone holds no results


def test_a_wall_time_in_a_sentence_is_not_an_answer_and_a_difference_names_its_line(tmp_path):
    from structsearch.experiments.unchanged import differences
    a, b = tmp_path / "a.md", tmp_path / "b.md"
    a.write_text("# Study\n\nSNLS on all maneuvers (10.3 s).\n\n| x | 0.5 |\n")
    b.write_text("# Study\n\nSNLS on all maneuvers (9.2 s).\n\n| x | 0.5 |\n")
    assert differences("study.md", a, b) == []
    b.write_text("# Study\n\nSNLS on all maneuvers (9.2 s).\n\n| x | 0.7 |\n")
    found = differences("study.md", a, b)
    assert [(d.where, d.first, d.second, d.kind) for d in found] == [("line 5", "| x | 0.5 |", "| x | 0.7 |", "number")]


def test_an_interrupted_demo_puts_the_earlier_results_back_and_leaves_no_copy(tmp_path, monkeypatch):
    """A demo stopped half way (Ctrl-C, a failure) over a checkout's results leaves them as they were: the files
    it had rewritten go back, and the snapshot it took is removed (before, it was removed without being put back,
    the only copy of the committed results). The snapshot is named as every run's temporary folder
    (``structsearch-<pid>-...``), so a run killed with -9 leaves nothing the next run does not sweep."""
    import os
    import tempfile

    import structsearch.workflows as workflows
    from structsearch.experiments import unchanged
    out = tmp_path / "results"
    out.mkdir()
    (out / "lift.md").write_text("the committed ranking\n")
    made = []
    real_snapshot = unchanged.snapshot

    def snapshot(path):
        made.append(real_snapshot(path))
        return made[-1]
    monkeypatch.setattr(unchanged, "snapshot", snapshot)

    def half_a_demo(out, **kwargs):
        (out / "lift.md").write_text("half of a new ranking\n")
        (out / "drag.md").write_text("a file the earlier results did not have\n")
        raise KeyboardInterrupt
    monkeypatch.setattr(workflows, "_demo", half_a_demo)
    with pytest.raises(KeyboardInterrupt):
        workflows.demo(out)
    assert (out / "lift.md").read_text() == "the committed ranking\n" and not (out / "drag.md").exists()
    assert made[0].name.startswith(f"structsearch-{os.getpid()}-") and made[0].parent == Path(tempfile.gettempdir())
    assert not made[0].exists()
