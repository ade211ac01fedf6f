"""What to do about a sticky valve (issue 15 point 5): simulate the loop fitted to the data
with no compensation, with each stiction compensator and with a retuned controller, over the
uncertainty of the fit, and recommend the option with the lowest PV variability for an
acceptable valve travel.

The fitted loop (a scenario built here, run by :func:`loopworks.sim.sweep.sweep`): the
identified PI controller (``pid``, its Kc and Ti), the compensators in series after it (each
passing its input through unless its variant enables it, as ``examples/sweep_compensators.toml``
does), a Choudhury valve with the estimated S and J, the identified process (``process.fopdt``
or ``process.ipdt``), a random-walk load, the transmitter noise seen in the data and a setpoint
step of 1 % at 20 s. The
options and how each is tuned from the estimate (spec plant-and-tuning section 2):

* ``none``: the loop as it is;
* ``dither_kicker``: the DeltaV stick-slip compensator (spec 2.3) with resolution = J,
  deadband = S − J and the identified process gain;
* ``knocker``: Hägglund (2002), spec 2.4: pulses of amplitude a = S/2, width one scan, every
  five scans;
* ``reinforcement``: constant reinforcement (Ivan & Lakshminarayanan 2009), spec 2.6:
  α = 0.55·S ("slightly above S/2 makes every reversal an immediate slip");
* ``two_move``: Srinivasan & Rengaswamy (2005), spec 2.5, with the estimated S, J and the
  identified gain;
* ``retuned``: the same loop with half the integral action (Ti doubled): spec 2.7, which
  lengthens the cycle without removing it.

Units: the loop is simulated with its PV in units of g = |K| (a FOPDT process's static gain,
PV per % of valve) or g = |K|·Ti (an integrating process's PV change when the valve is 1 % off
for one integral time of the identified PI), so the process gain is ±1 (±1/Ti) and the load
walk, the SP step, the two-move method's release band and the DeltaV compensator's
%PV/%OUT process gain mean the same whatever the record's PV units: a PV in m³/h or in bar
gets the options a PV in % of span gets (before 2026-12-07 they were in the record's units:
the spec 5.1 loop recorded ×50 moved its valve a tenth as far, ÷100 was "not reproduced").
The figures are then given back in the record's units. A direct-acting loop (K < 0) is
simulated as its mirror image, K > 0 under a reverse-acting PI: the same figures.

Uncertainty: the sweep draws S and J uniformly within ±:data:`SPREAD` of the estimate and the
process gain within ±:data:`GAIN_SPREAD` (Latin hypercube, seeded), so each option's figures
come as the median with the 5-95 % range. The rule: the options whose median valve travel is at
most :data:`TRAVEL_FACTOR` × the uncompensated one are acceptable; of those, the one with the
lowest median PV standard deviation is recommended, if it beats ``none`` by at least
:data:`MIN_GAIN`; otherwise none does enough to be worth it. A compensator is a stopgap: the
summary always says the valve should be repaired at the next opportunity.
"""

from __future__ import annotations

import math
import statistics
import tempfile
from pathlib import Path
from typing import Any

from loopworks.errors import InputError

#: the relative uncertainty drawn around the estimated S and J
SPREAD = 0.3
#: the relative uncertainty drawn around the identified process gain
GAIN_SPREAD = 0.2
#: an option is acceptable when its median valve travel is at most this × the uncompensated
TRAVEL_FACTOR = 3.0
#: the least relative reduction of the median PV std worth recommending an option for
MIN_GAIN = 0.1
#: the load's random walk (%/√s) that keeps the simulated loop moving, with the SP step of
#: 1 % at 20 s (as examples/sweep_compensators.toml): without them a loop at rest never
#: meets its valve's stiction
WALK_STD = 0.05
OPTIONS = ("none", "dither_kicker", "knocker", "reinforcement", "two_move", "retuned")
#: what a prediction's range covers, said with every prediction: an engineer's check of the
#: options on the true loops found most true figures outside the range (the flow process's
#: gain, dead time and time constant identified 2-5 times off, and a load not the record's)
SCOPE = ("The 5-95 % ranges cover S and J within ±{spread:g} % and the process gain within "
         "±{gain:g} % only: the fitted dead time and time constant, and the load (a random "
         "walk of {walk:g} %/√s and a 1 % setpoint step, % of the PV change a 1 % valve move "
         "makes, not the record's disturbances), are taken as they are, so try the option on "
         "the plant before relying on its figures.")


