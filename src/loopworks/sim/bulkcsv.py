"""Bulk reading of a replay CSV's data rows: whole lines cut into pieces, a piece's columns
converted at once by pyarrow.

The csv module stays the reference reader: a piece is marked ``fast`` only where pyarrow reads
it exactly as ``csv.reader`` would, and any other piece is parsed with the csv module, so the
result, and every error and its line number, is the same either way. A piece is fast when

* it has no lone carriage return (a line break the csv module counts and pyarrow may not);
* its quoting is well formed (a quote opens a field and closes it) with no line break inside
  quotes;
* no line is longer than the csv module's field limit (it refuses such a field);
* it has no ``(``: pyarrow's float parser takes ``nan(...)``, Python's ``float`` does not.

Where a piece cannot even be cut safely (lone carriage returns, malformed quoting, quoted line
breaks), :class:`Rest` hands the rest of the file, from a known line and byte, to the csv
module. A piece ends where the csv module's reader ends a chunk of ``rows`` rows (blank lines
are no rows), so both readers cut the file alike; memory stays bounded by about one piece.

This module imports pyarrow; :mod:`loopworks.sim.replay` imports it only for large files.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, BinaryIO

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.csv as pacsv

MIN_READ = 1 << 12  # bytes read from the file at least at a time
MAX_PIECE = 1 << 27  # a piece's bytes at most, however many rows fit
_QUOTE, _COMMA, _LF, _CR = 34, 44, 10, 13


@dataclass
class Piece:
    """Whole lines of the file: ``data`` starts at line ``line``; ``fast`` if pyarrow reads it
    as the csv module would."""

    line: int
    data: bytes
    fast: bool


@dataclass
class Rest:
    """The rest of the file, from line ``line`` at byte ``offset``, for the csv module."""

    line: int
    offset: int


def pieces(raw: BinaryIO, buf: bytes, offset: int, line: int,
           rows: int) -> Iterator[Piece | Rest]:
    """The file's lines from byte ``offset`` (line ``line``), cut after every ``rows``
    non-blank lines: where the csv module's reader cuts its chunks of ``rows`` rows.

    ``buf`` holds the bytes from ``offset`` already read; ``raw`` is positioned after them.
    The buffer holds about one piece: it is refilled when it holds fewer than ``rows`` rows.
    """
    eof = False
    ends, solid = _lines(buf, eof)
    while True:
        have = int(solid[-1]) if len(solid) else 0
        if have < rows and not eof and len(buf) < MAX_PIECE:
            per_row = len(buf) / have if have else 64.0
            more = raw.read(max(MIN_READ, int(1.1 * per_row * (rows - have))))
            eof = not more
            buf += more
            ends, solid = _lines(buf, eof)
            continue
        if len(ends) == 0:  # nothing left, or a line longer than any field may be
            if buf:
                yield Rest(line, offset)
            return
        take = min(int(np.searchsorted(solid, rows)), len(ends) - 1)  # the piece's last line
        cut = int(ends[take])
        data = buf[:cut]
        feeds = ends[:take + 1] - 1
        verdict = _verdict(data, feeds if data.endswith(b"\n") else feeds[:-1])
        if verdict is None:
            yield Rest(line, offset)
            return
        yield Piece(line, data, verdict)
        line += take + 1
        offset += cut
        buf = buf[cut:]
        ends, solid = ends[take + 1:] - cut, solid[take + 1:] - solid[take]


#: bytes that make the cell holding them non-blank (not whitespace, not a comma or a quote)
_SURE = np.zeros(256, dtype=bool)
_SURE[[*range(0x00, 0x09), *range(0x0E, 0x1C), *range(0x21, 0x80)]] = True
_SURE[[_COMMA, _QUOTE]] = False


def _lines(buf: bytes, eof: bool) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Where each complete line of ``buf`` ends (after its line feed; at EOF the last line
    needs none), and how many of the lines up to each are not blank (``csv.reader`` gives a
    row that is not all whitespace)."""
    a = np.frombuffer(buf, dtype=np.uint8)
    ends = _newlines(buf) + 1
    if eof and len(a) and (len(ends) == 0 or ends[-1] < len(a)):
        ends = np.append(ends, len(a))
    if len(ends) == 0:
        return ends, ends.copy()
    starts = np.concatenate(([0], ends[:-1]))
    solid = _SURE[a[starts]]  # a line that starts with a digit, a letter, a sign... is a row
    doubt = np.flatnonzero(~solid)
    if len(doubt) > 64 + len(starts) // 16:  # many (quoted cells?): look at every byte at once
        solid = np.logical_or.reduceat(_sure_bytes(a[:ends[-1]]), starts)
        doubt = np.flatnonzero(~solid)
    for j in doubt:
        line = a[starts[j]:ends[j]]
        solid[j] = bool(_SURE[line].any()) or _not_blank(line.tobytes())
    return ends, np.cumsum(solid)


