"""The simulate report: a trend plot per variant, ``metrics.json``, the scenario used and
``report.html`` showing them together.

    DIR/
      report.html        the metrics table and every trend plot
      metrics.json       {variant: {metric name: value}}, names as in the printed table
      scenario.toml      the scenario file that was run
      VARIANT.png        PV and SP, controller output (and compensated signal), valve position
      VARIANT.csv        every signal of the run, with .ST status columns
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

from loopworks.sim.result import SimResult


def trend_plot(result: SimResult, path: Path, title: str) -> None:
    """PV and SP, controller output, and valve position (when there is a valve) against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loops = result.controllers()
    valves = [n for n in result.kinds if f"{n}.position" in result.values]
    comps = [n for n in result.kinds if f"{n}.signal_out" in result.values
             or f"{n}.op_out" in result.values]
    panels = 2 + (1 if valves else 0)
    fig, axes = plt.subplots(panels, 1, sharex=True, figsize=(10, 2.8 * panels), squeeze=False)
    ax = axes[0, 0]
    for loop in loops:
        ax.plot(result.t, result.working_sp(loop), label=f"{loop} SP", linestyle="--")
        ax.plot(result.t, result[f"{loop}.pv"], label=f"{loop} PV")
    ax.set_ylabel("PV, SP (EU)")
    ax = axes[1, 0]
    for loop in loops:
        ax.plot(result.t, result[f"{loop}.out"], label=f"{loop} OUT")
    for comp in comps:
        port = "signal_out" if f"{comp}.signal_out" in result.values else "op_out"
        ax.plot(result.t, result[f"{comp}.{port}"], label=f"{comp} {port}", alpha=0.7)
    ax.set_ylabel("controller output (%)")
    if valves:
        ax = axes[2, 0]
        for valve in valves:
            ax.plot(result.t, result[f"{valve}.position"], label=f"{valve} position")
        ax.set_ylabel("valve position (%)")
    for a in axes[:, 0]:
        a.grid(True, alpha=0.3)
        a.legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("t (s)")
    fig.suptitle(title)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.97))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _cell(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:.4g}"


#: what the report shows of an [autotune] relay test (the whole record is in autotune.json)
AUTOTUNE_ROWS = ("loop", "variant", "outcome", "process_gain", "ku", "pu", "dead_time",
                 "time_constant", "relay_amplitude", "hysteresis", "amplitude")


def _autotune_html(autotune: dict[str, Any] | None) -> str:
    if autotune is None:
        return ""
    rows = "\n".join(
        f"<tr><th>{html.escape(k)}</th><td>"
        + html.escape(f"{autotune[k]:.4g}" if isinstance(autotune[k], float)
                      else str(autotune[k])) + "</td></tr>"
        for k in AUTOTUNE_ROWS if autotune.get(k) is not None)
    return ("<h2>Relay auto-tune ([autotune])</h2>\n<p>Before the run a relay test identified "
            "the process gain that the scenario's [autotune] parameters took (% PV per % "
            "output); all of it is in <a href=\"autotune.json\">autotune.json</a>.</p>\n"
            f"<table>{rows}</table>")


def write_report(directory: Path, title: str, scenario_text: str,
                 results: dict[str, SimResult], metrics: dict[str, dict[str, float]],
                 autotune: dict[str, Any] | None = None) -> None:
    """Write the report directory (created if needed); ``autotune`` is the scenario's
    [autotune] result (autotune.json and a section of the page)."""
    directory.mkdir(parents=True, exist_ok=True)
    if autotune is not None:
        (directory / "autotune.json").write_text(json.dumps(autotune, indent=2) + "\n",
                                                 encoding="utf-8")
    (directory / "scenario.toml").write_text(scenario_text, encoding="utf-8")
    clean = {v: {k: (None if math.isnan(x) else x) for k, x in m.items()}
             for v, m in metrics.items()}
    (directory / "metrics.json").write_text(json.dumps(clean, indent=2) + "\n",
                                            encoding="utf-8")
    for variant, result in results.items():
        trend_plot(result, directory / f"{variant}.png", f"{title}: {variant}")
        result.to_csv(directory / f"{variant}.csv")
    names = list(next(iter(metrics.values()))) if metrics else []
    rows = "\n".join(
        "<tr><th>" + html.escape(n) + "</th>"
        + "".join(f"<td>{_cell(metrics[v][n])}</td>" for v in metrics) + "</tr>"
        for n in names)
    head = "".join(f"<th>{html.escape(v)}</th>" for v in metrics)
    images = "\n".join(f'<h2>{html.escape(v)}</h2><img src="{html.escape(v)}.png" '
                       f'alt="trend plot of {html.escape(v)}">' for v in results)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}img{{max-width:100%}}</style>
</head><body>
<h1>{html.escape(title)}</h1>
<table><tr><th>metric</th>{head}</tr>
{rows}
</table>
{_autotune_html(autotune)}
<p>Data: <a href="metrics.json">metrics.json</a>, <a href="scenario.toml">scenario.toml</a>,
{", ".join(f'<a href="{html.escape(v)}.csv">{html.escape(v)}.csv</a>' for v in results)}.</p>
{images}
</body></html>
"""
    (directory / "report.html").write_text(page, encoding="utf-8")
