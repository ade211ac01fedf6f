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
column the output repeats it; otherwise t_0 = 0 and t_k = t_{k-1} + dt_k. Floats are written as
Python's ``repr`` writes them: the shortest text that reads back as the same double.

Rows are read, run and written ``chunk`` rows at a time, so memory does not grow with the file.

Two readers, one result. A file of at least :data:`BULK_MIN_BYTES` is read in bulk: its lines
are cut into pieces of ``chunk`` rows (where the row-by-row reader cuts its chunks), pyarrow
converts a piece's columns at once, and the rows are written by the compiled formatter of
:mod:`loopworks.sim.floatfmt` (the same text as ``csv.writer``). Any piece that does not convert
cleanly (a malformed cell, a non-increasing ``t``, a bad status byte, quoting or line breaks the
bulk reader might read differently: see :mod:`loopworks.sim.bulkcsv`) is parsed again, row by
row, by the csv module, which is the reference and gives the located error. Reading the next
chunk, running this one and writing the last overlap on two cores (:mod:`loopworks.sim.overlap`).
Small files go through the csv module only, which starts faster.
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
import math
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Literal, TextIO, cast

import numpy as np

from loopworks.blocks.block import Block
from loopworks.blocks.kernel import FloatArray, IntArray, jit_enabled, run_rows
from loopworks.errors import FileFormatError, InputError, LoopworksError

#: Files of at least this many bytes are read in bulk and written by the compiled formatter.
BULK_MIN_BYTES = 1 << 16
#: In bulk, read the next chunk and write the last in worker threads while one runs.
OVERLAP = True
#: a replay of fewer rows (in one chunk) runs interpreted: at ~10-60 us a row that is less than
#: the ~1 s numba needs to start before it can load any compiled code
INTERPRET_BELOW_ROWS = 5_000
_HEAD_BYTES = 1 << 20  # for the bulk reader, the header must end within the first MiB
_HEAD_READ = 1 << 16  # read so much of it at first


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
        if "\n" in name or "\r" in name:  # a quote opened in the header and never closed
            start = name.splitlines()[0] if name.splitlines() else ""
            raise FileFormatError(f"{source}, line 1: column {pos + 1} ('{start}...') opens a "
                                  "quote (\") that the header line does not close: expected a "
                                  "header of column names on one line")
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
    valued = {i for what, i in mapping.values() if what == "u"}
    for pos, (what, i) in mapping.items():
        if what == "s" and i not in valued:  # the block would run on a value never given
            name = block.INPUTS[i].name
            raise FileFormatError(f"{source}, line 1: column '{header[pos].strip()}' is the "
                                  f"status of input '{name}', and the file has no column "
                                  f"'{name}' for its value: give both")
    return mapping, t_col, dt_col


def _cell_error(source: str, line: int, header: list[str], pos: int, cell: str,
                expected: str) -> FileFormatError:
    col = header[pos].strip() if pos < len(header) else f"#{pos + 1}"
    return FileFormatError(f"{source}, line {line}, column '{col}': {cell!r} is not {expected}"
                           + _NOT_UTF8 * (_BAD_BYTE in cell))


_BAD_BYTE = "\ufffd"  # what an undecodable byte reads as
_NOT_UTF8 = " (the file is not UTF-8 text: save it as UTF-8 CSV)"


@dataclass
class _Layout:
    """What the header says: the file, its columns, and where the timing comes from."""

    source: str
    header: list[str]
    mapping: dict[int, tuple[str, int]]
    t_col: int | None
    dt_col: int | None
    dt: float | None


@dataclass
class _Clock:
    """The timing carried from one parsed chunk to the next."""

    rows: int = 0
    prev_t: float | None = None
    t_clock: float = 0.0


