"""The report of ``loopworks diagnose -o DIR``: ``report.html`` with the verdict, the data's
quality, the evidence table, the stiction estimate and the recommendation, and its plots:
``trends.png`` (SP and PV, OP over time), ``pv_op.png`` (PV against OP, with the fitted valve
and process model's PV over it when the data supports a stiction estimate),
``valve_travel.png`` when the record has the valve position (position against OP, with the
valve fitted to it) and, with a recommendation, ``recommendation.png`` (the predicted PV
variability against valve travel of each option)."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

from loopworks.analysis.diagnosis import Diagnosis
from loopworks.analysis.loopdata import LoopData


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def trends(data: LoopData, path: Path) -> Path:
    """SP and PV (top), OP (bottom) over time."""
    plt = _plt()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 6), sharex=True, layout="constrained")
    top.plot(data.t, data.pv, lw=0.8, label="PV")
    top.plot(data.t, data.sp, lw=1.0, color="k", ls="--",
             label="SP" if data.sp_recorded else "SP (not recorded: the PV's mean)")
    top.set_ylabel("PV, SP")
    top.legend(loc="upper right")
    bottom.plot(data.t, data.op, lw=0.8, color="tab:orange", label="OP")
    if data.position is not None:
        bottom.plot(data.t, data.position, lw=0.8, color="tab:green", label="valve position")
        bottom.legend(loc="upper right")
    bottom.set_ylabel("OP (%)")
    bottom.set_xlabel("t (s)")
    top.set_title(f"{data.source}: {len(data)} samples every {data.dt:g} s")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def pv_op(result: Diagnosis, data: LoopData, path: Path) -> Path:
    """PV against OP: the loop's phase plot. A sticky valve draws parallelograms (flat
    stretches of PV while OP moves through the stick band, then a jump); with a stiction
    estimate, the fitted model's PV for the same OP is drawn over the data (for a level loop,
    predicted from the record a few samples back: :func:`~loopworks.analysis.valve_fit.
    model_pv`)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 6), layout="constrained")
    ax.plot(data.op, data.pv, lw=0.6, color="0.6", label="data")
    ax.plot(data.op, data.pv, ".", ms=2, color="tab:blue")
    fit = result.stiction
    if fit is not None and result.model_pv is not None:
        what = ("fitted model's PV, predicted from the record"
                if fit["process"]["model"] == "integrating" else "fitted model's PV")
        ax.plot(data.op, result.model_pv, lw=0.9, color="tab:red", alpha=0.8,
                label=f"{what} (S = {fit['s']:.3g} %, J = {fit['j']:.3g} %)")
    ax.set_xlabel("OP (%)")
    ax.set_ylabel("PV")
    ax.set_title(f"PV against OP: {result.verdict} (confidence {result.confidence:.2f})")
    ax.legend(loc="best")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def travel(result: Diagnosis, data: LoopData, path: Path) -> Path | None:
    """The recorded valve position against OP (when the record has one), with the valve
    the diagnosis fitted to it (:mod:`loopworks.analysis.valve_travel`) over the data: a
    sticky valve's position stays flat while the OP crosses the stick band, then jumps."""
    if data.position is None:
        return None
    fit = result.travel
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 6), layout="constrained")
    ax.plot(data.op, data.position, lw=0.6, color="0.6", label="data")
    ax.plot(data.op, data.position, ".", ms=2, color="tab:green")
    if fit is not None and fit.ok and result.model_position is not None:
        ax.plot(data.op, result.model_position, lw=0.9, color="tab:red", alpha=0.8,
                label=f"fitted valve (S = {fit.s:.3g} %, J = {fit.j:.3g} %)")
    ax.set_xlabel("OP (%)")
    ax.set_ylabel("valve position")
    ax.set_title("valve position against OP" + ("" if fit is None or fit.ok else
                                                  ": no valve fitted (see the evidence)"))
    ax.legend(loc="best")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def recommendation(result: Diagnosis, path: Path) -> Path | None:
    """Each option's predicted PV standard deviation against its valve travel."""
    rec = result.recommendation
    if rec is None or not rec.get("options"):
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5.2), layout="constrained")
    for opt in rec["options"]:
        x, y = opt["valve_travel"], opt["pv_std"]
        chosen = opt["name"] == rec.get("recommended")
        ax.errorbar(x, y, yerr=[[y - opt["pv_std_p5"]], [opt["pv_std_p95"] - y]],
                    xerr=[[x - opt["valve_travel_p5"]], [opt["valve_travel_p95"] - x]],
                    fmt="o", ms=9 if chosen else 6, capsize=3, lw=0.8,
                    mec="k" if chosen else None)
        ax.annotate(opt["name"] + (" (recommended)" if chosen else ""), (x, y),
                    textcoords="offset points", xytext=(6, 4))
    base = next((o for o in rec["options"] if o["name"] == "none"), None)
    if base is not None:
        from loopworks.analysis.recommend import TRAVEL_FACTOR

        ax.axvline(TRAVEL_FACTOR * base["valve_travel"], color="0.5", ls="--", lw=0.8,
                   label=f"acceptable travel: {TRAVEL_FACTOR:g}× no compensation")
        ax.legend(loc="best")
    ax.set_xlabel("predicted valve travel (% of stroke)")
    ax.set_ylabel("predicted PV standard deviation")
    ax.set_title("what each option would do on the fitted loop (median, 5-95 %)")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _fmt(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.4g}"


