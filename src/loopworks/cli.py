"""The ``loopworks`` command line: thin; parses, calls the API, prints and writes files.

Every user error (bad parameter, unknown kind, malformed file) prints one line starting with
``error:`` on standard error and exits with code 2; nothing prints a traceback.
"""

from __future__ import annotations

import functools
import math
import os
import shlex
import sys
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
    rich_markup_mode=None,  # help texts are plain: "[compare]" is a TOML table, not markup
)


def _version(value: bool) -> None:
    if value:
        from loopworks import __version__

        typer.echo(f"loopworks {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option(
        "--version", callback=_version, is_eager=True, help="print the version and exit")
    ] = False,
) -> None:
    """Industrial PID control loops: vendor blocks, simulation and historian replay."""


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
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="report directory: plots, metrics.json, report.html "
        "[default: loopworks-report; with --json: none unless given]")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
    as_json: Annotated[bool, typer.Option(
        "--json", help="print the metrics as metrics.json has them (one JSON object) instead "
        "of the table; the report is written only with -o")] = False,
) -> None:
    """Run a scenario (each [compare] variant), print the metrics, write a report directory."""
    from rich.console import Console
    from rich.markup import escape
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn
    from rich.table import Table

    from loopworks.sim.report import json_text, write_report
    from loopworks.sim.result import SimResult
    from loopworks.sim.scenario import load_scenario, run_autotune

    if output is None and not as_json:
        output = Path("loopworks-report")
    if output is not None:
        _check_report_directory(output)
    sc = load_scenario(scenario)
    for warning in sc.warnings:
        typer.echo(f"warning: {warning}", err=True)
    console = Console(stderr=as_json)  # with --json, standard output is the JSON alone
    title = sc.title or sc.source
    if sc.autotune_test is not None:  # the [autotune] relay test: an explicit step
        test = sc.autotune_test
        with Progress("[progress.description]{task.description}",
                      "[progress.elapsed]{task.fields[seconds]}", console=console,
                      transient=True, disable=quiet) as bar:
            task = bar.add_task(escape(f"relay test on {test.loop} ({test.variant})"),
                                total=None,
                                seconds="")

            def relay_tick(seconds: float) -> None:
                bar.update(task, seconds=f"{seconds:.0f} s of test")

            at = run_autotune(sc, progress=relay_tick)
        assert at is not None
        console.print(f"[autotune] relay test on {at['loop']} ({at['variant']}): {at['outcome']}, "
                      f"process gain {_g(at['process_gain'])} %PV/%OUT, Ku {_g(at.get('ku'))}, "
                      f"Pu {_g(at.get('pu'))} s", markup=False)
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
    from loopworks.sim.module import scan_count

    run_s = scan_count(sc.duration, sc.dt) * sc.dt  # what ran: a duration off the grid rounds
    if as_json:
        typer.echo(json_text(metrics), nl=False)
    table = Table(title=escape(f"{title}: {run_s:g} s in scans of {sc.dt:g} s{scored}"))
    table.add_column("metric")
    for key in metrics:
        table.add_column(escape(key), justify="right")
    # every metric of any loop (a later loop's valve rows when the first has no valve)
    for name in dict.fromkeys(k for m in metrics.values() for k in m):
        table.add_row(name, *("n/a" if math.isnan(m.get(name, math.nan))
                              else f"{m[name]:.4g}" for m in metrics.values()))
    if metrics and not as_json:
        console.print(table)
    elif not metrics:
        console.print(f"{title}: no controller to score (a block with sp and pv inputs and an "
                      "out output)", markup=False)
    if output is None:
        return
    try:
        write_report(output, title, sc.text, results, metrics, sc.autotune, sc.metrics_window)
    except OSError as exc:
        _fail(f"{exc.filename or output}: cannot write the report: {exc.strerror}")
    console.print(f"wrote {output}/report.html, metrics.json, scenario.toml and "
                  f"{len(results)} trend plot(s)", markup=False)


def _given_values(row: dict[str, Any], metrics: list[str]) -> dict[str, Any]:
    """A results row for JSON: a given value of ±inf (``pid.ti = inf``, no integral action)
    as the text "inf" / "-inf", as results.csv writes it; null stays for a metric that has no
    value (n/a)."""
    return {k: (("inf" if v > 0 else "-inf") if k not in metrics and isinstance(v, float)
                and math.isinf(v) else v) for k, v in row.items()}


def _g(value: Any) -> str:
    """A figure for a summary line; n/a when there is none."""
    return "n/a" if not isinstance(value, float | int) or not math.isfinite(value) \
        else f"{value:.4g}"


def _check_report_directory(output: Path) -> None:
    """Before a run: ``output`` is an existing writable directory, or one that can be made
    (tried: made and removed again, so a run that fails leaves nothing), so a place the report
    cannot go is one error line before the work, not a traceback after it."""
    if output.exists():
        if not output.is_dir():
            _fail(f"-o {output}: exists and is not a directory: the report is a directory; "
                  "choose another name")
        if not os.access(output, os.W_OK | os.X_OK):
            _fail(f"-o {output}: the directory is not writable")
        return
    parent = output.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        _fail(f"-o {output}: cannot create the report directory: {parent} is a file")
    if not os.access(parent, os.W_OK | os.X_OK):
        _fail(f"-o {output}: cannot create the report directory: {parent} is not writable")
    made = [d for d in [output.absolute(), *output.absolute().parents] if not d.exists()]
    try:
        output.mkdir(parents=True)
    except OSError as exc:
        _fail(f"-o {output}: cannot create the report directory: {exc.strerror or exc}")
    for d in made:  # deepest first
        d.rmdir()


