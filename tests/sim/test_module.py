"""Modules: wiring, execution order, constants, events, results, save/resume."""

from __future__ import annotations

import json
import math
import re
from typing import Any

import matplotlib
import numpy as np
import pytest

import loopworks
from loopworks import Module, create_block
from loopworks.errors import InputError
from loopworks.sim.module import Event

matplotlib.use("Agg")

DT = 0.5
K, TI = 1.2, 15.0           # PI
GAIN, TAU = 2.0, 20.0       # first-order process


def closed_loop(order: list[str] | None = None, events: list[Event] | None = None) -> Module:
    return Module({"pid": create_block("pid", k=K, ti=TI, out_lo=-1e9, out_hi=1e9),
                   "process": create_block("process.first_order", gain=GAIN, time_constant=TAU)},
                  wires={"process.u": "pid.out", "pid.pv": "process.y"},
                  inputs={"pid": {"sp": 10.0}}, order=order, events=events)


def reference_loop(n: int, pid_first: bool) -> tuple[np.ndarray, np.ndarray]:
    """The same loop written out from the textbook recurrences, without any block code:
    u_k = K·e_k + I_k with I_k = I_{k-1} + K/Ti·dt·e_k;  y_k = a·y_{k-1} + (1-a)·GAIN·u_k."""
    a = math.exp(-DT / TAU)
    y = 0.0
    integral = 0.0
    u = 0.0
    us, ys = np.empty(n), np.empty(n)
    for k in range(n):
        if pid_first:
            e = 10.0 - y
            integral += K / TI * DT * e
            u = K * e + integral
            y = a * y + (1 - a) * GAIN * u
        else:
            y = a * y + (1 - a) * GAIN * u
            e = 10.0 - y
            integral += K / TI * DT * e
            u = K * e + integral
        us[k], ys[k] = u, y
    return us, ys


@pytest.mark.parametrize(("order", "pid_first"), [(None, True), (["process", "pid"], False)])
def test_closed_loop_matches_the_textbook_recurrence(order: list[str] | None,
                                                     pid_first: bool) -> None:
    """An input reads its source's newest value: this scan's if the source already ran."""
    result = closed_loop(order).run(duration=100 * DT, dt=DT)
    u, y = reference_loop(100, pid_first)
    np.testing.assert_allclose(result["pid.out"], u, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result["process.y"], y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result.t, np.arange(100) * DT)


def test_result_has_every_port_and_status() -> None:
    result = closed_loop().run(duration=10.0, dt=DT)
    for name in ("pid.sp", "pid.pv", "pid.out", "pid.p_term", "process.u", "process.y"):
        assert len(result[name]) == 20
        assert len(result[f"{name}.ST"]) == 20
    assert set(result["pid.out.ST"]) == {128}
    assert (result["pid.sp"] == 10.0).all()          # the constant input
    np.testing.assert_array_equal(result["process.u"], result["pid.out"])  # the wire


def test_events_set_an_input_at_their_time() -> None:
    m = closed_loop(events=[Event(5.0, "pid.sp", 20.0)])
    result = m.run(duration=10.0, dt=DT)
    assert (result["pid.sp"][result.t < 5.0] == 10.0).all()
    assert (result["pid.sp"][result.t >= 5.0] == 20.0).all()


def test_an_event_may_be_a_table_or_a_tuple_and_anything_else_is_named() -> None:
    """`Module(..., events=[dict(t=..., set=..., value=...)])` (a scenario's [[events]] row)
    was a bare AttributeError ('dict' object has no attribute 't'; found by a user)."""
    for ev in ({"t": 5.0, "set": "pid.sp", "value": 20.0}, (5.0, "pid.sp", 20.0)):
        result = closed_loop(events=[ev]).run(duration=10.0, dt=DT)  # type: ignore[list-item]
        assert (result["pid.sp"][result.t >= 5.0] == 20.0).all()
    with pytest.raises(InputError, match=r"event \{'when': 5.0\}: expected Event"):
        closed_loop(events=[{"when": 5.0}])  # type: ignore[list-item]


