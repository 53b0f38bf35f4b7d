"""``simulate --jsbsim NAME --modify FILE`` (docs/interfaces.md 8.2): a table replaced, and a separation state the
project exported flown inside a JSBSim aircraft in place of what a function read, checked inside JSBSim itself."""
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.export.card import CoefficientModel, ExportedModel, StateModel
from structsearch.export.jsbsim_files import system_xml
from structsearch.foreign.modify import Modification, read_modify

jsbsim = pytest.importorskip("jsbsim", reason="flying a JSBSim aircraft needs the jsbsim package (the test extra has it)")

from structsearch.foreign.aircraft_xml import read_aircraft  # noqa: E402
from structsearch.foreign.private_copy import make_copy  # noqa: E402

CLWBH = "aero/coefficient/CLwbh"
# c172p's CLwbh table: rows alpha [rad], columns aero/stall-hyst-norm (0 before the stall, 1 after)
ROWS = [-0.09, 0.0, 0.09, 0.1, 0.12, 0.14, 0.16, 0.17, 0.19, 0.21, 0.24, 0.26, 0.28, 0.3, 0.32, 0.34, 0.36]
ATTACHED = [-0.22, 0.25, 0.73, 0.83, 0.92, 1.02, 1.08, 1.13, 1.19, 1.25, 1.35, 1.44, 1.47, 1.43, 1.38, 1.30, 1.15]
STALLED = [-0.22, 0.25, 0.73, 0.78, 0.79, 0.81, 0.82, 0.83, 0.85, 0.86, 0.88, 0.90, 0.92, 0.95, 0.99, 1.05, 1.15]
STATE = {"tau1_ss": 0.3, "tau2_ss": 0.0, "a1_ss": 40.0, "a_star_ss": 0.27}


def _state_system() -> str:
    """The system `export --format jsbsim` writes for one U separation state of a lift model reading it."""
    lift = CoefficientModel("CL", "CL-test", (("CL0", "1"), ("CL_KL", "K_L(X_ss)")), {"CL0": 0.1, "CL_KL": 4.0})
    model = ExportedModel((lift,), (StateModel("ss", "U", STATE),), {"S": 16.2, "cbar": 1.49, "b": 11.0},
                          {"alpha_rad": [0.0, 0.4]}, {"source": "test"})
    return system_xml(model)


def _write(tmp_path: Path, text: str, system: bool = True) -> Path:
    if system:
        (tmp_path / "systems").mkdir(exist_ok=True)
        (tmp_path / "systems" / "states.xml").write_text(_state_system())
    path = tmp_path / "modify.toml"
    path.write_text(text)
    return path


STATE_ENTRY = ('[[state]]\nsystem = "systems/states.xml"\nstate = "structsearch/X_ss"\nfunction = "' + CLWBH
               + '"\ninput = "aero/stall-hyst-norm"\ncomplement = true\n')


def _fdm(holder, name: str):
    jsbsim.FGJSBBase().debug_lvl = 0
    fdm = jsbsim.FGFDMExec(holder.name)
    fdm.set_debug_level(0)
    assert fdm.load_model(name)
    return fdm


def _at(fdm, alpha: float) -> None:
    for prop, value in (("ic/h-sl-ft", 5000.0), ("ic/vt-fps", 120.0), ("ic/alpha-rad", alpha), ("ic/beta-rad", 0.0),
                        ("ic/theta-rad", alpha), ("ic/phi-rad", 0.0), ("ic/q-rad_sec", 0.0)):
        fdm[prop] = value
    fdm.run_ic()


