"""Property-based tests of the campaign reader (issue 13): random corruptions of a valid campaign each
give a StructSearchError naming the right file (and column where there is one), never another exception."""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from structsearch.data.campaign import read_campaign
from structsearch.data.errors import StructSearchError

COLUMNS = ("t", "alpha", "q", "V", "de", "CL", "CD", "Cm")
N = 300
MANIFEST = ('name = "p"\n[aircraft]\nS = {S}\ncbar = {cbar}\nb = 15.75\n'
            '[[maneuver]]\nid = "m"\nfile = "m.csv"\nkind = "quasi-steady"\nsplit = "train"\n')
# corruptions tried in all (counted by the tests, quoted in the issue note)
EXAMPLES = 120


def _valid_lines():
    t = np.arange(N) * 0.01
    data = {"t": t, "alpha": 0.1 + 0.05 * np.sin(t), "q": 0.01 * np.cos(t), "V": 80 + 0 * t,
            "de": -0.05 + 0 * t, "CL": 0.6 + 0.1 * np.sin(t), "CD": 0.05 + 0 * t, "Cm": 0.001 * np.cos(t)}
    rows = [",".join(f"{data[c][i]:.6g}" for c in COLUMNS) for i in range(N)]
    return [",".join(COLUMNS)] + rows


def _cell_edit(lines, row, col, text):
    cells = lines[row].split(",")
    cells[col] = text
    lines[row] = ",".join(cells)
    return lines


corruption = st.one_of(
    st.tuples(st.just("cell"), st.integers(1, N), st.integers(0, len(COLUMNS) - 1),
              st.sampled_from(["nan", "inf", "-inf", "abc", "1.0.0", "", "  ", "1e999"])),
    st.tuples(st.just("duplicate_time"), st.integers(2, N)),
    st.tuples(st.just("swap_rows"), st.integers(1, N - 1)),
    st.tuples(st.just("drop_column"), st.integers(0, 4)),
    st.tuples(st.just("misspell_header"), st.integers(0, 4), st.sampled_from(["upper", "space", "typo"])),
    st.tuples(st.just("truncate"), st.integers(0, 20)),
    st.tuples(st.just("degrees"), st.sampled_from(["alpha", "de"])),
    st.tuples(st.just("manifest"), st.sampled_from(["S", "cbar"]), st.sampled_from(["nan", "inf", "-1.0", "0.0"])),
    st.tuples(st.just("airspeed"), st.integers(1, N), st.sampled_from(["0", "-5"])),
)


def _apply(kind, args, lines, manifest):
    if kind == "cell":
        row, col, text = args
        return _cell_edit(lines, row, col, text), manifest, COLUMNS[col]
    if kind == "duplicate_time":
        (row,) = args
        return _cell_edit(lines, row, 0, lines[row - 1].split(",")[0]), manifest, "t"
    if kind == "swap_rows":
        (row,) = args
        lines[row], lines[row + 1] = lines[row + 1], lines[row]
        return lines, manifest, "t"
    if kind == "drop_column":
        (col,) = args
        return [",".join(c for i, c in enumerate(line.split(",")) if i != col) for line in lines], manifest, \
            COLUMNS[col]
    if kind == "misspell_header":
        col, how = args
        name = COLUMNS[col]
        wrong = {"upper": name.upper() if name != name.upper() else name.lower(), "space": f" {name}",
                 "typo": name + "x"}[how]
        return _cell_edit(lines, 0, col, wrong), manifest, name
    if kind == "truncate":
        (keep,) = args
        return lines[:keep], manifest, None
    if kind == "degrees":
        (name,) = args
        col = COLUMNS.index(name)
        for row in range(1, N + 1):
            lines = _cell_edit(lines, row, col, f"{float(lines[row].split(',')[col]) * 57.3 + 20:.6g}")
        return lines, manifest, name
    if kind == "manifest":
        key, text = args
        return lines, {**manifest, key: text}, key
    if kind == "airspeed":
        row, text = args
        return _cell_edit(lines, row, 3, text), manifest, "V"
    raise AssertionError(kind)


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(corruption)
def test_every_corruption_is_one_project_error_naming_the_file(tmp_path_factory, change):
    kind, *args = change
    directory = tmp_path_factory.mktemp("c")
    lines, manifest, column = _apply(kind, args, _valid_lines(), {"S": "30.0", "cbar": "2.013"})
    (directory / "m.csv").write_text("\n".join(lines) + ("\n" if lines else ""))
    (directory / "campaign.toml").write_text(MANIFEST.format(**manifest))
    with pytest.raises(StructSearchError) as info:
        read_campaign(directory)
    message = str(info.value)
    assert ("campaign.toml" if kind == "manifest" else "m.csv") in message, message
    if column is not None:
        assert f"'{column}'" in message or f"column {column}" in message, message


def test_the_uncorrupted_campaign_reads(tmp_path):
    """The base of the corruptions is valid: every error above comes from the corruption."""
    (tmp_path / "m.csv").write_text("\n".join(_valid_lines()) + "\n")
    (tmp_path / "campaign.toml").write_text(MANIFEST.format(S="30.0", cbar="2.013"))
    assert read_campaign(tmp_path).data.n_samples == N


# a [[maneuver]] entry's periodic keys (docs/interfaces.md 7.5): TOML values, valid or not
periodic_value = st.sampled_from(["true", "false", '"yes"', "1", "nan"])
frequency_value = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32).map(lambda v: repr(float(v))),
                            st.floats(0.2, 2.0).map(repr),
                            st.sampled_from(['"1.2"', "0", "-3", "true", "[1.0]", "1e999"]))


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(st.none(), periodic_value), st.one_of(st.none(), frequency_value), st.booleans())
def test_periodic_keys_read_or_are_one_error_naming_the_key(tmp_path_factory, periodic, frequency, with_time):
    """Any ``periodic`` and ``frequency`` on a maneuver with or without its time column: it reads, periodic with
    period 1/frequency (or, without a frequency, its duration and one step), or raises one project error naming
    the manifest's entry and the key (the file and ``t`` where the time column is missing without a frequency, or
    ``frequency`` where the record does not cover the period it gives)."""
    directory = tmp_path_factory.mktemp("p")
    lines = _valid_lines()
    if not with_time:
        lines = [",".join(line.split(",")[1:]) for line in lines]
    (directory / "m.csv").write_text("\n".join(lines) + "\n")
    entry = "".join(f"{key} = {value}\n" for key, value in (("periodic", periodic), ("frequency", frequency))
                    if value is not None)
    text = 'name = "p"\n[aircraft]\nS = 30.0\ncbar = 2.013\nb = 15.75\n' + \
        '[[maneuver]]\nid = "m"\nfile = "m.csv"\nkind = "quasi-steady"\nsplit = "train"\n' + entry
    (directory / "campaign.toml").write_text(text)
    try:
        data = read_campaign(directory).data
    except StructSearchError as exc:
        message = str(exc)
        assert "campaign.toml" in message or "m.csv" in message, message
        assert any(f"'{key}'" in message for key in ("periodic", "frequency", "t")) or "TOML" in message, message
        return
    assert with_time or frequency is not None
    if frequency is None and periodic != "true":
        assert data.periods is None
    else:
        expected = 1 / float(frequency) if frequency is not None else 3.0
        assert data.periods == pytest.approx((expected,))