@dataclass
class _Chunk:
    """Parsed rows: the file's values by input index, its status bytes by input index, and
    each row's time and scan time (NaN for the very first row of a ``t`` column)."""

    values: dict[int, FloatArray]
    stats: dict[int, IntArray]
    ts: FloatArray
    dts: FloatArray

    @property
    def n(self) -> int:
        """The number of rows."""
        return len(self.ts)


@dataclass
class _Start:
    """Where the bulk reader starts: the header, and the first data line at byte ``offset``
    (``buf`` holds the bytes from there already read)."""

    header: list[str]
    line: int
    offset: int
    buf: bytes


def replay(block: Block, input_path: str | Path, output: str | Path | TextIO | None = None,
           dt: float | None = None, chunk: int = 65536,
           progress: Callable[[int], None] | None = None) -> ReplaySummary:
    """Run the rows of ``input_path`` through ``block`` and write the outputs as CSV.

    ``input_path`` ``"-"`` is standard input. ``output`` is a path, an open text file, or
    None for standard output.
    """
    source = "<stdin>" if str(input_path) == "-" else str(input_path)
    if dt is not None and not 0.0 < dt < math.inf:
        raise InputError(f"--dt = {dt!r} s is not allowed: dt must be > 0 and finite")
    with _open_input(input_path, source) as raw:
        header, start, reader = _read_header(raw, source)
        if header is None:
            raise FileFormatError(f"{source}: the file is empty: expected a header row naming "
                                  f"the inputs of {block.kind} ({', '.join(block._in_index)})")
        lay, clock = _layout(block, header, source, dt)
        size = max(chunk, 2)  # the first scan's dt needs the second row
        if reader is not None:
            chunks = _first_two_rows(_slow_chunks(reader, lay, _Clock(), block, size))
            return _replay_chunks(block, chunks, lay, clock, output, progress, size, bulk=False)
        assert start is not None
        chunks = _first_two_rows(_bulk_chunks(raw, start, lay, block, size))
        if not OVERLAP:
            return _replay_chunks(block, chunks, lay, clock, output, progress, size, bulk=True)
        from loopworks.sim.overlap import Ahead

        ahead = Ahead(chunks)
        try:
            return _replay_chunks(block, ahead, lay, clock, output, progress, size, bulk=True)
        finally:
            ahead.close()  # before the input closes


def _open_input(input_path: str | Path, source: str) -> BinaryIO:
    """The input file, opened for reading bytes; a pipe (``/dev/stdin``, a FIFO), which the
    reader cannot rewind, is read into memory first."""
    if str(input_path) == "-":  # standard input: read whole, as any pipe
        return io.BytesIO(sys.stdin.buffer.read())
    try:
        fh = open(input_path, "rb")  # noqa: SIM115 - the caller closes it
        if fh.seekable():
            return fh
        with fh:
            return io.BytesIO(fh.read())
    except OSError as exc:
        raise FileFormatError(f"{source}: cannot read the input: {exc.strerror}") from None


def _read_header(raw: BinaryIO, source: str) -> tuple[list[str] | None, _Start | None,
                                                      _Rows | None]:
    """The header row (None in an empty file), and how to read on: from the bulk reader's
    start, or from the csv module's reader over the whole file."""
    start = _bulk_start(raw, source)
    if start is not None:
        return start.header, start, None
    raw.seek(0)
    # undecodable bytes become U+FFFD, so the cell holding them is the located error
    reader = _Rows(csv.reader(_text(raw, "utf-8-sig")), source)
    return _header(reader), None, reader


def _layout(block: Block, header: list[str], source: str,
            dt: float | None) -> tuple[_Layout, int | None]:
    """What the header says, checked: its columns and the timing; and the block's clock
    input when the replay feeds it the row's time (the file has no clock column)."""
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
    return _Layout(source, header, mapping, t_col, dt_col, dt), clock


