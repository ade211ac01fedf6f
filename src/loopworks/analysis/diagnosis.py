"""Diagnosis of one loop from its data: is the valve sticky, how sure, and on what evidence
(issue 15; spec plant-and-tuning 4.2-4.3).

The rules, in order:

0. **A valve that does not move** (:mod:`loopworks.analysis.seized`): the PV holds one value
   while, in automatic, the OP walks across a large part of its span and the error keeps its
   sign. ``stiction`` (a seized valve, or a closed block valve or dead transmitter: the
   reason says to check them) at confidence 0.5, whatever the quality gate says of the
   record, since the frozen PV is the finding.
1. **Data quality first** (:func:`loopworks.analysis.quality.check_quality`): a record that
   fails the gate (too short, frozen or compressed, saturated, in manual, too many Bad values)
   gets ``undetermined`` with the gate's reasons, confidence 0, and no index is computed.
2. **Oscillation** of the control error e = SP − PV by the regularity of its autocorrelation
   (Thornhill, Huang & Zhang 2003): detected or not, with its period. Reported; not required:
   a sticky valve whose slip jump is small against the load noise often does not cycle
   regularly, so no rule below needs a clean limit cycle.
3. **The battery**, each method with its published rule and a vote (``stiction``,
   ``no_stiction`` or ``undetermined``), weighted by how much the method is worth on this
   kind of loop (:data:`WEIGHTS`):

   =============================  ========================  ==========================
   method                         self-regulating loop      integrating loop
   =============================  ========================  ==========================
   Horch (1999) CCF of OP and PV  yes                       no (not valid: Horch 1999)
   area ratio (Singhal 2005)      yes, on e                 no (self-regulating only)
   curve fit (He et al. 2007)     on OP                     on PV
   bicoherence (Choudhury 2004)   on e: linear → against    the same
   valve fit (Jelali 2008)        votes                     votes
   =============================  ========================  ==========================

   Horch, the area ratio and the curve fit were published for oscillating loops: they
   abstain when the error does not oscillate regularly (:data:`NEEDS_OSCILLATION`).
   The valve fit (:mod:`loopworks.analysis.valve_fit`) works without a limit cycle: it votes
   stiction when the fitted S is at least :data:`MIN_S` % and the valve nonlinearity explains at
   least :data:`MIN_R2_GAIN` of the PV variance a linear valve leaves unexplained; no stiction
   when the fit is good and S is below :data:`MIN_S` or that share below :data:`NO_R2_GAIN`;
   otherwise (or when the record does not support a fit, or S is above :data:`MAX_S` %, or
   the fit explains less than the linear valve, :func:`_fit_vote`, or it would vote against
   stiction with a fitted time constant shorter than the sample period, which does not
   resolve the loop: :func:`_valve_fit_vote`) it abstains. On a record
   whose setpoint moves up and down, its stiction vote stands only when more of the long
   stretches with the SP held vote stiction than against it (:func:`_held_sp_vote`), else it
   abstains (a cascade slave's SP, which never holds long enough to fit, is not checked).

   When the record has the valve position (a digital positioner's travel feedback), the
   valve is also measured on it (:mod:`loopworks.analysis.valve_travel`: OP → position, no
   process in between), weight 2, with the valve fit's thresholds; its S and J then replace
   the valve fit's in the estimate.

   The bicoherence is reported with weight 0 (it does not vote). By its rule it can only say
   "linear, so no stiction" (Choudhury, Shah & Thornhill 2004 run the stiction test only on
   nonlinear loops) or abstain, but on the simulated set (docs/diagnose.md) it found every
   error linear, sticky or not: a symmetric stick-slip cycle has odd harmonics only and no
   quadratic phase coupling, and on records of a few thousand samples its noise level is
   above the 0.001 threshold (:mod:`loopworks.analysis.bicoherence`).
4. **Verdict**: the score is Σ wᵢ·vᵢ (v = +1 stiction, −1 no stiction, 0 undetermined) over
   the methods run and W = Σ wᵢ over the same methods, those that abstain (or do not apply
   to the record) included. ``stiction`` when the score ≥ :data:`DECIDE` and
   either two methods vote stiction or the valve fit or the valve travel does
   (:data:`SUFFICIENT`: the methods that need no cycle); ``no_stiction`` when the score
   ≤ −:data:`DECIDE`;
   otherwise ``undetermined``. Confidence = |score| / W, in [0, 1]: the weighted share of the
   battery that agrees with the verdict, net of the evidence against it (0 for
   ``undetermined``): a verdict one method carries while the others abstain is given with
   the confidence of one of several.
5. **How sticky and what to do** (a ``stiction`` verdict whose valve fit is good): S and J
   with resolution = J and deadband = S − J (spec 1.7), the process and the fit's R²; with
   the PI identified from the same data (:func:`~loopworks.analysis.valve_fit.fit_controller`),
   every compensator simulated on the fitted loop (:mod:`loopworks.analysis.recommend`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from loopworks.analysis import LoopType, Verdict, loop_type_of
from loopworks.analysis.area_ratio import area_ratio
from loopworks.analysis.bicoherence import bicoherence_test
from loopworks.analysis.curve_fit import curve_fit_loop
from loopworks.analysis.horch import horch_test
from loopworks.analysis.loopdata import LoopData, bad, hold_last, parse_columns, read_csv
from loopworks.analysis.oscillation import Oscillation, regularity
from loopworks.analysis.quality import (
    Quality,
    check_quality,
    held_sp_stretches,
    sp_reversals,
)
from loopworks.analysis.seized import CONFIDENCE as SEIZED_CONFIDENCE
from loopworks.analysis.seized import Seized, seized_valve
from loopworks.analysis.valve_fit import MIN_SAMPLES as MIN_FIT_SAMPLES
from loopworks.analysis.valve_fit import (
    ControllerFit,
    ValveFit,
    fit_controller,
    fit_valve,
    model_pv,
)
from loopworks.analysis.valve_travel import TravelFit, fit_travel, model_position
from loopworks.errors import InputError

#: each method's weight in the verdict (rule 4)
WEIGHTS: dict[str, float] = {"horch": 1.0, "area_ratio": 1.0, "curve_fit": 1.0,
                             "bicoherence": 0.0, "valve_fit": 1.0, "valve_travel": 2.0}
#: the methods whose stiction vote alone can carry the verdict (rule 4): the two that need no
#: cycle and see the valve itself, through the process (valve_fit) or on its recorded travel
SUFFICIENT = ("valve_fit", "valve_travel")
#: the oscillation test's noise band (:func:`~loopworks.analysis.oscillation.regularity`): ACF
#: zero crossings count only between lobes that leave ±this·1/√N
OSCILLATION_NOISE_SIGMAS = 3.0
#: the methods published for oscillating loops only ("... in oscillating control loops":
#: Horch 1999, Singhal & Salsbury 2005, He et al. 2007): they abstain when the error does not
#: oscillate (rule 3)
NEEDS_OSCILLATION = ("horch", "area_ratio", "curve_fit")
#: the valve fit votes stiction from this S (% of span) on [ours: below it a stick band is
#: inside what the transmitter noise and the fit's own resolution can show]
MIN_S = 0.3
#: ... when the fitted valve explains at least this share of what a linear valve leaves
#: unexplained, (R² − R²_linear)/(1 − R²_linear) [ours: on the simulated set (docs/diagnose.md)
#: 0.05 kept 1 of 120 clean loops and 32 of 120 sticky ones]
MIN_R2_GAIN = 0.05
#: the valve fit votes no stiction below this share (a good fit that needs no stiction)
NO_R2_GAIN = 0.005
#: the valve fit abstains when its S (% of span) is above this [ours: the simulated set's
#: valves go to 5 % nominal (a Karnopp valve shows up to S + J, 9.9 %, on reversal) and the
#: fit puts them at 7.2 % at most; the one clean loop it called
#: sticky, a level loop driven by an external sine, got S = 17.8 %, a backlash that fits
#: the sine's phase, not a valve a loop could run with]
MAX_S = 10.0
#: the recommendation is withheld when the fitted loop, simulated without compensation, varies
#: more than this many times the record's SP - PV (standard deviations) [ours: the simulated
#: loop has its own load and a 1 % SP step, so only a gross mismatch, an unstable fitted loop,
#: is read as one]
REPRODUCE_FACTOR = 10.0
#: Horch's test and the area ratio abstain on an oscillation of fewer samples a period, and
#: the valve fit's vote against too [ours]: a half cycle of fewer than 4 samples has no
#: placed peak and a stick band in it does not show (a 26 s stiction cycle recorded every
#: 10 s, 2.6 samples, was called no_stiction by all three). Not more: at 9.3 samples an
#: external sine's area ratio, 0.82, was the vote that kept a false valve fit from a verdict
MIN_PERIOD_SAMPLES = 8
#: Most stretches with the SP held that :func:`_held_sp_vote` fits again (the longest) [ours:
#: each is a valve fit of its own; a cascade slave's record has hundreds of short ones]
HELD_STRETCHES = 8
#: Fewest of those stretches voting stiction for the valve fit's stiction vote to stand [ours:
#: one stretch in five voted stiction on three of eight clean servo records, see
#: :func:`_held_sp_vote`]
HELD_VOTES = 2
#: the score a verdict needs (rule 4): one full vote's worth of net evidence
DECIDE = 1.0
#: what an estimate of S and J from a record means (docs/diagnose.md, "Why J is not
#: estimated"): the valve moves on the controller's output at its scan, the record samples it
SAMPLED = ("S and J are the band and the jump the valve shows to the OP as recorded (every "
           "{dt:g} s): when the controller scans faster and its OP is noisy, the valve breaks "
           "away sooner than the record shows, its own S is larger and its J is not known.")
#: the bicoherence abstains below this many segments: its noise level on Gaussian data is
#: about 1/K (K segments), so NGI = 0.001 can only separate noise from K ≈ 1000 on; at 100
#: segments a linear loop's NGI is ≈ 0.01 and is still read as "linear" by the relative rule
#: NGI ≤ 3/K used here (an assumption: the published threshold is 0.001, meant for long records)
MIN_BICOHERENCE_SEGMENTS = 30

_SIGN = {"stiction": 1.0, "no_stiction": -1.0, "undetermined": 0.0}


@dataclass(frozen=True)
class Evidence:
    """One method's vote: ``key`` (``horch``, ``area_ratio``, ``curve_fit``, ``bicoherence``),
    its name and source, the vote, its weight, the index value and the method's reason;
    ``applies`` False when the method was not made for this record (an oscillation method
    on a loop that does not oscillate regularly, or on a cycle of too few samples): its
    value is then kept here, with the reason, but is no index (:attr:`Diagnosis.indices`)."""

    key: str
    method: str
    vote: Verdict
    weight: float
    value: float
    reason: str
    applies: bool = True


@dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` found (module docstring): the verdict, its confidence, the data's
    quality, the oscillation, the evidence of each method, and (when the data supports one)
    the valve's estimated stiction and a recommendation."""

    verdict: Verdict
    confidence: float
    loop_type: LoopType
    source: str
    quality: Quality
    oscillation: Oscillation | None
    evidence: list[Evidence] = field(default_factory=list)
    score: float = 0.0
    reason: str = ""
    stiction: dict[str, Any] | None = None
    recommendation: dict[str, Any] | None = None
    #: the fitted model's PV over the record (the report's PV-OP plot), not in the JSON
    model_pv: np.ndarray | None = field(default=None, repr=False)
    #: the valve measured on the recorded position (None without one), and that fitted
    #: valve's position over the record (the report's valve-travel plot), not in the JSON
    travel: TravelFit | None = field(default=None, repr=False)
    model_position: np.ndarray | None = field(default=None, repr=False)

    @property
    def indices(self) -> dict[str, float]:
        """Each method's index value by its key: NaN where it could not be computed or the
        method does not apply to the record (``Evidence.applies``: Horch's phase of a loop
        that does not oscillate is a number, not an index of anything)."""
        return {e.key: e.value if e.applies else math.nan for e in self.evidence}

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``loopworks diagnose --json`` (docs/diagnose.md, "JSON")."""
        osc = self.oscillation
        from loopworks.sim.report import json_safe

        return dict(json_safe({
            "source": self.source,
            "loop_type": self.loop_type,
            "verdict": self.verdict,
            "confidence": round(self.confidence, 3),
            "score": self.score,
            "reason": self.reason,
            "quality": {"passed": self.quality.passed, "reasons": list(self.quality.reasons),
                        "notes": list(self.quality.notes), "samples": self.quality.n},
            "oscillation": None if osc is None else {
                # a period from crossings that are not regular is not one the data supports
                "detected": osc.detected, "period_s": osc.period_s if osc.detected else None,
                "regularity": osc.regularity, "reason": osc.reason},
            "indices": self.indices,
            "evidence": [{"key": e.key, "method": e.method, "vote": e.vote,
                          "weight": e.weight, "value": e.value, "reason": e.reason}
                         for e in self.evidence],
            "stiction": self.stiction,
            "recommendation": self.recommendation,
        }))


def _battery(data: LoopData, loop_type: LoopType, osc: Oscillation) -> list[Evidence]:
    """Every applicable method's vote (module docstring, rule 3)."""
    out = _methods(data, loop_type, osc.period_s / data.dt if osc.detected else None)
    if osc.detected:
        return out
    return [Evidence(e.key, e.method, "undetermined", e.weight, e.value,
                     f"abstains: published for oscillating loops, and this one does not "
                     f"oscillate regularly ({e.reason})", applies=False)
            if e.key in NEEDS_OSCILLATION else e for e in out]


