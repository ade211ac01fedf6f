"""The simulate report: did the compensator (or whatever the variants change) help, and at
what cost. Written by ``loopworks simulate``:

    DIR/
      report.html        the headline per variant, the figures, the metrics table with units
      metrics.json       {variant: {metric name: value, or null where the data cannot support
                         one}}, names as in the printed table
      metrics.md         every metric's unit, definition and n/a rule (docs/metrics.md)
      scenario.toml      the scenario file that was run
      autotune.json      the [autotune] relay test, when the scenario has one
      overview.png       the variants overlaid: PV and SP, valve position, valve command, the
                         scored window shaded, a zoom of about 100 s beside the whole run
                         (overview_LOOP.png for each loop of a scenario with several)
      signature.png      valve position against controller output (and valve command), one
                         panel per variant, over the scored window (signature_LOOP.png)
      VARIANT.png        one variant: PV and SP, controller output and compensated signal,
                         valve position
      VARIANT.csv        every signal of the run, with .ST status columns

Every JSON file is strict JSON (``json_text``): a non-finite figure is written as null. A
directory that holds an earlier report loses the files of it this report does not replace
(another scenario's variants, its autotune.json); no other file in it is touched.
"""

from __future__ import annotations

import html
import json
import math
import os
import sys
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from loopworks.sim.metrics import METRICS, markdown, metric_info
from loopworks.sim.result import SimResult

#: the zoomed panel of the overview figure, s
ZOOM_SPAN = 100.0

#: the headline's figures: (metric name, the headline's word for it)
HEADLINE = (("PV std", "PV std"), ("valve travel", "stem travel"),
            ("valve-command travel", "valve-command travel"))

