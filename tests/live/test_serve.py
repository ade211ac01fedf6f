"""The live controller without a network: the built-in scenario's controller side scanned
against its own plant side in memory (:mod:`loopworks.live.loopback`), so the
vendor rules for a Bad PV, the operator's writes and the checkpoint can be checked scan by
scan."""

from __future__ import annotations

import asyncio
import math
from pathlib import Path
from typing import Any

import pytest

from loopworks.blocks import status as st
from loopworks.live.loopback import LoopbackIO
from loopworks.live.opcua import MODES, WriteRefused
from loopworks.live.registers import default_map
from loopworks.live.serve import LiveController
from loopworks.live.split import split_scenario
from loopworks.sim.scenario import load_scenario

MAN, AUTO = 3, 4  # deltav.pid mode codes (OOS, IMAN, LO, MAN, AUTO, CAS)


def make(checkpoint: Path | None = None) -> tuple[LiveController, LoopbackIO]:
    split = split_scenario(load_scenario(None), "compensation_off")
    io = LoopbackIO(split)
    return LiveController(split, default_map(split), io, checkpoint=checkpoint), io


def scans(ctl: LiveController, n: int) -> None:
    async def go() -> None:
        for _ in range(n):
            await ctl.scan()

    asyncio.run(go())


def pid_out(ctl: LiveController, port: str) -> float:
    b = ctl.module.blocks["pid"]
    return float(b.y[b._out_index[port]])


def test_the_loop_runs_and_goes_to_auto_on_the_scenario_event() -> None:
    ctl, _ = make()
    assert list(ctl.loops()) == ["pid"]
    scans(ctl, 40)  # 20 s: the built-in scenario puts the PID in AUTO at t = 5 s
    assert pid_out(ctl, "mode_actual") == AUTO
    snap = ctl.snapshot()
    assert snap["pid.MODE"][0] == AUTO
    assert math.isfinite(snap["pid.PV"][0]) and snap["pid.PV"][1] == st.GOOD_NC


def test_bad_pv_sheds_the_deltav_pid_to_man_holding_out_and_it_returns() -> None:
    # spec vendor-blocks 4.5: PV Bad -> actual mode Man (target kept); back to the target
    # mode once the PV is Good again (no "Target to Manual if Bad IN" by default)
    ctl, io = make()
    scans(ctl, 40)
    io.lost = True
    scans(ctl, 1)
    held = pid_out(ctl, "out")
    assert pid_out(ctl, "mode_actual") == MAN
    assert ctl.snapshot()["pid.PV"][1] == st.BAD_NO_COMM_LUV
    scans(ctl, 5)
    assert pid_out(ctl, "out") == held
    assert pid_out(ctl, "mode_actual") == MAN
    assert ctl.snapshot()["pid.MODE"][0] == AUTO  # the target stays AUTO
    io.lost = False
    scans(ctl, 2)
    assert pid_out(ctl, "mode_actual") == AUTO


def test_operator_writes_are_validated_by_the_block_rules() -> None:
    ctl, _ = make()
    scans(ctl, 20)

    def refused(role: str | None, name: str, value: Any) -> str:
        with pytest.raises(WriteRefused) as info:
            ctl.write("someone", role, "pid", name, value)
        return info.value.code

    assert refused(None, "SP", 40.0) == "BadUserAccessDenied"
    assert refused("viewer", "SP", 40.0) == "BadUserAccessDenied"
    assert refused("operator", "SP", 1e6) == "BadOutOfRange"  # outside SP_LO_LIM..SP_HI_LIM
    assert refused("operator", "SP", float("nan")) == "BadOutOfRange"
    assert refused("operator", "OUT", 30.0) == "BadInvalidState"  # OUT only in MAN
    assert refused("operator", "MODE", "IMAN") == "BadOutOfRange"  # set by the block only
    assert refused("operator", "GAIN", -1.0) == "BadOutOfRange"
    assert refused("operator", "PV", 1.0) == "BadNotWritable"
    ctl.write("op", "operator", "pid", "SP", 55.0)
    scans(ctl, 1)
    assert ctl.snapshot()["pid.SP"][0] == 55.0
    ctl.write("op", "operator", "pid", "MODE", "MAN")
    ctl.write("op", "operator", "pid", "OUT", 30.0)
    scans(ctl, 1)
    assert pid_out(ctl, "mode_actual") == MAN
    assert pid_out(ctl, "out") == pytest.approx(30.0)
    ctl.write("op", "operator", "pid", "GAIN", 1.2)
    assert ctl.module.blocks["pid"].params["gain"] == 1.2
    assert ctl.snapshot()["pid.GAIN"][0] == 1.2


