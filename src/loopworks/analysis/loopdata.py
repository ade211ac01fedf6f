"""One loop's recorded time series (SP, PV, OP, optionally valve position and mode) and the
reader of historian CSV exports that makes it.

:class:`LoopData` holds uniformly sampled float64 arrays; it needs no blocks. :func:`read_csv`
reads a historian export with the csv module and numpy (no pandas):

* comma-separated, or tab-separated when the first line holds tabs and no comma (as many
  historians export); a header row; the columns are found by name in any letter case: time
  ``t``, ``time``, ``timestamp`` or ``datetime``; setpoint ``sp``, ``setpoint`` or ``sv``;
  process variable ``pv``; controller output ``op``, ``mv``, ``out`` or ``output``; valve
  stem position ``position`` or ``valve`` (optional); ``mode`` (optional: 1 = automatic, 0 =
  manual, 2 = cascade (automatic), loopworks' pid codes, or the words of :data:`MODE_WORDS`;
  any other number is a located error, not a guess). Tag names are mapped explicitly with
  ``columns={"sp": "FIC101.SV", ...}`` (:func:`parse_columns` reads the same from the text
  ``sp=FIC101.SV,pv=FIC101.PV``); roles not mapped are still looked for by name;
* the time column holds seconds (numbers) or ISO 8601 time stamps (``2024-03-01 12:00:10``,
  ``2024-03-01T12:00:10``, with fractions of a second or a UTC offset), converted to seconds
  from the first sample; a file without a time column is refused, unless its sample period
  is given (``sample_time``, s: the rows are then samples every ``sample_time`` seconds, as
  the International Stiction Database gives its loops: OP, PV and a sample time Ts);
* a file without a setpoint column is refused, unless read with ``sp_optional=True``
  (``loopworks diagnose``): then the SP is taken as constant at the PV's mean over the samples
  in automatic, and :attr:`LoopData.sp_recorded` is False. A loop with integral action holds
  its PV at its SP on average (the integral of the error stays bounded while the OP does), so
  this is the SP of a regulatory loop at a fixed setpoint; it is not that of a loop whose SP
  moved (a cascade secondary);
* time must increase from row to row. A repeated time stamp is an error, unless read with
  ``duplicates="last"``: then the later row at that time is kept, as a historian's zero-order
  hold would (the earlier one is overwritten), and :attr:`LoopData.resampled` says how many
  rows were dropped;
* irregular sampling is resampled onto a uniform grid: the period is the median interval
  between samples, the grid runs from the first sample to the last, and the value at each grid
  time is the last sample at or before it (zero-order hold: a historian stores a value when it
  changes and holds it until the next). :attr:`LoopData.resampled` says so with the numbers.
  Intervals within a relative :data:`REGULAR_TOLERANCE` of the median (floating-point noise in
  the text), or within the rounding of the times themselves (epoch seconds), count as
  regular: the samples are kept as they are. A gap that would make the grid more than
  :data:`MAX_GRID_GROWTH` times as long as the rows read is an error naming its line;
* an empty or ``nan`` cell in sp, pv, op, position or mode is kept as NaN (a Bad value); the
  quality gate (:mod:`loopworks.analysis.quality`) counts them. Any other cell that is not a
  finite number is an error naming the file, the line (1-based, the header is line 1) and the
  column.

Every error is a :class:`~loopworks.errors.FileFormatError` (a problem in the file) or an
:class:`~loopworks.errors.InputError` (a malformed column mapping).
"""

from __future__ import annotations

import csv
import math
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Literal, TextIO

import numpy as np
import numpy.typing as npt

from loopworks.blocks.pid import INPUT_LIMIT
from loopworks.errors import FileFormatError, InputError

FloatArray = npt.NDArray[np.float64]

