"""Historian replay: recorded inputs from a CSV file through one block, streamed in chunks.

Input CSV (architecture contract):

* a header row; columns named after the block's inputs, in any letter case;
* timing from a ``t`` column (s, increasing: the scan at row k has dt = t_k - t_{k-1}, and the
  first row takes t_1 - t_0), or a ``dt`` column (s, per row), or the ``dt`` argument;
* ``NAME.ST`` columns give an input's integer status byte (Good non-cascade, 128, when absent);
* a block with a ``clock`` input (a controller clock, s) gets the row's time there (the ``t``
  column, or the accumulated time) unless the file has a ``clock`` column;
* ``nan`` is a legal value (a missing measurement: the block handles it as its vendor does);
  an empty or non-numeric cell is an error naming its line and column.

Output CSV: ``t``, every output, then ``NAME.ST`` for outputs that carry status. With a ``t``
column the output repeats it; otherwise t_0 = 0 and t_k = t_{k-1} + dt_k.

Rows are read, run and written ``chunk`` rows at a time, so memory does not grow with the file.
"""

from __future__ import annotations

import csv
import math
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import run_rows
from loopworks.errors import FileFormatError, InputError


@dataclass
class ReplaySummary:
    """What a replay did: rows, the time span covered, and where the output went."""

    rows: int
    t_start: float
    t_end: float
    output: str


def _columns(block: Block, header: list[str], source: str) -> tuple[dict[int, tuple[str, int]],
                                                                    int | None, int | None]:
    """Map header positions to (what, index): ("u", i) input value, ("s", i) input status."""
    ins = {p.name: i for i, p in enumerate(block.INPUTS)}
    valid = ["t", "dt", *ins, *(f"{n}.ST" for n, i in ins.items() if block.INPUTS[i].status)]
    mapping: dict[int, tuple[str, int]] = {}
    t_col = dt_col = None
    seen: dict[str, int] = {}
    for pos, raw in enumerate(header):
        name = raw.strip()
        low = name.lower()
        if low in seen:
            raise FileFormatError(f"{source}, line 1: column '{name}' appears twice "
                                  f"(columns {seen[low] + 1} and {pos + 1})")
        seen[low] = pos
        if low == "t":
            t_col = pos
        elif low == "dt":
            dt_col = pos
        elif low in ins:
            mapping[pos] = ("u", ins[low])
        elif low.endswith(".st") and low[:-3] in ins and block.INPUTS[ins[low[:-3]]].status:
            mapping[pos] = ("s", ins[low[:-3]])
        else:
            raise FileFormatError(f"{source}, line 1: unknown column '{name}' for {block.kind}; "
                                  f"valid columns: {', '.join(valid)}"
                                  + _NOT_UTF8 * (_BAD_BYTE in name))
    return mapping, t_col, dt_col


def _cell_error(source: str, line: int, header: list[str], pos: int, cell: str,
                expected: str) -> FileFormatError:
    col = header[pos].strip() if pos < len(header) else f"#{pos + 1}"
    return FileFormatError(f"{source}, line {line}, column '{col}': {cell!r} is not {expected}"
                           + _NOT_UTF8 * (_BAD_BYTE in cell))


_BAD_BYTE = "\ufffd"  # what an undecodable byte reads as
_NOT_UTF8 = " (the file is not UTF-8 text: save it as UTF-8 CSV)"