def test_a_restart_resumes_from_the_checkpoint_without_a_bump(tmp_path: Path) -> None:
    path = tmp_path / "checkpoint.json"
    ctl, io = make(path)
    scans(ctl, 60)  # 30 s, past the AUTO event; checkpoints every 10 scans
    ctl.save()
    plant_state = io.plant.state_dict()
    out_before = pid_out(ctl, "out")
    # the same controller continuing, against the same plant, gives the reference next OUT
    scans(ctl, 1)
    reference = pid_out(ctl, "out")
    again, io2 = make(path)
    assert again.resumed and again.scans == 60
    assert again.module.t == pytest.approx(30.0)
    assert pid_out(again, "out") == out_before  # restored, before any scan
    # against the plant as it was at the checkpoint, the resumed controller's next OUT is
    # the one the uninterrupted controller gave: no bump
    io2.plant.load_state(plant_state)
    scans(again, 1)
    assert pid_out(again, "mode_actual") == AUTO
    assert pid_out(again, "out") == pytest.approx(reference, abs=1e-9)


def test_a_checkpoint_of_another_module_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "checkpoint.json"
    path.write_text('{"layout": "something else", "module": {}}', encoding="utf-8")
    from loopworks.errors import InputError

    with pytest.raises(InputError, match="another controller module"):
        make(path)


def test_the_compensator_fed_by_the_loop_shows_as_comp_variables() -> None:
    ctl, _ = make()
    names = {v.name: v for v in ctl.loops()["pid"]}
    for name in ("COMP_SIGNAL_OUT", "COMP_DITHER_DELT", "COMP_KICKER_DELT", "COMP_START"):
        assert name in names and not names[name].writable, name
    assert "deltav.stick_slip" in names["COMP_DITHER_DELT"].description
    assert "COMP_SIGNAL_IN" not in names  # a wired input is the PID's OUT: not repeated
    scans(ctl, 4)
    snap = ctl.snapshot()
    assert snap["pid.COMP_START"][0] == 0.0  # the built-in first variant: compensation off
    assert snap["pid.COMP_SIGNAL_OUT"][0] == pytest.approx(snap["pid.OUT"][0], abs=1e-3)


def test_a_poll_period_reads_the_device_every_so_many_scans() -> None:
    # [io] poll_period = 2 s with 0.5 s scans: the device is read every 4th scan, and the
    # controller holds the value read in between
    split = split_scenario(load_scenario(None), "compensation_off")
    io = LoopbackIO(split)
    reads = 0
    read = io.read

    async def counted() -> dict[str, tuple[float, int]]:
        nonlocal reads
        reads += 1
        return await read()

    io.read = counted  # type: ignore[method-assign]
    regmap = default_map(split)
    polled = type(regmap)(regmap.points, regmap.device_id, regmap.heartbeat_address,
                          regmap.fault_bits_address, poll_period=2.0)
    ctl = LiveController(split, polled, io)
    assert ctl.poll_every == 4
    seen = []
    for _ in range(12):
        scans(ctl, 1)
        seen.append(ctl.snapshot()["pid.PV"][0])
    assert reads == 3  # scans 0, 4, 8
    assert seen[0] == seen[1] == seen[2] == seen[3]
    assert seen[4] == seen[5] == seen[6] == seen[7]
    assert seen[4] != seen[3]  # a new read (the transmitter's noise alone moves it)