_WINDOW_COLOUR = "#fff2b3"


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float (at any depth) replaced by None (JSON's null), numpy
    scalars and arrays as Python values, mappings' keys as text."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return [json_safe(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def json_text(data: Any) -> str:
    """Strict JSON (RFC 8259: no NaN or Infinity), indented; non-finite floats become null."""
    return json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n"


def metric_key(variant: str, loop: str, loops: list[str]) -> str:
    """The metrics table's column for ``loop`` of ``variant``: the variant's name, or
    "variant: loop" when the variant has several loops (as ``loopworks simulate`` names it)."""
    return variant if len(loops) == 1 else f"{variant}: {loop}"


def relative_change(base: float, value: float) -> float:
    """(value - base) / |base| · 100 %; NaN where either is n/a or ``base`` is 0."""
    if not (math.isfinite(base) and math.isfinite(value)) or base == 0.0:
        return math.nan
    return (value - base) / abs(base) * 100.0


def headline(base: dict[str, float], other: dict[str, float]) -> str:
    """"PV std -20 %, stem travel +38 %, valve-command travel +1090 %": ``other`` against
    ``base``, for the figures of ``HEADLINE`` that both have (controller output travel
    instead of the valve's for a loop without a valve)."""
    terms = [t for t in HEADLINE if t[0] in base and t[0] in other]
    if not any(name == "valve travel" for name, _ in terms):
        terms.append(("output travel", "output travel"))
    parts = []
    for name, word in terms:
        change = relative_change(base[name], other.get(name, math.nan))
        parts.append(f"{word} n/a" if math.isnan(change) else f"{word} {change:+.0f} %")
    return ", ".join(parts)


def _cell(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.4g}"


def _scored(t: np.ndarray, window: tuple[float, float] | None) -> np.ndarray:
    """The samples of the scored window (the whole run without one)."""
    if window is None:
        return np.ones(len(t), dtype=bool)
    return (t >= window[0]) & (t <= window[1])


def zoom_span(t: np.ndarray, window: tuple[float, float] | None,
              command: np.ndarray | None, span: float = ZOOM_SPAN) -> tuple[float, float]:
    """The zoomed panel's time range: ``span`` s inside the scored window, centred on the
    largest single move of ``command`` there (a kick, where the compensator shows both its
    kicks and its dither), or the middle of the window without a command."""
    lo, hi = (float(t[0]), float(t[-1])) if window is None else window
    lo, hi = max(lo, float(t[0])), min(hi, float(t[-1]))
    if hi - lo <= span:
        return lo, hi
    centre = 0.5 * (lo + hi)
    if command is not None:
        keep = np.flatnonzero(_scored(t, (lo, hi)))
        moves = np.abs(np.diff(command[keep]))
        if len(moves) and np.any(np.isfinite(moves)):
            centre = float(t[keep[int(np.nanargmax(moves)) + 1]])
    start = min(max(centre - 0.5 * span, lo), hi - span)
    return start, start + span


def _loop_signals(result: SimResult, loop: str) -> dict[str, np.ndarray]:
    """PV, working SP, controller output and, through the valve the loop drives, its position
    and command (the signal at its op input)."""
    signals = {"pv": result.pv(loop), "sp": result.working_sp(loop),
               "out": result.out(loop)}
    valve = result.valve_of(loop)
    if valve is not None:
        signals["position"] = result[f"{valve}.position"]
        if f"{valve}.op" in result.values:
            signals["command"] = result[f"{valve}.op"]
    return signals


def overview_plot(results: dict[str, SimResult], loop: str, path: Path, title: str,
                  window: tuple[float, float] | None = None) -> None:
    """The variants overlaid on shared axes: PV and SP, valve position and valve command (or
    controller output without a valve), against time; the whole run on the left with the
    scored window shaded, a zoom of ``ZOOM_SPAN`` s on the right."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.artist import Artist
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    sigs = {v: _loop_signals(r, loop) for v, r in results.items()}
    first = next(iter(results.values()))
    rows = [("pv", "PV and SP (PV units)")]
    if all("position" in s for s in sigs.values()):
        rows.append(("position", "valve position (%)"))
        if all("command" in s for s in sigs.values()):
            rows.append(("command", "valve command (%)"))
    else:  # in the unit the controller's output is in (GE's counts read as % before)
        rows.append(("out", f"controller output ({first.out_units(loop)})"))
    last = list(sigs.values())[-1]
    z0, z1 = zoom_span(first.t, window, last.get("command", last["out"]))
    fig, axes = plt.subplots(len(rows), 2, figsize=(14, 2.7 * len(rows) + 1.2), squeeze=False,
                             sharex="col", gridspec_kw={"width_ratios": (2.2, 1.0)},
                             layout="constrained")
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    same_sp = all(np.array_equal(s["sp"], sigs[next(iter(sigs))]["sp"]) for s in sigs.values())
    for row, (signal, label) in enumerate(rows):
        for col in (0, 1):
            ax = axes[row, col]
            for i, (variant, s) in enumerate(sigs.items()):
                t = results[variant].t
                keep = _scored(t, None if col == 0 else (z0, z1))
                ax.plot(t[keep], s[signal][keep], color=colours[i % len(colours)], lw=0.8,
                        alpha=0.9, zorder=3 - i * 0.1)
                if signal == "pv" and (i == 0 or not same_sp):
                    ax.plot(t[keep], s["sp"][keep], color="k" if same_sp else
                            colours[i % len(colours)], ls="--", lw=1.0, zorder=4)
            if col == 0:
                if window is not None:
                    ax.axvspan(*window, color=_WINDOW_COLOUR, zorder=0)
                ax.axvspan(z0, z1, fill=False, ec="0.4", ls=":", lw=1.0, zorder=5)
                ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("t (s): the whole run")
    axes[-1, 1].set_xlabel(f"t (s): zoom {z0:g}..{z1:g} s (dotted box on the left)")
    handles: list[Artist] = [Line2D([], [], color=colours[i % len(colours)], lw=1.5, label=v)
                             for i, v in enumerate(sigs)]
    handles.append(Line2D([], [], color="k", ls="--", label="SP"))
    if window is not None:
        handles.append(Patch(color=_WINDOW_COLOUR, label=f"scored window {window[0]:g}.."
                             f"{window[1]:g} s"))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), frameon=False)
    fig.suptitle(f"{title}: {loop}")
    fig.savefig(path, dpi=100)
    plt.close(fig)


def signature_plot(results: dict[str, SimResult], loop: str, path: Path,
                   window: tuple[float, float] | None = None) -> bool:
    """Valve position against controller output (the stiction signature: a sticking valve
    traces flat stretches and jumps) and against the valve command, one panel per variant on
    shared axes, over the scored window. False (no file) when the loop drives no valve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sigs = {v: _loop_signals(r, loop) for v, r in results.items()}
    if not all("position" in s for s in sigs.values()):
        return False
    n = len(sigs)
    fig, axes = plt.subplots(1, n, figsize=(max(5.2 * n, 6.4) + 0.6, 5.8), squeeze=False,
                             sharex=True, sharey=True, layout="constrained")
    for ax, (variant, s) in zip(axes[0], sigs.items(), strict=True):
        keep = _scored(results[variant].t, window)
        unit = results[variant].out_units(loop)
        same = "command" not in s or np.array_equal(s["command"][keep], s["out"][keep])
        if not same:
            ax.plot(s["command"][keep], s["position"][keep], color="0.7", lw=0.5,
                    label="vs valve command")
        # an output in counts or EU gets its own (top) axis: on the command's % axis it was
        # drawn 320 times wide and labelled %
        out_ax = ax if unit == "%" or same else ax.twiny()
        out_ax.plot(s["out"][keep], s["position"][keep], color="C3", lw=0.9,
                    label="vs controller output" + ("" if out_ax is ax else " (top axis)"))
        ax.set_title(variant + (" (valve command = controller output)"
                                if same and "command" in s else ""))
        if out_ax is ax:
            ax.set_xlabel(f"{loop} output, valve command ({unit})" if "command" in s
                          else f"{loop} output ({unit})")
        else:
            ax.set_xlabel("valve command (%)")
            out_ax.set_xlabel(f"{loop} output ({unit})", color="C3")
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("valve position (%)")
    legend: dict[str, Any] = {}
    for ax in fig.axes:  # the panels and their top axes
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(label, handle)
    scored = ("the whole run" if window is None
              else f"scored window {window[0]:g}..{window[1]:g} s")
    fig.legend(list(legend.values()), list(legend), loc="outside lower center", ncol=2,
               frameon=False)
    # on three lines: one panel's width cut the one-line title at both ends
    fig.suptitle(f"{loop}: valve position\nvs controller output and vs valve command\n"
                 f"{scored}")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True


def _trend_figure(result: SimResult, title: str,
                  window: tuple[float, float] | None) -> tuple[Any, list[Any]]:
    """The figure of ``trend_plot`` and its panels, not yet saved."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loops = result.controllers()
    valves = [n for n in result.kinds if f"{n}.position" in result.values]
    comps = [n for n in result.kinds if f"{n}.signal_out" in result.values
             or f"{n}.op_out" in result.values]
    panels = 2 + (1 if valves else 0)
    fig, axes = plt.subplots(panels, 1, sharex=True, figsize=(12, 2.6 * panels + 0.6),
                             squeeze=False, layout="constrained")
    # one colour per loop in every panel (its PV solid and SP dashed, its compensator's
    # output thin, its OUT, its valve): the colour cycle ran on across a panel's lines, so a
    # loop's PV and its OUT were different colours
    cycle = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    colour = {loop: cycle[i % len(cycle)] for i, loop in enumerate(loops)}
    owner = {result.valve_of(loop): loop for loop in loops}
    ax = axes[0, 0]
    for loop in loops:
        ax.plot(result.t, result.pv(loop), label=f"{loop} PV", lw=0.8, color=colour[loop])
        ax.plot(result.t, result.working_sp(loop), label=f"{loop} SP", ls="--", lw=1.0,
                color=colour[loop])
    ax.set_ylabel("PV, SP (PV units)")
    ax = axes[1, 0]
    for comp in comps:
        port = "signal_out" if f"{comp}.signal_out" in result.values else "op_out"
        source = (result.wires.get(f"{comp}.signal_in")
                  or result.wires.get(f"{comp}.op_in") or "")
        fed = next((lp for lp in loops if source.startswith(f"{lp}.")), None)
        ax.plot(result.t, result[f"{comp}.{port}"], label=f"{comp} {port}", lw=0.5,
                alpha=0.6, color=colour[fed] if fed is not None else "0.6")
    for loop in loops:
        ax.plot(result.t, result.out(loop), label=f"{loop} OUT", lw=0.8, color=colour[loop])
    units = {result.out_units(loop) for loop in loops}
    ax.set_ylabel(f"controller output ({units.pop() if len(units) == 1 else 'output units'})")
    if valves:
        ax = axes[2, 0]
        for valve in valves:
            driver = owner.get(valve)
            ax.plot(result.t, result[f"{valve}.position"], label=f"{valve} position", lw=0.8,
                    color=colour[driver] if driver is not None else None)
        ax.set_ylabel("valve position (%)")
    for a in axes[:, 0]:
        if window is not None:
            a.axvspan(*window, color=_WINDOW_COLOUR, zorder=0,
                      label="scored window" if a is axes[0, 0] else None)
        a.grid(True, alpha=0.3)
        a.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8, frameon=False)
    axes[-1, 0].set_xlabel("t (s)")
    fig.suptitle(title)
    return fig, list(axes[:, 0])


def trend_plots(results: dict[str, SimResult], directory: Path, title: str,
                window: tuple[float, float] | None = None) -> None:
    """VARIANT.png for each variant: PV and SP, controller output (and compensated signal),
    and valve position (when there is a valve) against time, the scored window shaded; a
    panel has the same y range in every variant's plot, so they can be compared."""
    import matplotlib.pyplot as plt

    figures = {v: _trend_figure(r, f"{title}: {v}", window) for v, r in results.items()}
    for row in range(min(len(axes) for _, axes in figures.values())):
        lows, highs = zip(*(axes[row].get_ylim() for _, axes in figures.values()), strict=True)
        for _, axes in figures.values():
            axes[row].set_ylim(min(lows), max(highs))
    for variant, (fig, _) in figures.items():
        fig.savefig(directory / f"{variant}.png", dpi=100)
        plt.close(fig)


#: what the report shows of an [autotune] relay test (the whole record is in autotune.json)
AUTOTUNE_ROWS = ("loop", "variant", "outcome", "process_gain", "ku", "pu", "dead_time",
                 "time_constant", "relay_amplitude", "hysteresis", "amplitude")


def _autotune_html(autotune: dict[str, Any] | None) -> str:
    if autotune is None:
        return ""
    rows = "\n".join(
        f"<tr><th>{html.escape(k)}</th><td>"
        + html.escape(_cell(autotune[k]) if isinstance(autotune[k], float)
                      else str(autotune[k])) + "</td></tr>"
        for k in AUTOTUNE_ROWS if autotune.get(k) is not None)
    return ("<h2>Relay auto-tune ([autotune])</h2>\n<p>Before the run a relay test identified "
            "the process gain that the scenario's [autotune] parameters took (% PV per % "
            "output); all of it is in <a href=\"autotune.json\">autotune.json</a>.</p>\n"
            f"<table>{rows}</table>")


def _anchor(name: str) -> str:
    return "m-" + "".join(c if c.isalnum() else "-" for c in name)


def _metrics_html(metrics: dict[str, dict[str, float]]) -> str:
    """The metrics table: a row per metric with its unit, linked to its definition."""
    names = list(dict.fromkeys(n for m in metrics.values() for n in m))
    head = "".join(f"<th>{html.escape(v)}</th>" for v in metrics)
    rows = "\n".join(
        f'<tr><th><a href="#{_anchor(n)}">{html.escape(n)}</a></th>'
        f"<td class=u>{html.escape(_unit(n))}</td>"
        + "".join(f"<td>{_cell(metrics[v].get(n, math.nan))}</td>" for v in metrics) + "</tr>"
        for n in names)
    return f"<table><tr><th>metric</th><th>unit</th>{head}</tr>\n{rows}\n</table>"


def _unit(name: str) -> str:
    try:
        return metric_info(name).unit
    except KeyError:
        return ""


def _definitions_html() -> str:
    rows = "\n".join(
        f'<tr id="{_anchor(m.name)}"><th>{html.escape(m.name)}</th>'
        f"<td class=u>{html.escape(m.unit)}</td><td class=l>{html.escape(m.definition)}</td>"
        f"<td class=l>{html.escape(m.not_available)}</td></tr>" for m in METRICS)
    return ("<h2>Metric definitions</h2>\n<p>From <a href=\"metrics.md\">metrics.md</a> "
            "(docs/metrics.md of loopworks), which says more. A figure the data cannot "
            "support is n/a here and null in metrics.json.</p>\n"
            "<table><tr><th>metric</th><th>unit</th><th>definition</th><th>n/a when</th></tr>"
            f"\n{rows}\n</table>")


def _headlines_html(results: dict[str, SimResult],
                    metrics: dict[str, dict[str, float]]) -> str:
    """A line per variant (after the first) and loop: its headline against the first."""
    variants = list(results)
    if len(variants) < 2:
        return ""
    base_variant = variants[0]
    base_loops = results[base_variant].controllers()
    lines = []
    for variant in variants[1:]:
        loops = results[variant].controllers()
        for loop in loops:
            key = metric_key(variant, loop, loops)
            base_key = metric_key(base_variant, loop, base_loops)
            if key not in metrics or base_key not in metrics:
                continue
            lines.append(f"<li><b>{html.escape(key)}</b> against "
                         f"{html.escape(base_key)}: "
                         f"{html.escape(headline(metrics[base_key], metrics[key]))}</li>")
    return "<ul class=headline>\n" + "\n".join(lines) + "\n</ul>" if lines else ""


def forked(job: Callable[[], None]) -> Callable[[], None]:
    """Start ``job`` (drawing figures to files: matplotlib holds the GIL while it draws, so
    a thread would not run beside the caller) in a forked child process, and return the
    function that waits for it. Only where forking is safe: Linux, and this process runs one
    thread (no lock can be held by another thread across the fork). When the child fails,
    or no child was started, the wait runs ``job`` here, so its error is raised as if no
    child had been used; the child itself ends with ``os._exit`` (no exit handlers, no
    second flush of the parent's buffers)."""
    if not sys.platform.startswith("linux") or threading.active_count() > 1:
        return job
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child's coverage is not collected
        code = 1
        try:
            job()
            code = 0
        finally:
            os._exit(code)

    def wait() -> None:
        _, status = os.waitpid(pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            job()

    return wait


def _earlier_report(directory: Path) -> set[str]:
    """The files an earlier report left in ``directory`` that a new one may not write: its
    variants' CSVs and trend plots (by its metrics.json), its overview and signature plots
    and its autotune.json; none unless the directory holds a report (report.html and a
    readable metrics.json), so no other file is touched. A reused directory kept them beside
    the new report (an earlier scenario's autotune.json and variants; found by an outside
    audit)."""
    if not (directory / "report.html").is_file():
        return set()
    try:
        variants = json.loads((directory / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return set()
    if not isinstance(variants, dict):
        return set()
    names = {f"{v}.{ext}" for v in variants for ext in ("csv", "png")}
    names |= {p.name for pattern in ("overview*.png", "signature*.png")
              for p in directory.glob(pattern)}
    return {n for n in names | {"autotune.json"} if (directory / n).is_file()}


def write_report(directory: Path, title: str, scenario_text: str,
                 results: dict[str, SimResult], metrics: dict[str, dict[str, float]],
                 autotune: dict[str, Any] | None = None,
                 window: tuple[float, float] | None = None) -> None:
    """Write the report directory (created if needed); ``autotune`` is the scenario's
    [autotune] result (autotune.json and a section of the page), ``window`` the scored
    window (s; shaded in the figures)."""
    directory.mkdir(parents=True, exist_ok=True)
    earlier = _earlier_report(directory)
    if autotune is not None:
        (directory / "autotune.json").write_text(json_text(autotune), encoding="utf-8")
    (directory / "scenario.toml").write_text(scenario_text, encoding="utf-8")
    (directory / "metrics.json").write_text(json_text(metrics), encoding="utf-8")
    (directory / "metrics.md").write_text(markdown(), encoding="utf-8")
    loops = list(dict.fromkeys(loop for r in results.values() for loop in r.controllers()))
    loops = [lp for lp in loops if all(lp in r.controllers() for r in results.values())]
    figures = []

    def draw_overviews() -> None:
        for loop in loops:
            suffix = "" if len(loops) == 1 else f"_{loop}"
            overview_plot(results, loop, directory / f"overview{suffix}.png", title, window)

    wait = forked(draw_overviews)  # drawn beside the rest: half the report's time on two cores
    for loop in loops:
        suffix = "" if len(loops) == 1 else f"_{loop}"
        figures.append((f"overview{suffix}.png", f"{loop}: the variants overlaid"))
        if signature_plot(results, loop, directory / f"signature{suffix}.png", window):
            figures.append((f"signature{suffix}.png",
                            f"{loop}: valve position against controller output"))
    trend_plots(results, directory, title, window)
    for variant, result in results.items():
        result.to_csv(directory / f"{variant}.csv")
    wait()
    written = {"autotune.json"} if autotune is not None else set()
    written |= {name for name, _ in figures}
    written |= {f"{v}.{ext}" for v in results for ext in ("csv", "png")}
    for name in earlier - written:  # an earlier report's file this one does not replace
        (directory / name).unlink(missing_ok=True)
    scored = ("over the whole run" if window is None
              else f"over the scored window {window[0]:g}..{window[1]:g} s")
    overviews, signatures = ("\n".join(
        f'<h2>{html.escape(caption)}</h2><img src="{html.escape(name)}" '
        f'alt="{html.escape(caption)}">' for name, caption in figures if name.startswith(kind))
        for kind in ("overview", "signature"))
    trends = "\n".join(f'<h2>{html.escape(v)}</h2><img src="{html.escape(v)}.png" '
                       f'alt="trend plot of {html.escape(v)}">' for v in results)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}td.u,td.l{{text-align:left}}
td.l{{max-width:40em}}img{{max-width:100%}}ul.headline{{font-size:1.15em}}</style>
</head><body>
<h1>{html.escape(title)}</h1>
{_headlines_html(results, metrics)}
{overviews}
<p>Metrics {html.escape(scored)}; every metric's unit and definition are
<a href="#definitions">below</a> and in <a href="metrics.md">metrics.md</a>.</p>
{_metrics_html(metrics)}
{signatures}
{_autotune_html(autotune)}
<p>Data: <a href="metrics.json">metrics.json</a>, <a href="scenario.toml">scenario.toml</a>,
{", ".join(f'<a href="{html.escape(v)}.csv">{html.escape(v)}.csv</a>' for v in results)}.</p>
{trends}
<div id="definitions">{_definitions_html()}</div>
</body></html>
"""
    (directory / "report.html").write_text(page, encoding="utf-8")
