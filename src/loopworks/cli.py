"""The ``loopworks`` command line: thin; parses, calls the API, prints and writes files.

Every user error (bad parameter, unknown kind, malformed file) prints one line starting with
``error:`` on standard error and exits with code 2; nothing prints a traceback.
"""

from __future__ import annotations

import functools
import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

app = typer.Typer(
    name="loopworks",
    help="Industrial PID control loops: vendor blocks, simulation and historian replay.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)


def _fail(message: str) -> None:
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(2)


F = TypeVar("F", bound=Callable[..., None])


def _user_errors(fn: F) -> F:
    """Turn loopworks' user errors into one ``error:`` line and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> None:
        from loopworks.errors import LoopworksError

        try:
            fn(*args, **kwargs)
        except LoopworksError as exc:
            _fail(str(exc))

    return wrapper  # type: ignore[return-value]


@app.command()
@_user_errors
def simulate(
    scenario: Annotated[Path | None, typer.Argument(
        help="scenario TOML file; omit to run the built-in scenario")] = None,
    output: Annotated[Path, typer.Option(
        "--output", "-o", help="report directory: plots, metrics.json, report.html")] = Path(
        "loopworks-report"),
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Run a scenario (each [compare] variant), print the metrics, write a report directory."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn
    from rich.table import Table

    from loopworks.sim.report import write_report
    from loopworks.sim.result import SimResult
    from loopworks.sim.scenario import load_scenario

    sc = load_scenario(scenario)
    console = Console()
    title = sc.title or sc.source
    results: dict[str, SimResult] = {}
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeRemainingColumn(), console=console,
                  transient=True, disable=quiet) as bar:
        for variant, module in sc.variants.items():
            task = bar.add_task(f"simulating {variant}", total=None)

            def tick(done: int, total: int, task: Any = task) -> None:
                bar.update(task, completed=done, total=total)

            results[variant] = module.run(sc.duration, sc.dt, progress=tick)
    metrics: dict[str, dict[str, float]] = {}
    for variant, result in results.items():
        for loop in result.controllers():
            key = variant if len(result.controllers()) == 1 else f"{variant}: {loop}"
            metrics[key] = result.metrics(loop, window=sc.metrics_window)
    scored = ("" if sc.metrics_window is None
              else f", scored over {sc.metrics_window[0]:g}..{sc.metrics_window[1]:g} s")
    table = Table(title=f"{title}: {sc.duration:g} s in scans of {sc.dt:g} s{scored}")
    table.add_column("metric")
    for key in metrics:
        table.add_column(key, justify="right")
    for name in next(iter(metrics.values()), {}):
        table.add_row(name, *("n/a" if math.isnan(m.get(name, math.nan))
                              else f"{m[name]:.4g}" for m in metrics.values()))
    if metrics:
        console.print(table)
    else:
        console.print(f"{title}: no controller to score (a block with sp and pv inputs and an "
                      "out output)")
    write_report(output, title, sc.text, results, metrics)
    console.print(f"wrote {output}/report.html, metrics.json, scenario.toml and "
                  f"{len(results)} trend plot(s)")


@app.command()
@_user_errors
def blocks(
    kind: Annotated[str | None, typer.Argument(help="a block kind to describe")] = None,
    markdown: Annotated[bool, typer.Option(
        "--markdown", help="print the kind's reference page in Markdown (docs/blocks/)")] = False,
) -> None:
    """List the block kinds, or describe one: parameters, inputs and outputs."""
    from rich.console import Console
    from rich.table import Table

    from loopworks.blocks import reference
    from loopworks.blocks.registry import block_class, kinds

    console = Console()
    if kind is None:
        table = Table(title="block kinds")
        table.add_column("kind")
        table.add_column("what it is")
        for k in kinds():
            table.add_row(k, block_class(k).describe())
        console.print(table)
        return
    cls = block_class(kind)
    if markdown:
        typer.echo(reference.markdown(cls), nl=False)
        return
    console.print(f"[bold]{cls.kind}[/bold]: {cls.describe()}")
    sections: list[tuple[str, tuple[str, ...], list[Any]]] = [
        ("parameters", ("name", "unit", "default", "range", "meaning"),
         list(reference.parameter_rows(cls))),
        ("inputs", ("name", "unit", "default", "meaning"), list(reference.input_rows(cls))),
        ("outputs", ("name", "unit", "status", "meaning"), list(reference.output_rows(cls))),
    ]
    for title, header, rows in sections:
        table = Table(title=title)
        for col in header:
            table.add_column(col, overflow="fold")
        for row in rows:
            table.add_row(*row)
        console.print(table)


@app.command()
@_user_errors
def replay(
    kind: Annotated[str, typer.Argument(help="block kind, e.g. pid")],
    input_csv: Annotated[Path, typer.Argument(metavar="INPUT.csv", help="recorded inputs")],
    param: Annotated[list[str] | None, typer.Option(
        "--param", "-p", metavar="NAME=VALUE", help="a block parameter (repeatable)")] = None,
    params: Annotated[Path | None, typer.Option(
        "--params", metavar="FILE.toml", help="block parameters from a TOML table")] = None,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="OUT.csv", help="output CSV (default: standard output)")] = None,
    dt: Annotated[float | None, typer.Option(
        "--dt", help="scan time in seconds, when the CSV has no t or dt column")] = None,
) -> None:
    """Run recorded inputs from a CSV file through one block and write its outputs."""
    from loopworks.blocks.registry import block_class
    from loopworks.sim.replay import replay as run_replay

    cls = block_class(kind)
    values: dict[str, Any] = {}
    if params is not None:
        values.update(read_params_file(params, cls.kind))
    for item in param or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            _fail(f"-p {item!r}: expected NAME=VALUE")
        values[name.strip()] = value.strip()
    block = cls(**values)
    from rich.console import Console

    console = Console(stderr=True)
    if output is None or not console.is_terminal:
        summary = run_replay(block, input_csv, output, dt=dt)
    else:  # a row counter on the terminal while a long file streams
        from rich.progress import Progress, SpinnerColumn, TextColumn

        with Progress(SpinnerColumn(), TextColumn("{task.description}"), transient=True,
                      console=console) as bar:
            task = bar.add_task(f"replaying {input_csv.name} through {cls.kind}")

            def tick(rows: int) -> None:
                bar.update(task, description=f"replaying {input_csv.name} through {cls.kind}: "
                                             f"{rows} rows")

            summary = run_replay(block, input_csv, output, dt=dt, progress=tick)
    if output is not None:
        typer.echo(f"replayed {summary.rows} rows (t = {summary.t_start:g}..{summary.t_end:g} s) "
                   f"through {cls.kind}; wrote {output}", err=True)


def read_params_file(path: Path, kind: str) -> dict[str, Any]:
    """Parameters from a TOML file: a flat table, optionally with ``kind`` (which must match)."""
    from loopworks.errors import FileFormatError

    try:
        with open(path, "rb") as fh:
            table = tomllib.load(fh)
    except OSError as exc:
        raise FileFormatError(f"{path}: cannot read the parameters: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"{path}: invalid TOML: {exc}") from None
    given_kind = table.pop("kind", None)
    if given_kind is not None and str(given_kind).lower() != kind:
        raise FileFormatError(f"{path}: kind = {given_kind!r} does not match the block kind "
                              f"{kind!r}")
    for key, value in table.items():
        if isinstance(value, dict | list):
            raise FileFormatError(f"{path}: '{key}' is a table or array: expected a flat table "
                                  "of parameter = value")
    return table


def main() -> None:
    """Entry point of the ``loopworks`` console script."""
    app()


if __name__ == "__main__":
    main()