def scenario_text(s: float, j: float, process: dict[str, Any], kc: float, ti: float,
                  noise_std: float, dt: float, duration: float) -> str:
    """The fitted loop as a scenario (module docstring), every option a ``[compare]``
    variant."""
    gain = float(process["gain"])
    lag = float(process.get("time_constant_s") or 0.0)
    theta = max(float(process["dead_time_s"]), 0.0)
    integrating = process["model"] == "integrating"
    cap = max(1000, math.ceil(theta / dt) + 10)
    proc = (f'kind = "process.ipdt"\ngain = {gain!r}\ndead_time = {theta!r}\nu0 = 50.0\n'
            f"y0 = 50.0\ndelay_capacity = {cap}"
            if integrating else
            f'kind = "process.fopdt"\ngain = {gain!r}\ntime_constant = {lag!r}\n'
            f"dead_time = {theta!r}\nu0 = 50.0\ny0 = 50.0\ndelay_capacity = {cap}")
    walk = WALK_STD
    events = "".join(f'\n[[events]]\nt = 20.0\nset = "{b}.sp"\nvalue = 51.0\n'
                     for b in ("pid", "knocker", "two_move", "dither_kicker"))
    return f"""[simulation]
title = "the fitted loop: S = {s:.3g} %, J = {j:.3g} %"
dt = {dt!r}
duration = {duration!r}
metrics_window = [{duration / 2!r}, {duration!r}]

[blocks.pid]
kind = "pid"
k = {kc!r}
ti = {ti!r}
bias = 50.0
sp = 50.0

[blocks.knocker]
kind = "compensator.knocker"
amplitude = {max(s / 2.0, 1e-3)!r}
pulse_width = {dt!r}
interval = {5 * dt!r}
enable = 0.0
sp = 50.0

[blocks.reinforcement]
kind = "compensator.constant_reinforcement"
alpha = {max(0.55 * s, 1e-3)!r}
enable = 0.0

[blocks.two_move]
kind = "compensator.two_move"
s = {max(s, 1e-3)!r}
j = {max(min(j, s), 0.0)!r}
model_gain = {gain if not integrating else 1.0!r}
release_band = 0.5
enable = 0.0
sp = 50.0

[blocks.dither_kicker]
kind = "deltav.stick_slip"
resolution = {max(j, 0.0)!r}
deadband = {max(s - j, 0.0)!r}
process_gain = {gain if not integrating else 1.0!r}
comp_start = 0.0
sp = 50.0

[blocks.valve]
kind = "valve.choudhury"
s = {s!r}
j = {j!r}
y0 = 50.0

[blocks.process]
{proc}

[blocks.load]
kind = "disturbance.load"
walk_std = {walk!r}
seed = 4

[blocks.sensor]
kind = "sensor.transmitter"
noise_std = {max(noise_std, 0.0)!r}
seed = 5

[wires]
"knocker.op_in" = "pid.out"
"reinforcement.op_in" = "knocker.op_out"
"two_move.op_in" = "reinforcement.op_out"
"dither_kicker.signal_in" = "two_move.op_out"
"valve.op" = "dither_kicker.signal_out"
"process.u" = "valve.position"
"load.u" = "process.y"
"sensor.y" = "load.y"
"pid.pv" = "sensor.pv"
"knocker.pv" = "sensor.pv"
"two_move.pv" = "sensor.pv"
"dither_kicker.pv" = "sensor.pv"
{events}
[compare.none]

[compare.dither_kicker]
"dither_kicker.comp_start" = 1.0

[compare.knocker]
"knocker.enable" = 1.0

[compare.reinforcement]
"reinforcement.enable" = 1.0

[compare.two_move]
"two_move.enable" = 1.0

[compare.retuned]
"pid.ti" = {2.0 * ti!r}
"""


def _spread(name: str, value: float, rel: float) -> str:
    lo, hi = value * (1.0 - rel), value * (1.0 + rel)
    return f"{name}=uniform({lo!r},{hi!r})"


def pv_unit(process: dict[str, Any], ti: float) -> float:
    """g, the record's PV units per simulated PV unit (module docstring, "Units"): |K| for a
    FOPDT process, |K|·Ti for an integrating one; 1 when that is not a finite positive
    number."""
    g = abs(float(process["gain"]))
    if process["model"] == "integrating":
        g *= ti
    return g if math.isfinite(g) and g > 0.0 else 1.0