def _methods(data: LoopData, loop_type: LoopType, period: float | None = None
             ) -> list[Evidence]:
    """Each method's own vote by its published rule; the half-cycle methods measure the half
    cycles of the oscillation of ``period`` samples when one was detected."""
    e = data.sp - data.pv
    out: list[Evidence] = []
    if loop_type == "self-regulating":
        coarse = (f"; abstains: the oscillation's period is {period:.3g} samples, fewer than "
                  f"{MIN_PERIOD_SAMPLES}, too few to place its CCF zero crossings or its "
                  "half cycles' peaks" if period is not None and period < MIN_PERIOD_SAMPLES
                  else "")
        h = horch_test(data.op, data.pv, data.dt, loop_type)
        out.append(Evidence("horch", "Horch (1999) cross-correlation of OP and PV",
                            "undetermined" if coarse else h.verdict,
                            WEIGHTS["horch"], h.asymmetry * 90.0, h.reason + coarse,
                            applies=not coarse))
        a = area_ratio(e, data.dt, period=period)
        out.append(Evidence("area_ratio", "area ratio of the error's half cycles (Singhal & "
                            "Salsbury 2005)", "undetermined" if coarse else a.verdict,
                            WEIGHTS["area_ratio"], a.ratio, a.reason + coarse,
                            applies=not coarse))
    c = curve_fit_loop(data.op, data.pv, data.dt, loop_type, period=period)
    signal = "OP" if loop_type == "self-regulating" else "PV"
    out.append(Evidence("curve_fit", f"curve fitting of the {signal}'s half cycles (He et al. "
                        "2007)", c.verdict, WEIGHTS["curve_fit"], c.si, c.reason))
    out.append(_bicoherence_vote(e, data.dt))
    return out