def write_report(result: Diagnosis, data: LoopData, directory: Path) -> Path:
    """report.html and its plots in ``directory`` (created)."""
    directory.mkdir(parents=True, exist_ok=True)
    images = [trends(data, directory / "trends.png"), pv_op(result, data, directory / "pv_op.png")]
    for name, extra in (("valve_travel.png", travel(result, data, directory / "valve_travel.png")),
                        ("recommendation.png", recommendation(result,
                                                              directory / "recommendation.png"))):
        if extra is not None:
            images.append(extra)
        else:  # an earlier report's plot in this directory is not this diagnosis's
            (directory / name).unlink(missing_ok=True)
    (directory / "diagnosis.json").write_text(
        json.dumps(result.to_json(), indent=2, ensure_ascii=False), encoding="utf-8")
    rows = "".join(f"<tr><td>{html.escape(e.method)}</td><td>{e.vote}</td>"
                   f"<td>{_fmt(e.value)}</td><td>{e.weight:g}</td>"
                   f"<td style='text-align:left'>{html.escape(e.reason)}</td></tr>"
                   for e in result.evidence)
    quality = "".join(f"<li>{html.escape(x)}</li>"
                      for x in (*result.quality.reasons, *result.quality.notes))
    osc = result.oscillation
    osc_html = ("" if osc is None else
                f"<p>Oscillation of SP − PV: {'yes' if osc.detected else 'no'}"
                + (f", period {osc.period_s:.4g} s, regularity {osc.regularity:.3g}"
                   if osc.detected else f" ({html.escape(osc.reason)})") + ".</p>")
    st = result.stiction
    st_html = "" if st is None else (
        f"<h2>How sticky</h2><p>S = {st['s']:.3g} %, J = {st['j']:.3g} % (resolution "
        f"{st['resolution']:.3g} %, deadband {st['deadband']:.3g} %), fit R² = "
        f"{st['r2']:.3f} (of the "
        + ("recorded valve position" if st.get("r2_of") == "position"
           else "PV, through the fitted process")
        + f"). {html.escape(str(st.get('reason', '')))}</p>")
    rec = result.recommendation
    rec_html = "" if rec is None else (
        f"<h2>What to do</h2><p>{html.escape(rec['summary'])}</p>")
    imgs = "\n".join(f'<img src="{html.escape(p.name)}" alt="{html.escape(p.stem)}">'
                     for p in images)
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>diagnosis of {html.escape(data.source)}</title>
<style>body{{font-family:sans-serif;max-width:1300px;margin:1em auto;padding:0 1em}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}
img{{max-width:100%;display:block;margin:1em 0}}</style></head><body>
<h1>{html.escape(data.source)}: {result.verdict}</h1>
<p>{html.escape(result.loop_type)} loop, {len(data)} samples every {data.dt:g} s.
Verdict <b>{result.verdict}</b>, confidence {result.confidence:.2f}:
{html.escape(result.reason)}.</p>
<h2>Data quality</h2><p>{'passed' if result.quality.passed else 'failed'}</p>
<ul>{quality}</ul>
{osc_html}
<h2>Evidence</h2>
<table><tr><th>method</th><th>vote</th><th>index</th><th>weight</th><th>why</th></tr>
{rows}</table>
{st_html}
{rec_html}
{imgs}
<p>The same in <code>diagnosis.json</code>.</p>
</body></html>
"""
    path = directory / "report.html"
    path.write_text(page, encoding="utf-8")
    return path