@app.command()
@_user_errors
def blocks(
    kind: Annotated[str | None, typer.Argument(help="a block kind to describe")] = None,
    markdown: Annotated[bool, typer.Option(
        "--markdown", help="print the kind's reference page in Markdown (docs/blocks/)")] = False,
    as_json: Annotated[bool, typer.Option(
        "--json", help="print the kind's whole declaration as JSON (docs/blocks-json.md); "
        "without KIND, the kinds and their summaries")] = False,
) -> None:
    """List the block kinds, or describe one: parameters, inputs and outputs."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from loopworks.blocks import reference
    from loopworks.catalog import block_class, kinds

    if as_json:
        import json

        from loopworks.blocks.controller import Controller

        data: Any = ([{"kind": k, "summary": block_class(k).describe(),
                       "controller": issubclass(block_class(k), Controller)} for k in kinds()]
                     if kind is None else reference.declaration(block_class(kind)))
        typer.echo(json.dumps(data, indent=2, allow_nan=False))
        return
    console = Console()
    if kind is None:
        table = Table(title="block kinds")
        table.add_column("kind")
        table.add_column("what it is")
        for k in kinds():
            table.add_row(k, escape(block_class(k).describe()))
        console.print(table)
        return
    cls = block_class(kind)
    if markdown:
        typer.echo(reference.markdown(cls), nl=False)
        return
    console.print(f"[bold]{cls.kind}[/bold]: {escape(cls.describe())}")
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
            table.add_row(*(escape(cell) for cell in row))
        console.print(table)


@app.command()
@_user_errors
def replay(
    kind: Annotated[str, typer.Argument(help="block kind, e.g. pid")],
    input_csv: Annotated[Path, typer.Argument(metavar="INPUT.csv", help="recorded inputs")],
    param: Annotated[list[str] | None, typer.Option(
        "--param", "-p", metavar="NAME=VALUE", help="a block parameter (repeatable; it "
        "replaces the same parameter of --params, in any letter case)")] = None,
    params: Annotated[Path | None, typer.Option(
        "--params", metavar="FILE.toml", help="block parameters from a TOML table")] = None,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="OUT.csv", help="output CSV (default: standard output)")] = None,
    dt: Annotated[float | None, typer.Option(
        "--dt", help="scan time in seconds, when the CSV has no t or dt column")] = None,
) -> None:
    """Run recorded inputs from a CSV file through one block and write its outputs."""
    from loopworks.catalog import block_class
    from loopworks.sim.replay import replay as run_replay

    cls = block_class(kind)
    if output is not None and str(output) == "-":
        output = None  # the usual spelling of standard output
    if output is not None and output.suffix.lower() not in ("", ".csv", ".txt", ".dat"):
        _fail(f"-o {output}: replay writes CSV text; name the output .csv (or leave -o out "
              "for standard output)")
    if output is not None and output.exists() and input_csv.exists() \
            and output.resolve() == input_csv.resolve():
        _fail(f"-o {output}: is the input file: the replay would overwrite the record it "
              "reads; choose another output")
    values: dict[str, Any] = {}
    if params is not None:
        values.update(read_params_file(params, cls.kind))
    values.update(_pairs(param, "-p"))  # -p replaces the file's (a block reads any case)
    from loopworks.errors import ParameterError

    try:
        block = cls(**values)
    except ParameterError as exc:
        if params is None:
            raise
        where = f"{params}" + (" (with the -p options)" if param else "")
        raise ParameterError(f"{where}: {exc}") from None
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
        rows = f"{summary.rows} row" + "s" * (summary.rows != 1)
        typer.echo(f"replayed {rows} (t = {summary.t_start:g}..{summary.t_end:g} s) "
                   f"through {cls.kind}; wrote {output}", err=True)


def _number_of(value: Any) -> Any:
    """``value`` as a number when it is the text of one (an int when whole), else as it is."""
    if not isinstance(value, str):
        return value
    try:
        x = float(value)
    except ValueError:
        return value
    return int(x) if x.is_integer() and "." not in value and "e" not in value.lower() else x


def _pairs(items: list[str] | None, option: str) -> dict[str, str]:
    """NAME=VALUE options into a dict (names lower-cased); a name given twice (in any letter
    case) is an error, not the last one silently winning."""
    values: dict[str, str] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            _fail(f"{option} {item!r}: expected NAME=VALUE")
        key = name.strip().lower()
        if key in values:
            _fail(f"{option} {item!r}: '{key}' is given twice ({key} = {values[key]!r} "
                  "before); give it once")
        values[key] = value.strip()
    return values


def _json_safe(value: Any) -> Any:
    """inf and NaN as strings ("inf", "-inf", "nan") so the output is strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    return value