@pytest.mark.parametrize("period", [0.0, -1.0, float("inf"), "2"])
def test_a_wrong_poll_period_is_named(period: object) -> None:
    from loopworks.errors import InputError

    split = split_scenario(load_scenario(None), "compensation_off")
    regmap = default_map(split)
    with pytest.raises(InputError, match="poll_period"):
        type(regmap)(regmap.points, poll_period=period)  # type: ignore[arg-type]


# --- issue hc (black-box report): modes, working SP, OUT and scale writes, checkpoints -------

CASCADE = Path(__file__).resolve().parents[2] / "examples" / "cascade.toml"


def make_cascade(checkpoint: Path | None = None) -> LiveController:
    """examples/cascade.toml: two generic pids, the secondary in CAS on the primary's OUT."""
    split = split_scenario(load_scenario(CASCADE))
    return LiveController(split, default_map(split), LoopbackIO(split), checkpoint=checkpoint)


def refusal(ctl: LiveController, loop: str, name: str, value: Any) -> WriteRefused:
    with pytest.raises(WriteRefused) as info:
        ctl.write("op", "operator", loop, name, value)
    return info.value


def test_a_generic_pid_s_mode_is_published_and_written_by_its_name() -> None:
    # the pid's mode input codes MAN 0, AUTO 1, CAS 2; the MODE node's are MODES (OOS 0,
    # IMAN 1, LO 2, MAN 3, AUTO 4, CAS 5): the name is what is kept, both ways
    ctl = make_cascade()
    scans(ctl, 2)
    snap = ctl.snapshot()
    assert MODES[snap["primary.MODE"][0]] == "AUTO" and snap["primary.MODE"][1] == st.GOOD_NC
    assert MODES[snap["secondary.MODE"][0]] == "CAS"
    declared = {v.name: v for v in ctl.loops()["primary"]}
    assert MODES[int(declared["MODE"].value)] == "AUTO"
    assert "MAN, AUTO, CAS" in declared["MODE"].description
    secondary = ctl.module.blocks["secondary"]
    ctl.write("op", "operator", "secondary", "MODE", MODES.index("MAN"))  # OPC UA code 3
    assert _in(secondary, "mode") == 0.0  # the pid's MAN
    assert MODES[ctl.snapshot()["secondary.MODE"][0]] == "MAN"
    ctl.write("op", "operator", "secondary", "MODE", MODES.index("AUTO"))
    assert _in(secondary, "mode") == 1.0
    ctl.write("op", "operator", "secondary", "MODE", "cas")
    assert _in(secondary, "mode") == 2.0
    oos = refusal(ctl, "secondary", "MODE", MODES.index("OOS"))  # code 0 is not the pid's MAN
    assert oos.code == "BadOutOfRange"
    assert "OOS" in oos.message and "MAN, AUTO, CAS" in oos.message
    assert _in(secondary, "mode") == 2.0  # unchanged
    assert refusal(ctl, "secondary", "MODE", 7).code == "BadOutOfRange"


def _in(block: Any, port: str) -> float:
    return float(block.u[block._in_index[port]])


def test_the_sp_node_shows_the_cascade_setpoint_and_refuses_an_operator_sp_in_cas() -> None:
    # the generic pid in CAS controls to cas_sp (blocks/pid.py): SP shows it, not the unused
    # local sp (0); an SP write then would be silently unused, so it is refused with the reason
    ctl = make_cascade()
    scans(ctl, 5)
    primary_out = float(ctl.snapshot()["primary.OUT"][0])
    assert primary_out == pytest.approx(50.0, abs=1.0)
    assert ctl.snapshot()["secondary.SP"][0] == pytest.approx(primary_out)
    refused = refusal(ctl, "secondary", "SP", 40.0)
    assert refused.code == "BadInvalidState"
    assert "cas_sp" in refused.message and "CAS" in refused.message
    assert _in(ctl.module.blocks["secondary"], "sp") == 0.0  # not written
    ctl.write("op", "operator", "secondary", "MODE", "AUTO")
    ctl.write("op", "operator", "secondary", "SP", 40.0)
    assert ctl.snapshot()["secondary.SP"][0] == 40.0