def recommend(s: float, j: float, process: dict[str, Any], kc: float, ti: float,
              noise_std: float, dt: float, samples: int = 24, seed: int = 0) -> dict[str, Any]:
    """Simulate every option on the fitted loop (module docstring) and recommend one:
    ``{"recommended", "summary", "options": [{"name", "pv_std", "pv_std_p5", "pv_std_p95",
    "valve_travel", ...}], "rule", "scenario"}``. ``process``, ``kc`` (% per PV unit) and
    ``noise_std`` are in the record's PV units, and so are the PV figures returned; the
    scenario is in units of :func:`pv_unit`."""
    from loopworks.sim.sweep import sweep

    if not (math.isfinite(s) and s > 0.0 and math.isfinite(j) and j >= 0.0):
        raise InputError(f"recommend: S = {s!r} %, J = {j!r} %: a sticky valve has S > 0, "
                         "J >= 0")
    if not (math.isfinite(kc) and kc > 0.0 and math.isfinite(ti) and ti > 0.0):
        raise InputError(f"recommend: the controller Kc = {kc!r}, Ti = {ti!r} s must be > 0")
    g = pv_unit(process, ti)
    gain = abs(float(process["gain"])) / g  # 1, or 1/Ti; a direct-acting loop's mirror image
    process = {**process, "gain": gain if math.isfinite(gain) and gain > 0.0 else 1.0}
    kc, noise_std = kc * g, noise_std / g
    theta = float(process["dead_time_s"])
    lag = float(process.get("time_constant_s") or 0.0)
    step = min(dt, max(0.05, (theta or lag or 10.0 * dt) / 10.0), 1.0)
    duration = float(max(60.0 * max(ti, theta + lag, 1.0), 1200.0))
    duration = min(duration, 20000.0 * step)
    text = scenario_text(s, j, process, kc, ti, noise_std, step, duration)
    vary = [_spread("valve.s", s, SPREAD), _spread("process.gain", float(process["gain"]),
                                                   GAIN_SPREAD)]
    if j > 0.0:
        vary.append(_spread("valve.j", j, SPREAD))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fitted_loop.toml"
        path.write_text(text, encoding="utf-8")
        result = sweep(path, vary, samples=samples, seed=seed)
    cols = result.columns
    options = []
    for name in OPTIONS:
        rows = [i for i, v in enumerate(cols["variant"]) if v == name]
        std = sorted(x for x in (cols["PV std"][i] for i in rows) if math.isfinite(x))
        travel = sorted(x for x in (cols["valve travel"][i] for i in rows) if math.isfinite(x))
        if not std or not travel:
            continue
        std = [g * x for x in std]  # back in the record's PV units
        options.append({"name": name, "pv_std": statistics.median(std),
                        "pv_std_p5": _quantile(std, 0.05), "pv_std_p95": _quantile(std, 0.95),
                        "valve_travel": statistics.median(travel),
                        "valve_travel_p5": _quantile(travel, 0.05),
                        "valve_travel_p95": _quantile(travel, 0.95)})
    base = next((o for o in options if o["name"] == "none"), None)
    rule = (f"lowest median PV std among the options whose median valve travel is at most "
            f"{TRAVEL_FACTOR:g}× the uncompensated one, if at least {MIN_GAIN:.0%} lower "
            "than with no compensation")
    if base is None:
        return {"recommended": None, "summary": "the fitted loop could not be simulated",
                "options": options, "rule": rule, "scenario": text}
    ok = [o for o in options if o["valve_travel"] <= TRAVEL_FACTOR * base["valve_travel"]]
    best = min(ok, key=lambda o: o["pv_std"]) if ok else base
    repair = ("Repair or replace the valve at the next opportunity; a compensator is a "
              "stopgap. " + SCOPE.format(spread=100.0 * SPREAD, gain=100.0 * GAIN_SPREAD,
                                          walk=WALK_STD))
    if best["name"] == "none" or best["pv_std"] > (1.0 - MIN_GAIN) * base["pv_std"]:
        summary = (f"no option lowers the PV std by {MIN_GAIN:.0%} for an acceptable travel "
                   f"(none: PV std {base['pv_std']:.3g}, valve travel "
                   f"{base['valve_travel']:.3g} %). {repair}")
        chosen = "none"
    else:
        summary = (f"{best['name']}: PV std {best['pv_std']:.3g} (5-95 %: "
                   f"{best['pv_std_p5']:.3g}-{best['pv_std_p95']:.3g}) instead of "
                   f"{base['pv_std']:.3g}, valve travel {best['valve_travel']:.3g} % instead "
                   f"of {base['valve_travel']:.3g} % (predicted on the fitted loop over "
                   f"{samples} draws of S, J and the gain). {repair}")
        chosen = best["name"]
    return {"recommended": chosen, "summary": summary, "options": options, "rule": rule,
            "scenario": text}


def _quantile(sorted_values: list[float], q: float) -> float:
    """The q-quantile of sorted values (linear interpolation)."""
    if len(sorted_values) == 1:
        return sorted_values[0]
    pos = q * (len(sorted_values) - 1)
    lo = math.floor(pos)
    hi = min(lo + 1, len(sorted_values) - 1)
    return sorted_values[lo] + (pos - lo) * (sorted_values[hi] - sorted_values[lo])