def _fmt_value(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


@app.command()
@_user_errors
def tune(
    scenario: Annotated[Path | None, typer.Argument(
        help="scenario TOML file; omit for the built-in scenario")] = None,
    loop: Annotated[str, typer.Option(
        "--loop", help="the controller block to tune (default: the [autotune] loop)")] = "",
    rule: Annotated[str | None, typer.Option(
        "--rule", help="tuning rule (docs/tuning-rules.md); default: chosen from what the "
        "test identifies")] = None,
    controller: Annotated[str, typer.Option(
        "--controller", help="controller type: P, PI or PID")] = "PI",
    amplitude: Annotated[float | None, typer.Option(
        "--amplitude", help="relay amplitude d, controller output units (default 5 % of the "
        "output range)")] = None,
    hysteresis: Annotated[float | None, typer.Option(
        "--hysteresis", help="relay hysteresis ε, PV units (default 3 σ of the PV noise)")] = None,
    symmetric: Annotated[bool, typer.Option(
        "--symmetric", help="symmetric relay only (no biased stage, no static gain)")] = False,
    bias_ratio: Annotated[float | None, typer.Option(
        "--bias-ratio", help="d_down/d of the second stage (default 0.5, or [autotune])")] = None,
    offset: Annotated[float | None, typer.Option(
        "--offset", help="second stage switches around SP + offset·a (default 0, or "
        "[autotune])")] = None,
    start: Annotated[float | None, typer.Option(
        "--start", help="start of the test, s (default 60 s after the last event)")] = None,
    option: Annotated[list[str] | None, typer.Option(
        "--option", "-O", metavar="NAME=VALUE", help="rule option: tau_c, lam, t2 (s)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
) -> None:
    """Relay-test a loop of a scenario; print the identified model and the settings in the
    loop controller's own parameters. A scenario with an [autotune] table tests its loop (the
    default --loop) with that table's settings; the options given here override them. Without
    --loop or [autotune], the scenario's only controller is tested. A test whose record
    supports no identification is refused (one error line; with --json also an object whose
    `refusal` says why)."""
    import json

    from loopworks.sim.scenario import load_scenario
    from loopworks.sim.tune import RelayTestRefused, default_loop, tune_loop

    sc = load_scenario(scenario)
    test = sc.autotune_test
    module = sc.module
    if not loop and test is None:
        loop = default_loop(module)
    relay: dict[str, Any] = {}
    if test is not None and loop.lower() in ("", test.loop):  # the scenario's own test
        loop, module, relay = test.loop, test.build(None, sc.seed), dict(test.relay)
    given = {"amplitude": amplitude, "hysteresis": hysteresis, "start": start,
             "bias_ratio": bias_ratio, "offset": offset}
    relay.update({k: v for k, v in given.items() if v is not None})
    options: dict[str, float] = {}
    for k, v in _pairs(option, "--option").items():
        try:
            options[k] = float(v)
        except ValueError:
            _fail(f"--option {k}={v!r}: expected a number (s)")
    # before the test (found by an outside audit: a wrong --rule, --controller or -O was told
    # after a test of minutes, or never when the test was refused; --symmetric dropped
    # --bias-ratio and --offset silently; a dead time longer than the delay line read as a
    # Bad PV)
    from loopworks.tuning.rules import check_request

    check_request(rule, controller, options)
    if symmetric:
        dropped = [f"--{k.replace('_', '-')}" for k in ("bias_ratio", "offset")
                   if given[k] is not None]
        if dropped:
            _fail(f"--symmetric with {' and '.join(dropped)}: a symmetric test has no bias "
                  "or shift; leave out one or the other")
    module.check_dt(sc.dt)
    try:
        report = tune_loop(module, loop, sc.dt, rule=rule, controller=controller.upper(),
                           options=options, biased=not symmetric, **relay)
    except RelayTestRefused as exc:
        if as_json:
            typer.echo(json.dumps(_json_safe(exc.run.refusal_record()), indent=2))
        raise
    data = report.as_dict()
    if as_json:
        typer.echo(json.dumps(_json_safe(data), indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    console = Console()
    ident = Table(title=f"relay test on {loop} ({data['kind']}): {data['outcome']}")
    ident.add_column("quantity")
    ident.add_column("value", justify="right")
    ident.add_column("±", justify="right")
    for key in ("relay_amplitude", "relay_amplitude_down", "relay_shift", "hysteresis",
                "amplitude", "period",
                "ku", "ku_describing_function", "ku_hysteresis_corrected", "pu",
                "process_type", "process_gain", "integrating_gain", "dead_time",
                "time_constant"):
        if data[key] is not None:
            spread = data["uncertainty"].get(key)
            ident.add_row(key, _fmt_value(data[key]),
                          "" if spread is None else f"{spread:.2g}")
    console.print(ident)
    settings = Table(title=f"{data['rule']} {data['controller']} in {data['kind']} parameters")
    settings.add_column("parameter")
    settings.add_column("value", justify="right")
    for key, value in data["settings"].items():
        settings.add_row(key, _fmt_value(value))
    console.print(settings)
    if data["ms"] is not None:
        console.print(f"Ms {data['ms']:.3g} on the identified model (docs/tune.md)")
    if data["note"]:
        console.print(data["note"], markup=False)
    for warning in data["warnings"]:
        console.print(f"warning: {warning}", markup=False)

@app.command()
@_user_errors
def convert(
    from_kind: Annotated[str, typer.Option("--from", help="source controller kind")],
    to_kind: Annotated[str, typer.Option("--to", help="target controller kind")],
    param: Annotated[list[str] | None, typer.Option(
        "--param", "-p", metavar="NAME=VALUE", help="a source parameter (repeatable)")] = None,
    target: Annotated[list[str] | None, typer.Option(
        "--target", "-t", metavar="NAME=VALUE", help="a fixed target setting: form, spans, "
        "throttling_range, scale, ... (repeatable)")] = None,
    sample_time: Annotated[float | None, typer.Option(
        "--sample-time", help="loop sample time, s (S5 OB 13 interval, E2 update interval)")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object")] = False,
) -> None:
    """Convert controller settings between the controllers of loopworks (docs/conversion.md)."""
    import json

    from loopworks.tuning.convert import convert as run_convert

    result = run_convert(from_kind, _pairs(param, "-p"), to_kind, sample_time=sample_time,
                         target=_pairs(target, "-t"))
    if as_json:
        from loopworks.catalog import block_class

        # a number given as text (-p pv_scale_eu_100=200) passed through as the text "200"
        # (found by an outside audit): a numeric parameter is a JSON number
        types = {p.name: p.type for p in block_class(to_kind).PARAMS}
        params = {k: _number_of(v) if types.get(k) in ("float", "int") else v
                  for k, v in result.params.items()}
        data = {**params, "exact": result.exact, "note": result.note,
                "response_errors": [{"omega": w, "error": e}
                                    for w, e in result.response_errors],
                "unmodelled": list(result.unmodelled)}
        typer.echo(json.dumps(_json_safe(data), indent=2))
        return
    for key, value in result.params.items():
        typer.echo(f"{key} = {_fmt_value(value)}")
    typer.echo(("exact: " if result.exact else "not exact: ") + result.note)


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
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{path}: not UTF-8 text (byte {exc.start}): a parameters file "
                              "is a TOML file") from None
    given_kind = table.pop("kind", None)
    if given_kind is not None and str(given_kind).lower() != kind:
        raise FileFormatError(f"{path}: kind = {given_kind!r} does not match the block kind "
                              f"{kind!r}")
    seen: dict[str, str] = {}
    for key, value in table.items():
        if isinstance(value, dict | list):
            raise FileFormatError(f"{path}: '{key}' is a table or array: expected a flat table "
                                  "of parameter = value")
        if key.lower() in seen:
            raise FileFormatError(f"{path}: '{key}' and '{seen[key.lower()]}' are one parameter "
                                  "(names are read in any letter case): give it once")
        seen[key.lower()] = key
    return table


@app.command()
@_user_errors
def sweep(
    scenario: Annotated[Path | None, typer.Argument(
        help="scenario TOML file; omit to sweep the built-in scenario")] = None,
    vary: Annotated[list[str] | None, typer.Option(
        "--vary", metavar="NAME=SPEC", help="block.parameter or block.input = a:b:n, "
        "v1,v2,..., uniform(a,b), loguniform(a,b), normal(m,s) or choice(v1,v2,...) "
        "(repeatable)")] = None,
    samples: Annotated[int, typer.Option(
        "--samples", help="Latin-hypercube samples of the distributions")] = 100,
    seed: Annotated[int | None, typer.Option(
        "--seed", help="the sweep's seed (default: the scenario's [simulation] seed, else 0)")
    ] = None,
    variant: Annotated[str | None, typer.Option(
        "--variant", help="sweep only this [compare] variant")] = None,
    workers: Annotated[int | None, typer.Option(
        "--workers", help="processes (default: one per core, at most 4, for 50,000 "
        "instances or more, else 1, whose batch runs on every core)")] = None,
    scheduler: Annotated[str | None, typer.Option(
        "--scheduler", help="a Dask distributed scheduler address (tcp://HOST:PORT)")] = None,
    metric: Annotated[str | None, typer.Option(
        "--metric", help="the metric the summary plots and ranks (default: PV std; with "
        "several loops the first loop's, 'LOOP: PV std')")] = None,
    trajectory: Annotated[list[int] | None, typer.Option(
        "--trajectory", metavar="POINT", help="also write this point's full run, every "
        "signal, as trajectory_VARIANT_POINT.csv (repeatable)")] = None,
    output: Annotated[Path, typer.Option(
        "--output", "-o", help="directory: results.parquet, results.csv, summary.html")] = Path(
        "loopworks-sweep"),
    as_json: Annotated[bool, typer.Option(
        "--json", help="print the per-variant summary as JSON")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Run a scenario over a grid or a Monte Carlo of parameter values; write the results table
    and a summary with plots."""
    import time

    from rich.console import Console
    from rich.markup import escape
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn
    from rich.table import Table

    from loopworks.sim import sweep_report
    from loopworks.sim.sweep import AUTOTUNE_ERROR
    from loopworks.sim.sweep import sweep as run_sweep

    _check_report_directory(output)
    if metric is not None:  # checked before the run ("loop: metric" with several loops)
        from loopworks.sim.metrics import METRICS
        from loopworks.sim.scenario import load_scenario
        from loopworks.sim.tune import controllers

        known = [m.name for m in METRICS]
        loops = controllers(load_scenario(scenario).module)
        loop, _, name = metric.rpartition(": ")
        if name not in known:
            _fail(f"--metric '{metric}': no such metric; metrics: {', '.join(known)}")
        if len(loops) > 1 and loop not in loops:
            _fail(f"--metric '{metric}': this scenario has {len(loops)} loops: name one, "
                  f"as 'LOOP: {name}' with LOOP one of {', '.join(loops)}")
        if len(loops) <= 1 and loop:
            _fail(f"--metric '{metric}': this scenario has one loop, whose metrics are "
                  f"named without it: '{name}'")
        from loopworks.sim.sweep import metric_columns

        have = metric_columns(load_scenario(scenario))
        if metric not in have:  # a known metric this scenario has no data for (no valve)
            _fail(f"--metric '{metric}': this scenario has no such metric; its metrics: "
                  + ", ".join(have))
    console = Console(stderr=as_json)
    started = time.perf_counter()
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), "[progress.elapsed]{task.fields[rate]}",
                  TimeRemainingColumn(), console=console, transient=True,
                  disable=quiet) as bar:
        task = bar.add_task("sweeping", total=None, rate="")

        since = [started]  # the instances' rate counts from the end of the relay tests

        def relay_tick(done: int, total: int) -> None:
            bar.update(task, description="relay tests ([autotune])", completed=done,
                       total=total, rate="")
            since[0] = time.perf_counter()

        def tick(done: int, total: int) -> None:
            rate = done / max(time.perf_counter() - since[0], 1e-9)
            bar.update(task, description="sweeping", completed=done, total=total,
                       rate=f"{rate:.1f} instances/s")

        result = run_sweep(scenario, vary or [], samples=samples, seed=seed, variant=variant,
                           workers="auto" if workers is None else workers,
                           scheduler=scheduler, progress=tick,
                           trajectories=trajectory or (), relay_progress=relay_tick)
    if metric is not None and metric not in result.metrics:
        _fail(f"--metric '{metric}': no such metric; metrics: {', '.join(result.metrics)}")
    sweep_report.write_results(result, output)
    written = set()
    for (v, point), run in result.trajectories.items():
        written.add(output / f"trajectory_{v}_{point}.csv")
        run.to_csv(output / f"trajectory_{v}_{point}.csv")
    sweep_report.remove_stale_trajectories(output, written)
    command = _sweep_command(sys.argv)
    title = f"sweep of {scenario if scenario is not None else 'the built-in scenario'}"
    sweep_report.write_summary(result, output, title, command, metric)
    chosen = sweep_report._metric(result, metric)
    rows = sweep_report.summary_table(result, chosen)
    finite = any(math.isfinite(x) for row in rows for x in row[1:5])
    failed = sum(e is not None for e in result.columns.get(AUTOTUNE_ERROR, []))
    if as_json:  # a metric with no value (n/a) is null, as in simulate's metrics.json
        from loopworks.sim.report import json_text

        typer.echo(json_text({
            "instances": len(set(result.columns["point"])), "runs": len(result),
            "not_run": failed, "design": result.design, "varied": result.varied,
            "seconds": result.seconds, "metric": chosen,
            "variants": {v: {"median": a, "p5": b, "p95": c, "best": d, "n_a": na}
                         for v, a, b, c, d, na in rows},
            "best": _given_values(result.best(chosen), result.metrics) if finite else None,
            "output": str(output)}), nl=False)
        return
    not_run = f" ({failed} not run: {AUTOTUNE_ERROR})" if failed else ""
    table = Table(title=escape(f"{title}: {result.design}, {len(result)} runs{not_run} in "
                               f"{result.seconds:.1f} s"))
    for col in ("variant", f"{chosen}: median", "5 %", "95 %", "best", "n/a"):
        table.add_column(escape(col), justify="right")
    for v, a, b, c, d, na in rows:
        table.add_row(escape(v), *(f"{x:.4g}" if math.isfinite(x) else "n/a"
                                   for x in (a, b, c, d)), str(na))
    console.print(table)
    console.print(f"wrote {output / 'results.parquet'}, results.csv and summary.html",
                  markup=False)


def _sweep_command(argv: list[str]) -> str:
    """The sweep's command line as summary.html shows it, quoted to paste into a shell
    (`--vary pid.k=uniform(1,2)` unquoted is a syntax error in bash, and `--metric PV std`
    two arguments; found by an outside audit)."""
    return shlex.join(["loopworks", "sweep", *argv[2:]])


@app.command()
@_user_errors
def diagnose(
    data: Annotated[Path, typer.Argument(help="historian CSV of one loop (t, sp, pv, op)")],
    columns: Annotated[list[str] | None, typer.Option(
        "--columns", metavar="ROLE=COLUMN,...", help="map the file's columns: "
        "sp=FIC101.SV,pv=FIC101.PV,op=FIC101.MV (roles t, sp, pv, op, position, mode)")] = None,
    loop_type: Annotated[str, typer.Option(
        "--loop-type", help="self-regulating or integrating; or the loop's service: flow, "
        "pressure, temperature (self-regulating), level (integrating)")] = "self-regulating",
    as_json: Annotated[bool, typer.Option("--json", help="print the diagnosis as JSON")] = False,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="directory for a report: report.html and its plots")] = None,
    op_range: Annotated[str | None, typer.Option(
        "--op-range", metavar="LO:HI", help="the OP's units at 0 % and 100 % of the valve's "
        "span (default: an OP in %, 0:100; a fraction 0:1, GE counts 0:32000, a DeltaV "
        "OUT_SCALE of 0..200 EU 0:200)")] = None,
    sample_time: Annotated[float | None, typer.Option(
        "--sample-time", metavar="SECONDS", help="the period of the rows of a file without a "
        "time column")] = None,
) -> None:
    """Say whether a loop's valve sticks, from its data: the evidence, the verdict, how sticky
    and what to do. A file without a setpoint column is read with the SP at the PV's mean (a
    loop with integral action holds its PV there on average; said in the output)."""
    import json

    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from loopworks.analysis import loop_type_of
    from loopworks.analysis.diagnosis import diagnose as run_diagnosis
    from loopworks.analysis.loopdata import parse_columns, read_csv
    from loopworks.errors import InputError

    try:
        loop_type = loop_type_of(loop_type)  # --loop-type level: integrating
    except InputError as exc:
        _fail(f"--loop-type {loop_type}: {exc}")
    if output is not None:
        _check_report_directory(output)
    # repeated --columns add up (a role mapped twice is parse_columns' error)
    mapping = parse_columns(",".join(columns)) if columns else None
    span: tuple[float, float] | None = None
    if op_range is not None:
        lo_text, _, hi_text = op_range.partition(":")
        try:
            lo, hi = float(lo_text), float(hi_text)
        except ValueError:
            _fail(f"--op-range {op_range}: expected LO:HI, two numbers (the OP's units at 0 % "
                  "and 100 %), e.g. 0:32000")
        if not (math.isfinite(lo) and math.isfinite(hi) and lo != hi):
            _fail(f"--op-range {op_range}: expected two different finite numbers (the OP's "
                  "units at 0 % and 100 % of the valve's span), e.g. 0:32000")
        span = (lo, hi)
    if sample_time is not None and not (math.isfinite(sample_time) and sample_time > 0):
        _fail(f"--sample-time {sample_time:g}: expected a number of seconds > 0 (the period "
              "of the rows of a file without a time column)")
    loop = read_csv(data, mapping, duplicates="last", sample_time=sample_time, sp_optional=True)
    result = run_diagnosis(loop, loop_type, op_range=span)
    if output is not None:
        from loopworks.analysis.diagnosis_report import write_report

        write_report(result, loop, output)
    if as_json:
        typer.echo(json.dumps(result.to_json(), indent=2, ensure_ascii=False))
        return
    console = Console()
    console.print(f"{data}: {len(loop)} samples every {loop.dt:g} s, {loop_type} loop",
                  markup=False)
    for line in (*result.quality.reasons, *result.quality.notes):
        console.print(f"  quality: {line}", markup=False)
    osc = result.oscillation
    if osc is not None:
        console.print("oscillation: " + (f"yes, period {osc.period_s:.4g} s, regularity "
                                         f"{osc.regularity:.3g}" if osc.detected
                                         else f"no ({osc.reason})"), markup=False)
    if result.evidence:
        table = Table(title="evidence")
        for col in ("method", "vote", "index", "why"):
            table.add_column(col, overflow="fold")
        for e in result.evidence:
            value = "n/a" if not math.isfinite(e.value) else f"{e.value:.4g}"
            table.add_row(escape(e.method), e.vote, value, escape(e.reason))
        console.print(table)
    console.print(f"verdict: {result.verdict} (confidence {result.confidence:.2f}): "
                  f"{result.reason}", markup=False)
    if result.stiction is not None:
        st = result.stiction
        console.print(f"stiction: S = {st['s']:.3g} %, J = {st['j']:.3g} % (resolution "
                      f"{st['resolution']:.3g} %, deadband {st['deadband']:.3g} %), fit "
                      f"R² = {st['r2']:.3f} (of the {_R2_OF[st['r2_of']]})", markup=False)
    if result.recommendation is not None:
        console.print(f"recommendation: {result.recommendation['summary']}", markup=False)
    if output is not None:
        console.print(f"wrote {output / 'report.html'}", markup=False)


#: what a diagnosis's fit R² is of (``stiction.r2_of``)
_R2_OF = {"pv": "PV, through the fitted process", "position": "recorded valve position"}


@app.command("compile")
@_user_errors
def compile_kinds(
    kinds: Annotated[list[str] | None, typer.Argument(
        help="block kinds to compile (default: every kind)")] = None,
    jobs: Annotated[int, typer.Option(
        "--jobs", "-j", help="compile in this many processes (at most one per core helps)")
    ] = 1,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Compile the kinds' kernels for this machine into the plan cache, so no later command
    (simulate, replay, a live controller's first scan) waits for a compilation. A kind
    that is cached already is loaded, not compiled again. Without kinds, also the CSV
    formatter and the metrics' compiled loop."""
    import time
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    import loopworks
    from loopworks.blocks import plan
    from loopworks.catalog import block_class

    if jobs < 1:
        _fail(f"--jobs {jobs}: expected a whole number of processes >= 1")
    plan.announce = None  # this command reports what it compiled itself
    chosen = [k.lower() for k in kinds] if kinds else loopworks.kinds()
    for kind in chosen:
        block_class(kind)  # an unknown kind is one error line, before anything compiles
    # one kind per kernel and guard (kinds that share a kernel share its entry), the longest
    # kernels first, so the processes finish together
    by_entry = {(block_class(k).kernel, block_class(k).SOUND_KERNEL): k for k in chosen}
    work = sorted(by_entry.values(), key=lambda k: -len(block_class(k).kernel.__code__.co_code))
    console = Console(stderr=True)
    start = time.perf_counter()
    done: list[tuple[str, float, bool]] = []
    with Progress("{task.description}", BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=console, transient=True, disable=quiet) as bar:
        task = bar.add_task("compiling", total=len(work))
        # the whole cache (no kinds named): also the compiled helpers every run may need,
        # first in a process of its own when there are several (it is the longest item)
        if jobs == 1:
            for kind in work:
                done.append(plan.compile_kind(block_class(kind)))
                bar.advance(task)
            if not kinds:
                _compile_helpers()
        else:
            with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
                helpers = None if kinds else pool.submit(_compile_helpers)
                for result in pool.map(plan.compile_kind, [block_class(k) for k in work]):
                    done.append(result)
                    bar.advance(task)
                if helpers is not None:
                    helpers.result()
    made = [d for d in done if d[2]]
    typer.echo(f"{len(made)} of {len(work)} kernels compiled, {len(work) - len(made)} "
               f"loaded from the cache, in {time.perf_counter() - start:.1f} s "
               f"({plan.cache_dir()})")


def _compile_helpers() -> None:
    """Compile (or load) the package's own cached compiled functions that are not kernels:
    the CSV formatter of ``simulate`` and ``replay`` (8 s to compile), the reversal count
    of the metrics and the valve fit's regression of ``diagnose`` (1.5 s), each for the one
    signature it is called with (their arguments go through
    :func:`loopworks.sim.arrays.compiled_arg`, or are converted by their Python wrapper).
    numba caches them beside the installed package (or in ``NUMBA_CACHE_DIR``)."""
    import numpy as np

    from loopworks.analysis.valve_fit import _sse_all_d
    from loopworks.sim.floatfmt import float_text
    from loopworks.sim.metrics import reversals

    float_text(np.zeros(1))
    reversals(np.zeros(2))
    _sse_all_d(np.zeros(4), np.ones(4), 0.5, 1, 4.0)


users_app = typer.Typer(
    help="The users file of a live controller's OPC UA server (loopworks serve --users FILE).",
    no_args_is_help=True,
)
app.add_typer(users_app, name="users")


def _read_password(name: str) -> str:
    """One line of standard input, or (on a terminal) a password typed twice."""
    if sys.stdin is not None and sys.stdin.isatty():
        import getpass

        first = getpass.getpass(f"password for {name}: ")
        second = getpass.getpass(f"password for {name} (again): ")
        if first != second:
            _fail("the two passwords differ: nothing written")
        return first
    line = sys.stdin.readline() if sys.stdin is not None else ""
    password = line.removesuffix("\n").removesuffix("\r")
    try:
        password.encode("utf-8")
    except UnicodeEncodeError:  # bytes that are not UTF-8 on standard input
        _fail("the password read from standard input is not UTF-8 text: nothing written")
    return password


@users_app.command("add")
@_user_errors
def users_add(
    file: Annotated[Path, typer.Argument(help="users file (TOML); created if missing")],
    name: Annotated[str, typer.Argument(help="user name: letters, digits, _ . -")],
    role: Annotated[str, typer.Option(
        "--role", help="viewer (reads) or operator (reads and writes)")] = "viewer",
) -> None:
    """Add a user or change a user's password and role. The password is one line of standard
    input (typed twice at a terminal); other users in the file are kept."""
    from loopworks.live.users import add_user, check_name, check_role

    check_name(name)  # before asking for a password
    check_role(role)
    new = add_user(file, name, _read_password(name), role)
    typer.echo(f"{'added' if new else 'updated'} user {name} ({role}) in {file}")


def _check_port(option: str, port: int | None, host: str = "127.0.0.1") -> None:
    """Before anything starts: ``port`` is 0 (any free port) or 1..65535, and free on
    ``host`` (a port in use is one error line, not a traceback after the other servers
    started)."""
    import socket

    if port is None or port == 0:
        return
    if not 0 < port < 65536:
        _fail(f"{option} {port}: allowed 1..65535, or 0 for any free port")
    try:
        with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            probe.bind((host, port))
    except socket.gaierror as exc:  # the host, not the port (found by an outside audit)
        _fail(f"--host {host}: not an address to listen on ({exc.strerror or exc})")
    except OSError as exc:
        _fail(f"{option} {port}: cannot listen on {host}:{port} ({exc.strerror or exc})")


def _check_duration(duration: float | None) -> None:
    """A live run's --duration: positive and finite (no option: until Ctrl-C)."""
    if duration is not None and not 0.0 < duration < math.inf:
        _fail(f"--duration {duration}: expected plant seconds > 0 and finite (leave it out "
              "to run until Ctrl-C)")


@app.command()
@_user_errors
def device(
    scenario: Annotated[Path | None, typer.Argument(
        help="scenario TOML file; omit for the built-in scenario")] = None,
    modbus_port: Annotated[int, typer.Option(
        "--modbus-port", help="Modbus TCP port to serve on (0: any free port)")] = 5020,
    host: Annotated[str, typer.Option(
        "--host", help="address to serve on (127.0.0.1: this machine only)")] = "127.0.0.1",
    speedup: Annotated[float, typer.Option(
        "--speedup", help="plant seconds per wall second (1: real time)")] = 1.0,
    variant: Annotated[str | None, typer.Option(
        "--variant", help="the [compare] variant whose plant runs (default: the first)")
    ] = None,
    duration: Annotated[float | None, typer.Option(
        "--duration", help="plant seconds to run (default: until Ctrl-C)")] = None,
    map_file: Annotated[Path, typer.Option(
        "--map-file", help="where to write the register map (TOML, the [io] table)")] = Path(
        "device-map.toml"),
    fstate_time: Annotated[float, typer.Option(
        "--fstate-time", help="wall seconds without a write before an input's fault "
        "action (hold) applies")] = 5.0,
    opcua_port: Annotated[int | None, typer.Option(
        "--opcua-port", help="serve the same points on an OPC UA server on 127.0.0.1 as well "
        "(NoSecurity, anonymous writes; 0: any free port; default: Modbus only)")] = None,
) -> None:
    """Run a scenario's plant blocks (process, valve, sensors, disturbances) as a simulated
    field device serving its I/O over Modbus TCP holding registers, and with --opcua-port on
    OPC UA as well (namespace urn:loopworks:device, nodes s=<block.port>); the controller side
    (loopworks serve, or any Modbus or OPC UA client) writes the valve and reads the
    measurement."""
    import asyncio
    import logging

    from loopworks.live.device import Device
    from loopworks.live.registers import map_of
    from loopworks.live.split import split_scenario
    from loopworks.sim.scenario import load_scenario

    _check_duration(duration)
    _check_port("--modbus-port", modbus_port, host)
    _check_port("--opcua-port", opcua_port)
    sc = load_scenario(scenario)
    split = split_scenario(sc, variant)
    regmap = map_of(sc, split)
    dev = Device(split, regmap, speedup=speedup, fstate_time=fstate_time)
    ua_server = None
    if opcua_port is not None:
        from loopworks.live.device_opcua import DeviceOpcua

        ua_server = DeviceOpcua(dev, host, opcua_port)  # checks the host and port now
    typer.echo(f"{sc.title or sc.source}: plant of variant {split.variant} "
               f"({', '.join(split.plant.order)})")
    typer.echo(regmap.text(), nl=False)
    regmap.write(map_file)
    typer.echo(f"wrote {map_file}")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    logger = logging.getLogger("loopworks.device")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)

    async def serve() -> None:
        import contextlib
        import signal

        task = asyncio.current_task()
        assert task is not None
        with contextlib.suppress(NotImplementedError, RuntimeError):  # Windows
            # SIGTERM stops the device as Ctrl-C does: servers closed, the stop reported
            # (it ended the process with no line; found by an outside audit)
            asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, task.cancel)
        port = await dev.start(host, modbus_port)
        try:
            if ua_server is not None:
                endpoint = await ua_server.start()
                typer.echo(f"serving OPC UA on {endpoint} (NoSecurity, anonymous; namespace "
                           f"urn:loopworks:device, nodes s=<point>, e.g. "
                           f"s={regmap.points[0].name})")
            until = ("until Ctrl-C" if duration is None else
                     f"for {duration:g} s of plant time")
            typer.echo(f"serving Modbus TCP on {host}:{port}, device id {regmap.device_id}, "
                       f"a plant scan of {split.dt:g} s every {dev.period:g} s "
                       f"(speedup {speedup:g}), {until}")
            sys.stdout.flush()
            await dev.run(duration)
        finally:
            if ua_server is not None:
                await ua_server.stop()
            await dev.stop()

    try:
        asyncio.run(serve())
    except (KeyboardInterrupt, asyncio.CancelledError):
        typer.echo(f"stopped at t = {dev.plant_time:g} s of plant time")
    else:
        typer.echo(f"done: {dev.scans} scans, t = {dev.plant_time:g} s of plant time, "
                   f"{dev.overruns} overruns")



@app.command()
@_user_errors
def serve(
    config: Annotated[Path | None, typer.Argument(
        help="scenario TOML whose controller side runs; omit for the built-in scenario")] = None,
    device: Annotated[str | None, typer.Option(
        "--device", help="the field device, modbus://HOST:PORT or opc.tcp://HOST:PORT/PATH "
        "(default: the url of an [io] table with protocol = \"opcua\", else the scenario's own "
        "plant started in another process on loopback)")] = None,
    opcua_port: Annotated[int, typer.Option(
        "--opcua-port", help="port of the controller's OPC UA server (0: any free port)")
    ] = 4840,
    host: Annotated[str, typer.Option(
        "--host", help="address the OPC UA server binds to (127.0.0.1: this machine only)")
    ] = "127.0.0.1",
    users: Annotated[Path | None, typer.Option(
        "--users", help="users file (loopworks users add); without it nobody can write")
    ] = None,
    speedup: Annotated[float, typer.Option(
        "--speedup", help="plant seconds per wall second (1: real time)")] = 1.0,
    duration: Annotated[float | None, typer.Option(
        "--duration", help="plant seconds to run (default: until Ctrl-C)")] = None,
    variant: Annotated[str | None, typer.Option(
        "--variant", help="the [compare] variant whose controller runs (default: the first)")
    ] = None,
    state_dir: Annotated[Path, typer.Option(
        "--state-dir", help="where checkpoints and the server certificate are kept")] = Path(
        "loopworks-state"),
    faceplate: Annotated[bool, typer.Option(
        "--faceplate", help="also start the operator's web faceplate (loopworks faceplate) "
        "on 127.0.0.1")] = False,
    faceplate_port: Annotated[int, typer.Option(
        "--faceplate-port", help="port of the web faceplate")] = 8080,
) -> None:
    """Run the controller side of a scenario (its controllers and compensators) live: scans
    on absolute deadlines, the device's I/O over Modbus TCP, every loop on an OPC UA server
    (opc.tcp://HOST:PORT, namespace urn:loopworks, nodes s=<loop>.PV, .SP, .OUT, .MODE),
    checkpoints to resume from. The controller scans in a process of its own (so no client
    can stall it), restarted from its checkpoint if it dies. Without --device the scenario's
    plant runs as a device on loopback in another process: a loop, live, in one command."""
    import asyncio

    from loopworks.live import supervisor
    from loopworks.live.serve import describe

    _check_duration(duration)
    _check_port("--opcua-port", opcua_port, host)
    if faceplate:
        _check_port("--faceplate-port", faceplate_port)

    supervisor.log_to_stderr()

    def ready(info: dict[str, Any]) -> None:
        dt = info["dt"]
        until = "until Ctrl-C" if duration is None else f"for {duration:g} s of plant time"
        typer.echo(f"controlling {info['device']}: loops {', '.join(info['loops'])}, a scan of "
                   f"{dt:g} s every {dt / speedup:g} s (speedup {speedup:g}), {until}, in "
                   f"process {info['pid']}"
                   + (f"; resumed from {info['checkpoint']} at scan {info['scans']}"
                      if info["resumed"] else ""))
        first = info["loops"][0]
        typer.echo(f"OPC UA server {info['endpoint']} (namespace urn:loopworks; e.g. "
                   f"s={first}.PV, s={first}.SP, s={first}.OUT, s={first}.MODE)"
                   + ("" if users else "; no --users file: read only"))
        sys.stdout.flush()

    stop = asyncio.Event()

    async def main() -> Any:
        import contextlib
        import signal

        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):  # Windows
                loop.add_signal_handler(sig, stop.set)
        return await supervisor.run(config, device=device, host=host, opcua_port=opcua_port,
                                    users=users, speedup=speedup, duration=duration,
                                    variant=variant, state_dir=state_dir, stop=stop,
                                    ready=ready,
                                    faceplate_port=faceplate_port if faceplate else None)

    done = asyncio.run(main())
    stats = done["stats"]
    typer.echo(("stopped: " + describe(stats) if stats else "stopped")
               + f"; checkpoint {done['checkpoint']}")
    if done.get("gave_up"):  # the controller kept dying: not a clean stop
        _fail("the controller process died too often (see the log above): gave up")


@app.command()
@_user_errors
def faceplate(
    opcua_url: Annotated[str, typer.Argument(
        help="the controller's OPC UA endpoint (loopworks serve)")] =
        "opc.tcp://127.0.0.1:4840/loopworks/",
    port: Annotated[int, typer.Option("--port", help="HTTP port of the faceplate")] = 8080,
    host: Annotated[str, typer.Option(
        "--host", help="address to serve on (127.0.0.1: this machine only)")] = "127.0.0.1",
) -> None:
    """The operator's faceplate in the browser for a running loopworks serve: an overview of
    every loop, a faceplate per loop (bars, mode, alarms, compensator, a live trend), and
    changes (SP, mode, OUT in MAN, tuning) made as the logged-in user's OPC UA writes."""
    import logging

    if not opcua_url.startswith("opc.tcp://"):
        _fail(f"OPCUA_URL {opcua_url!r}: expected opc.tcp://HOST:PORT/PATH")
    try:
        import socket

        socket.getaddrinfo(host, None)
    except OSError:
        _fail(f"--host {host}: not an address of this machine or a name that resolves")
    _check_port("--port", port, host)
    try:
        from loopworks.live.faceplate import run
    except ImportError as exc:
        _fail(f"the faceplate needs fastapi and uvicorn ({exc}); pip install loopworks")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logger = logging.getLogger("loopworks.faceplate")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)

    def ready(url: str) -> None:
        typer.echo(f"faceplate on {url} for {opcua_url}")
        sys.stdout.flush()

    try:
        run(opcua_url, host=host, port=port, ready=ready)
    except OSError as exc:
        _fail(str(exc))
    typer.echo("faceplate stopped")


def _announce(message: str) -> None:
    typer.echo(message, err=True)


def main() -> None:
    """Entry point of the ``loopworks`` console script. A compilation that the plan cache
    could not spare is announced on one line of stderr (blocks.plan)."""
    import warnings

    from loopworks.blocks import plan

    plan.announce = _announce
    # a warning is one line on stderr ("warning: ..."), not Python's file:line and source
    warnings.formatwarning = _warning_line
    try:
        app()  # typer's standalone mode ends in SystemExit
    except SystemExit as exc:
        _exit(exc.code)
    _exit(0)


def _exit(code: str | int | None) -> None:
    """End the process as ``sys.exit(code)`` would, without the interpreter's finalization
    when only this thread is left: the exit handlers run and the output is flushed, but the
    thousands of modules and objects numba, scipy and matplotlib loaded are not torn down
    one by one, which took 0.35-0.6 s of a 2.6 s ``loopworks simulate`` (2026-12-07: a run
    ended 2.07 s after its start and its process 0.63 s later, after the last exit
    handler). With another thread still running, the normal exit waits for it."""
    import atexit
    import threading

    if threading.active_count() > 1:
        sys.exit(code)
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:  # sys.exit("message"): the message on stderr, status 1
        print(code, file=sys.stderr)
        status = 1
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (loopworks ... | head): as CPython
            status = status or 120
    os._exit(status)


def _warning_line(message: Warning | str, category: type[Warning], filename: str,
                  lineno: int, line: str | None = None) -> str:
    """``warnings.formatwarning`` of the command line: ``warning: MESSAGE``, one line."""
    return f"warning: {str(message).removeprefix('loopworks: ')}\n"


if __name__ == "__main__":
    main()