def test_mode_events_take_names() -> None:
    m = closed_loop(events=[Event(2.0, "pid.mode", "MAN"), Event(2.0, "pid.man_out", 7.0)])
    result = m.run(duration=4.0, dt=DT)
    assert (result["pid.out"][result.t >= 2.0] == 7.0).all()
    assert (result["pid.out.ST"][result.t >= 2.0] == 131).all()


def test_resume_from_saved_module_state_equals_one_run() -> None:
    events = [Event(30.0, "pid.sp", 15.0)]
    whole = closed_loop(events=events).run(duration=60.0, dt=DT)
    m = closed_loop(events=events)
    first = m.run(duration=25.0, dt=DT)
    saved = json.loads(json.dumps(m.state_dict()))
    other = closed_loop(events=events)
    other.load_state(saved)
    second = other.run(duration=35.0, dt=DT, reset=False)
    np.testing.assert_array_equal(np.concatenate([first.t, second.t]), whole.t)
    for name in ("pid.out", "process.y", "pid.sp"):
        np.testing.assert_array_equal(np.concatenate([first[name], second[name]]), whole[name])


def test_a_retuning_before_the_save_is_resumed_too() -> None:
    """A parameter changed before the save (an event here; an operator's write in `serve`,
    where it was lost on every controller restart, found by a user) is part of what a saved
    state resumes: the resumed run equals the whole one."""
    events = [Event(10.0, "pid.k", 2.4), Event(30.0, "pid.sp", 15.0)]
    whole = closed_loop(events=events).run(duration=60.0, dt=DT)
    m = closed_loop(events=events)
    first = m.run(duration=25.0, dt=DT)
    saved = json.loads(json.dumps(m.state_dict()))
    assert saved["blocks"]["pid"]["params"]["k"] == 2.4
    other = closed_loop(events=events)
    other.load_state(saved)
    assert other.blocks["pid"].params["k"] == 2.4
    second = other.run(duration=35.0, dt=DT, reset=False)
    np.testing.assert_array_equal(np.concatenate([first["pid.out"], second["pid.out"]]),
                                  whole["pid.out"])


@pytest.mark.parametrize(("wires", "inputs", "message"), [
    ({"process.u": "pidx.out"}, {}, "unknown block 'pidx'"),
    ({"process.u": "pid.outt"}, {}, "has no output 'outt'; outputs: out"),
    ({"process.uu": "pid.out"}, {}, "has no input 'uu'; inputs: u"),
    ({"process.u": "pid"}, {}, "must be written 'block.port'"),
    ({"process.u": "pid.out"}, {"process": {"u": 1.0}}, "conflicts with its wire"),
])
def test_wiring_errors_name_what_is_wrong(wires: dict[str, str],
                                          inputs: dict[str, dict[str, float]],
                                          message: str) -> None:
    with pytest.raises(InputError, match=message):
        Module({"pid": create_block("pid"), "process": create_block("process.first_order")},
               wires=wires, inputs=inputs)


def test_order_must_name_each_block_once() -> None:
    with pytest.raises(InputError, match="order"):
        Module({"pid": create_block("pid")}, order=["pid", "pid"])


@pytest.mark.parametrize("compiled", [True, False])
def test_a_module_whose_blocks_went_into_another_module_refuses_to_run(compiled: bool) -> None:
    """A module moves its blocks' buffers into its own; putting the same block objects in a
    second module moved them again, and the first module then ran on numbers its blocks no
    longer held: a run that looked fine and was not (relay_test did this to the caller's
    module, found by an outside audit). Now a located error; the second module runs."""
    def blocks() -> dict[str, Any]:
        return {"pid": create_block("pid", k=1.0, ti=10.0, jit=compiled),
                "process": create_block("process.first_order", jit=compiled)}

    wires = {"process.u": "pid.out", "pid.pv": "process.y"}
    shared = blocks()
    first = Module(shared, wires=wires)
    first.run(5.0, 0.1)
    second = Module(shared, wires=wires)
    reference = Module(blocks(), wires=wires).run(5.0, 0.1)
    assert np.array_equal(second.run(5.0, 0.1)["process.y"], reference["process.y"])
    for call in (lambda: first.run(5.0, 0.1), lambda: first.scan(0.1), first.reset):
        with pytest.raises(InputError, match=r"block 'pid' \(pid\) was put into another "
                                             r"module .* \(create_block again"):
            call()