def _valve_fit_vote(fit: ValveFit, dt: float) -> Evidence:
    """The valve fit's vote (module docstring, rule 3) on a record sampled every ``dt`` s: no
    vote against stiction from a fitted FOPDT whose time constant is shorter than ``dt``
    [ours: a flow loop of T = 10 s recorded every 5 s, its valve sticky by S = 3 %, was fitted
    T = 2.8 s, K a fifth of the truth, S = 0.43 %, and called no_stiction (found by an outside
    audit); on the simulated set this turns 2 of the 6 sticky loops called no_stiction, and 4
    clean ones, to undetermined, and no other verdict. A band found so still votes: no
    stiction call of the set came from such a fit wrongly]."""
    name = "valve and process fitted jointly (Choudhury S, J; Jelali 2008)"
    gain = (fit.r2 - fit.r2_linear) / max(1.0 - fit.r2_linear, 1e-12)
    if not fit.ok:
        return Evidence("valve_fit", name, "undetermined", WEIGHTS["valve_fit"], math.nan,
                        fit.reason)
    why = (f"{fit.reason} The valve's stiction explains {_share(gain)} of what a linear "
           "valve leaves unexplained")
    if fit.s > MAX_S:
        return Evidence("valve_fit", name, "undetermined", WEIGHTS["valve_fit"], fit.s,
                        f"{why}; S above {MAX_S:g} % is not a valve a loop runs with, more "
                        "likely a model that fits something else (abstains)")
    vote = _fit_vote(fit.s, gain)
    tau = (fit.process or {}).get("time_constant_s")
    if vote == "no_stiction" and tau is not None and tau < dt:
        return Evidence("valve_fit", name, "undetermined", WEIGHTS["valve_fit"], fit.s,
                        f"{why}; but the fitted process's time constant, {tau:.3g} s, is "
                        f"shorter than the record's sample period, {dt:g} s: the record does "
                        "not resolve the loop's response, so a stick band the fit does not "
                        "find may still be there (abstains)")
    return Evidence("valve_fit", name, vote, WEIGHTS["valve_fit"], fit.s, why)