def replay(block: Block, input_path: str | Path, output: str | Path | TextIO | None = None,
           dt: float | None = None, chunk: int = 65536,
           progress: Callable[[int], None] | None = None) -> ReplaySummary:
    """Run the rows of ``input_path`` through ``block`` and write the outputs as CSV.

    ``output`` is a path, an open text file, or None for standard output.
    """
    source = str(input_path)
    if dt is not None and not 0.0 < dt < math.inf:
        raise InputError(f"--dt = {dt!r} s is not allowed: dt must be > 0 and finite")
    try:
        # undecodable bytes become U+FFFD, so the cell holding them is the located error
        fh = open(input_path, newline="", encoding="utf-8-sig",  # noqa: SIM115 - closed below
                  errors="replace")
    except OSError as exc:
        raise FileFormatError(f"{source}: cannot read the input: {exc.strerror}") from None
    with fh:
        reader = _Rows(csv.reader(fh), source)
        header = next(reader, None)
        while header is not None and not any(c.strip() for c in header):
            header = next(reader, None)
        if header is None:
            raise FileFormatError(f"{source}: the file is empty: expected a header row naming "
                                  f"the inputs of {block.kind} ({', '.join(block._in_index)})")
        mapping, t_col, dt_col = _columns(block, header, source)
        clock = block._in_index.get("clock")
        if clock is not None and ("u", clock) in mapping.values():
            clock = None  # the file gives the clock itself
        timing = sum(x is not None for x in (t_col, dt_col, dt))
        if timing == 0:
            raise FileFormatError(f"{source}: no timing: give a 't' column (s), a 'dt' column "
                                  "(s) or --dt")
        if timing > 1:
            raise FileFormatError(f"{source}: timing given twice: use one of a 't' column, a "
                                  "'dt' column and --dt")
        block._release_last()
        chunks = _chunks(reader, max(chunk, 2))  # the first scan's dt needs the second row
        first_chunk = next(chunks, None)
        if first_chunk is None:
            raise FileFormatError(f"{source}: no data rows after the header")
        with _open_output(output) as out_fh:
            writer = csv.writer(out_fh, lineterminator="\n")
            st_out = [p for p in block.OUTPUTS if p.status]
            writer.writerow(["t", *(p.name for p in block.OUTPUTS),
                             *(f"{p.name}.ST" for p in st_out)])
            st_idx = [block._out_index[p.name] for p in st_out]
            rows = 0
            t_first = t_last = math.nan
            prev_t: float | None = None
            t_clock = 0.0
            for numbered in _prepend(first_chunk, chunks):
                n = len(numbered)
                U = np.empty((n, len(block.INPUTS)))
                US = np.empty((n, len(block.INPUTS)), dtype=np.int64)
                dts = np.empty(n)
                ts = np.empty(n)
                u_now = block.u.copy()
                us_now = block.us.copy()
                for r, (line, row) in enumerate(numbered):
                    if len(row) != len(header):
                        raise FileFormatError(
                            f"{source}, line {line}: {len(row)} cells, expected {len(header)} "
                            f"(one per header column)")
                    for pos, (what, i) in mapping.items():
                        cell = row[pos]
                        if what == "u":
                            try:
                                u_now[i] = block.INPUTS[i].parse(cell)
                            except ValueError:
                                exp = "a number"
                                if block.INPUTS[i].choices:
                                    exp += " or one of " + ", ".join(block.INPUTS[i].choices)
                                raise _cell_error(source, line, header, pos, cell, exp) from None
                        else:
                            try:
                                v = int(cell)
                            except ValueError:
                                v = -1
                            if not 0 <= v <= 255:
                                raise _cell_error(source, line, header, pos, cell,
                                                  "a status byte (integer 0..255)")
                            us_now[i] = v
                    U[r] = u_now
                    US[r] = us_now
                    if t_col is not None:
                        tv = _number(row[t_col], source, line, header, t_col)
                        if prev_t is not None and not tv > prev_t:
                            raise FileFormatError(f"{source}, line {line}: t = {tv:g} s does not "
                                                  f"increase (previous row t = {prev_t:g} s)")
                        ts[r] = tv
                        dts[r] = tv - prev_t if prev_t is not None else math.nan
                        prev_t = tv
                    else:
                        if dt_col is not None:
                            step = _number(row[dt_col], source, line, header, dt_col)
                            if not step > 0.0:
                                raise FileFormatError(f"{source}, line {line}: dt = {step:g} s "
                                                      "is not allowed: dt must be > 0")
                        else:
                            step = float(dt or 0.0)
                        t_clock = t_clock + step if rows + r > 0 else 0.0
                        if not math.isfinite(t_clock):
                            raise FileFormatError(f"{source}, line {line}: the accumulated time "
                                                  "overflows: the dt values are too large")
                        ts[r] = t_clock
                        dts[r] = step
                if clock is not None:
                    U[:, clock] = ts
                if rows == 0 and math.isnan(dts[0]):
                    if n < 2:
                        raise FileFormatError(f"{source}: a single row with a 't' column gives "
                                              "no scan time: add rows, or use a 'dt' column")
                    dts[0] = dts[1]
                for step in np.unique(dts):
                    block.check_dt(float(step))
                Y = np.empty((n, len(block.OUTPUTS)))
                YS = np.empty((n, len(block.OUTPUTS)), dtype=np.int64)
                Y[0] = block.y
                YS[0] = block.ys
                run_rows(type(block).kernel, dts, block.p, block.x, U, US, Y, YS, jit=block.jit)
                block.u[:] = U[-1]
                block.us[:] = US[-1]
                block._all_good = bool((block.us == 128).all())
                block.y[:] = Y[-1]
                block.ys[:] = YS[-1]
                if rows == 0:
                    t_first = float(ts[0])
                t_last = float(ts[-1])
                rows += n
                body = np.concatenate([ts[:, None], Y], axis=1).tolist()
                stats = YS[:, st_idx].tolist()
                writer.writerows(b + s for b, s in zip(body, stats, strict=True))
                if progress is not None:
                    progress(rows)
    name = output if isinstance(output, str | Path) else "<stdout>"
    return ReplaySummary(rows, t_first, t_last, str(name))


