"""The files of a sweep (``loopworks sweep -o DIR``): ``results.parquet`` and ``results.csv``
(one row per instance and variant) and ``summary.html`` with the plots that fit the sweep:

* one varied name on a grid: each metric against it, one line per variant;
* two on a grid: a heat map of the chosen metric over the grid, one per variant;
* Monte Carlo (sampled names): histograms of the chosen metric and of valve travel, one colour
  per variant, and the Pareto plot of PV variability (PV std) against valve travel with each
  variant's non-dominated instances joined;
* otherwise (three or more grid names): the Monte Carlo plots, over the grid's points.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from loopworks.sim.sweep import SweepResult

#: the metrics plotted when the caller names none (the first the sweep has)
DEFAULT_METRICS = ("PV std", "IAE", "mean |e|")
#: every figure a sweep may write (which ones depends on the sweep's design)
FIGURES = ("metrics_vs_parameter.png", "heatmap.png", "histograms.png", "pareto.png")
#: the metric of the x axis of the Pareto plot
TRAVEL = ("valve travel", "output travel")


def _metric(result: SweepResult, name: str | None) -> str:
    if name is not None:
        if name not in result.metrics:
            raise KeyError(f"no metric '{name}'; metrics: {', '.join(result.metrics)}")
        return name
    for m in DEFAULT_METRICS:
        for col in result.metrics:
            if col == m or col.endswith(f": {m}"):
                return col
    return result.metrics[0]


def _travel(result: SweepResult) -> str | None:
    for m in TRAVEL:
        for col in result.metrics:
            if col == m or col.endswith(f": {m}"):
                return col
    return None


def _floats(values: list[Any]) -> np.ndarray:
    return np.array([float(v) if isinstance(v, int | float) else math.nan for v in values])


def _wide(values: np.ndarray) -> bool:
    """Non-negative values spanning more than two decades (travel: 0 to thousands)."""
    finite = values[np.isfinite(values)]
    if finite.size < 2 or finite.min() < 0.0:
        return False
    return bool(finite.max() > 100.0 * max(float(np.median(finite)), 1.0) or
                finite.max() > 100.0 * max(float(np.percentile(finite, 25)), 1.0))


def pareto(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats in both x and y (smaller is better),
    sorted by x."""
    order = np.argsort(x, kind="stable")
    front: list[int] = []
    best = math.inf
    for i in order:
        if math.isfinite(x[i]) and math.isfinite(y[i]) and y[i] < best:
            front.append(int(i))
            best = float(y[i])
    return np.array(front, dtype=int)