def _held_sp_vote(data: LoopData, loop_type: LoopType, sign: float,
                  vote: Evidence) -> Evidence:
    """The valve fit's stiction vote on a record whose setpoint moves up and down
    (:func:`loopworks.analysis.quality.sp_reversals`), checked with the SP held: the valve
    is fitted again on each stretch between setpoint changes at least half as long as the
    longest (:func:`loopworks.analysis.quality.held_sp_stretches`, at most
    :data:`HELD_STRETCHES`), and the vote stands when more of them vote stiction than vote
    against it, and at least :data:`HELD_VOTES` do (or all, when fewer are long enough);
    else it abstains. When the SP never holds for the fit's fewest samples (a cascade
    slave's SP moves nearly every sample), the check cannot be made and the vote stands.
    A setpoint step reverses the OP by far more than its noise does, and a stick band's
    offset, which flips sign at each such reversal, can stand in for the slow
    load a linear valve leaves unexplained; setpoint moves that all go one way flip it at
    most once, and are left alone [ours: a clean PI loop with a walking load and
    five setpoint steps of 400 samples fitted S = 0.3-1 % explaining 22-33 % of the linear
    valve's residual in seven of eight seeds; refitted, at most one of its five held
    stretches voted stiction; with S = 2 %, two to three did in seven of eight seeds, with
    S = 3 % in all eight]."""
    stretches = held_sp_stretches(data)
    longest = stretches[0].stop - stretches[0].start
    if longest < MIN_FIT_SAMPLES:
        return replace(vote, reason=(
            f"{vote.reason}; the SP moves up and down and never holds for "
            f"{MIN_FIT_SAMPLES} samples (a cascade slave's), so the stick band is not checked "
            "with it held"))
    votes: list[str] = []
    for span in stretches[:HELD_STRETCHES]:
        n = span.stop - span.start
        if n < max(2, longest / 2):
            break
        t0, t1 = float(data.t[span.start]), float(data.t[span.stop - 1])
        fit = fit_valve(data.window(t0, t1 + 0.5 * data.dt), loop_type, gain_sign=sign)
        votes.append(_valve_fit_vote(fit, data.dt).vote)
    pro, con = votes.count("stiction"), votes.count("no_stiction")
    tally = (f"the SP moves, and of the {len(votes)} stretch(es) with it held (at least "
             f"{max(2, math.ceil(longest / 2))} samples) fitted again, {pro} vote(s) stiction "
             f"and {con} against")
    if pro > con and pro >= min(HELD_VOTES, len(votes)):
        return replace(vote, reason=f"{vote.reason}; {tally}")
    return replace(vote, vote="undetermined", reason=(
        f"{vote.reason}; abstains: {tally}. A stick band's offset flips at each setpoint "
        "step and can stand in for the load a linear valve leaves unexplained"))


