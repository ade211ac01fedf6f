"""LoopData and the historian CSV reader: the plant files, column mapping, time stamps,
resampling by zero-order hold, and located errors."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from loopworks.analysis.loopdata import LoopData, parse_columns, read_csv
from loopworks.errors import FileFormatError, InputError

PLANT = Path(__file__).resolve().parent.parent / "data" / "plant-loops"
REGULAR = [f"plant0{i}.csv" for i in range(1, 7)]


def write(tmp_path: Path, text: str, name: str = "plant.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def raw_column(path: Path, name: str) -> list[float]:
    """A column as the csv module reads it, for comparison."""
    with open(path, newline="") as f:
        return [float(row[name]) for row in csv.DictReader(f)]


# ----------------------------------------------------------------------------- plant files

@pytest.mark.parametrize("name", REGULAR)
def test_plant_file_reads_as_stored(name: str) -> None:
    path = PLANT / name
    data = read_csv(path)
    assert len(data) == 751
    assert data.dt == pytest.approx(10.0, rel=1e-12)
    assert data.t[0] == 0.0 and data.t[-1] == 7500.0
    assert data.resampled == ""
    assert data.position is None
    assert data.mode is not None and (data.mode == 1).all()
    assert name in data.source
    for role in ("sp", "pv", "op"):
        np.testing.assert_array_equal(getattr(data, role), raw_column(path, role))


def test_plant07_repeated_time_stamps_are_refused_by_default() -> None:
    # plant07.csv: line 32 repeats line 31's t = 300.0 (checked by eye), 25 such repeats
    with pytest.raises(FileFormatError) as exc:
        read_csv(PLANT / "plant07.csv")
    text = str(exc.value)
    assert "plant07.csv" in text and "line 32" in text and "'t'" in text
    assert "25 repeated" in text and "duplicates='last'" in text


def test_plant07_with_duplicates_last_is_resampled_as_stated() -> None:
    data = read_csv(PLANT / "plant07.csv", duplicates="last")
    assert len(data) == 751 and data.dt == pytest.approx(10.0)
    assert "25 rows with a repeated time stamp dropped" in data.resampled
    assert "zero-order hold" in data.resampled
    # the file goes t = 0 (sp 0), 20 (sp 0.001481703), ...: t = 10 holds the t = 0 row
    assert data.sp[:3].tolist() == [0.0, 0.0, 0.001481703]
    # lines 31 and 32 are both t = 300 (sp 0 and 0), line 33 is t = 320 (sp 0): the grid's
    # t = 310 holds the later row at 300
    assert data.t[31] == 310.0 and data.sp[31] == 0.0


# ----------------------------------------------------------------------------- columns

def test_columns_found_in_any_letter_case_and_by_alias(tmp_path: Path) -> None:
    path = write(tmp_path, "TIME,SetPoint,Pv,MV,Valve,MODE\n0,1,2,3,4,1\n1,1.5,2.5,3.5,4.5,0\n")
    data = read_csv(path)
    assert data.sp.tolist() == [1.0, 1.5] and data.pv.tolist() == [2.0, 2.5]
    assert data.op.tolist() == [3.0, 3.5]
    assert data.position is not None and data.position.tolist() == [4.0, 4.5]
    assert data.mode is not None and data.mode.tolist() == [1.0, 0.0]


def test_output_and_timestamp_aliases(tmp_path: Path) -> None:
    path = write(tmp_path, "Timestamp,SV,PV,Output\n0,1,2,3\n2,1,2,4\n")
    data = read_csv(path)
    assert data.op.tolist() == [3.0, 4.0] and data.dt == 2.0 and data.mode is None


def test_explicit_mapping(tmp_path: Path) -> None:
    path = write(tmp_path, "Time,FIC101.SV,FIC101.PV,FIC101.MV,FIC101.MODE\n"
                           "0,5,6,7,AUTO\n1,5,6.5,7.5,MAN\n")
    data = read_csv(path, columns={"sp": "FIC101.SV", "PV": "fic101.pv", "op": "FIC101.MV",
                                   "mode": "FIC101.MODE"})
    assert data.sp.tolist() == [5.0, 5.0] and data.pv.tolist() == [6.0, 6.5]
    assert data.op.tolist() == [7.0, 7.5]
    assert data.mode is not None and data.mode.tolist() == [1.0, 0.0]


def test_parse_columns() -> None:
    assert parse_columns("sp=FIC101.SV, PV = FIC101.PV,op=FIC101.MV") == {
        "sp": "FIC101.SV", "pv": "FIC101.PV", "op": "FIC101.MV"}


@pytest.mark.parametrize(("text", "words"), [
    ("sp=A,pv B", ["item 2", "'pv B'", "ROLE=COLUMN"]),
    ("sp=A,,op=C", ["item 2 is empty"]),
    ("sp=A,flow=B", ["item 2", "unknown role 'flow'", "t, sp, pv, op, position, mode"]),
    ("sp=A,SP=B", ["item 2", "'sp' is given twice"]),
    ("sp=", ["item 1", "ROLE=COLUMN"]),
])
def test_parse_columns_errors_are_located(text: str, words: list[str]) -> None:
    with pytest.raises(InputError) as exc:
        parse_columns(text)
    for word in words:
        assert word in str(exc.value)


def test_unknown_role_in_mapping(tmp_path: Path) -> None:
    path = write(tmp_path, "t,sp,pv,op\n0,1,2,3\n1,1,2,3\n")
    with pytest.raises(InputError, match="unknown role 'flow'"):
        read_csv(path, columns={"flow": "pv"})


# ----------------------------------------------------------------------------- time stamps

@pytest.mark.parametrize("sep", [" ", "T"])
def test_iso_timestamps_become_seconds_from_the_first(tmp_path: Path, sep: str) -> None:
    rows = "".join(f"2024-03-01{sep}12:00:{s:02d},1,2,3\n" for s in (0, 10, 20, 30))
    data = read_csv(write(tmp_path, "timestamp,sp,pv,op\n" + rows))
    assert data.t.tolist() == [0.0, 10.0, 20.0, 30.0] and data.resampled == ""


def test_timestamps_across_midnight_with_offset(tmp_path: Path) -> None:
    text = ("time,sp,pv,op\n2024-03-01T23:59:55+01:00,1,2,3\n"
            "2024-03-02T00:00:00+01:00,1,2,3\n2024-03-02T00:00:05+01:00,1,2,3\n")
    assert read_csv(write(tmp_path, text)).t.tolist() == [0.0, 5.0, 10.0]


# ----------------------------------------------------------------------------- resampling

def test_irregular_sampling_zero_order_hold_hand_computed(tmp_path: Path) -> None:
    # intervals 1, 1, 2, 1: median 1 s; grid 0..5; t = 3 holds the sample at t = 2
    text = "t,sp,pv,op\n0,1,10,20\n1,1,11,21\n2,1,12,22\n4,1,14,24\n5,1,15,25\n"
    data = read_csv(write(tmp_path, text))
    assert data.t.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert data.pv.tolist() == [10.0, 11.0, 12.0, 12.0, 14.0, 15.0]
    assert data.op.tolist() == [20.0, 21.0, 22.0, 22.0, 24.0, 25.0]
    for words in ("1 of 4 intervals", "median 1 s", "from 1 to 2 s", "5 samples to 6",
                  "last sample at or before", "zero-order hold",
                  # where the longest gap is, so a frozen stretch there is read as the gap
                  "the longest interval, 2 s from t = 2 to 4 s, is held over 1 grid sample "
                  "(a frozen"):
        assert words in data.resampled


def test_seconds_from_midnight_in_the_day_number_range_are_seconds(tmp_path: Path) -> None:
    # 45352 s is 12:35:52; every 0.5 s or every 1 ms (a fast logger) is read as seconds:
    # 0.5 day is a whole 43200 s, but a round number of milliseconds as seconds
    for step in ("0.5", "0.001", "10"):
        rows = "".join(f"{45352 + k * float(step)!r},1,2,3\n" for k in range(4))
        data = read_csv(write(tmp_path, "t,sp,pv,op\n" + rows))
        assert data.dt == pytest.approx(float(step))


def test_epoch_seconds_every_tenth_of_a_second_are_regular(tmp_path: Path) -> None:
    """Epoch seconds (1.7e9) keep 0.1-s steps to 2.4e-7 s only, so their intervals differ
    from the median by 2e-6 of it: the record was taken as irregular and resampled, shifting
    every sample after the second by one and dropping the last (found by an outside audit).
    It is kept as it is, as the same rows with times from 0 are."""
    rows = [(k * 0.1, 50.0, 40.0 + (k % 7), 30.0 + (k % 5)) for k in range(751)]
    epoch = "".join(f"{1700000000.0 + k / 10:.1f},{sp},{pv},{op}\n" for k, (_, sp, pv, op)
                    in enumerate(rows))
    relative = "".join(f"{t:.1f},{sp},{pv},{op}\n" for t, sp, pv, op in rows)
    a = read_csv(write(tmp_path, "t,sp,pv,op\n" + epoch, "epoch.csv"))
    b = read_csv(write(tmp_path, "t,sp,pv,op\n" + relative, "relative.csv"))
    assert a.resampled == b.resampled == ""
    assert a.pv.tolist() == b.pv.tolist() == [pv for _, _, pv, _ in rows]
    assert a.dt == pytest.approx(0.1, rel=1e-5)


def test_a_stray_row_far_after_the_record_is_a_located_error(tmp_path: Path) -> None:
    """One row months after a 2-hour record made a resampling grid of 3e8 samples (out of
    memory), or of a million samples that diagnose cut to their last 20,000, all copies of
    one held row (found by an outside audit): the gap is named instead."""
    rows = "".join(f"{k * 10},1,{2 + k % 3},3\n" for k in range(751))
    path = write(tmp_path, "t,sp,pv,op\n" + rows + "1e7,1,2,3\n")
    with pytest.raises(FileFormatError) as exc:
        read_csv(path)
    for words in ("plant.csv, line 753, column 't'", "from line 752",
                  "752 samples would become 1000001", "Split the file at the gap"):
        assert words in str(exc.value)
    # a gap within the record is resampled and held, as before
    held = read_csv(write(tmp_path, "t,sp,pv,op\n" + rows + "7600,1,2,3\n", "gap.csv"))
    assert len(held) == 761 and "held over 9 grid samples" in held.resampled


def test_jittered_sampling_hand_computed(tmp_path: Path) -> None:
    # intervals 2.1, 1.8, 2.1, 2.2: median 2.1; grid 0, 2.1, 4.2, 6.3 (8.4 is past 8.2);
    # 4.2 holds t = 3.9 (value 3), 6.3 holds t = 6.0 (value 4)
    text = "t,sp,pv,op\n0,0,1,0\n2.1,0,2,0\n3.9,0,3,0\n6.0,0,4,0\n8.2,0,5,0\n"
    data = read_csv(write(tmp_path, text))
    np.testing.assert_allclose(data.t, [0.0, 2.1, 4.2, 6.3])
    assert data.pv.tolist() == [1.0, 2.0, 3.0, 4.0]
    assert data.dt == pytest.approx(2.1)


# ----------------------------------------------------------------------------- missing values

def test_empty_and_nan_cells_are_kept_as_nan(tmp_path: Path) -> None:
    data = read_csv(write(tmp_path, "t,sp,pv,op\n0,1,,3\n1,1,NaN,3\n2,,2,nan\n"))
    assert np.isnan(data.pv).tolist() == [True, True, False]
    assert np.isnan(data.sp).tolist() == [False, False, True]
    assert np.isnan(data.op).tolist() == [False, False, True]


# ----------------------------------------------------------------------------- errors

@pytest.mark.parametrize(("text", "words"), [
    ("t,sp,pv,op\n0,1,2,3\n1,1,abc,3\n", ["line 3", "column 'pv'", "'abc' is not a number"]),
    ("t,sp,PV,op\n0,1,2,3\ninf,1,2,3\n", ["line 3", "column 't'", "not a time in seconds"]),
    ("t,sp,pv,op\n0,1,2,3\n\n1,1,2,x\n", ["line 4", "column 'op'", "'x'"]),
    ("t,sp,pv,op\n0,1,2,3\n1,1,2\n", ["line 3", "3 cells", "has 4"]),
    ("t,sp,pv,op\n0,1,2,3\n1,1,2,3\n0.5,1,2,3\n", ["line 4", "column 't'", "'0.5' is before "
                                                   "line 3's '1'"]),
    ("t,sp,pv,op\n0,1,2,3\n1,1,2,3\n1,1,2,3\n", ["line 4", "column 't'", "repeats line 3"]),
    ("t,sp,pv,op\n0,1,2,3\n,1,2,3\n", ["line 3", "column 't'", "not a time in seconds"]),
    ("time,sp,pv,op\n03/01/2024 12:00,1,2,3\n03/01/2024 12:01,1,2,3\n",
     ["line 2", "column 'time'", "neither seconds nor an ISO 8601"]),
    ("time,sp,pv,op\n2024-03-01 12:00:00,1,2,3\n2024-03-01 12:00:1O,1,2,3\n",
     ["line 3", "column 'time'", "not an ISO 8601 time stamp"]),
    ("time,sp,pv,op\n2024-03-01 12:00:00,1,2,3\n2024-03-01 12:00:10Z,1,2,3\n",
     ["line 3", "UTC offset"]),
    ("t,sp,pv,op,mode\n0,1,2,3,1\n1,1,2,3,maybe\n", ["line 3", "column 'mode'", "'maybe'"]),
    # times that are evidently not seconds (found by an outside audit): epoch milliseconds,
    # a spreadsheet's day numbers (1 s apart)
    ("t,sp,pv,op\n1770000000000,1,2,3\n1770000001000,1,2,3\n",
     ["line 2", "column 't'", "epoch milliseconds? divide them by 1000"]),
    ("time,sp,pv,op\n46082.0,1,2,3\n46082.0000115741,1,2,3\n46082.0000231481,1,2,3\n",
     ["line 2", "column 'time'", "a spreadsheet's day numbers (1 s apart)?"]),
    # day numbers every 5 minutes (0.00347 of a day: a whole 300 s, and no round number of
    # milliseconds as seconds) were read as seconds 3.5 ms apart (found by an outside audit)
    ("time,sp,pv,op\n45352.0,1,2,3\n45352.00347222222,1,2,3\n45352.00694444444,1,2,3\n",
     ["line 2", "column 'time'", "a spreadsheet's day numbers (300 s apart)?"]),
    # a decimal comma (in a tab-separated file) is named as one (found by an outside audit)
    ("t\tsp\tpv\top\n0\t50,0\t2\t3\n1\t50\t2\t3\n",
     ["line 2", "column 'sp'", "'50,0' is not a number (a decimal comma: the file must use "
      "decimal points)"]),
])
def test_bad_cells_are_located(tmp_path: Path, text: str, words: list[str]) -> None:
    with pytest.raises(FileFormatError) as exc:
        read_csv(write(tmp_path, text))
    assert "plant.csv, line" in str(exc.value)
    for word in words:
        assert word in str(exc.value)


def test_missing_role_names_it_and_the_columns_present(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError) as exc:
        read_csv(write(tmp_path, "t,sp,pv,flow\n0,1,2,3\n1,1,2,3\n"))
    text = str(exc.value)
    assert "plant.csv" in text and "line 1" in text and "controller output" in text
    assert "op, mv, out, output" in text and "'flow'" in text and "'t'" in text


def test_no_time_column_says_which_names_were_looked_for(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError) as exc:
        read_csv(write(tmp_path, "sp,pv,op\n1,2,3\n1,2,3\n"))
    assert "no time column" in str(exc.value) and "t, time, timestamp, datetime" in str(exc.value)


def test_rows_at_a_given_sample_time_need_no_time_column(tmp_path: Path) -> None:
    """An export of OP and PV and a sample time Ts (as the International Stiction Database
    gives its loops): the rows are samples every Ts seconds. A time column and a sample time
    together, or a sample time that is not a number of seconds > 0, are refused."""
    path = write(tmp_path, "sp,pv,op\n1,2,3\n1,2.5,3\n1,2,4\n")
    with pytest.raises(FileFormatError, match=r"--sample-time SECONDS"):
        read_csv(path)
    data = read_csv(path, sample_time=2.5)
    assert data.t.tolist() == [0.0, 2.5, 5.0] and data.dt == 2.5 and data.resampled == ""
    assert data.pv.tolist() == [2.0, 2.5, 2.0] and data.op.tolist() == [3.0, 3.0, 4.0]
    timed = write(tmp_path, "t,sp,pv,op\n0,1,2,3\n1,1,2,3\n", "timed.csv")
    with pytest.raises(InputError, match=r"sample_time = 2\.5 s .* time column 't'"):
        read_csv(timed, sample_time=2.5)
    for bad in (0.0, -1.0, float("nan"), float("inf"), True):
        with pytest.raises(InputError, match=r"sample_time = .*: expected a finite number"):
            read_csv(path, sample_time=bad)


def test_a_record_without_setpoint_is_read_only_when_asked_with_the_pvs_mean(
        tmp_path: Path) -> None:
    """Without an SP column the reader refuses the file, unless ``sp_optional``: then the SP
    is constant at the PV's mean over the samples in automatic with a finite PV (here the
    manual row's 90 and the empty cell are left out: (2 + 4 + 6) / 3 = 4), and
    ``sp_recorded`` is False (also in a window)."""
    path = write(tmp_path, "t,pv,op,mode\n0,2,3,1\n1,90,3,0\n2,,3,1\n3,4,3,1\n4,6,3,auto\n")
    with pytest.raises(FileFormatError, match="no setpoint column"):
        read_csv(path)
    data = read_csv(path, sp_optional=True)
    assert data.sp.tolist() == [4.0] * 5 and not data.sp_recorded
    assert not data.window(0.0, 3.0).sp_recorded
    assert read_csv(write(tmp_path, "t,sp,pv,op\n0,1,2,3\n1,1,2,3\n", "with.csv"),
                    sp_optional=True).sp_recorded


def test_mapped_column_absent(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError) as exc:
        read_csv(write(tmp_path, "t,sp,pv,op\n0,1,2,3\n1,1,2,3\n"), columns={"pv": "FIC.PV"})
    assert "no column 'FIC.PV'" in str(exc.value) and "given for pv" in str(exc.value)


def test_two_columns_for_one_role(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError) as exc:
        read_csv(write(tmp_path, "t,sp,pv,op,out\n0,1,2,3,4\n1,1,2,3,4\n"))
    assert "'op' (#4) and 'out' (#5)" in str(exc.value) and "line 1" in str(exc.value)


@pytest.mark.parametrize(("text", "words"), [
    ("", ["the file is empty"]),
    ("\n\n", ["the file is empty"]),
    ("t,sp,pv,op\n", ["0 data rows", "at least 2"]),
    ("t,sp,pv,op\n0,1,2,3\n", ["1 data row ", "at least 2"]),
])
def test_empty_and_short_files(tmp_path: Path, text: str, words: list[str]) -> None:
    with pytest.raises(FileFormatError) as exc:
        read_csv(write(tmp_path, text))
    assert "plant.csv" in str(exc.value)
    for word in words:
        assert word in str(exc.value)


def test_a_byte_that_is_not_utf8_is_located_in_the_file(tmp_path: Path) -> None:
    """The reader decodes in blocks, and its error counted the bad byte from the block: one
    Latin-1 byte on line 602 was "byte 2189" (found by an outside audit). The file's line and
    offset are named."""
    rows = "".join(f"{k},1,2,3,{'x' * 40}\n" for k in range(800)).encode()
    at = rows.index(b"600,1,2,3,") + 12
    path = tmp_path / "latin1.csv"
    path.write_bytes(b"t,sp,pv,op,tag\n" + rows[:at] + b"\xe9" + rows[at + 1:])
    with pytest.raises(FileFormatError) as exc:
        read_csv(path)
    assert (f"latin1.csv, line 602 (byte {at + 15} of the file): not UTF-8 text"
            in str(exc.value))


def test_unreadable_file(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match=r"absent\.csv: cannot read the file"):
        read_csv(tmp_path / "absent.csv")


# ----------------------------------------------------------------------------- LoopData

def make(n: int = 10, dt: float = 0.5) -> LoopData:
    t = dt * np.arange(n)
    return LoopData(t=t, sp=np.zeros(n), pv=t.copy(), op=-t, source="x")


def test_dt_len_and_window_half_open() -> None:
    data = make()
    assert len(data) == 10 and data.dt == 0.5
    part = data.window(1.0, 2.5)
    assert part.t.tolist() == [1.0, 1.5, 2.0] and part.op.tolist() == [-1.0, -1.5, -2.0]
    assert part.source == "x"


def test_window_too_small_is_refused() -> None:
    with pytest.raises(InputError, match="holds 1 samples"):
        make().window(1.0, 1.5)


def test_arrays_are_read_only_copies() -> None:
    pv = np.arange(5.0)
    data = LoopData(t=np.arange(5.0), sp=pv, pv=pv, op=pv)
    pv[0] = 99.0
    assert data.pv[0] == 0.0
    with pytest.raises(ValueError):
        data.pv[0] = 1.0


@pytest.mark.parametrize(("t", "words"), [
    ([0.0, 1.0, 3.0], "must be uniform"),
    ([0.0, 1.0, 1.0], "must increase"),
])
def test_loopdata_refuses_bad_times(t: list[float], words: str) -> None:
    with pytest.raises(InputError, match=words):
        LoopData(t=np.array(t), sp=np.zeros(3), pv=np.zeros(3), op=np.zeros(3))


def test_loopdata_refuses_unequal_lengths() -> None:
    with pytest.raises(InputError, match=r"LoopData\.pv: 2 values, t has 3"):
        LoopData(t=np.arange(3.0), sp=np.zeros(3), pv=np.zeros(2), op=np.zeros(3))


def test_mode_codes_and_words(tmp_path: Path) -> None:
    """loopworks' pid codes MAN 0, AUTO 1, CAS 2 (cascade is automatic) and DeltaV's mode
    words; DeltaV's MODE codes (AUTO = 4, MAN = 3: what a simulate CSV of deltav.pid's
    mode_actual holds) were read as "manual" for the whole record; another number is now a
    located error, not a guess (found by a user's run)."""
    rows = "".join(f"{k},1,2,3,{m}\n" for k, m in enumerate(
        ["0", "1", "2", "AUTO", "Cas", "rcas", "MAN", "oos", "IMAN", "lo", "ROUT", ""]))
    data = read_csv(write(tmp_path, "t,sp,pv,op,mode\n" + rows))
    assert data.mode is not None
    assert data.mode[:11].tolist() == [0, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0]
    assert np.isnan(data.mode[11])  # an empty cell: a Bad value
    for code in ("4", "3", "-1", "0.5"):
        with pytest.raises(FileFormatError, match=rf"line 3, column 'mode': '{code}' is not a "
                                                  r"mode: 0 \(manual\), 1 \(automatic\), 2 "):
            read_csv(write(tmp_path, f"t,sp,pv,op,mode\n0,1,2,3,1\n1,1,2,3,{code}\n"))


def test_a_column_named_twice_is_chosen_by_its_position(tmp_path: Path) -> None:
    """Two columns named pv: the error said to map one with --columns, and --columns pv=pv
    then said 2 columns are named 'pv', a dead end (found by a user). A column can be given
    by its position, #N (1-based), which the errors name."""
    path = write(tmp_path, "t,sp,pv,op,pv\n0,1,2,3,4\n1,1,2,3,4\n")
    with pytest.raises(FileFormatError, match=r"'pv' \(#3\) and 'pv' \(#5\).*--columns pv=#3"):
        read_csv(path)
    with pytest.raises(FileFormatError, match=r"name one by its position, #3, #5"):
        read_csv(path, {"pv": "pv"})
    assert read_csv(path, {"pv": "#5"}).pv.tolist() == [4.0, 4.0]
    assert read_csv(path, parse_columns("pv=#3")).pv.tolist() == [2.0, 2.0]
    with pytest.raises(FileFormatError, match="columns #1 to #5"):
        read_csv(path, {"pv": "#9"})


def test_a_tab_separated_export_reads_as_its_csv(tmp_path: Path) -> None:
    """Many historians export tab-separated text (the StictionGPT records are): it was
    refused as "one column"; it now reads as the same file with commas, value for value,
    and a comma in the first line keeps it a CSV."""
    source = PLANT / "plant06.csv"
    text = source.read_text()
    tabbed = write(tmp_path, text.replace(",", "\t"), "plant06.txt")
    a, b = read_csv(source), read_csv(tabbed)
    for role in ("t", "sp", "pv", "op", "mode"):
        np.testing.assert_array_equal(getattr(a, role), getattr(b, role))
    # a comma-separated file whose cells hold a tab is still read by commas
    mixed = write(tmp_path, "t,sp,pv,op\n" + "".join(
        f"{k},50,\t{50 + k % 3},40\n" for k in range(5)), "mixed.csv")
    np.testing.assert_array_equal(read_csv(mixed).pv, [50, 51, 52, 50, 51])


def test_a_simulate_csv_without_a_mapping_is_offered_its_block_ports(tmp_path: Path) -> None:
    """A CSV that `loopworks simulate` writes names its ports block.port: the error offers
    them, the setpoint the controller worked to (DeltaV's working_sp) first, not its SP
    input, which it is not in CAS or while SP tracks PV (found by an engineer)."""
    path = write(tmp_path, "t,pid.sp,pid.working_sp,pid.pv,pid.out\n0,50,50,50,50\n"
                           "1,50,50,50,50\n2,50,50,50,50\n")
    with pytest.raises(FileFormatError, match=r"perhaps 'pid\.working_sp', 'pid\.sp' "
                                              r"\(--columns sp=pid\.working_sp\)"):
        read_csv(path)


def test_an_infinite_value_is_a_bad_sample_not_a_refused_file(tmp_path: Path) -> None:
    """docs/diagnose.md: `inf` or a number beyond the float range is a Bad value of its sample
    (as one beyond ±1e12 is), which the quality gate counts; one such cell refused the whole
    file, while the gate's rule names infinite values among those it tolerates (found by an
    outside audit). A time must still be finite."""
    from loopworks.analysis.loopdata import bad

    path = write(tmp_path, "t,sp,pv,op\n0,1,2,3\n1,1,inf,3\n2,1,1e400,-inf\n3,1,2,3\n")
    data = read_csv(path)
    assert bad(data.pv).tolist() == [False, True, True, False]
    assert bad(data.op).tolist() == [False, False, True, False]


def test_a_column_a_mapping_gave_to_another_role_is_named(tmp_path: Path) -> None:
    """--columns op=pv: the PV is then missing, and the message says its column was mapped to
    the OP (it listed a column 'pv' while saying none was found; found by an outside
    audit)."""
    path = write(tmp_path, "t,sp,pv,op\n0,1,2,3\n1,1,2,3\n")
    with pytest.raises(FileFormatError, match=r"no process variable column: looked for pv "
                                              r"\(any letter case\) \('pv' is mapped to op\)"):
        read_csv(path, {"op": "pv"})