def _lift_table(fdm) -> float:
    """CLwbh over what multiplies its table (q S and the ground effect): the table's value as JSBSim read it."""
    return fdm[CLWBH] / (fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"] * fdm["aero/function/kCLge"])


def test_a_replaced_table_is_what_jsbsim_reads_and_keeps_the_inputs_it_read(tmp_path):
    lifted = [v + 0.1 for v in ATTACHED]
    path = _write(tmp_path, f'[[replace]]\nfunction = "{CLWBH}"\nrows = {ROWS}\ncolumns = [0.0, 1.0]\n'
                  f'values = {[[a, s] for a, s in zip(lifted, STALLED)]}\n', system=False)
    modification = read_modify(path)
    assert [t.function for t in modification.tables] == [CLWBH] and not modification.acts_over_time
    aircraft = read_aircraft("c172p")
    stock, replaced = make_copy(aircraft, rewrite=False), make_copy(aircraft, rewrite=False,
                                                                   tables=modification.tables)
    try:
        before, after = _fdm(stock, "c172p"), _fdm(replaced, "c172p")
        for alpha in (0.05, 0.15, 0.22):
            _at(before, alpha)
            _at(after, alpha)
            assert before["aero/stall-hyst-norm"] == after["aero/stall-hyst-norm"] == 0.0
            assert _lift_table(after) == pytest.approx(_lift_table(before) + 0.1, abs=1e-9)
            assert _lift_table(before) == pytest.approx(np.interp(alpha, ROWS, ATTACHED), abs=1e-9)
    finally:
        stock.cleanup()
        replaced.cleanup()
    assert modification.digest() != Modification({CLWBH: 1.0}).digest()


def test_a_replaced_table_must_match_the_functions_table(tmp_path):
    aircraft = read_aircraft("c172p")
    one_input = read_modify(_write(tmp_path, f'[[replace]]\nfunction = "{CLWBH}"\nrows = [0.0, 0.3]\n'
                                   'values = [0.2, 1.2]\n', system=False))
    with pytest.raises(DeclarationError, match=r"\[\[replace\]\] entry 1: the table of .* reads 2 inputs "
                                               r"\(aero/alpha-rad, aero/stall-hyst-norm\)"):
        make_copy(aircraft, rewrite=False, tables=one_input.tables).cleanup()


def test_an_exported_separation_state_flies_in_place_of_the_stall_latch(tmp_path):
    """c172p's lift table picks its column by the stall latch; the exported state, complemented, picks it instead:
    past the state's a* (0.27 rad) the lift leaves the attached column by 1 - X of the way, X the state JSBSim
    integrated, and the lift follows the state's lag after a step in alpha."""
    modification = read_modify(_write(tmp_path, STATE_ENTRY))
    assert modification.acts_over_time and modification.states[0].complement
    aircraft = read_aircraft("c172p")
    with pytest.raises(DeclarationError, match="acts over time"):
        make_copy(aircraft, states=modification.states)
    holder = make_copy(aircraft, rewrite=False, states=modification.states)
    try:
        copy = (Path(holder.name) / "aircraft" / "c172p" / "c172p.xml").read_text()
        assert '<system name="structsearch_states">' in copy and "structsearch/state-1/complement" in copy
        fdm = _fdm(holder, "c172p")
        _at(fdm, 0.30)
        x = fdm["structsearch/X_ss"]
        static = 0.5 * (1 - np.tanh(STATE["a1_ss"] * (fdm["aero/alpha-rad"] - STATE["a_star_ss"])))
        assert 0.0 < x < 1.0
        for _ in range(5):
            fdm.run()
        alpha, x = fdm["aero/alpha-rad"], fdm["structsearch/X_ss"]
        expected = np.interp(alpha, ROWS, ATTACHED) * x + np.interp(alpha, ROWS, STALLED) * (1 - x)
        assert _lift_table(fdm) == pytest.approx(expected, abs=1e-6)
        assert abs(x - static) < 0.5          # the state follows its static curve, lagged
    finally:
        holder.cleanup()


def test_a_system_two_states_share_is_flown_once_and_two_systems_may_not_compute_one_property(tmp_path):
    """A system inserted twice would step its states twice a frame."""
    two = STATE_ENTRY + STATE_ENTRY.replace("aero/coefficient/CLwbh", "aero/coefficient/CDwbh").replace(
        'input = "aero/stall-hyst-norm"', 'input = "aero/alpha-rad"')
    modification = read_modify(_write(tmp_path, two))
    holder = make_copy(read_aircraft("c172p"), rewrite=False, states=modification.states)
    try:
        copy = (Path(holder.name) / "aircraft" / "c172p" / "c172p.xml").read_text()
        assert copy.count('<system name="structsearch_states">') == 1
    finally:
        holder.cleanup()
    (tmp_path / "systems" / "other.xml").write_text(_state_system().replace("structsearch_states", "other"))
    clash = STATE_ENTRY + STATE_ENTRY.replace("systems/states.xml", "systems/other.xml").replace(
        "aero/coefficient/CLwbh", "aero/coefficient/CDwbh").replace('input = "aero/stall-hyst-norm"',
                                                                    'input = "aero/alpha-rad"')
    (tmp_path / "modify.toml").write_text(clash)
    with pytest.raises(DeclarationError, match=r"\[\[state\]\] entry 2: its system systems/other.xml computes"):
        read_modify(tmp_path / "modify.toml")


def test_state_and_table_entries_from_anyone_get_one_error_naming_file_and_entry(tmp_path):
    (tmp_path / "outside.xml").write_text("<system/>")
    inner = tmp_path / "inner"
    inner.mkdir()
    table = f'[[replace]]\nfunction = "{CLWBH}"\n'
    for text, words in ((table + 'rows = [0.1, 0.0]\nvalues = [1, 2]\n', "rows must increase"),
                        (table + 'rows = [0.0, 0.1]\nvalues = [1]\n', "one entry per row breakpoint"),
                        (table + 'rows = [0.0, 0.1]\ncolumns = [0, 1]\nvalues = [1, 2]\n', "one number per column"),
                        (table + 'rows = [0.0, 0.1]\nvalues = [1, nan]\n', "finite number"),
                        (table + 'rows = [0.0, 0.1]\nvalues = [1, 2]\n' + table + 'rows = [0.0, 0.1]\n'
                         'values = [1, 2]\n', "replaced twice"),
                        (STATE_ENTRY.replace("complement = true", 'complement = "yes"'), "true or false"),
                        (STATE_ENTRY.replace("input = ", "reads = "), "entry 1: give system"),
                        (STATE_ENTRY.replace("systems/states.xml", "systems/absent.xml"), "the system 'systems/absent.xml': .*not found"),
                        (STATE_ENTRY.replace("systems/states.xml", "../outside.xml"), r"entry 1: .*leads outside"),
                        (STATE_ENTRY.replace("structsearch/X_ss", "structsearch/X_sss"),
                         "computes no property 'structsearch/X_sss' \\(its states: .*structsearch/X_ss"),
                        (table + 'rows = [0.0, 1' + "0" * 400 + ']\nvalues = [1, 2]\n', "finite number")):
        path = _write(inner, text)
        with pytest.raises(DeclarationError, match=words) as err:
            read_modify(path)
        assert str(path) in str(err.value) and len(str(err.value)) < 600
    _write(inner, STATE_ENTRY)
    (inner / "systems" / "states.xml").write_text("<aerodynamics/>")
    with pytest.raises(DeclarationError, match="is not a JSBSim <system> file"):
        read_modify(inner / "modify.toml")
    (inner / "systems" / "states.xml").write_text('<!DOCTYPE x [<!ENTITY a "b">]><system>&a;</system>')
    with pytest.raises(DeclarationError, match="entities are never expanded"):
        read_modify(inner / "modify.toml")
    # JSBSim would load a file a `file` attribute names, from anywhere: refused, unread
    (inner / "systems" / "states.xml").write_text('<system name="x" file="/etc/passwd"/>')
    with pytest.raises(DeclarationError, match="names another file"):
        read_modify(inner / "modify.toml")
    assert ET.fromstring(_state_system()).tag == "system"