def _fit_vote(s: float, gain: float) -> Verdict:
    """A fitted valve's vote (rule 3): stiction when S ≥ :data:`MIN_S` and the stiction
    explains at least :data:`MIN_R2_GAIN` of what a linear valve leaves unexplained (``gain``);
    no stiction when S is below :data:`MIN_S` (explaining less than MIN_R2_GAIN) or ``gain``
    in [0, :data:`NO_R2_GAIN`). A fit
    that explains *less* than the linear valve abstains: S = J = 0 is one of the valves it
    could have chosen, so it did not find its best, and its S says nothing either way (sticky
    level loops fitted so were called no_stiction) - with S ≥ MIN_S for any gain < 0, with S
    below it for gain < -NO_R2_GAIN (a fit as good as the linear valve's, within the
    no-stiction share, is one that found the valve linear; a fit 12 % worse with S = 0.08 %
    called a sticky level loop no_stiction). A band below MIN_S that explains MIN_R2_GAIN or
    more is no evidence against stiction either: it abstains (a sticky valve recorded every
    5 s, whose noisy OP shook it loose between samples, fitted S = 0.27 % explaining 24 % and
    was voted against at weight 2)."""
    if s >= MIN_S and gain >= MIN_R2_GAIN:
        return "stiction"
    if gain < (0.0 if s >= MIN_S else -NO_R2_GAIN):
        return "undetermined"
    if (s < MIN_S and gain < MIN_R2_GAIN) or gain < NO_R2_GAIN:
        return "no_stiction"
    return "undetermined"


def _share(gain: float) -> str:
    """A share of what a linear valve leaves unexplained, for a sentence ("0.0 %" for a
    gain that rounds to zero either side, not "-0.0 %")."""
    text = f"{gain:.1%}"
    return "0.0%" if text == "-0.0%" else text


def _valve_travel_vote(fit: TravelFit) -> Evidence:
    """The recorded valve position's vote (module docstring, rule 3), by the valve fit's
    thresholds (:data:`MIN_S`, :data:`MIN_R2_GAIN`, :data:`NO_R2_GAIN`) on the position."""
    name = "valve model fitted to the recorded position (OP → stem travel)"
    weight = WEIGHTS["valve_travel"]
    if not fit.ok:
        return Evidence("valve_travel", name, "undetermined", weight, math.nan, fit.reason)
    gain = (fit.r2 - fit.r2_linear) / max(1.0 - fit.r2_linear, 1e-12)
    why = (f"{fit.reason} The valve's stiction explains {_share(gain)} of what a linear "
           "valve leaves unexplained")
    return Evidence("valve_travel", name, _fit_vote(fit.s, gain), weight, fit.s, why)


def _bicoherence_vote(e: np.ndarray, dt: float) -> Evidence:
    """The bicoherence's vote (module docstring, rule 3): against stiction when the error is
    linear, else abstain."""
    name = "bicoherence of the error (Choudhury, Shah & Thornhill 2004)"
    weight = WEIGHTS["bicoherence"]
    try:
        b = bicoherence_test(e, dt)
    except (ValueError, InputError) as exc:
        return Evidence("bicoherence", name, "undetermined", weight, math.nan, str(exc))
    if b.segments < MIN_BICOHERENCE_SEGMENTS:
        return Evidence("bicoherence", name, "undetermined", weight, b.ngi,
                        f"{b.segments} segments: fewer than {MIN_BICOHERENCE_SEGMENTS}, so its "
                        "noise level is above the test's threshold (abstains)")
    linear = b.ngi <= 3.0 / b.segments
    if linear:
        return Evidence("bicoherence", name, "no_stiction", weight, b.ngi,
                        f"NGI = {b.ngi:.4f} ≤ 3/K = {3.0 / b.segments:.4f} (the noise level "
                        f"of an estimate from {b.segments} segments; the published 0.001 "
                        "needs about 1000): no nonlinearity the estimate can resolve, the "
                        "error reads as linear")
    return Evidence("bicoherence", name, "undetermined", weight, b.ngi,
                    f"NGI = {b.ngi:.4f}, NLI = {b.nli:.4f}: the error is "
                    + ("nonlinear" if b.nonlinear else "non-Gaussian")
                    + "; that alone does not say it is the valve (abstains)")


def verdict_of(evidence: list[Evidence]) -> tuple[Verdict, float, float, str]:
    """(verdict, confidence, score, reason) from the evidence (module docstring, rule 4)."""
    score = sum(_SIGN[e.vote] * e.weight for e in evidence)
    total = sum(e.weight for e in evidence) or 1.0
    for_ = [e.key for e in evidence if e.vote == "stiction" and e.weight > 0]
    against = [e.key for e in evidence if e.vote == "no_stiction" and e.weight > 0]
    tally = (f"score {score:+.2g} of {total:g} (for: {', '.join(for_) or 'none'}; against: "
             f"{', '.join(against) or 'none'})")
    vetoed = "valve_fit" in against and not any(k in for_ for k in SUFFICIENT)
    if score >= DECIDE and vetoed:
        # the valve, fitted to this record, finds no stick band worth its parameters; the
        # oscillation methods read the cycle's shape, which an external oscillation
        # mimics (a linear loop under a 400 s sine recorded every 10 s: Horch and the area
        # ratio for, the valve fit against; never so on the simulated set's sticky loops)
        return "undetermined", 0.0, score, (
            tally + ": the oscillation methods' shape evidence against the valve fit's, "
            "which finds no stick band in the same record")
    if score >= DECIDE and (len(for_) >= 2 or any(k in for_ for k in SUFFICIENT)):
        return "stiction", abs(score) / total, score, tally
    if score <= -DECIDE:
        return "no_stiction", abs(score) / total, score, tally
    return "undetermined", 0.0, score, tally + ": not enough net evidence either way"


