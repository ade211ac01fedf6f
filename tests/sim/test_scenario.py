"""Scenario files: TOML to module, the built-in scenario, and located errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loopworks.errors import FileFormatError
from loopworks.sim.scenario import load_scenario, parse_scenario

GOOD = """
[simulation]
dt = 0.5
duration = 20.0

[blocks.process]
kind = "process.first_order"
GAIN = 2.0
time_constant = 10.0

[blocks.pid]
kind = "pid"
k = 1.0
ti = 10.0
SP = 4.0

[wires]
"process.u" = "pid.out"
"pid.pv" = "process.y"

[[events]]
t = 10.0
set = "pid.sp"
value = 6.0
"""


def test_tables_build_the_module_in_file_order() -> None:
    sc = parse_scenario(GOOD, "good.toml")
    assert sc.module.order == ["process", "pid"]
    assert sc.dt == 0.5 and sc.duration == 20.0
    assert sc.module.blocks["process"].params["gain"] == 2.0      # any letter case
    result = sc.module.run(sc.duration, sc.dt)
    assert len(result.t) == 40
    assert (result["pid.sp"][:20] == 4.0).all() and (result["pid.sp"][20:] == 6.0).all()
    # process runs first, so at scan 0 it sees the pid's initial output (0): y stays 0
    assert result["process.y"][0] == 0.0
    np.testing.assert_array_equal(result["process.u"][1:], result["pid.out"][:-1])


def test_order_option_overrides_file_order() -> None:
    text = GOOD.replace("duration = 20.0", 'duration = 20.0\norder = ["pid", "process"]')
    assert parse_scenario(text).module.order == ["pid", "process"]


def test_built_in_scenario_shows_the_seed_claim_and_its_cost() -> None:
    """The built-in scenario (the seed's case, spec plant-and-tuning 2.2-2.3): with the
    compensator on, the PV varies less over the second half, and the valve travels further and
    reverses more often (the finding the README reports)."""
    sc = load_scenario()
    assert list(sc.variants) == ["compensation_off", "compensation_on"]
    assert sc.metrics_window == (1800.0, 3600.0)
    off, on = (sc.variants[v].run(sc.duration, sc.dt).metrics(window=sc.metrics_window)
               for v in ("compensation_off", "compensation_on"))
    assert on["PV std"] < 0.9 * off["PV std"]
    assert on["mean |e|"] < off["mean |e|"]
    assert on["valve travel"] > 1.1 * off["valve travel"]
    assert on["valve reversals"] > off["valve reversals"] > 0
    assert off["mean |e|"] < 0.5


def test_example_files_load() -> None:
    """Every scenario in examples/ parses and builds (they are the user's starting points)."""
    examples = Path(__file__).resolve().parents[2] / "examples"
    files = sorted(examples.glob("*.toml"))
    assert len(files) >= 3
    for path in files:
        assert load_scenario(path).variants
    from importlib import resources

    builtin = resources.files("loopworks.scenarios").joinpath("default.toml").read_text()
    assert (examples / "default.toml").read_text() == builtin


def test_load_from_file(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(GOOD)
    assert load_scenario(path).source == str(path)


@pytest.mark.parametrize(("text", "message"), [
    (GOOD.replace("dt = 0.5", "dt = 0.5 0.6"), r"bad\.toml: invalid TOML: .*line 3"),
    (GOOD.replace("dt = 0.5", "dt = -0.5"), r"bad\.toml: simulation\.dt: .*greater than 0"),
    (GOOD.replace("dt = 0.5", "dtt = 0.5"), r"simulation\.dtt: Extra inputs"),
    (GOOD.replace('kind = "pid"', 'kind = "pidd"'), r"\[blocks\.pid\]: unknown block kind"),
    (GOOD.replace("ti = 10.0", "tii = 10.0"), r"\[blocks\.pid\]: pid: unknown parameter 'tii'"),
    (GOOD.replace("ti = 10.0", "ti = -10.0"), r"\[blocks\.pid\]: pid: parameter 'ti' = -10"),
    (GOOD.replace('"pid.pv" = "process.y"', '"pid.pv" = "process.yy"'), r"no output 'yy'"),
    (GOOD.replace('set = "pid.sp"', 'set = "pid.pv"'), r"conflicts with its wire"),
    (GOOD.replace("SP = 4.0", 'SP = "high"'), r"input 'sp' = 'high'"),
])
def test_errors_name_the_file_and_place(text: str, message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        parse_scenario(text, "bad.toml")


def test_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="cannot read the scenario"):
        load_scenario(tmp_path / "nope.toml")


def test_compare_variants_change_parameters_and_inputs() -> None:
    text = GOOD + """
[compare.slow]
"pid.k" = 0.5
[compare.high_sp]
"pid.sp" = 8.0
"""
    sc = parse_scenario(text, "cmp.toml")
    assert list(sc.variants) == ["slow", "high_sp"]
    assert sc.module is sc.variants["slow"]
    assert sc.variants["slow"].blocks["pid"].params["k"] == 0.5
    assert sc.variants["high_sp"].blocks["pid"].params["k"] == 1.0
    r = sc.variants["high_sp"].run(sc.duration, sc.dt)
    assert r["pid.sp"][0] == 8.0


def test_without_compare_there_is_one_base_variant() -> None:
    sc = parse_scenario(GOOD)
    assert list(sc.variants) == ["base"]


@pytest.mark.parametrize(("extra", "message"), [
    ('[compare.x]\n"nope.k" = 1.0\n', r"compare\.x: 'nope\.k' must be 'block\.parameter'"),
    ('[compare.x]\n"pid.kind" = "pid"\n', r"not the kind"),
    ('[compare.x]\n"pid.kk" = 1.0\n', r"compare\.x\).*unknown parameter 'kk'"),
])
def test_compare_errors_are_located(extra: str, message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        parse_scenario(GOOD + extra, "bad.toml")


def test_an_event_can_change_a_parameter() -> None:
    """[[events]] set = "pid.k" changes the gain at t = 10 s: the P term follows at once."""
    text = GOOD + '\n[[events]]\nt = 15.0\nset = "pid.k"\nvalue = 3.0\n'
    sc = parse_scenario(text)
    r = sc.module.run(sc.duration, sc.dt)
    e = r["pid.sp"] - r["pid.pv"]
    before = r.t < 15.0
    np.testing.assert_allclose(r["pid.p_term"][before], 1.0 * e[before], atol=1e-12)
    np.testing.assert_allclose(r["pid.p_term"][~before], 3.0 * e[~before], atol=1e-12)