def _sure_bytes(a: npt.NDArray[np.uint8]) -> npt.NDArray[np.bool_]:
    """Which bytes are in ``_SURE`` (by comparisons: faster than a table on many bytes)."""
    sure: npt.NDArray[np.bool_] = (((a >= 0x21) & (a < 0x80) & (a != _COMMA) & (a != _QUOTE))
                                   | (a < 0x09) | ((a >= 0x0E) & (a < 0x1C)))
    return sure


def _not_blank(line: bytes) -> bool:
    """Whether the csv module reads this one line as a row that is not blank."""
    if line in (b"\n", b"\r\n"):
        return False
    try:
        row = next(csv.reader([line.decode("utf-8", errors="replace")]), [])
    except csv.Error:
        return True  # a row the csv module refuses: it says so where it reads it
    return any(c.strip() for c in row)


def _newlines(data: bytes) -> npt.NDArray[np.intp]:
    """The positions of the line feeds in ``data``."""
    return np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == _LF)


def _verdict(data: bytes, ends: npt.NDArray[np.intp]) -> bool | None:
    """True if pyarrow reads ``data`` as the csv module would, False if only the csv module
    should read it, None if it may not even be cut where it was (the rest goes to csv)."""
    if b"\r" in data and data.count(b"\r") != data.count(b"\r\n"):
        return None
    if b'"' in data and not _simple_quotes(data, ends):
        return None
    if b"(" in data:
        return False
    starts = np.concatenate(([0], ends + 1))
    stops = np.concatenate((ends, [len(data)]))
    return int((stops - starts).max()) <= csv.field_size_limit()


def _simple_quotes(data: bytes, ends: npt.NDArray[np.intp]) -> bool:
    """Quoting that the csv module and pyarrow read alike: quotes come in pairs, each pair
    opens at a field's start and closes at its end (or is a doubled quote inside the field),
    and no line break lies inside a pair."""
    a = np.frombuffer(data, dtype=np.uint8)
    q = np.flatnonzero(a == _QUOTE)
    if len(q) % 2:
        return False
    opens, closes = q[0::2], q[1::2]
    before = a[np.maximum(opens - 1, 0)]
    after = a[np.minimum(closes + 1, len(a) - 1)]
    open_ok = (opens == 0) | np.isin(before, (_COMMA, _LF, _CR, _QUOTE))
    close_ok = (closes == len(a) - 1) | np.isin(after, (_COMMA, _LF, _CR, _QUOTE))
    inside = np.searchsorted(ends, closes) - np.searchsorted(ends, opens)
    return bool(open_ok.all() and close_ok.all() and not inside.any())


Column = npt.NDArray[np.float64] | tuple[list[str], npt.NDArray[np.intp]]


def read_columns(data: bytes, ncols: int, text: set[int]) -> tuple[int, list[Column]] | None:
    """The rows and columns of a fast piece: float64 arrays, and for the columns in ``text``
    the distinct cells and each row's index into them. None if a cell is not a number where one is
    expected, a row has another number of cells, or pyarrow refuses the piece otherwise: then
    the csv module reads it and names the cell."""
    names = [f"c{i}" for i in range(ncols)]
    types = {name: (pa.dictionary(pa.int32(), pa.string()) if i in text else pa.float64())
             for i, name in enumerate(names)}
    try:
        table = pacsv.read_csv(
            pa.py_buffer(data),
            read_options=pacsv.ReadOptions(column_names=names, use_threads=False,
                                           block_size=max(1 << 20, len(data) + 1)),
            parse_options=pacsv.ParseOptions(delimiter=",", quote_char='"', double_quote=True,
                                             escape_char=False, newlines_in_values=False,
                                             ignore_empty_lines=True),
            convert_options=pacsv.ConvertOptions(column_types=types, null_values=[],
                                                 strings_can_be_null=False,
                                                 quoted_strings_can_be_null=False))
    except pa.ArrowException:
        return None
    columns: list[Column] = []
    for i, col in enumerate(table.columns):
        if col.null_count:
            return None
        columns.append(_text_column(col) if i in text else _floats(col))
    return table.num_rows, columns


def _numbers(array: Any, dtype: Any) -> npt.NDArray[Any]:
    """The values of a pyarrow array without nulls, as a numpy view on its data (asking
    pyarrow for numpy imports pandas, when it is installed: a second and more)."""
    dtype = np.dtype(dtype)
    return np.frombuffer(array.buffers()[1], dtype=dtype, count=len(array),
                         offset=array.offset * dtype.itemsize)


def _floats(col: Any) -> npt.NDArray[np.float64]:
    """A float64 column as one numpy array."""
    parts = [_numbers(chunk, np.float64) for chunk in col.chunks]
    if len(parts) == 1:
        return parts[0]
    return np.concatenate(parts) if parts else np.empty(0)


def _text_column(col: Any) -> tuple[list[str], npt.NDArray[np.intp]]:
    """A dictionary column as (distinct cells, each row's index into them)."""
    col = col.unify_dictionaries()
    if col.num_chunks == 0:
        return [], np.empty(0, dtype=np.intp)
    cells = col.chunk(0).dictionary.to_pylist()
    codes = [_numbers(chunk.indices, np.int32) for chunk in col.chunks]
    return cells, np.concatenate(codes).astype(np.intp)