def figures(result: SweepResult, directory: Path, metric: str | None = None,
            clean: bool = False) -> list[Path]:
    """Write the sweep's figures (module docstring) into ``directory``; their paths. With
    ``clean`` (a sweep's report directory, reused by the next sweep), a figure this sweep
    does not draw is removed, as an earlier sweep's; without it (``SweepResult.plot()``, by
    default into the current directory) no file is removed (found by an outside audit:
    ``.plot()`` deleted a user's own heatmap.png there)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    chosen = _metric(result, metric)
    variants = list(dict.fromkeys(result.columns["variant"]))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    vcol = np.array(result.columns["variant"])
    paths: list[Path] = []
    grid = result.design == "grid"
    if grid and len(result.varied) == 1:
        name = result.varied[0]
        xs = result.columns[name]
        numeric = all(isinstance(v, int | float) for v in xs)
        shown = [m for m in result.metrics if not np.all(np.isnan(_floats(result.columns[m])))]
        cols = 3
        rows = math.ceil(len(shown) / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(13, 2.6 * rows + 0.8), squeeze=False,
                                 layout="constrained")
        for ax, m in zip(axes.flat, shown, strict=False):
            for i, v in enumerate(variants):
                keep = vcol == v
                x = _floats(xs)[keep] if numeric else np.arange(int(keep.sum()))
                # joined in x order, not the order given (`--vary pid.ti=30,5,15,10` drew a
                # zig-zag no response has)
                order = np.argsort(x, kind="stable") if numeric else np.arange(len(x))
                ax.plot(x[order], _floats(result.columns[m])[keep][order], "o-", ms=3,
                        color=colours[i % len(colours)], label=v)
            ax.set_title(m, fontsize=9)
            ax.grid(True, alpha=0.3)
            if not numeric:
                ax.set_xticks(range(len(set(xs))), [str(x) for x in dict.fromkeys(xs)])
        for ax in list(axes.flat)[len(shown):]:
            ax.set_visible(False)
        for ax in axes[-1]:
            ax.set_xlabel(name)
        axes[0, 0].legend(fontsize=8)
        fig.suptitle(f"every metric against {name}")
        paths.append(_save(fig, directory / "metrics_vs_parameter.png"))
    elif grid and len(result.varied) == 2:
        xn, yn = result.varied
        fig, axes = plt.subplots(1, len(variants), figsize=(5.2 * len(variants) + 0.6, 4.4),
                                 squeeze=False, layout="constrained")
        # one colour scale for every variant (a colour is a value, panel to panel), and the
        # best instance ringed
        allz = _floats(result.columns[chosen])
        lo, hi = ((float(np.nanmin(allz)), float(np.nanmax(allz))) if np.isfinite(allz).any()
                  else (0.0, 1.0))
        try:
            best = result.best(chosen)
        except KeyError:
            best = None

        def axis(values: Any) -> list[Any]:
            """The grid's values along an axis, sorted when numeric (the order given
            otherwise)."""
            seen = list(dict.fromkeys(values))
            return (sorted(seen) if all(isinstance(u, int | float) for u in seen) else seen)

        for ax, v in zip(axes[0], variants, strict=True):
            keep = vcol == v
            xv = axis(np.array(result.columns[xn], dtype=object)[keep])
            yv = axis(np.array(result.columns[yn], dtype=object)[keep])
            z = np.full((len(yv), len(xv)), math.nan)
            for xval, yval, zval in zip(np.array(result.columns[xn], dtype=object)[keep],
                                        np.array(result.columns[yn], dtype=object)[keep],
                                        _floats(result.columns[chosen])[keep], strict=True):
                z[yv.index(yval), xv.index(xval)] = zval
            im = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis", vmin=lo, vmax=hi)
            if best is not None and best["variant"] == v:
                ax.plot(xv.index(best[xn]), yv.index(best[yn]), "s", ms=22, mfc="none",
                        mec="red", mew=2.0, label="best")
                ax.legend(loc="upper right", fontsize=7, markerscale=0.4)
            ax.set_xticks(range(len(xv)), [f"{x:g}" if isinstance(x, float) else str(x)
                                           for x in xv], rotation=45, fontsize=8)
            ax.set_yticks(range(len(yv)), [f"{y:g}" if isinstance(y, float) else str(y)
                                           for y in yv], fontsize=8)
            middle = 0.5 * (lo + hi)
            for (r, c), val in np.ndenumerate(z):
                if math.isfinite(val):  # dark text on the light (high) end of viridis
                    ax.text(c, r, f"{val:.3g}", ha="center", va="center", fontsize=7,
                            color="k" if val > middle else "w")
            ax.set_xlabel(xn)
            ax.set_ylabel(yn)
            ax.set_title(v, fontsize=10)
            fig.colorbar(im, ax=ax, label=chosen)
        fig.suptitle(f"{chosen} over the grid")
        paths.append(_save(fig, directory / "heatmap.png"))
    else:
        travel = _travel(result)
        shown = [chosen] + ([travel] if travel is not None else [])
        fig, axes = plt.subplots(1, len(shown), figsize=(6.2 * len(shown), 3.8), squeeze=False,
                                 layout="constrained")
        for ax, m in zip(axes[0], shown, strict=True):
            data = _floats(result.columns[m])
            finite = data[np.isfinite(data)]
            wide = _wide(finite)
            bins: Any = 10
            if wide:  # travel spans decades: log-spaced bins on a symlog axis
                bins = np.concatenate(([0.0], np.geomspace(1.0, max(finite.max(), 10.0), 30)))
                ax.set_xscale("symlog", linthresh=1.0)
            elif finite.size:
                bins = np.histogram_bin_edges(finite, bins=30)
            for i, v in enumerate(variants):
                d = data[(vcol == v) & np.isfinite(data)]
                ax.hist(d, bins=bins, histtype="step", lw=1.6, color=colours[i % len(colours)],
                        label=f"{v} (median {np.median(d):.3g})" if d.size else v)
            ax.set_xlabel(m + (" (symlog axis)" if wide else ""))
            ax.set_ylabel("instances")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
        per = len(result) // max(1, len(variants))
        not_run = len(_not_run(result))
        fig.suptitle(f"distribution over {per - not_run} instances per variant"
                     + (f" ({not_run} not run: their relay test gave no gain)"
                        if not_run else ""))
        paths.append(_save(fig, directory / "histograms.png"))
        if travel is not None:
            pv = next((c for c in result.metrics if c == "PV std" or c.endswith(": PV std")),
                      chosen)
            fig, ax = plt.subplots(figsize=(7.5, 5.2), layout="constrained")
            for i, v in enumerate(variants):
                keep = vcol == v
                x, y = _floats(result.columns[travel])[keep], _floats(result.columns[pv])[keep]
                colour = colours[i % len(colours)]
                ax.scatter(x, y, s=9, alpha=0.45, color=colour, label=v)
                front = pareto(x, y)
                if front.size:
                    ax.plot(x[front], y[front], "-", color=colour, lw=1.6)
            if _wide(_floats(result.columns[travel])):
                ax.set_xscale("symlog", linthresh=1.0)
            ax.set_xlabel(f"{travel} (lower is less wear"
                          + ("; symlog axis)" if ax.get_xscale() == "symlog" else ")"))
            ax.set_ylabel(f"{pv} (lower is tighter control)")
            what = "output travel" if travel.endswith("output travel") else "valve travel"
            ax.set_title(f"PV variability against {what}; lines: each variant's "
                         "non-dominated instances", fontsize=10)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
            paths.append(_save(fig, directory / "pareto.png"))
    for name in FIGURES if clean else ():  # an earlier sweep's figure is not this sweep's
        if directory / name not in paths:
            (directory / name).unlink(missing_ok=True)
    return paths


def remove_stale_trajectories(directory: Path, written: set[Path]) -> list[Path]:
    """Remove the ``trajectory_*.csv`` files in ``directory`` that this sweep did not write
    (an earlier sweep's runs, which would read as this one's); the removed paths."""
    stale = [p for p in directory.glob("trajectory_*.csv") if p not in written]
    for p in stale:
        p.unlink()
    return stale


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_results(result: SweepResult, directory: Path) -> list[Path]:
    """``results.parquet`` and ``results.csv`` (same rows and columns) in ``directory``."""
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    directory.mkdir(parents=True, exist_ok=True)
    table = result.to_arrow()
    pq.write_table(table, directory / "results.parquet")
    pacsv.write_csv(table, directory / "results.csv")
    return [directory / "results.parquet", directory / "results.csv"]


def summary_table(result: SweepResult, metric: str) -> list[tuple[str, float, float, float,
                                                                    float, int]]:
    """(variant, median, 5th percentile, 95th percentile, best, n/a) of ``metric``: the
    figures over the runs where it has a value, and how many runs it has none (left out,
    and counted: they were left out silently; found by an outside audit); the best is the
    smallest, of a signed metric the nearest 0 (``metrics.SIGNED``)."""
    from loopworks.sim.metrics import SIGNED

    rows = []
    vcol = np.array(result.columns["variant"])
    values = _floats(result.columns[metric])
    signed = metric.rpartition(": ")[2] in SIGNED
    for v in dict.fromkeys(result.columns["variant"]):
        d = values[(vcol == v) & np.isfinite(values)]
        na = int(np.count_nonzero(vcol == v)) - int(d.size)
        if d.size:
            best = float(d[np.argmin(np.abs(d))]) if signed else float(d.min())
            rows.append((v, float(np.median(d)), float(np.percentile(d, 5)),
                         float(np.percentile(d, 95)), best, na))
        else:
            rows.append((v, math.nan, math.nan, math.nan, math.nan, na))
    return rows


def _not_run(result: SweepResult) -> dict[int, str]:
    """Point -> why it did not run (its ``[autotune]`` relay test gave no gain)."""
    from loopworks.sim.sweep import AUTOTUNE_ERROR

    return {p: e for p, e in zip(result.columns["point"],
                                 result.columns.get(AUTOTUNE_ERROR, []), strict=False)
            if e is not None}


def write_summary(result: SweepResult, directory: Path, title: str, command: str,
                  metric: str | None = None) -> Path:
    """``summary.html``: what was swept, a per-variant table of the chosen metric (and valve
    travel), the best instance, and the figures."""
    chosen = _metric(result, metric)
    images = figures(result, directory, chosen, clean=True)
    shown = [chosen] + [m for m in [_travel(result)] if m is not None and m != chosen]
    tables = []
    for m in shown:
        body = "".join(
            f"<tr><td>{html.escape(v)}</td>" + "".join(
                f"<td>{'n/a' if math.isnan(x) else f'{x:.4g}'}</td>" for x in (a, b, c, d))
            + f"<td>{na}</td></tr>" for v, a, b, c, d, na in summary_table(result, m))
        tables.append(f"<h2>{html.escape(m)}</h2><table><tr><th>variant</th><th>median</th>"
                      f"<th>5 %</th><th>95 %</th><th>best</th><th>runs n/a (left out)</th>"
                      f"</tr>{body}</table>")
    try:
        best = result.best(chosen)
        best_html = ("<p>Best instance by " + html.escape(chosen) + ": "
                     + html.escape(", ".join(f"{k} = {v}" for k, v in best.items()
                                             if k in ("variant", "point", "seed", chosen,
                                                      *result.varied)))
                     + "</p>")
    except KeyError:
        best_html = f"<p>{html.escape(chosen)} is n/a in every instance.</p>"
    n_var = len(set(result.columns["variant"]))
    per = len(result) // max(1, n_var)
    from loopworks.sim.sweep import AUTOTUNE_ERROR

    rate = len(result) / result.seconds if result.seconds > 0 else math.nan
    errors = _not_run(result)
    failed = (f"<p>{len(errors)} of {per} points did not run: their [autotune] relay test "
              f"identified no process gain (their rows are n/a; column {AUTOTUNE_ERROR}). "
              f"Point {min(errors)}: {html.escape(errors[min(errors)])}</p>" if errors else "")
    imgs = "\n".join(f'<img src="{html.escape(p.name)}" alt="{html.escape(p.stem)}">'
                     for p in images)
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1400px;margin:1em auto;padding:0 1em}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}
img{{max-width:100%;display:block;margin:1em 0}}code{{background:#f4f4f4}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>{html.escape(result.design)}: {per} instances × {n_var} variant(s) = {len(result)} runs,
varying {html.escape(", ".join(result.varied))}; {result.seconds:.1f} s ({rate:.1f}
instances/s).</p>
{failed}
<p><code>{html.escape(command)}</code></p>
{best_html}
{"".join(tables)}
{imgs}
<p>Every row, with its seed and values, is in <code>results.parquet</code> and
<code>results.csv</code>; a row is reproduced by <code>loopworks simulate</code> with
<code>[simulation] seed</code> = its seed and its values.</p>
</body></html>
"""
    path = directory / "summary.html"
    path.write_text(page, encoding="utf-8")
    return path