def _replay_chunks(block: Block, chunks: Iterator[_Chunk], lay: _Layout, clock: int | None,
                   output: str | Path | TextIO | None, progress: Callable[[int], None] | None,
                   chunk_rows: int, bulk: bool) -> ReplaySummary:
    """Run the parsed chunks through ``block`` and write the outputs (``bulk``: compiled
    formatting, written behind in a worker thread)."""
    first_chunk = next(chunks, None)
    if first_chunk is None:
        raise FileFormatError(f"{lay.source}: no data rows after the header")
    opener = _open_output(output)
    with opener as out_fh:
        sink = _Sink(out_fh, _binary_under(out_fh, opener, output), bulk)
        try:
            st_out = [p for p in block.OUTPUTS if p.status]
            st_idx = [block._out_index[p.name] for p in st_out]
            rows = 0
            t_first = t_last = math.nan
            # a replay that fits in one chunk of fewer than INTERPRET_BELOW_ROWS rows runs
            # interpreted: loading compiled code (numba's start-up) would cost more than it saves
            jit = block.jit and not (first_chunk.n < INTERPRET_BELOW_ROWS
                                     and _is_last(first_chunk, chunk_rows))
            parts = itertools.chain([first_chunk], chunks)
            while True:
                try:
                    part = next(parts, None)
                    if part is None:
                        break
                    Y, YS = _run(block, part, clock, lay.source, first=rows == 0, jit=jit,
                                 row0=rows)
                except LoopworksError as exc:
                    if rows and output is None:  # a stream cannot be taken back: say so
                        raise type(exc)(f"{exc} ({rows} rows were already written to "
                                        "standard output: that output is incomplete)"
                                        ) from None
                    raise
                if rows == 0:  # the header once the first rows ran: an error before them
                    # leaves the output empty
                    sink.header(["t", *(p.name for p in block.OUTPUTS),
                                 *(f"{p.name}.ST" for p in st_out)])
                    t_first = float(part.ts[0])
                t_last = float(part.ts[-1])
                rows += part.n
                sink.rows(part.ts, Y, YS[:, st_idx])
                if progress is not None:
                    progress(rows)
            sink.finish()
        finally:
            sink.close()
    name = output if isinstance(output, str | Path) else "<stdout>"
    return ReplaySummary(rows, t_first, t_last, str(name))


def _is_last(part: _Chunk, chunk_rows: int) -> bool:
    """True when ``part`` is the whole file: the readers fill every chunk but the last."""
    return part.n < chunk_rows


def _run(block: Block, part: _Chunk, clock: int | None, source: str,
         first: bool, jit: bool, row0: int = 0) -> tuple[FloatArray, IntArray]:
    """Run one chunk of rows through ``block`` (compiled when ``jit``); its outputs, row by
    row. ``row0``: the data rows before the chunk (a scan time the block cannot run at is
    named by its data row and time)."""
    n = part.n
    U, US = _inputs(block, part, clock)
    dts = part.dts
    if first and math.isnan(dts[0]):
        if n < 2:
            raise FileFormatError(f"{source}: a single row with a 't' column gives "
                                  "no scan time: add rows, or use a 'dt' column")
        dts[0] = dts[1]
    if (dts == dts[0]).all():
        firsts = np.zeros(1, dtype=np.int64)
    else:  # each scan time once, in the order the file first runs it
        firsts = np.sort(np.unique(dts, return_index=True)[1])
    for i in firsts:
        try:
            block.check_dt(float(dts[i]))
        except LoopworksError as exc:  # located: the file's first row it refuses
            raise FileFormatError(f"{source}, data row {row0 + i + 1} (t = {part.ts[i]:.15g} "
                                  f"s, a scan of {dts[i]:.6g} s): {exc}") from None
    Y = np.empty((n, len(block.OUTPUTS)))
    YS = np.empty((n, len(block.OUTPUTS)), dtype=np.int64)
    Y[0] = block.y
    YS[0] = block.ys
    run_rows(type(block).kernel, dts, block.p, block.x, U, US, Y, YS, jit=jit,
             full=not block.SOUND_KERNEL)
    block.u[:] = U[-1]
    block.us[:] = US[-1]
    block._all_good = bool((block.us == 128).all())
    block.y[:] = Y[-1]
    block.ys[:] = YS[-1]
    return Y, YS