def diagnose(data: LoopData | str | Path, loop_type: str = "self-regulating",
             columns: Mapping[str, str] | str | None = None, *, recommend: bool = True,
             samples: int = 24, op_range: tuple[float, float] | None = None,
             sample_time: float | None = None) -> Diagnosis:
    """Diagnose one loop (module docstring) from ``data``: a :class:`LoopData`, or the path
    of a historian CSV (read by :func:`~loopworks.analysis.loopdata.read_csv` with
    ``columns``; a repeated time stamp keeps the later row, as a historian's hold does, and
    the data's ``resampled`` note says so). ``loop_type``: ``"self-regulating"`` (also
    ``"flow"``, ``"pressure"``, ``"temperature"``) or ``"integrating"`` (``"level"``), any
    letter case (:func:`~loopworks.analysis.loop_type_of`). ``recommend``: simulate the
    options for a sticky valve (``samples`` draws of the fit's uncertainty each).
    ``op_range``: the OP's units at 0 % and 100 % of the valve's span (:func:`op_in_percent`;
    S, J and every OP figure are in % of it). A file without a setpoint column is read with
    the SP at the PV's mean (the quality notes say so); one without a time column needs
    ``sample_time`` (s, the period of its rows)."""
    lt = loop_type_of(loop_type)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise InputError(f"samples = {samples!r}: expected a whole number >= 1 (the draws of "
                         "the fit's uncertainty each option is simulated over)")
    if not isinstance(data, LoopData):
        if isinstance(columns, str):  # the CLI's text form, "sp=FIC101.SV,pv=..."
            columns = parse_columns(columns)
        data = read_csv(data, columns, duplicates="last", sample_time=sample_time,
                        sp_optional=True)
    elif sample_time is not None:
        raise InputError(f"sample_time = {sample_time!r} is for a file without a time column; "
                         f"a LoopData has its times")
    data = op_in_percent(_bad_as_nan(data), op_range)
    data, cut = _most_recent(data)
    quality = check_quality(data)
    if cut:
        quality.notes.insert(0, cut)
    seized = seized_valve(data)
    if seized is not None:
        return _seized_diagnosis(data, lt, quality, seized)
    if not quality.passed:
        return Diagnosis("undetermined", 0.0, lt, data.source, quality, None,
                         reason="the data fails the quality gate: "
                         + "; ".join(quality.reasons))
    data, held = _hold_bad(data)
    osc = regularity(data.sp - data.pv, data.dt, noise_sigmas=OSCILLATION_NOISE_SIGMAS)
    evidence = _battery(data, lt, osc)
    ctl = fit_controller(data)
    sign = 0.0 if not ctl.ok else (1.0 if ctl.action == "reverse" else -1.0)
    fit = fit_valve(data, lt, gain_sign=sign)
    vote = _valve_fit_vote(fit, data.dt)
    if (vote.vote == "no_stiction" and osc.detected
            and osc.period_s / data.dt < MIN_PERIOD_SAMPLES):
        # a cycle of a few samples: the record cannot show a stick band in it, so finding
        # none is no evidence (a 26 s stiction cycle recorded every 10 s was voted against)
        vote = replace(vote, vote="undetermined", reason=(
            f"{vote.reason}; abstains: the oscillation's period is "
            f"{osc.period_s / data.dt:.3g} samples, fewer than {MIN_PERIOD_SAMPLES}: a stick "
            "band in it does not show in the record"))
    if vote.vote == "stiction" and sp_reversals(data):
        vote = _held_sp_vote(data, lt, sign, vote)
    evidence.append(vote)
    travel = fit_travel(data)
    if travel is not None:
        evidence.append(_valve_travel_vote(travel))
    verdict, confidence, score, reason = verdict_of(evidence)
    if held:
        reason += (f"; {held} Bad (NaN, infinite or beyond ±1e12) sample(s) of SP, PV or OP "
                   "held at the last good value before the tests")
    stiction: dict[str, Any] | None = None
    model = rec = None
    r2 = (fit.r2, fit.r2_linear)  # of the fit S and J come from
    r2_of = "pv"
    if verdict == "stiction" and travel is not None and travel.ok:
        r2 = (travel.r2, travel.r2_linear)
        r2_of = "position"
        # measured on the stem: better than the estimate through the process
        fit = replace(fit, s=travel.s, j=travel.j, resolution=travel.j,
                      deadband=travel.s - travel.j,
                      reason=f"{travel.reason} Process: {fit.reason}")
        if not fit.ok:  # the stem shows it; the process fit was refused: no loop model
            stiction = {"s": travel.s, "j": travel.j, "resolution": travel.j,
                        "deadband": travel.s - travel.j, "r2": travel.r2,
                        "r2_linear": travel.r2_linear, "r2_of": "position", "process": None,
                        "reason": travel.reason}
            if recommend:
                rec = _no_options(
                    f"the recorded valve travel shows a stick band of S = {travel.s:.3g} %, "
                    f"but the process could not be fitted ({fit.reason}), so the options "
                    "cannot be simulated. Repair or replace the valve at the next "
                    "opportunity.")
    if verdict == "stiction" and fit.ok:
        model = model_pv(data, fit)
        stiction = {"s": fit.s, "j": fit.j, "resolution": fit.resolution,
                    "deadband": fit.deadband, "r2": r2[0], "r2_linear": r2[1], "r2_of": r2_of,
                    "process": dict(fit.process),
                    "reason": f"{fit.reason} {SAMPLED.format(dt=data.dt)}"}
        if recommend:
            rec = _recommendation(data, fit, ctl, model, samples)
    position = (model_position(data, travel) if travel is not None and travel.ok
                else None)
    return Diagnosis(verdict, confidence, lt, data.source, quality, osc, evidence, score,
                     reason, stiction, rec, model, travel, position)


