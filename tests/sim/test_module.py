"""Modules: wiring, execution order, constants, events, results, save/resume."""

from __future__ import annotations

import json
import math

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