def _inputs(block: Block, part: _Chunk, clock: int | None) -> tuple[FloatArray, IntArray]:
    """The kernel's input rows: the file's columns, the block's latched inputs elsewhere, and
    the row's time on the clock input when the file has no clock column."""
    n = part.n
    U = np.empty((n, len(block.INPUTS)))
    US = np.empty((n, len(block.INPUTS)), dtype=np.int64)
    U[:] = block.u
    US[:] = block.us
    for i, values in part.values.items():
        U[:, i] = values
    for i, stats in part.stats.items():
        US[:, i] = stats
    if clock is not None:
        U[:, clock] = part.ts
    return U, US


def _text(raw: BinaryIO, encoding: str) -> TextIO:
    """``raw`` from where it stands as text, read as the csv module needs it."""
    return io.TextIOWrapper(raw, encoding=encoding, errors="replace", newline="")


def _header(reader: _Rows) -> list[str] | None:
    """The first row with a non-blank cell, or None if there is none."""
    header = next(reader, None)
    while header is not None and not any(c.strip() for c in header):
        header = next(reader, None)
    return header


# -- the csv module: the reference reader ------------------------------------------------------


def _slow_chunks(reader: _Rows, lay: _Layout, clock: _Clock, block: Block,
                 size: int) -> Iterator[_Chunk]:
    """The rows of ``reader``, parsed ``size`` rows at a time."""
    for numbered in _chunks(reader, size):
        yield _parse_rows(numbered, lay, clock, block)


def _parse_rows(numbered: list[tuple[int, list[str]]], lay: _Layout, clock: _Clock,
                block: Block) -> _Chunk:
    """Parse rows cell by cell; a malformed cell or timing is a located FileFormatError."""
    source, header = lay.source, lay.header
    n = len(numbered)
    values = {i: np.empty(n) for what, i in lay.mapping.values() if what == "u"}
    stats = {i: np.empty(n, dtype=np.int64) for what, i in lay.mapping.values() if what == "s"}
    dts = np.empty(n)
    ts = np.empty(n)
    for r, (line, row) in enumerate(numbered):
        if len(row) != len(header):
            opened = next((pos for pos, cell in enumerate(row) if "\n" in cell or "\r" in cell),
                          None)
            if opened is not None:  # a quote that never closed ran on over the lines after
                cell = row[opened]  # it holds every line end from its line on
                start = line - cell.count("\n") + cell.endswith(("\n", "\r"))
                col = header[opened].strip() if opened < len(header) else f"#{opened + 1}"
                raise FileFormatError(f"{source}, line {start}, column '{col}': a quote (\") "
                                      f"opens there and is never closed (the cell runs on to "
                                      f"line {line}): expected one value per cell")
            raise FileFormatError(f"{source}, line {line}: {len(row)} cells, expected "
                                  f"{len(header)} (one per header column)")
        for pos, (what, i) in lay.mapping.items():
            cell = row[pos]
            if what == "u":
                try:
                    values[i][r] = block.INPUTS[i].parse(cell)
                except ValueError:
                    raise _cell_error(source, line, header, pos, cell,
                                      block.INPUTS[i].expected) from None
            else:
                try:
                    stats[i][r] = _status_byte(cell)
                except ValueError:
                    raise _cell_error(source, line, header, pos, cell,
                                      "a status byte (integer 0..255)") from None
        if lay.t_col is not None:
            tv = _number(row[lay.t_col], source, line, header, lay.t_col)
            prev_t = clock.prev_t
            if prev_t is not None and not tv > prev_t:
                raise FileFormatError(f"{source}, line {line}: t = {tv:g} s does not "
                                      f"increase (previous row t = {prev_t:g} s)")
            ts[r] = tv
            dts[r] = tv - prev_t if prev_t is not None else math.nan
            clock.prev_t = tv
        else:
            if lay.dt_col is not None:
                step = _number(row[lay.dt_col], source, line, header, lay.dt_col)
                if not step > 0.0:
                    raise FileFormatError(f"{source}, line {line}: dt = {step:g} s "
                                          "is not allowed: dt must be > 0")
            else:
                step = float(lay.dt or 0.0)
            if lay.dt_col is None:  # --dt: row k at k·dt, as a module's scans (no drift)
                clock.t_clock = (clock.rows + r) * step
            else:
                clock.t_clock = clock.t_clock + step if clock.rows + r > 0 else 0.0
            if not math.isfinite(clock.t_clock):
                raise FileFormatError(f"{source}, line {line}: the accumulated time "
                                      "overflows: the dt values are too large")
            ts[r] = clock.t_clock
            dts[r] = step
    clock.rows += n
    return _Chunk(values, stats, ts, dts)