#: the roles a column can play, in the order they are reported
ROLES = ("t", "sp", "pv", "op", "position", "mode")
#: the roles a file must have
REQUIRED = ("t", "sp", "pv", "op")
#: the column names (lower case) each role is found by when not mapped explicitly
ALIASES: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "timestamp", "datetime"),
    "sp": ("sp", "setpoint", "sv"),
    "pv": ("pv",),
    "op": ("op", "mv", "out", "output"),
    "position": ("position", "valve"),
    "mode": ("mode",),
}
MEANING = {
    "t": "time", "sp": "setpoint", "pv": "process variable", "op": "controller output",
    "position": "valve stem position", "mode": "controller mode",
}
#: mode words (lower case) and the mode they mean: 1 automatic (cascade and remote cascade
#: are automatic), 0 not (manual; DeltaV's out of service, initialisation manual, local
#: override and remote output)
MODE_WORDS = {"auto": 1.0, "automatic": 1.0, "cas": 1.0, "cascade": 1.0, "rcas": 1.0,
              "man": 0.0, "manual": 0.0, "oos": 0.0, "iman": 0.0, "lo": 0.0, "rout": 0.0}
#: mode codes and the mode they mean: loopworks' pid's (MAN 0, AUTO 1, CAS 2); any other
#: number is refused, not guessed (DeltaV's MODE codes, AUTO = 4, are another numbering)
MODE_CODES = {0.0: 0.0, 1.0: 1.0, 2.0: 1.0}
#: intervals within this fraction of the median interval are regular (text rounding, not
#: irregular sampling): no resampling
REGULAR_TOLERANCE = 1e-6
#: blank or this (lower case) is a missing value: NaN
_MISSING = ("", "nan")