def test_the_deltav_sp_node_shows_the_working_setpoint_and_refuses_writes_in_cas() -> None:
    # spec vendor-blocks 4.5: in Cas the SP comes from CAS_IN, in Auto the operator sets it;
    # SP publishes the block's working SP (its working_sp role output)
    ctl, _ = make()
    scans(ctl, 20)
    pid = ctl.module.blocks["pid"]
    pid.set_inputs({"cas_in": 57.0})
    ctl.write("op", "operator", "pid", "MODE", "CAS")
    scans(ctl, 1)
    assert pid_out(ctl, "mode_actual") == MODES.index("CAS")
    assert ctl.snapshot()["pid.SP"][0] == 57.0  # the working SP, not the operator's sp (50)
    assert _in(pid, "sp") == 50.0
    refused = refusal(ctl, "pid", "SP", 45.0)
    assert refused.code == "BadInvalidState" and "cascade" in refused.message
    assert _in(pid, "sp") == 50.0
    ctl.write("op", "operator", "pid", "MODE", "AUTO")
    scans(ctl, 1)
    ctl.write("op", "operator", "pid", "SP", 45.0)
    scans(ctl, 1)
    assert ctl.snapshot()["pid.SP"][0] == 45.0


@pytest.mark.parametrize(("scenario", "loop"), [("deltav", "pid"), ("cascade", "primary")])
def test_an_out_beyond_the_output_limits_is_refused_not_clamped(scenario: str,
                                                                loop: str) -> None:
    ctl = make()[0] if scenario == "deltav" else make_cascade()
    scans(ctl, 2)
    ctl.write("op", "operator", loop, "MODE", "MAN")
    for value in (150.0, -20.0, 100.5):
        refused = refusal(ctl, loop, "OUT", value)
        assert refused.code == "BadOutOfRange"
        assert f"OUT = {value:g} is outside the output limits 0..100" == refused.message
    ctl.write("op", "operator", loop, "OUT", 100.0)
    scans(ctl, 1)
    assert ctl.snapshot()[f"{loop}.OUT"][0] == 100.0


def test_a_scale_is_written_in_oos_only() -> None:
    # Fieldbus PID parameter tables: PV_SCALE and OUT_SCALE are written in OOS (e.g. Fisher
    # DVC6000f manual, table 4-31); a scale sets what PV, SP and OUT mean (spec vendor-blocks
    # 4.1, 4.9: changing a span changes the effective gain), so in AUTO it bumps the output
    ctl, _ = make()
    scans(ctl, 20)
    pid = ctl.module.blocks["pid"]
    names = {v.name: v for v in ctl.loops()["pid"]}
    assert names["OUT_SCALE_EU_100"].writable
    assert "OOS only" in names["OUT_SCALE_EU_100"].description
    out = pid_out(ctl, "out")
    for name, value in (("OUT_SCALE_EU_100", 10.0), ("PV_SCALE_EU_100", 200.0),
                        ("OUT_SCALE_EU_0", -5.0), ("PV_SCALE_EU_0", 1.0)):
        refused = refusal(ctl, "pid", name, value)
        assert refused.code == "BadInvalidState"
        assert "OOS" in refused.message and "AUTO" in refused.message, refused.message
    scans(ctl, 1)
    assert pid.params["out_scale_eu_100"] == 100.0 and pid.params["pv_scale_eu_100"] == 100.0
    assert pid_out(ctl, "out") == pytest.approx(out, abs=1.0)  # no bump
    ctl.write("op", "operator", "pid", "MODE", "OOS")
    ctl.write("op", "operator", "pid", "PV_SCALE_EU_100", 200.0)
    assert pid.params["pv_scale_eu_100"] == 200.0
    ctl.write("op", "operator", "pid", "GAIN", 0.7)  # ordinary tuning: any mode
    assert pid.params["gain"] == 0.7