def _status_byte(cell: str) -> int:
    """A status byte cell as an int; ValueError unless it is an integer 0..255."""
    try:
        v = int(cell)
    except ValueError:
        v = -1
    if not 0 <= v <= 255:
        raise ValueError(cell)
    return v


def _number(cell: str, source: str, line: int, header: list[str], pos: int) -> float:
    try:
        v = float(cell)
    except ValueError:
        raise _cell_error(source, line, header, pos, cell, "a number") from None
    if not math.isfinite(v):
        raise _cell_error(source, line, header, pos, cell, "a finite number")
    return v


class _Rows:
    """A csv reader whose malformed rows (an oversized field) are located FileFormatErrors;
    ``offset`` lines precede what it reads."""

    def __init__(self, reader: Any, source: str, offset: int = 0) -> None:
        self.reader = reader
        self.source = source
        self.offset = offset

    @property
    def line_num(self) -> int:
        return self.offset + int(self.reader.line_num)

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


def _first_two_rows(chunks: Iterable[_Chunk]) -> Iterator[_Chunk]:
    """The chunks, the first one joined with the next while it has fewer than two rows (the
    first scan's dt may need the second row)."""
    it = iter(chunks)
    first = next(it, None)
    if first is None:
        return
    while first.n < 2:
        more = next(it, None)
        if more is None:
            break
        first = _Chunk({i: np.concatenate((v, more.values[i])) for i, v in first.values.items()},
                       {i: np.concatenate((v, more.stats[i])) for i, v in first.stats.items()},
                       np.concatenate((first.ts, more.ts)), np.concatenate((first.dts, more.dts)))
    yield first
    yield from it


# -- the bulk reader ---------------------------------------------------------------------------


def _bulk_start(raw: BinaryIO, source: str) -> _Start | None:
    """The header read from the head of a large regular file, and where its data starts; None
    for the csv module to read the whole file (small, not a regular file, or a header that
    does not end within the first MiB or has a lone carriage return)."""
    try:
        size = os.fstat(raw.fileno()).st_size
    except (OSError, ValueError):
        return None
    if size < BULK_MIN_BYTES:
        return None
    head = b""
    while len(head) < _HEAD_BYTES:
        more = raw.read(max(_HEAD_READ, len(head)))
        head += more
        start = _header_in(head, not more, source)
        if start is not False:
            return start
        if not more:
            return None
    return None