@dataclass(frozen=True, eq=False)
class LoopData:
    """One loop's uniformly sampled record.

    ``t`` is in seconds, strictly increasing with a constant step (within
    :data:`REGULAR_TOLERANCE`); ``sp``, ``pv``, ``op`` and the optional ``position`` (valve
    stem) and ``mode`` (1 automatic, 0 manual; None when the record has none) have one value
    per time, NaN for a Bad value. ``source`` names the file in messages; ``resampled`` is empty,
    or a sentence saying what resampling rule the reader applied. ``sp_recorded`` is False
    when the record had no setpoint and ``sp`` is the PV's mean (:func:`read_csv`). The
    arrays are read-only float64 copies.
    """

    t: FloatArray
    sp: FloatArray
    pv: FloatArray
    op: FloatArray
    position: FloatArray | None = None
    mode: FloatArray | None = None
    source: str = ""
    resampled: str = ""
    sp_recorded: bool = True

    def __post_init__(self) -> None:
        n = -1
        for name in ("t", "sp", "pv", "op", "position", "mode"):
            value = getattr(self, name)
            if value is None:
                continue
            a = np.array(value, dtype=np.float64)
            if a.ndim != 1:
                raise InputError(f"LoopData.{name}: a 1-D array is expected, got {a.ndim}-D")
            if n < 0:
                n = len(a)
            elif len(a) != n:
                raise InputError(f"LoopData.{name}: {len(a)} values, t has {n}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if n < 2:
            raise InputError(f"LoopData: {n} samples: at least 2 are needed")
        _check_uniform(self.t)

    @property
    def dt(self) -> float:
        """The sample period, s."""
        return float(self.t[-1] - self.t[0]) / (len(self.t) - 1)

    def __len__(self) -> int:
        return len(self.t)

    def window(self, t0: float, t1: float) -> LoopData:
        """The samples with ``t0 <= t < t1`` (half open, so windows tile a record), times
        kept as they are; at least 2 samples must fall inside."""
        keep = (self.t >= t0) & (self.t < t1)
        if int(keep.sum()) < 2:
            raise InputError(f"{self.source or 'LoopData'}: the window {t0:g} s to {t1:g} s "
                             f"holds {int(keep.sum())} samples of a record from "
                             f"{self.t[0]:g} s to {self.t[-1]:g} s: at least 2 are needed")

        def cut(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[keep]

        return LoopData(t=self.t[keep], sp=self.sp[keep], pv=self.pv[keep], op=self.op[keep],
                        position=cut(self.position), mode=cut(self.mode), source=self.source,
                        resampled=self.resampled, sp_recorded=self.sp_recorded)


def bad(a: FloatArray) -> npt.NDArray[np.bool_]:
    """True where a sample is Bad: NaN, infinite, or beyond ±INPUT_LIMIT (1e12) in its units,
    the rule of a block's input (no real measurement is that large; pid docstring), so a
    test that squares and sums samples never meets one."""
    return ~(np.abs(a) <= INPUT_LIMIT)


def _check_uniform(t: FloatArray) -> None:
    """Refuse times that are not finite, strictly increasing and uniform."""
    if not np.isfinite(t).all():
        raise InputError("LoopData.t: the times must be finite")
    d = np.diff(t)
    if (d <= 0).any():
        k = int(np.flatnonzero(d <= 0)[0])
        raise InputError(f"LoopData.t: t[{k + 1}] = {t[k + 1]:g} s does not follow "
                         f"t[{k}] = {t[k]:g} s: the times must increase")
    step = float(t[-1] - t[0]) / (len(t) - 1)
    if np.abs(d - step).max() > _tolerance(t, step):
        raise InputError(f"LoopData.t: intervals from {d.min():g} to {d.max():g} s: the times "
                         f"must be uniform (read_csv resamples irregular files)")


# ----------------------------------------------------------------------------- column mapping

def parse_columns(text: str) -> dict[str, str]:
    """The column mapping ``ROLE=COLUMN,ROLE=COLUMN`` (the CLI's ``--columns``) as a dict.

    Roles are those of :data:`ROLES`, in any letter case; a column name is the header's text
    (it may hold dots, spaces are stripped at both ends, it may not hold a comma). A malformed
    item, an unknown or repeated role is an :class:`InputError` naming the item.
    """
    mapping: dict[str, str] = {}
    items = text.split(",")
    for k, raw in enumerate(items, start=1):
        item = raw.strip()
        where = f"--columns {text!r}: item {k}"
        if not item:
            raise InputError(f"{where} is empty: expected ROLE=COLUMN items separated by commas")
        role, eq, column = item.partition("=")
        role, column = role.strip().lower(), column.strip()
        if not eq or not role or not column:
            raise InputError(f"{where} ({item!r}) is not ROLE=COLUMN, e.g. pv=FIC101.PV")
        if role not in ROLES:
            raise InputError(f"{where}: unknown role {role!r}: the roles are "
                             f"{', '.join(ROLES)}")
        if role in mapping:
            raise InputError(f"{where}: the role {role!r} is given twice")
        mapping[role] = column
    return mapping


def _check_mapping(columns: Mapping[str, str]) -> dict[str, str]:
    """The explicit mapping with lower-case roles; an unknown role or a column given for two
    roles is an InputError."""
    mapping: dict[str, str] = {}
    for role, column in columns.items():
        key = role.strip().lower()
        if key not in ROLES:
            raise InputError(f"columns: unknown role {role!r}: the roles are {', '.join(ROLES)}")
        if key in mapping:
            raise InputError(f"columns: the role {key!r} is given twice")
        mapping[key] = column.strip()
    used: dict[str, str] = {}
    for role, column in mapping.items():
        if column.lower() in used:
            raise InputError(f"columns: {column!r} is given for both {used[column.lower()]} "
                             f"and {role}")
        used[column.lower()] = role
    return mapping


def _locate(header: Sequence[str], mapping: Mapping[str, str], source: str,
            line: int, optional: Sequence[str] = ()) -> dict[str, int]:
    """Each role's position in the header: mapped names first (exactly, else in any letter
    case), then the aliases of the roles not mapped. A missing required role (not in
    ``optional``), or a role two columns could be, is a FileFormatError naming the columns
    present."""
    names = [h.strip() for h in header]
    lower = [h.lower() for h in names]
    present = ", ".join(repr(h) for h in names)
    if len(names) == 1:  # one column: another separator, most likely
        sep = next((c for c in ";\t|" if c in names[0]), None)
        if sep is not None:
            raise FileFormatError(f"{source}, line {line}: the header {names[0]!r} is one "
                                  f"column: the file seems separated by {sep!r}; a historian "
                                  "CSV here is comma- or tab-separated (export it so, or "
                                  "convert it)")
    found: dict[str, int] = {}
    for role, column in mapping.items():
        hits = [i for i, h in enumerate(names) if h == column]
        if not hits:
            hits = [i for i, h in enumerate(lower) if h == column.lower()]
        if not hits and column.startswith("#") and column[1:].isdigit():
            # a column by its position, 1-based (two columns of one name can be told apart)
            if not 1 <= int(column[1:]) <= len(names):
                raise FileFormatError(f"{source}, line {line}: column {column} (given for "
                                      f"{role}): the header has columns #1 to #{len(names)}")
            hits = [int(column[1:]) - 1]
        if not hits:
            raise FileFormatError(f"{source}, line {line}: no column {column!r} (given for "
                                  f"{role}, the {MEANING[role]}); the columns are {present}")
        if len(hits) > 1:
            where = ", ".join(f"#{i + 1}" for i in hits)
            raise FileFormatError(f"{source}, line {line}: {len(hits)} columns are named "
                                  f"{column!r} (given for {role}): name one by its position, "
                                  f"{where} (--columns {role}=#{hits[0] + 1})")
        found[role] = hits[0]
    taken = set(found.values())
    for role in ROLES:
        if role in found:
            continue
        hits = [i for i, h in enumerate(lower) if h in ALIASES[role] and i not in taken]
        if len(hits) > 1:
            both = " and ".join(f"{names[i]!r} (#{i + 1})" for i in hits)
            raise FileFormatError(f"{source}, line {line}: columns {both} could each be the "
                                  f"{role} ({MEANING[role]}): map one with "
                                  f"columns={{'{role}': NAME}}, or by its position "
                                  f"(--columns {role}=#{hits[0] + 1})")
        if hits:
            found[role] = hits[0]
            taken.add(hits[0])
        elif role in REQUIRED and role not in optional:
            looked = ", ".join(ALIASES[role])
            # a module's CSV (loopworks simulate) names its ports block.port: offer those
            # the setpoint the controller worked to first (DeltaV's working_sp: its SP
            # input is not it in CAS or while SP tracks PV)
            ports = ("working_sp", *ALIASES[role]) if role == "sp" else ALIASES[role]
            near = sorted((names[i] for i, h in enumerate(lower)
                           if h.rpartition(".")[2] in ports and "." in h),
                          key=lambda n: ports.index(n.lower().rpartition(".")[2]))
            hint = (f"; perhaps {', '.join(repr(n) for n in near)} (--columns "
                    f"{role}={near[0]})" if near else "")
            other = (", or give the sample period (sample_time, --sample-time SECONDS) of "
                     "a file whose rows are samples at a fixed period" if role == "t" else "")
            # a column of this role's name that a mapping gave to another role
            given = [f"{names[i]!r} is mapped to {r}" for r, i in found.items()
                     if lower[i] in ALIASES[role]]
            taken_by = f" ({', '.join(given)})" if given else ""
            raise FileFormatError(f"{source}, line {line}: no {MEANING[role]} column: looked "
                                  f"for {looked} (any letter case){taken_by}{hint}; the columns "
                                  f"are {present}; map one with columns={{'{role}': NAME}} "
                                  f"(--columns {role}=NAME){other}")
    return found


# ----------------------------------------------------------------------------- reading

def read_csv(path: str | os.PathLike[str], columns: Mapping[str, str] | None = None, *,
             duplicates: Literal["error", "last"] = "error", sample_time: float | None = None,
             sp_optional: bool = False) -> LoopData:
    """Read one loop from a historian CSV export (the rules are in the module docstring).

    ``columns`` maps roles (t, sp, pv, op, position, mode) to header names; ``duplicates``
    says what a repeated time stamp does: ``"error"`` refuses the file naming the line,
    ``"last"`` keeps the later row at that time and says so in ``resampled``.
    ``sample_time`` (s): the period of the rows of a file without a time column.
    ``sp_optional``: a file without a setpoint column is read with the SP at the PV's mean.
    """
    source = os.fspath(path)
    mapping = _check_mapping(columns or {})
    if sample_time is not None and (isinstance(sample_time, bool) or not isinstance(
            sample_time, (int, float)) or not math.isfinite(sample_time) or sample_time <= 0):
        raise InputError(f"sample_time = {sample_time!r}: expected a finite number of seconds "
                         f"> 0 (the period of the rows of a file without a time column)")
    rows = list(_rows(source))
    if not rows:
        raise FileFormatError(f"{source}: the file is empty: expected a header row naming "
                              f"the columns (t, sp, pv, op) and rows of samples")
    header_line, header = rows[0]
    optional = (("t",) if sample_time is not None else ()) + (("sp",) if sp_optional else ())
    where = _locate(header, mapping, source, header_line, optional)
    if sample_time is not None and "t" in where:
        raise InputError(f"sample_time = {sample_time:g} s was given, but {source} has a time "
                         f"column {header[where['t']].strip()!r}: give the sample time only "
                         f"for a file without one")
    body = rows[1:]
    if len(body) < 2:
        raise FileFormatError(f"{source}: {len(body)} data row{'s' * (len(body) != 1)} after "
                              f"the header: at least 2 are needed")
    for line, row in body:
        if len(row) != len(header):
            raise FileFormatError(f"{source}, line {line}: {len(row)} cells, the header "
                                  f"(line {header_line}) has {len(header)}")
    lines = np.array([line for line, _ in body], dtype=np.int64)
    names = {role: header[i].strip() for role, i in where.items()}
    cells = {role: [row[i] for _, row in body] for role, i in where.items()}
    values = {role: _values(cells[role], lines, source, names[role], role)
              for role in where if role != "t"}
    note = ""
    if sample_time is None:
        t = _times(cells["t"], lines, source, names["t"])
        t, values, dropped, rows_kept = _ordered(t, values, lines, source, names["t"],
                                                 cells["t"], duplicates)
        t, values, note = _uniform(t, values, lines[rows_kept], source, names["t"])
        if dropped:
            kept = (f"{dropped} row{'s' * (dropped != 1)} with a repeated time stamp dropped "
                    f"(the later row at each time kept, as a historian's hold would)")
            note = f"{kept}; {note}" if note else f"{kept}."
    else:
        t = np.arange(len(body), dtype=np.float64) * float(sample_time)
    recorded = "sp" in values
    if not recorded:
        values["sp"] = np.full(len(t), _mean_in_auto(values["pv"], values.get("mode")))
    return LoopData(t=t, sp=values["sp"], pv=values["pv"], op=values["op"],
                    position=values.get("position"), mode=values.get("mode"), source=source,
                    resampled=note, sp_recorded=recorded)


def _mean_in_auto(pv: FloatArray, mode: FloatArray | None) -> float:
    """The PV's mean over its finite samples in automatic (all, without a mode column; NaN
    when there are none: the quality gate then refuses the record)."""
    keep = np.isfinite(pv) & (np.abs(pv) <= INPUT_LIMIT)
    if mode is not None:
        keep &= mode == 1.0
    return float(np.mean(pv[keep])) if keep.any() else math.nan


def _rows(source: str) -> Iterator[tuple[int, list[str]]]:
    """The file's non-blank rows with the line each ends on (1-based); a file that cannot be
    read or parsed is a FileFormatError."""
    try:
        with open(source, newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f, delimiter=_separator(f))
            while True:
                try:
                    row = next(reader)
                except StopIteration:
                    return
                except csv.Error as exc:
                    raise FileFormatError(f"{source}, line {reader.line_num}: {exc}") from None
                if any(c.strip() for c in row):
                    yield reader.line_num, row
    except UnicodeDecodeError:
        raise FileFormatError(f"{source}, {_bad_utf8(source)}: not UTF-8 text (save it as "
                              f"UTF-8 CSV)") from None
    except OSError as exc:
        raise FileFormatError(f"{source}: cannot read the file: {exc.strerror}") from None


def _bad_utf8(source: str) -> str:
    """Where the first byte that is not UTF-8 is in the file: its line (1-based) and offset
    (the reader decodes in blocks, so its own error counts from the block, not the file)."""
    with open(source, "rb") as f:
        raw = f.read()
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        return f"line {line} (byte {exc.start} of the file)"
    return "at a byte the reader could not decode"  # pragma: no cover - it found one


def _separator(f: TextIO) -> str:
    """A tab when the file's first non-blank line holds tabs and no comma (a tab-separated
    export, as many historians write), else a comma; ``f`` is left at its start."""
    first = next((line for line in f if line.strip()), "")
    f.seek(0)
    return "\t" if "\t" in first and "," not in first else ","


def _number(cell: str) -> float | None:
    """The cell as a float (±inf for an infinite value or one beyond the float range: a Bad
    value, as one beyond ±1e12 is), NaN if missing, None if it is not a number."""
    text = cell.strip()
    if text.lower() in _MISSING:
        return math.nan
    try:
        return float(text)
    except ValueError:
        return None


def _values(cells: list[str], lines: npt.NDArray[np.int64], source: str, name: str,
            role: str) -> FloatArray:
    """A value column as float64, NaN for a missing value; a cell that is not a finite number
    (or, for mode, a mode word) is a located FileFormatError."""
    out = np.empty(len(cells))
    for k, cell in enumerate(cells):
        value = _number(cell)
        if role == "mode" and cell.strip().lower() not in _MISSING:
            value = (MODE_WORDS.get(cell.strip().lower()) if value is None
                     else MODE_CODES.get(value))
        if value is None:
            what = ("a mode: 0 (manual), 1 (automatic), 2 (cascade) or a mode word (auto, cas, "
                    "rcas; man, oos, iman, lo, rout); a code of another numbering (DeltaV's "
                    "MODE, AUTO = 4) is not guessed: write its name" if role == "mode"
                    else "a number")
            if role != "mode" and re.fullmatch(r"[+-]?\d+,\d+", cell.strip()):
                what += " (a decimal comma: the file must use decimal points)"
            raise FileFormatError(f"{source}, line {lines[k]}, column '{name}': {cell!r} is "
                                  f"not {what}")
        out[k] = value
    return out


def _times(cells: list[str], lines: npt.NDArray[np.int64], source: str,
           name: str) -> FloatArray:
    """The time column in seconds: numbers as they are, ISO 8601 time stamps as seconds from
    the first. The first cell decides which; a cell of the other kind is a located error."""
    first = cells[0].strip()
    if _number(first) is not None and first.lower() not in _MISSING:
        out = np.empty(len(cells))
        for k, cell in enumerate(cells):
            value = _number(cell)
            if value is None or not math.isfinite(value):
                raise FileFormatError(f"{source}, line {lines[k]}, column '{name}': {cell!r} "
                                      f"is not a time in seconds (the first row gives seconds)")
            out[k] = value
        _plausible_seconds(out, lines, source, name)
        return out
    start = _stamp(first)
    if start is None:
        raise FileFormatError(f"{source}, line {lines[0]}, column '{name}': {cells[0]!r} is "
                              f"neither seconds nor an ISO 8601 time stamp "
                              f"(e.g. 2024-03-01 12:00:10)")
    out = np.empty(len(cells))
    for k, cell in enumerate(cells):
        stamp = _stamp(cell.strip())
        if stamp is None:
            raise FileFormatError(f"{source}, line {lines[k]}, column '{name}': {cell!r} is "
                                  f"not an ISO 8601 time stamp (e.g. 2024-03-01 12:00:10)")
        if (stamp.tzinfo is None) != (start.tzinfo is None):
            has = "has" if stamp.tzinfo is not None else "has no"
            first_has = "has" if start.tzinfo is not None else "has none"
            raise FileFormatError(f"{source}, line {lines[k]}, column '{name}': {cell!r} "
                                  f"{has} UTC offset; the first time stamp {first_has}")
        out[k] = (stamp - start).total_seconds()
    return out


#: numeric times from here on, read as seconds, would be more than 3000 years: epoch
#: milliseconds (1.7e12 in 2024) [ours]
EPOCH_MS_FROM = 1e11
#: numeric times in this range, a sample less than a millisecond apart or apart by a whole
#: number of seconds written in days (300 s: 0.00347222), and no round number of
#: milliseconds as seconds: day numbers of a spreadsheet (45000 is 2023; one second is
#: 1.16e-5 of a day) [ours: seconds from midnight (5.5 to 22 hours) every 0.5 s or 1 ms are
#: seconds, a round number of milliseconds; day numbers every 86.4 s (0.001) are the case
#: this reads wrongly]
DAY_NUMBERS = (2e4, 8e4)
DAY_NUMBER_STEP = 1e-3


def _day_step(step: float) -> bool:
    """True when ``step`` (the median interval of numeric times in the day-number range)
    reads as a spreadsheet's days: no whole number of milliseconds read as seconds, and
    either under :data:`DAY_NUMBER_STEP` or a whole number of seconds in days (to 1 ms, or
    1e-4 of it for days written with few decimals)."""
    if not 0.0 < step < 1.0:
        return False
    if abs(step * 1000.0 - round(step * 1000.0)) < 1e-6:  # 0.5, 0.001: seconds
        return False
    seconds = step * 86400.0
    return step < DAY_NUMBER_STEP or (
        round(seconds) >= 1 and abs(seconds - round(seconds)) <= max(1e-3, 1e-4 * seconds))


def _plausible_seconds(t: FloatArray, lines: npt.NDArray[np.int64], source: str,
                       name: str) -> None:
    """FileFormatError when numeric times are evidently not seconds: epoch milliseconds, or a
    spreadsheet's day numbers (found by an outside audit: read as seconds, a 1-s record of
    day numbers gave a time constant of 0.0003 s, and epoch milliseconds one of 24637 s)."""
    where = f"{source}, line {lines[0]}, column '{name}'"
    if len(t) and abs(float(t[0])) >= EPOCH_MS_FROM:
        raise FileFormatError(f"{where}: times from {t[0]:.6g}: read as seconds that is more "
                              "than 3000 years; epoch milliseconds? divide them by 1000, or "
                              "export ISO 8601 time stamps")
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if DAY_NUMBERS[0] <= float(t[0]) <= DAY_NUMBERS[1] and _day_step(step):
        raise FileFormatError(f"{where}: times from {t[0]:.6g}, {step:.3g} apart: a "
                              f"spreadsheet's day numbers ({step * 86400.0:.3g} s apart)? "
                              "diagnose reads seconds or ISO 8601 time stamps: convert them")


def _stamp(text: str) -> datetime | None:
    """An ISO 8601 date and time (``T`` or a space between them), or None."""
    if not text or text[0] not in "0123456789":
        return None
    try:
        return datetime.fromisoformat(text)
    except ValueError:
        return None


def _ordered(t: FloatArray, values: dict[str, FloatArray], lines: npt.NDArray[np.int64],
             source: str, name: str, cells: list[str],
             duplicates: Literal["error", "last"]) -> tuple[FloatArray, dict[str, FloatArray],
                                                            int, npt.NDArray[np.bool_]]:
    """Refuse time going back (and a repeated time, unless ``duplicates == "last"``: then keep
    the later row at each time); the rows kept, how many were dropped, and which."""
    d = np.diff(t)
    back = np.flatnonzero(d < 0)
    if len(back):
        k = int(back[0]) + 1
        raise FileFormatError(f"{source}, line {lines[k]}, column '{name}': "
                              f"{cells[k].strip()!r} is before line {lines[k - 1]}'s "
                              f"{cells[k - 1].strip()!r}: time must increase")
    same = np.flatnonzero(d == 0)
    if not len(same):
        return t, values, 0, np.ones(len(t), dtype=bool)
    if duplicates != "last":
        k = int(same[0]) + 1
        raise FileFormatError(f"{source}, line {lines[k]}, column '{name}': "
                              f"{cells[k].strip()!r} repeats line {lines[k - 1]}'s time stamp "
                              f"({len(same)} repeated in the file): time must increase "
                              f"(read with duplicates='last' to keep the later row at a time)")
    keep = np.append(d != 0, True)
    if int(keep.sum()) < 2:
        raise FileFormatError(f"{source}: every row has the same time stamp: at least 2 "
                              f"times are needed")
    return t[keep], {role: v[keep] for role, v in values.items()}, len(same), keep


#: the most samples resampling may make per sample read: a grid longer than this is
#: refused, naming the gap that would make it (one stray row months after a 2-hour record
#: made a grid of 3e8 samples, out of memory, or, 116 days later, a million samples of
#: which diagnose read the last 20,000, all one held row; found by an outside audit) [ours]
MAX_GRID_GROWTH = 10


def _tolerance(t: FloatArray, period: float) -> float:
    """How far an interval may be from ``period`` and still be regular: a relative
    :data:`REGULAR_TOLERANCE`, and no less than the rounding of the times themselves (epoch
    seconds of 1.7e9 are stored to 2.4e-7 s, so their 0.1-s intervals differ by 2e-6 of it)."""
    scale = max(abs(float(t[0])), abs(float(t[-1])))
    return max(REGULAR_TOLERANCE * period, 8.0 * float(np.finfo(np.float64).eps) * scale)


def _t(x: float, t: FloatArray, period: float) -> str:
    """A time of ``t`` in a sentence, with the digits that resolve ``period``."""
    scale = max(abs(float(t[0])), abs(float(t[-1])), period)
    digits = max(6, math.ceil(math.log10(scale / period)) + 3) if period > 0 else 6
    return f"{x:.{digits}g}"


def _uniform(t: FloatArray, values: dict[str, FloatArray], lines: npt.NDArray[np.int64],
             source: str, name: str) -> tuple[FloatArray, dict[str, FloatArray], str]:
    """Regular times made exactly uniform (t0 + k * median interval); irregular ones resampled
    onto that grid by zero-order hold, with the sentence that says so (``lines``: each time's
    line in the file, for the error when the grid would be too long)."""
    d = np.diff(t)
    period = float(np.median(d))
    tol = _tolerance(t, period)
    off = np.abs(d - period) > tol
    if not off.any():
        return t[0] + period * np.arange(len(t)), values, ""
    gap = int(np.argmax(d))
    m = math.floor((t[-1] - t[0] + tol) / period) + 1
    if m > MAX_GRID_GROWTH * len(t):
        raise FileFormatError(
            f"{source}, line {lines[gap + 1]}, column '{name}': the time jumps by "
            f"{d[gap]:.6g} s ({d[gap] / period:.3g} median intervals of {period:g} s) from "
            f"line {lines[gap]}; resampled onto the median interval the {len(t)} samples "
            f"would become {m}: more than {MAX_GRID_GROWTH} times as many. Split the file at "
            f"the gap, or remove stray rows")
    grid = t[0] + period * np.arange(m)
    idx = np.searchsorted(t, grid + tol, side="right") - 1
    held = round(d[gap] / period) - 1

    def at(x: float) -> str:
        return _t(x, t, period)

    note = (f"irregular sampling ({int(off.sum())} of {len(d)} intervals differ from the "
            f"median {period:g} s; they range from {d.min():g} to {d.max():g} s): resampled "
            f"onto a uniform {period:g}-s grid (the median interval) from {at(t[0])} to "
            f"{at(grid[-1])} s, {len(t)} samples to {m}, each grid time taking the last "
            f"sample at or before it (zero-order hold, as historians store values); the "
            f"longest interval, {d[gap]:g} s from t = {at(t[gap])} to {at(t[gap + 1])} s, is "
            f"held over {held} grid sample{'' if held == 1 else 's'} (a frozen stretch there "
            f"is the gap).")
    return grid, {role: v[idx] for role, v in values.items()}, note


def hold_last(x: FloatArray) -> FloatArray:
    """x with each non-finite sample replaced by the last finite one before it (the first
    finite one for a leading stretch): a historian's hold."""
    good = np.isfinite(x)
    if good.all() or not good.any():
        return x
    idx = np.where(good, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(good))
    idx[:first] = first
    return np.asarray(x[idx], dtype=np.float64)
