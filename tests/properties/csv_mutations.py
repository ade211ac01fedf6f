"""Edits of a CSV's rows for the file fuzzers (replay's input, a historian export): each draw
changes a cell, drops or adds one, repeats, drops or swaps a row, renames a header, or sets
a stretch of one column to one value. Hypothesis draws which edits, where and with what."""

from __future__ import annotations

from collections.abc import Sequence

from hypothesis import strategies as st

#: every edit :func:`mutate` knows
EDITS = ("cell", "drop_cell", "add_cell", "dup_line", "drop_line", "header", "swap", "column")


def mutate(draw: st.DrawFn, rows: list[list[str]], *, cells: Sequence[str],
           headers: Sequence[str], edits: Sequence[str] = EDITS[:-1],
           stretch: int = 200, first_column: int = 0) -> str:
    """Apply 1 to 6 of ``edits`` to ``rows`` (the header first) and return the CSV text.
    ``cells``: what a changed cell may hold (or short random text, for "cell"); ``headers``:
    what a renamed header may be; "column" sets up to ``stretch`` rows of one column (from
    ``first_column``) to one of ``cells``."""
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(list(edits)))
        r = draw(st.integers(0, len(rows) - 1))
        row = rows[r]
        if op == "cell" and row:
            row[draw(st.integers(0, len(row) - 1))] = draw(st.sampled_from(list(cells))
                                                           | st.text(max_size=6))
        elif op == "drop_cell" and row:
            row.pop(draw(st.integers(0, len(row) - 1)))
        elif op == "add_cell":
            row.append(draw(st.sampled_from(list(cells))))
        elif op == "dup_line":
            rows.insert(r, list(row))
        elif op == "drop_line" and len(rows) > 1:
            rows.pop(r)
        elif op == "header":
            rows[0][draw(st.integers(0, len(rows[0]) - 1))] = draw(st.sampled_from(
                list(headers)))
        elif op == "swap" and len(rows) > 2:
            a, b = draw(st.integers(1, len(rows) - 1)), draw(st.integers(1, len(rows) - 1))
            rows[a], rows[b] = rows[b], rows[a]
        elif op == "column" and len(rows) > 1:
            j = draw(st.integers(first_column, len(rows[0]) - 1))
            start = draw(st.integers(1, len(rows) - 1))
            value = draw(st.sampled_from(list(cells)))
            for line in rows[start:start + draw(st.integers(1, stretch))]:
                if j < len(line):
                    line[j] = value
    return "\n".join(",".join(row) for row in rows) + "\n"