def test_run_rejects_bad_dt_and_duration() -> None:
    m = closed_loop()
    with pytest.raises(InputError, match="dt"):
        m.run(duration=10.0, dt=0.0)
    with pytest.raises(InputError, match="duration"):
        m.run(duration=-1.0, dt=0.1)


def test_to_pandas_and_plot() -> None:
    import pandas as pd  # a test extra
    result = closed_loop().run(duration=5.0, dt=DT)
    df = result.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert df.index.name == "t"
    assert "pid.out" in df.columns and "pid.out.ST" in df.columns
    assert df["pid.out"].to_numpy() == pytest.approx(result["pid.out"])
    axes = result.plot()
    assert len(axes) == 3   # pid SP/PV, pid output, process
    labels = [line.get_label() for line in axes[0].get_lines()]
    assert labels == ["pid.sp", "pid.pv"]
    ax = result.plot(["process.y"])
    assert [line.get_label() for line in ax.get_lines()] == ["process.y"]


def test_to_csv_writes_every_signal(tmp_path: object) -> None:
    import csv
    from pathlib import Path

    path = Path(str(tmp_path)) / "run.csv"
    result = closed_loop().run(duration=2.0, dt=DT)
    result.to_csv(path)
    rows = list(csv.reader(path.open()))
    assert rows[0][0] == "t" and "pid.out" in rows[0] and "pid.out.ST" in rows[0]
    assert len(rows) == 1 + 4
    col = rows[0].index("process.y")
    assert float(rows[2][col]) == result["process.y"][1]