#: the most samples a diagnosis reads: a longer record is cut to its most recent ones [ours:
#: the valve fit's time grows with the record (a 1,000,000-sample file did not finish in 10
#: minutes and took 1.5 GB; 100,000 samples 30 s; 20,000 about 7 s), and one S and J read
#: from days of data assume a valve that did not change over them]
MAX_SAMPLES = 20_000


def _most_recent(data: LoopData) -> tuple[LoopData, str]:
    """The record's last :data:`MAX_SAMPLES` samples, and a note saying so (empty when the
    record is no longer)."""
    n = len(data)
    if n <= MAX_SAMPLES:
        return data, ""
    t0 = float(data.t[n - MAX_SAMPLES])
    kept = data.window(t0, math.inf)
    hours = (float(kept.t[-1]) - t0 + data.dt) / 3600.0
    return kept, (f"the record has {n} samples; the diagnosis reads its most recent "
                  f"{MAX_SAMPLES} (from t = {t0:g} s, {hours:.3g} h): a longer record takes "
                  "minutes to fit, and one S and J read from it assume a valve that did not "
                  "change over it (cut the file to the stretch to diagnose)")


def _seized_diagnosis(data: LoopData, loop_type: LoopType, quality: Quality,
                      seized: Seized) -> Diagnosis:
    """The diagnosis of a valve that does not move (rule 0, :mod:`loopworks.analysis.seized`):
    ``stiction`` at :data:`~loopworks.analysis.seized.CONFIDENCE`, its one piece of evidence,
    no S and J estimate (a valve that never moved shows only that S exceeds the OP's travel)
    and the one thing to do."""
    evidence = [Evidence("seized", "valve that does not move while the OP travels",
                         "stiction", 1.0, seized.op_travel, seized.reason)]
    gate = ("" if quality.passed else " (the record fails the quality gate, "
            + "; ".join(quality.reasons) + ", and that is the finding)")
    rec = _no_options(
        f"no compensator moves a valve that has not moved over {seized.op_travel:.3g} % of OP "
        "travel: put the loop in manual, check the block valves and the transmitter, then "
        "stroke the valve and repair or replace it.")
    return Diagnosis("stiction", SEIZED_CONFIDENCE, loop_type, data.source, quality, None,
                     evidence, 1.0, seized.reason + gate, None, rec)


#: the share of OP samples that may lie outside 0..100 % (by more than OP_MARGIN) before the
#: OP is taken to be in other units; the margin is DeltaV's widest output limits, -10..110 %
#: (a tight shut-off at -2 % or a limit at 102 % is an OP in %)
OP_OUTSIDE_SHARE = 0.01
OP_MARGIN = 10.0