def _header_in(head: bytes, eof: bool, source: str) -> _Start | Literal[False] | None:
    """The header in the first bytes of the file and where the data starts; False if the
    header may go on past ``head``; None for the csv module to read the whole file."""
    if head.count(b"\r") != head.count(b"\r\n"):
        return None
    cut = len(head) if eof else head.rfind(b"\n") + 1
    lines = np.flatnonzero(np.frombuffer(head, dtype=np.uint8, count=cut) == 10)
    reader = _Rows(csv.reader(io.StringIO(head[:cut].decode("utf-8-sig", errors="replace"),
                                          newline="")), source)
    try:
        header = _header(reader)
    except FileFormatError:
        return None  # the csv module reads the file again and says so
    used = reader.line_num
    if not eof and (header is None or used >= len(lines)):
        return False
    if header is None:
        return None
    offset = int(lines[used - 1]) + 1 if used <= len(lines) else cut
    return _Start(header, used + 1, offset, head[offset:])


def _bulk_chunks(raw: BinaryIO, start: _Start, lay: _Layout, block: Block,
                 size: int) -> Iterator[_Chunk]:
    """The data rows after the header, ``size`` lines a piece: converted in bulk where the
    piece is clean, else parsed by the csv module (which then names the bad cell)."""
    from loopworks.sim import bulkcsv

    clock = _Clock()
    text = {pos for pos, (what, i) in lay.mapping.items()
            if what == "s" or block.INPUTS[i].choices}
    for piece in bulkcsv.pieces(raw, start.buf, start.offset, start.line, size):
        if isinstance(piece, bulkcsv.Rest):
            raw.seek(piece.offset)
            reader = _Rows(csv.reader(_text(raw, "utf-8")), lay.source, piece.line - 1)
            yield from _slow_chunks(reader, lay, clock, block, size)
            return
        part = None
        if piece.fast:
            table = bulkcsv.read_columns(piece.data, len(lay.header), text)
            if table is not None:
                part = _bulk_parse(*table, lay, clock, block)
        if part is None:
            lines = io.StringIO(piece.data.decode("utf-8", errors="replace"), newline="")
            reader = _Rows(csv.reader(lines), lay.source, piece.line - 1)
            yield from _slow_chunks(reader, lay, clock, block, size)
        elif part.n:
            yield part


def _bulk_parse(n: int, columns: list[Any], lay: _Layout, clock: _Clock,
                block: Block) -> _Chunk | None:
    """A piece's converted columns as parsed rows; None (``clock`` untouched) if a cell or the
    timing is not what the csv module would accept as it stands."""
    values: dict[int, FloatArray] = {}
    stats: dict[int, IntArray] = {}
    for pos, (what, i) in lay.mapping.items():
        column = columns[pos]
        if what == "s":
            status = _lookup(column, _status_byte, np.int64)
            if status is None:
                return None
            stats[i] = status
        elif isinstance(column, tuple):  # an enumerated input: names or codes
            value = _lookup(column, block.INPUTS[i].parse, np.float64)
            if value is None:
                return None
            values[i] = value
        else:
            values[i] = column
    times = _bulk_times(n, columns, lay, clock)
    if times is None:
        return None
    ts, dts = times
    if n:
        clock.rows += n
        if lay.t_col is not None:
            clock.prev_t = float(ts[-1])
        else:
            clock.t_clock = float(ts[-1])
    return _Chunk(values, stats, ts, dts)


def _lookup(column: tuple[list[str], Any], convert: Callable[[str], float],
            dtype: Any) -> Any:
    """A text column converted cell by distinct cell; None if one does not convert."""
    cells, codes = column
    try:
        table = np.array([convert(cell) for cell in cells], dtype=dtype)
    except ValueError:
        return None
    return table[codes]