def test_to_csv_is_the_same_text_compiled_and_interpreted(tmp_path: object,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """SimResult.to_csv formats compiled (floatfmt) or with csv.writer (LOOPWORKS_JIT=0): the
    same bytes, and every value reads back as the same double, awkward ones included."""
    import csv
    from pathlib import Path

    from loopworks.sim.result import SimResult

    rng = np.random.default_rng(7)
    t = np.arange(6) * 0.1
    awkward = np.array([0.1, -0.0, np.nan, np.inf, -1e-5, 1.2345678901234567e-308])
    values = {"a.y": awkward, "b.y": rng.normal(size=6) * 1e6}
    status = {"a.y": np.array([128, 0, 0x47, 0, 131, 255], dtype=np.uint8),
              "b.y": np.full(6, 128, dtype=np.uint8)}
    result = SimResult(t=t, values=values, status=status)
    texts = []
    for jit in ("1", "0"):
        monkeypatch.setenv("LOOPWORKS_JIT", jit)
        path = Path(str(tmp_path)) / f"run{jit}.csv"
        result.to_csv(path)
        texts.append(path.read_bytes())
    assert texts[0] == texts[1]
    rows = list(csv.reader(texts[0].decode().splitlines()))
    assert rows[0] == ["t", "a.y", "b.y", "a.y.ST", "b.y.ST"]
    got = np.array([[float(v) for v in row[:3]] for row in rows[1:]])
    np.testing.assert_array_equal(got, np.column_stack([t, awkward, values["b.y"]]))
    assert [row[1] for row in rows[1:3]] == ["0.1", "-0.0"]
    assert [int(row[3]) for row in rows[1:]] == [128, 0, 0x47, 0, 131, 255]


def test_module_is_exported() -> None:
    assert loopworks.Module is Module


def test_result_metrics_for_the_first_controller() -> None:
    """The result object computes the loop metrics itself (spec plant-and-tuning 4.1)."""
    result = closed_loop().run(duration=50.0, dt=DT)
    assert result.controllers() == ["pid"]
    m = result.metrics()
    e = result["pid.sp"] - result["pid.pv"]
    assert m["IAE"] == pytest.approx(float(np.sum(np.abs(e))) * DT)
    assert "valve travel" not in m
    late = result.metrics(window=(25.0, 50.0))
    assert late["IAE"] < m["IAE"]


def test_metrics_follow_the_wires_to_each_loops_valve() -> None:
    """Two loops, one through a compensator: each loop's valve travel is its own valve's."""
    blocks = {}
    wires = {}
    for n, comp in (("a", False), ("b", True)):
        blocks[f"pid_{n}"] = create_block("pid", k=1.0, ti=10.0, bias=50.0)
        blocks[f"valve_{n}"] = create_block("valve.choudhury", s=3.0, j=1.0, y0=50.0)
        blocks[f"proc_{n}"] = create_block("process.fopdt", u0=50.0)
        if comp:
            blocks[f"comp_{n}"] = create_block("compensator.constant_reinforcement")
            wires.update({f"comp_{n}.op_in": f"pid_{n}.out", f"valve_{n}.op": f"comp_{n}.op_out"})
        else:
            wires[f"valve_{n}.op"] = f"pid_{n}.out"
        wires.update({f"proc_{n}.u": f"valve_{n}.position", f"pid_{n}.pv": f"proc_{n}.y"})
    m = Module(blocks, wires=wires, inputs={"pid_a": {"sp": 51.0}, "pid_b": {"sp": 51.0}})
    r = m.run(200.0, 0.2)
    assert r.controllers() == ["pid_a", "pid_b"]
    assert (r.valve_of("pid_a"), r.valve_of("pid_b")) == ("valve_a", "valve_b")
    for n in ("a", "b"):
        expected = float(np.sum(np.abs(np.diff(r[f"valve_{n}.position"]))))
        assert r.metrics(f"pid_{n}")["valve travel"] == pytest.approx(expected)


def test_every_vendor_controller_is_a_loop_of_the_result() -> None:
    """GE (sp, pv -> cv) and S5 (w, x -> y) are controllers too: their roles (issue 13) name
    the ports the metrics read (they were missed by an sp/pv/out port test)."""
    blocks = {"ge": create_block("ge.pid_isa", kc=1.0, ti=20.0, bias=16000.0, jit=False),
              "proc_ge": create_block("process.first_order", gain=1.0, time_constant=10.0,
                                      y0=16000.0, jit=False),
              "s5": create_block("s5.pid", k=1024, ti=50, y0=500, bgug=0, bgog=1000,
                                 jit=False),
              "proc_s5": create_block("process.first_order", gain=1.0, time_constant=10.0,
                                      y0=500.0, jit=False)}
    wires = {"proc_ge.u": "ge.cv", "ge.pv": "proc_ge.y",
             "proc_s5.u": "s5.y", "s5.x": "proc_s5.y"}
    m = Module(blocks, wires=wires, inputs={"ge": {"sp": 17000.0}, "s5": {"w": 520.0}})
    r = m.run(60.0, 1.0, plan="python")
    assert r.controllers() == ["ge", "s5"]
    for loop, sp, pv, out in (("ge", "sp", "pv", "cv"), ("s5", "w", "x", "y")):
        np.testing.assert_array_equal(r.pv(loop), r[f"{loop}.{pv}"])
        np.testing.assert_array_equal(r.out(loop), r[f"{loop}.{out}"])
        e = r[f"{loop}.{sp}"] - r[f"{loop}.{pv}"]
        assert r.metrics(loop)["IAE"] == pytest.approx(float(np.sum(np.abs(e))) * 1.0)
        assert r.metrics(loop)["IAE"] > 0.0
    with pytest.raises(KeyError, match=re.escape("'proc_ge' is a process.first_order block, "
                                                 "not a controller; controllers: ge, s5")):
        r.metrics("proc_ge")


# -- enumerated inputs take only enumerated wires (issue 11 point 3) --------------------------


def test_an_analog_wire_into_a_mode_input_is_refused_naming_the_wire() -> None:
    """pid.mode = process.y once ran the pid in 'mode 37'; now the module is refused."""
    with pytest.raises(InputError) as err:
        Module({"pid": create_block("pid"), "process": create_block("process.first_order")},
               wires={"process.u": "pid.out", "pid.mode": "process.y"})
    message = str(err.value)
    assert "wire 'pid.mode' = 'process.y'" in message
    assert "enumerated input (MAN 0, AUTO 1, CAS 2)" in message and "analog output" in message


def test_a_mode_wire_needs_the_same_codes() -> None:
    """deltav.pid's mode_actual (OOS 0 .. CAS 5) into another deltav.pid's mode is a mode
    wire; into the generic pid's mode (MAN 0, AUTO 1, CAS 2) the codes mean other modes."""
    m = Module({"a": create_block("deltav.pid"), "b": create_block("deltav.pid")},
               wires={"b.mode": "a.mode_actual"})
    assert m.wires == {"b.mode": "a.mode_actual"}
    with pytest.raises(InputError, match=r"output with other codes \(OOS 0, IMAN 1"):
        Module({"a": create_block("deltav.pid"), "b": create_block("pid")},
               wires={"b.mode": "a.mode_actual"})


def test_the_relay_hands_an_s5_loop_over_through_a_mode_wire() -> None:
    """The relay test's handover of S5 (``auto`` = relay ``inactive``, loopworks.sim.tune)
    is a mode wire: relay.inactive carries S5's codes MAN 0 / AUTO 1."""
    m = Module({"s5": create_block("s5.pid"), "relay": create_block("relay")},
               wires={"s5.auto": "relay.inactive"})
    assert m.wires["s5.auto"] == "relay.inactive"
    with pytest.raises(InputError, match="enumerated input"):
        Module({"s5": create_block("s5.pid"), "relay": create_block("relay")},
               wires={"s5.auto": "relay.active"})


# -- events, constants: checked when the module is made, and named as what they are -----------


@pytest.mark.parametrize(("event", "message"), [
    (Event(5.0, "pid.mode", "HIGH"), r"event at t = 5 s, set = 'pid.mode': input 'mode' = 'HIGH'"),
    (Event(5.0, "pid.k", math.inf), r"event at t = 5 s, set = 'pid.k': pid: parameter 'k' = inf"),
    (Event(5.0, "pid.out_lo", 1e10), r"set = 'pid.out_lo': .*out_hi"),
    (Event(5.0, "pidx.sp", 1.0), r"set = 'pidx.sp': unknown block 'pidx'"),
    (Event(5.0, "pid.foo", 1.0), r"has no input or parameter 'foo'"),
])
def test_a_bad_event_is_refused_before_any_scan(event: Event, message: str) -> None:
    with pytest.raises(InputError, match=message) as err:
        closed_loop(events=[event])
    assert "wire '" not in str(err.value)


def test_parameter_events_are_checked_in_time_order() -> None:
    """out_hi raised first, then out_lo above the old out_hi: valid in that order."""
    m = closed_loop(events=[Event(2.0, "pid.out_hi", 2e9), Event(1.0, "pid.out_lo", -2e9),
                            Event(3.0, "pid.out_lo", 1.5e9)])
    r = m.run(duration=5.0, dt=DT)
    assert r["pid.out"][-1] == 1.5e9  # clamped at the new low limit


def test_errors_about_constants_do_not_call_them_wires() -> None:
    with pytest.raises(InputError, match=r"^constant 'pid.foo': block 'pid' \(pid\) has no "
                                         r"input 'foo'"):
        closed_loop_with(inputs={"pid": {"foo": 1.0}})
    with pytest.raises(InputError, match=r"the constant for 'pid.pv' conflicts with its wire "
                                         r"from 'process.y'"):
        closed_loop_with(inputs={"pid": {"pv": 1.0}})
    with pytest.raises(InputError, match=r"the event for 'pid.pv' conflicts .* or an event, "):
        closed_loop(events=[Event(1.0, "pid.pv", 1.0)])


def closed_loop_with(inputs: dict[str, dict[str, float]]) -> Module:
    return Module({"pid": create_block("pid"), "process": create_block("process.first_order")},
                  wires={"process.u": "pid.out", "pid.pv": "process.y"}, inputs=inputs)


def test_late_events_are_the_ones_no_scan_reaches() -> None:
    """20 s in scans of 0.5 s: the last scan executes at 19.5 s."""
    m = closed_loop(events=[Event(19.5, "pid.sp", 1.0), Event(19.6, "pid.sp", 2.0),
                            Event(30.0, "pid.sp", 3.0)])
    assert [e.t for e in m.late_events(20.0, DT)] == [19.6, 30.0]


# -- runs that could not be recorded are refused before the first scan -------------------------


def test_a_run_too_long_to_record_is_refused_with_the_memory_it_needs() -> None:
    """1e12 s at 1 ms is 1e15 scans; the estimate is (scans + 1) × signals written scan by
    scan × 9 bytes (float64 value + status byte): petabytes. Every input of this loop is
    wired or constant, so only the outputs are written."""
    m = closed_loop()
    outputs = sum(len(b.OUTPUTS) for b in m.blocks.values())
    need_gb = (1e15 + 1) * outputs * 9 / 1e9
    with pytest.raises(InputError) as err:
        m.run(duration=1e12, dt=1e-3)
    message = str(err.value)
    assert "1e+15 scans" in message and f"{need_gb:.3g} GB" in message
    assert "shorter duration or a longer dt" in message
    assert m.k == 0  # nothing ran


def test_the_memory_check_uses_what_is_available(monkeypatch: pytest.MonkeyPatch) -> None:
    import loopworks.sim.module as module

    m = closed_loop()
    need = m.record_bytes(round(1000.0 / DT))
    assert need == 2001 * sum(len(b.OUTPUTS) for b in m.blocks.values()) * 9
    monkeypatch.setattr(module, "available_memory", lambda: 1)
    m.run(duration=1000.0, dt=DT)  # under 64 MB: runs without asking
    monkeypatch.setattr(module, "RECORD_BYTES", 10**6)  # 1 MB a signal-scan: 2000 scans > 1 GB
    monkeypatch.setattr(module, "available_memory", lambda: 5 * 10**8)
    with pytest.raises(InputError, match=r"and 500 MB is available"):
        m.run(duration=1000.0, dt=DT)
    monkeypatch.setattr(module, "available_memory", lambda: None)
    monkeypatch.setattr(module, "RECORD_CAP", 10**8)
    with pytest.raises(InputError, match=r"the record cap of 100 MB"):
        m.run(duration=1000.0, dt=DT)


def test_a_scan_count_that_overflows_is_a_clear_error() -> None:
    with pytest.raises(InputError, match="more scans than can be counted"):
        closed_loop().run(duration=1e300, dt=1e-300)


@pytest.mark.parametrize("duration", [2.0**53 + 4096, 1e308])
def test_more_scans_than_a_double_counts_exactly_is_a_clear_error(duration: float) -> None:
    """A finite but huge duration (found by the scenario fuzzer: duration = 1e308 crashed the
    memory check with an OverflowError) is refused by name before anything is sized; 2**53
    scans, the most a double counts exactly, is the limit."""
    from loopworks.sim.module import MAX_SCANS, scan_count

    with pytest.raises(InputError, match=r"duration = .* more scans than can be counted"):
        closed_loop().run(duration=duration, dt=1.0)
    assert scan_count(float(MAX_SCANS), 1.0) == MAX_SCANS


def test_available_memory_is_a_positive_byte_count() -> None:
    from loopworks.sim.module import available_memory

    avail = available_memory()
    assert avail is None or avail > 0


def test_a_run_records_only_what_is_asked_and_the_metrics_read_only_that() -> None:
    """Module.run(record=...): the result holds the signals named; metric_signals() is what
    the metrics of every loop read (the sweep records only those): the same metrics."""
    from loopworks.sim.scenario import load_scenario

    sc = load_scenario(None)  # deltav.pid (working_sp), a compensator, the Karnopp valve
    module = sc.variants["compensation_on"]
    full = module.run(120.0, sc.dt)
    wanted = module.metric_signals()
    assert "pid.working_sp" in wanted and "valve.position" in wanted and "valve.op" in wanted
    part = module.run(120.0, sc.dt, record=wanted)
    assert set(part.values) == set(wanted)
    for name in wanted:
        np.testing.assert_array_equal(part[name], full[name])
    np.testing.assert_equal(part.metrics(window=(60.0, 120.0)),
                            full.metrics(window=(60.0, 120.0)))
    with pytest.raises(InputError, match=re.escape("record: no signal 'pid.nope'")):
        module.run(1.0, sc.dt, record=["pid.nope"])


def test_every_run_from_the_start_sees_the_same_parameters() -> None:
    """A parameter event (a retune at 3 s) changes the parameter for the rest of that run;
    the next run from the start (reset) begins with the value before the event again, so
    two runs of one module agree. A value set between runs (``set_params``) stays."""
    def loop() -> Module:
        return Module({"pid": loopworks.create_block("pid", k=2.0, ti=10.0),
                       "p": loopworks.create_block("process.first_order", time_constant=5.0)},
                      wires={"p.u": "pid.out", "pid.pv": "p.y"}, inputs={"pid": {"sp": 1.0}},
                      events=[Event(3.0, "pid.k", 0.5)])

    module = loop()
    first = module.run(10.0, 0.1, plan="python")
    assert module.blocks["pid"].params["k"] == 0.5  # the event's value, after the run
    again = module.run(10.0, 0.1, plan="python")
    np.testing.assert_array_equal(again["pid.out"], first["pid.out"])
    assert first["pid.out"][0] == pytest.approx(2.0 * 1.0 + 0.1 * 2.0 / 10.0)  # k = 2 at t = 0
    module.blocks["pid"].set_params(k=4.0)  # between runs: kept
    third = module.run(1.0, 0.1, plan="python")
    assert third["pid.out"][0] == pytest.approx(4.0 * 1.0 + 0.1 * 4.0 / 10.0)


def test_a_copied_or_pickled_module_and_block_run_on_numbers_of_their_own() -> None:
    """copy.deepcopy of a module ran its plan on buffers its copied blocks no longer held,
    and a copied block's scans wrote into the original's buffers (raw addresses copied; found
    by an outside audit through loopworks.compat). A copy runs as the original would, and
    leaves the original as it was."""
    import copy
    import pickle

    import loopworks

    def made() -> Module:
        return Module({"pid": loopworks.create_block("pid", k=1.5, ti=4.0),
                       "p": loopworks.create_block("process.first_order", time_constant=3.0)},
                      wires={"p.u": "pid.out", "pid.pv": "p.y"}, inputs={"pid": {"sp": 1.0}})

    fresh = made().run(3.0, 0.1).values["p.y"]
    for how in (copy.deepcopy, lambda m: pickle.loads(pickle.dumps(m))):
        original = made()
        original.run(3.0, 0.1)
        twin = how(original)
        np.testing.assert_array_equal(twin.run(3.0, 0.1).values["p.y"], fresh)
        twin.scan(0.1)
        assert twin.blocks["p"].y[0] != original.blocks["p"].y[0]  # the twin moved alone
    block = loopworks.create_block("pid", k=1.0, ti=2.0)
    block.step(0.1, sp=1.0, pv=0.0)
    before = block.outputs()["out"].value
    for how in (copy.deepcopy, copy.copy, lambda b: pickle.loads(pickle.dumps(b))):
        twin = how(block)
        assert twin.step(0.1, sp=1.0, pv=0.5)["out"].value == pytest.approx(0.575, rel=1e-12)
        assert block.outputs()["out"].value == before