def op_in_percent(data: LoopData, op_range: tuple[float, float] | None = None) -> LoopData:
    """The record with its OP in % of the valve's span, op% = 100·(op - lo)/(hi - lo) for
    ``op_range`` = (lo, hi), the OP's units at 0 % and 100 % (None: an OP in %, 0..100).
    Every method reads the OP in %: the valve model clips it to 0..100 and S, J are % of the
    span. InputError naming the range when more than OP_OUTSIDE_SHARE of the OP lies outside
    0..100 % by more than OP_MARGIN: an OP in counts or engineering units (a GE CV of 16000
    counts read as 16000 % gave no fit at all; an OUT of 120-150 EU on 0..200 was clipped at
    100). With no range given, also when every OP sample lies within 0..1 and it moves: a
    fraction of the span read as % moves a hundredth as far, so a 3 % stick band reads
    0.03 % and the valve fit votes against stiction; the range (0:1 for a fraction, 0:100
    for a valve that does open under 1 %) must then be given. An OP in other units that
    stays within -10..110 cannot be told from one in %: its range must be given."""
    given = op_range is not None
    lo, hi = (float(v) for v in (op_range if op_range is not None else (0.0, 100.0)))
    if not (math.isfinite(lo) and math.isfinite(hi) and hi != lo):
        raise InputError(f"op_range = {op_range!r}: two different finite numbers expected "
                         "(the OP's units at 0 % and 100 % of the valve's span)")
    op = data.op if (lo, hi) == (0.0, 100.0) else 100.0 * (data.op - lo) / (hi - lo)
    seen = op[np.isfinite(op)]
    outside = np.count_nonzero((seen < -OP_MARGIN) | (seen > 100.0 + OP_MARGIN))
    if len(seen) and outside > OP_OUTSIDE_SHARE * len(seen):
        after = "" if (lo, hi) == (0.0, 100.0) else f" (after --op-range {lo:g}:{hi:g})"
        raise InputError(
            f"{data.source or 'the record'}: the OP runs {float(np.min(seen)):.6g} to "
            f"{float(np.max(seen)):.6g}{after}, {100 * outside / len(seen):.0f} % of it outside "
            "0..100: diagnose reads the OP in % of the valve's span (S and J are % of it); give "
            "the OP's units at 0 % and 100 % with --op-range LO:HI (0:32000 for GE counts, "
            "0:200 for a DeltaV OUT_SCALE of 0..200 EU)")
    if not given and len(seen) and float(np.min(seen)) >= 0.0 and float(np.max(seen)) <= 1.0 \
            and float(np.max(seen)) > float(np.min(seen)):
        raise InputError(
            f"{data.source or 'the record'}: the OP runs {float(np.min(seen)):.6g} to "
            f"{float(np.max(seen)):.6g}, all of it within 0..1: a fraction of the valve's span "
            "read as % would move a hundredth as far (a 3 % stick band would read 0.03 %); "
            "give its range: --op-range 0:1 for a fraction, --op-range 0:100 for an OP in % "
            "that stays under 1 %")
    return data if op is data.op else replace(data, op=op)


def _bad_as_nan(data: LoopData) -> LoopData:
    """The record with every Bad sample of SP, PV, OP and valve position (infinite, or beyond
    ±1e12: :func:`~loopworks.analysis.loopdata.bad`) as NaN, the reader's Bad value, so the
    gate counts it and the tests hold it (the caller's record is not changed)."""
    changes: dict[str, Any] = {}
    for name in ("sp", "pv", "op", "position"):
        a = getattr(data, name)
        if a is not None:
            marked = bad(a) & ~np.isnan(a)
            if marked.any():
                changes[name] = np.where(marked, np.nan, a)
    return replace(data, **changes) if changes else data


def _hold_bad(data: LoopData) -> tuple[LoopData, int]:
    """The record with its Bad samples of SP, PV and OP held (the gate lets through at most
    :data:`~loopworks.analysis.quality.MAX_NAN_FRACTION` of them; every test below needs
    finite samples), and how many samples were held."""
    bad = ~(np.isfinite(data.sp) & np.isfinite(data.pv) & np.isfinite(data.op))
    count = int(bad.sum())
    if count == 0:
        return data, 0
    return replace(data, sp=hold_last(data.sp), pv=hold_last(data.pv), op=hold_last(data.op)), count


def _recommendation(data: LoopData, fit: ValveFit, ctl: ControllerFit, model: np.ndarray,
                    samples: int) -> dict[str, Any] | None:
    """The options simulated on the fitted loop (:mod:`loopworks.analysis.recommend`), or a
    sentence saying why they cannot be."""
    from loopworks.analysis.recommend import recommend

    if not ctl.ok or not math.isfinite(ctl.ti_s):
        return _no_options("the controller could not be identified from the data "
                           f"({ctl.reason}), so the options cannot be simulated. Repair or "
                           "replace the valve at the next opportunity.")
    residual = data.pv - model
    noise = float(np.nanstd(residual)) if np.isfinite(residual).any() else 0.0
    try:
        out = recommend(fit.s, fit.j, fit.process, ctl.kc, ctl.ti_s, noise, data.dt,
                        samples=samples)
    except InputError as exc:
        return _no_options(f"the fitted loop cannot be simulated ({exc}). Repair or replace "
                           "the valve at the next opportunity.")
    out["controller"] = {"kc": ctl.kc, "ti_s": ctl.ti_s, "r2": ctl.r2, "action": ctl.action}
    out.pop("scenario", None)
    base = next((o for o in out.get("options", []) if o["name"] == "none"), None)
    recorded = float(np.nanstd(data.sp - data.pv))
    if base is not None and not base["pv_std"] <= REPRODUCE_FACTOR * recorded:
        return _no_options((
                    f"the fitted loop does not reproduce the record: run as it is, its PV "
                    f"varies {base['pv_std']:.3g} (std) against {recorded:.3g} in the record, "
                    f"more than {REPRODUCE_FACTOR:g} times as much (the identified PI, Kc = "
                    f"{ctl.kc:.3g} and Ti = {ctl.ti_s:.3g} s, or the process does not match "
                    "the plant: a derivative action, a filter, a cascade or a gain off), so "
                    "no option is predicted from it. Repair or replace the valve at the next "
                    "opportunity."), controller=out["controller"])
    return out


def _no_options(summary: str, **extra: Any) -> dict[str, Any]:
    """A recommendation with no option simulated: the JSON's keys (docs/diagnose.md), no
    option recommended, ``rule`` null, and the ``summary`` that says what to do instead."""
    return {"recommended": None, "options": [], "summary": summary, "rule": None, **extra}