def _bulk_times(n: int, columns: list[Any], lay: _Layout,
                clock: _Clock) -> tuple[FloatArray, FloatArray] | None:
    """Each row's time and scan time, as :func:`_parse_rows` computes them; None if a time
    is not finite or does not increase, or a dt is not finite and > 0."""
    if n == 0:
        return np.empty(0), np.empty(0)
    if lay.t_col is not None:
        t = columns[lay.t_col]
        prev = clock.prev_t
        if (not np.isfinite(t).all() or not (t[1:] > t[:-1]).all()
                or (prev is not None and not t[0] > prev)):
            return None
        dts = np.empty(n)
        with np.errstate(over="ignore"):  # as Python's float arithmetic: inf, no warning
            dts[1:] = t[1:] - t[:-1]
        dts[0] = float(t[0]) - prev if prev is not None else math.nan
        return t, dts
    if lay.dt_col is not None:
        steps = columns[lay.dt_col]
        if not (np.isfinite(steps) & (steps > 0.0)).all():
            return None
    else:  # --dt: row k at k·dt, as a module's scans (a running sum drifts: 0.7999999999999999)
        steps = np.full(n, float(lay.dt or 0.0))
        with np.errstate(over="ignore"):
            ts = (clock.rows + np.arange(n)) * steps
        return (ts, steps) if np.isfinite(ts).all() else None
    acc = steps.copy()
    acc[0] = clock.t_clock + float(steps[0]) if clock.rows > 0 else 0.0
    with np.errstate(over="ignore"):
        ts = np.add.accumulate(acc)  # in order, as the row-by-row sum
    if not np.isfinite(ts).all():
        return None
    return ts, steps


# -- output --------------------------------------------------------------------------------------


class _Sink:
    """The output CSV. Rows go through ``csv.writer``, or in bulk through the compiled
    formatter (the same text), written behind in a worker thread and, where there is one,
    straight into the binary file under the text file."""

    def __init__(self, fh: TextIO, binary: BinaryIO | None, bulk: bool) -> None:
        self.fh = fh
        self.binary = binary
        self.writer = csv.writer(fh, lineterminator="\n")
        self.formatted = bulk and jit_enabled()
        self.behind: Any = None
        if bulk and OVERLAP:
            from loopworks.sim.overlap import WriteBehind

            self.behind = WriteBehind()

    def header(self, names: list[str]) -> None:
        """Write the header row."""
        self.writer.writerow(names)

    def rows(self, ts: FloatArray, Y: FloatArray, stats: IntArray) -> None:
        """Write the rows ``t, *Y[r], *stats[r]`` (behind, in bulk)."""
        if self.behind is not None:
            self.behind.submit(self._write, ts, Y, stats)
        else:
            self._write(ts, Y, stats)

    def finish(self) -> None:
        """Wait for the rows written behind; raise a writer's error."""
        if self.behind is not None:
            self.behind.finish()

    def close(self) -> None:
        """Stop the writer thread (after :meth:`finish`, or while an error is raised)."""
        if self.behind is not None:
            self.behind.close()

    def _write(self, ts: FloatArray, Y: FloatArray, stats: IntArray) -> None:
        """Format and write rows now (in the writer thread, in bulk)."""
        if not self.formatted:
            body = np.concatenate([ts[:, None], Y], axis=1).tolist()
            self.writer.writerows(b + s for b, s in zip(body, stats.tolist(), strict=True))
            return
        from loopworks.sim.floatfmt import format_rows

        text = format_rows(ts, Y, stats)
        if self.binary is not None:
            self.fh.flush()
            self.binary.write(text.data)
        else:
            self.fh.write(text.tobytes().decode("ascii"))


def _binary_under(fh: TextIO, opener: _open_output, output: object) -> BinaryIO | None:
    """The binary file under ``fh`` when ASCII bytes written there read as the same text:
    the output file replay opened itself, or standard output in UTF-8 where a line ends in
    ``\\n``. None for a text file the caller gave (it may translate line ends)."""
    if fh is opener.fh:
        return opener.fh.buffer
    if output is None and os.linesep == "\n" and isinstance(fh, io.TextIOWrapper):
        try:
            name = codecs.lookup(fh.encoding).name
        except LookupError:
            return None
        if name in ("utf-8", "ascii"):
            return cast(BinaryIO, fh.buffer)
    return None


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