def test_an_accepted_write_is_in_the_checkpoint_at_once(tmp_path: Path) -> None:
    # the supervisor restarts a killed controller from its checkpoint (every 10 scans): an
    # acknowledged change must survive that
    path = tmp_path / "checkpoint.json"
    ctl, _ = make(path)
    scans(ctl, 23)  # the last periodic checkpoint is at scan 20
    ctl.write("op", "operator", "pid", "GAIN", 0.9)
    ctl.write("op", "operator", "pid", "MODE", "MAN")
    ctl.write("op", "operator", "pid", "OUT", 44.0)
    again, _ = make(path)  # a restart: no scan ran after the writes
    assert again.module.blocks["pid"].params["gain"] == 0.9
    scans(again, 1)
    assert pid_out(again, "mode_actual") == MODES.index("MAN")
    assert pid_out(again, "out") == pytest.approx(44.0)


def test_a_checkpoint_that_overrides_the_file_s_parameters_says_so(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "checkpoint.json"
    ctl, _ = make(path)
    ctl.module.blocks["pid"].set_params(gain=1.2, reset=33.0)  # or a file edited since
    ctl.save()
    with caplog.at_level("WARNING", logger="loopworks.serve"):
        again, _ = make(path)
    assert again.module.blocks["pid"].params["gain"] == 1.2  # the checkpoint's is kept
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(lines) == 1, lines
    assert "pid.gain = 1.2 (file: 0.8)" in lines[0] and "pid.reset = 33.0 (file: " in lines[0]
    caplog.clear()
    with caplog.at_level("WARNING", logger="loopworks.serve"):
        plain = tmp_path / "plain.json"  # a checkpoint of the file as it is: nothing to say
        make(plain)[0].save()
        make(plain)
    assert not [r for r in caplog.records if "differ" in r.getMessage()]
    caplog.clear()
    with caplog.at_level("WARNING", logger="loopworks.serve"):
        # an operator's write of a default the file leaves out overrides nothing (the
        # warning named `deadband_pos = 0.0 (file: 0.0)`; found by an operator)
        default = tmp_path / "default.json"
        ctl, _ = make(default)
        pid = ctl.module.blocks["pid"]
        assert "rate" not in pid.given
        pid.set_params(rate=pid.params["rate"])
        ctl.save()
        make(default)
    assert not [r for r in caplog.records if "differ" in r.getMessage()]


def test_out_is_bad_while_its_device_write_fails() -> None:
    """An operator's run: with the valve's device down, OUT stayed Good and the loop looked
    healthy (only the COMM_ERRORS count said otherwise). A loop whose device point was not
    written on the last scan publishes OUT Bad, no communication, last usable value."""
    from loopworks.blocks import status as st

    ctl, io = make()
    scans(ctl, 3)
    value, status = ctl.snapshot()["pid.OUT"]
    assert status & 0xC0 != 0  # Good (or Uncertain), not Bad

    async def down(values: dict[str, float]) -> bool:
        return False

    io.write = down  # type: ignore[method-assign]
    scans(ctl, 1)
    value, status = ctl.snapshot()["pid.OUT"]
    assert status == st.BAD_NO_COMM_LUV and math.isfinite(value)
    del io.write  # the device is back
    scans(ctl, 1)
    assert ctl.snapshot()["pid.OUT"][1] & 0xC0 != 0


WORD_LOOPS = """\
[simulation]
dt = 0.5
duration = 60.0

[blocks.ge]
kind = "ge.pid_ind"
kp = 0.5
ki = 0.05
sample_period = 0.5
bias = 16000
upper_clamp = 32000
lower_clamp = 0
sp = 16000

[blocks.p_ge]
kind = "process.first_order"
gain = 1.0
time_constant = 10.0
y0 = 16000.0

[blocks.s5]
kind = "s5.pid"
k = 500
r = 1000
ti = 50
td = 0
bgog = 2000
bgug = 0
y0 = 1000
no_z = true
w = 1000
yh = 1000

[blocks.p_s5]
kind = "process.first_order"
gain = 1.0
time_constant = 10.0
y0 = 1000.0

[wires]
"p_ge.u" = "ge.cv"
"ge.pv" = "p_ge.y"
"p_s5.u" = "s5.y"
"s5.x" = "p_s5.y"
"""


def live(tmp_path: Path, text: str = WORD_LOOPS) -> LiveController:
    """The live controller of scenario ``text`` (written into ``tmp_path``), against its own
    plant in memory."""
    path = tmp_path / "scenario.toml"
    path.write_text(text, encoding="utf-8")
    split = split_scenario(load_scenario(path))
    return LiveController(split, default_map(split), LoopbackIO(split))


def test_a_word_setpoint_takes_whole_counts_of_a_16_bit_word(tmp_path: Path) -> None:
    """GE's SP operand and S5's W are signed 16-bit words (spec vendor-blocks 1.1, 2.2): an
    operator's SP of 40000 was accepted and published Good while the GE block skipped every
    solution (ok = 0, CV frozen) and S5 used 32767; 16500.5 was published as typed while
    the blocks used 16501 (found by an operator). Both are refused, with the range; a whole
    number in range is taken."""
    ctl = live(tmp_path)
    scans(ctl, 4)
    for loop in ("ge", "s5"):
        for value in (40000.0, -40000.0, 1e9, 16500.5):
            refused = refusal(ctl, loop, "SP", value)
            assert refused.code == "BadOutOfRange", (loop, value)
            assert "16-bit word, a whole number of counts in -32768..32767" in str(refused)
        ctl.write("op", "operator", loop, "SP", 1200.0)
        scans(ctl, 2)
        assert ctl.snapshot()[f"{loop}.SP"][0] == 1200.0


def test_a_word_manual_output_takes_whole_counts(tmp_path: Path) -> None:
    """GE's Manual Command (word 14) and S5's YH are 16-bit words in native arithmetic (spec
    vendor-blocks 1.2, 2.2): an operator's OUT of 12345.5 was answered Good and ran as 12346
    (found by an outside audit), while an SP of 16000.5 is refused. Refused alike."""
    ctl = live(tmp_path)
    scans(ctl, 4)
    for loop, value in (("ge", 12345.5), ("s5", 1000.5)):
        ctl.write("op", "operator", loop, "MODE", MAN)
        refused = refusal(ctl, loop, "OUT", value)
        assert refused.code == "BadOutOfRange" and "a whole number of counts" in str(refused)
        ctl.write("op", "operator", loop, "OUT", float(round(value)))


def test_an_operators_manual_output_ends_with_manual(tmp_path: Path) -> None:
    """GE: an operator's OUT goes to the Manual Command input, a write into word 14 each
    sweep (spec vendor-blocks 1.2). It stayed latched after the return to Auto, so word 14
    no longer copied CV (spec 1.7 step 13: "so a switch to Manual is bumpless") and the next
    switch to Manual jumped to the old OUT (found by an operator). Leaving MAN ends the
    write."""
    ctl = live(tmp_path)
    scans(ctl, 4)
    ctl.write("op", "operator", "ge", "MODE", MAN)
    ctl.write("op", "operator", "ge", "OUT", 17000.0)
    scans(ctl, 4)
    assert ctl.snapshot()["ge.OUT"][0] == 17000.0
    ctl.write("op", "operator", "ge", "MODE", AUTO)
    ctl.write("op", "operator", "ge", "SP", 15000.0)  # Auto moves CV away from 17000
    scans(ctl, 20)
    auto_out = ctl.snapshot()["ge.OUT"][0]
    assert abs(auto_out - 17000.0) > 100.0
    ctl.write("op", "operator", "ge", "MODE", MAN)
    scans(ctl, 1)
    assert ctl.snapshot()["ge.OUT"][0] == pytest.approx(auto_out, abs=50.0)  # no jump back


def test_a_ge_tuning_write_is_a_value_its_word_holds(tmp_path: Path) -> None:
    """GE's tuning lives in 16-bit words (spec vendor-blocks 1.2/1.5: Kp = word 6/100, Ki =
    word 8/1000): KP 4.505 was answered Good and published as typed while the block ran
    word 6 = 451, 4.51 (and an ISA's TI 1500 s ran as 1000/word 8 = 1000 s; found by an
    operator). A value off the word's grid is refused naming what it would run as, and the
    block keeps its tuning; a value on the grid is taken."""
    ctl = live(tmp_path)
    scans(ctl, 2)
    ge = ctl.module.blocks["ge"]
    for name, value, runs in (("KP", 4.505, "4.51"), ("KI", 0.0123, "0.012")):
        refused = refusal(ctl, "ge", name, value)
        assert refused.code == "BadOutOfRange"
        assert f"it would run as {runs}" in str(refused)
    assert (ge.params["kp"], ge.params["ki"]) == (0.5, 0.05)
    assert ge.parameter_words()[6] == 50
    ctl.write("op", "operator", "ge", "KP", 4.51)
    assert ge.params["kp"] == 4.51 and ge.parameter_words()[6] == 451


def test_each_value_is_published_in_its_blocks_units(tmp_path: Path) -> None:
    """PV, SP and OUT were all "% of PV span" and tuning had no units (found by an
    operator): GE's and S5's are counts, the generic pid's its PV's and output's own units,
    and a tuning parameter carries the unit its block declares."""
    ctl = live(tmp_path)
    units = {loop: {v.name: v.units for v in variables}
             for loop, variables in ctl.loops().items()}
    assert units["ge"]["PV"] == units["ge"]["SP"] == units["ge"]["OUT"] == "counts"
    assert units["ge"]["KI"] == "repeats/s"
    assert units["s5"]["PV"] == "count"
    generic, _ = make()
    assert {v.name: v.units for v in generic.loops()["pid"]}["PV"] == "EU"  # deltav.pid
    cascade = {v.name: v.units for v in make_cascade().loops()["primary"]}
    assert cascade["PV"] == "PV units" and cascade["OUT"] == "output units"


def test_out_is_advertised_writable_only_where_it_can_be_written(tmp_path: Path) -> None:
    """E2's OUT was advertised writable "in MAN", but the block has no mode and every write
    was refused (found by an operator): its OUT is read-only, as written."""
    text = WORD_LOOPS + """
[blocks.e2]
kind = "e2.pid"
throttling_range = 20.0
kp = 1.0
ki = 0.2
update_interval = 1.0
output_at_setpoint = 50.0
error_sign = "setpoint_minus_input"
sp = 50.0

[blocks.p_e2]
kind = "process.first_order"
gain = 1.0
time_constant = 10.0
y0 = 50.0
"""
    text = text.replace('"s5.x" = "p_s5.y"\n', '"s5.x" = "p_s5.y"\n"p_e2.u" = "e2.out"\n'
                        '"e2.pv" = "p_e2.y"\n')
    ctl = live(tmp_path, text)
    writable = {loop: {v.name: v.writable for v in variables}
                for loop, variables in ctl.loops().items()}
    assert writable["e2"]["OUT"] is False and "MODE" not in writable["e2"]
    assert writable["ge"]["OUT"] is True  # GE: Manual Command, in MAN
    assert refusal(ctl, "e2", "OUT", 60.0).code == "BadNotWritable"


def test_a_ge_dead_band_is_set_edge_by_edge_as_the_plc_takes_it(tmp_path: Path) -> None:
    """GE's dead band edges are a pair (spec vendor-blocks 1.7 step 2: both 0, or DB+ > 0 and
    DB- < 0); written one node at a time, each edge alone was refused against the other, so
    the band could not be switched on (found by an operator). With the block's
    on_parameter_error = "ok_off" the server takes the words as the PLC does: between the two
    writes the PID does not solve (ok OFF, CV held), and OUT is published Bad,
    configuration error, until the pair is valid."""
    ctl = live(tmp_path, WORD_LOOPS.replace(
        'sample_period = 0.5\n', 'sample_period = 0.5\non_parameter_error = "ok_off"\n'))
    scans(ctl, 2)
    assert ctl.snapshot()["ge.OUT"][1] & 0xC0 != 0  # not Bad
    ctl.write("op", "operator", "ge", "DEADBAND_POS", 5.0)
    scans(ctl, 2)
    assert ctl.snapshot()["ge.OUT"][1] == st.BAD_CONFIGURATION_ERROR
    ctl.write("op", "operator", "ge", "DEADBAND_NEG", -5.0)
    scans(ctl, 2)
    assert ctl.snapshot()["ge.OUT"][1] & 0xC0 != 0
    words = ctl.module.blocks["ge"].parameter_words()
    assert (words[4], words[5]) == (5, -5)


@pytest.mark.parametrize(("pv", "status"), [(150.0, 0x56), (-20.0, 0x55), (1e30, 0x56),
                                            (60.0, st.GOOD_NC)])
def test_a_pv_outside_its_scale_is_uncertain_not_good(pv: float, status: int) -> None:
    """runtime-and-ecosystem 2d: Modbus has no quality bits; "a value outside the engineering
    range -> Uncertain (EngineeringUnitsExceeded)". A device sending 150 on the deltav.pid's
    0..100 PV_SCALE was used and published Good (found by an outside audit). Now Uncertain,
    EU range violation, with the limit bit of its side (FF: 0x54 | high 2 / low 1), and the
    deltav.pid treats an Uncertain PV as Bad (STATUS_OPTS "Use Uncertain as Good" off, spec
    4.6): it sheds to MAN holding OUT instead of driving it to a limit. Within the scale the
    PV stays Good and the loop in AUTO."""
    ctl, io = make()
    scans(ctl, 40)
    real = io.read
    point = ctl.reads[0][1]

    async def read() -> dict[str, tuple[float, int]]:
        values = await real()
        values[point] = (pv, st.GOOD_NC)
        return values

    io.read = read  # type: ignore[method-assign]
    before = pid_out(ctl, "out")
    scans(ctl, 1)
    snap = ctl.snapshot()
    assert snap["pid.PV"] == (pv, status)
    if status == st.GOOD_NC:
        assert pid_out(ctl, "mode_actual") == AUTO
    else:
        assert pid_out(ctl, "mode_actual") == MAN and pid_out(ctl, "out") == before


def test_a_tuning_write_of_inf_is_the_block_s_to_judge() -> None:
    """deltav.pid's RESET is (0, inf] s/repeat, inf = no integral action (spec 4.1); an
    operator's RESET = inf was refused as "not finite" before the block saw it (found by an
    outside audit). The block's range decides: RESET = inf is taken, GAIN = inf refused
    (GAIN is finite), and NaN is never a value."""
    ctl, _ = make()
    scans(ctl, 4)
    ctl.write("op", "operator", "pid", "RESET", math.inf)
    assert ctl.module.blocks["pid"].params["reset"] == math.inf
    scans(ctl, 2)
    assert ctl.snapshot()["pid.RESET"][0] == math.inf
    assert refusal(ctl, "pid", "GAIN", math.inf).code == "BadOutOfRange"
    assert refusal(ctl, "pid", "RESET", math.nan).code == "BadOutOfRange"
    assert refusal(ctl, "pid", "SP", math.inf).code == "BadOutOfRange"


def test_cas_is_refused_for_a_generic_pid_whose_cascade_setpoint_nothing_feeds() -> None:
    """The generic pid in CAS takes its setpoint from cas_sp; with cas_sp unwired a MODE =
    CAS write was accepted and SP read NaN with a Good status (found by an outside audit).
    Refused when nothing feeds cas_sp, with the reason; the cascade's secondary, whose
    cas_sp is wired to the primary, still goes to CAS; an unfed setpoint is never Good."""
    ctl = make_cascade()
    scans(ctl, 5)
    refused = refusal(ctl, "primary", "MODE", "CAS")
    assert refused.code == "BadInvalidState"
    assert "input cas_sp, which nothing feeds" in refused.message
    ctl.write("op", "operator", "secondary", "MODE", "AUTO")
    ctl.write("op", "operator", "secondary", "MODE", "CAS")  # fed: taken
    primary = ctl.by_name["primary"]
    primary.block.set_inputs({"mode": 2.0})  # CAS with nothing on cas_sp, as a file could
    assert ctl.working_sp(primary)[1] == st.BAD_NOT_CONNECTED