def _number(cell: str, source: str, line: int, header: list[str], pos: int) -> float:
    try:
        v = float(cell)
    except ValueError:
        raise _cell_error(source, line, header, pos, cell, "a number") from None
    if not math.isfinite(v):
        raise _cell_error(source, line, header, pos, cell, "a finite number")
    return v


class _Rows:
    """A csv reader whose malformed rows (an oversized field) are located FileFormatErrors."""

    def __init__(self, reader: Any, source: str) -> None:
        self.reader = reader
        self.source = source

    @property
    def line_num(self) -> int:
        return int(self.reader.line_num)

    def __iter__(self) -> _Rows:
        return self

    def __next__(self) -> list[str]:
        try:
            return list(next(self.reader))
        except csv.Error as exc:
            raise FileFormatError(f"{self.source}, line {self.line_num}: {exc}") from None


def _chunks(reader: Any, size: int) -> Iterator[list[tuple[int, list[str]]]]:
    """Non-blank rows in lists of ``size``, each with its line number in the file."""
    rows: list[tuple[int, list[str]]] = []
    for row in reader:
        if not row or not any(c.strip() for c in row):
            continue
        rows.append((reader.line_num, row))
        if len(rows) >= size:
            yield rows
            rows = []
    if rows:
        yield rows


def _prepend(first: list[tuple[int, list[str]]],
             rest: Iterator[list[tuple[int, list[str]]]]) -> Iterator[list[tuple[int, list[str]]]]:
    yield first
    yield from rest


def target_of(output: Any) -> Path:
    return Path(output)


class _open_output:
    """Context manager: a path is opened for writing; a file object or stdout is borrowed."""

    def __init__(self, output: str | Path | TextIO | None) -> None:
        self.output = output
        self.fh: TextIO | None = None
        self.partial: Path | None = None

    def __enter__(self) -> TextIO:
        if self.output is None:
            return sys.stdout
        if not isinstance(self.output, str | Path):
            return self.output
        target = Path(self.output)
        if target.is_dir():
            raise FileFormatError(f"{self.output}: is a directory: give the output CSV file's "
                                  "name")
        self.partial = target.with_name(target.name + ".partial")
        try:
            self.fh = open(self.partial, "w", newline="", encoding="utf-8")
        except OSError as exc:
            raise FileFormatError(f"{self.output}: cannot write the output: {exc.strerror}") \
                from None
        return self.fh

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        """A path output appears only when the whole replay succeeded."""
        if self.fh is None or self.partial is None:
            return
        self.fh.close()
        if exc_type is None:
            try:
                self.partial.replace(target_of(self.output))
            except OSError as exc:
                self.partial.unlink(missing_ok=True)
                raise FileFormatError(f"{self.output}: cannot write the output: "
                                      f"{exc.strerror}") from None
        else:
            self.partial.unlink(missing_ok=True)
