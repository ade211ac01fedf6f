"""CSV rows of float64 and int64 values, written exactly as Python writes them, compiled.

A float is written as ``repr(value)`` writes it: the shortest decimal that reads back as the
same double (``float(text) == value``), and of those the closest to the value, in Python's
layout (``22.0``, ``0.1``, ``1e-05``, ``1.2345678901234568e+17``, ``nan``, ``-inf``, ``-0.0``);
an integer as ``str(value)``. So a replay writes the same text whether its rows go through
``csv.writer`` or through :func:`format_rows`, only many times faster.

The shortest digits come from the Schubfach algorithm (R. Giulietti, "The Schubfach way to
render doubles", 2020): the value's rounding interval is scaled by a 128-bit power of ten and
the shortest decimal in it read off with 64-bit integer arithmetic. The powers of ten are
computed here, exactly, with Python integers.

The helpers are inlined by numba (``inline="always"``): compiling the formatter takes 8.5 s
on a fresh machine (once: ``loopworks compile`` does it), against 1.7 s as plain functions,
but those formatted rows 22 % slower (300,000 rows of 5 floats and 2 ints: 0.066 s against
0.054 s; 2026-12-07), and formatting is most of a replay's or a simulate CSV's writing.

This module imports numba; :mod:`loopworks.sim.replay` imports it only for large outputs.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import numpy.typing as npt
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

_U = np.uint64
_ZERO = _U(0)
_ONE = _U(1)
_TWO = _U(2)
_FOUR = _U(4)
_TEN = _U(10)
_HUNDRED = _U(100)
_E4 = _U(10**4)
_E8 = _U(10**8)
_E16 = _U(10**16)
_S32 = _U(32)
_S52 = _U(52)
_S63 = _U(63)
_MANT = _U((1 << 52) - 1)
_EXP = _U(0x7FF)
_HIDDEN = _U(1 << 52)

_E_MIN = -292  # the decimal exponents the table covers: every double's -k lies in them
_E_MAX = 324

#: the characters of the fixed parts of a number
_DOT, _MINUS, _PLUS, _E, _COMMA, _NL, _D0 = (ord(c) for c in ".-+e,\n0")

FORMATTED_MAX = 24  # characters of the longest float: -1.2345678901234567e-308
INT_MAX = 20  # characters of the longest int64: -9223372036854775808


def _pow10_table() -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.uint64]]:
    """For e in [-292, 324], 10^e = beta·2^r with 2^127 <= beta < 2^128: g = floor(beta) + 1
    (the paper's overestimate), as its high and low 64-bit halves."""
    hi = np.empty(_E_MAX - _E_MIN + 1, dtype=np.uint64)
    lo = np.empty_like(hi)
    for e in range(_E_MIN, _E_MAX + 1):
        num, den = (10 ** e, 1) if e >= 0 else (1, 10 ** -e)
        r = num.bit_length() - den.bit_length()  # 2^(r-1) < num/den < 2^(r+1)
        if num << max(0, -r) < den << max(0, r):
            r -= 1  # now 2^r <= num/den < 2^(r+1)
        r -= 127
        g = (num << -r) // den + 1 if r < 0 else num // (den << r) + 1
        hi[e - _E_MIN] = g >> 64
        lo[e - _E_MIN] = g & ((1 << 64) - 1)
    return hi, lo


_G_HI, _G_LO = _pow10_table()
_POW10 = np.array([10 ** i for i in range(20)], dtype=np.uint64)


def _mul_hi_typed(typingctx: Any, a: Any, b: Any) -> Any:
    """The high 64 bits of the 128-bit product of two uint64 (one machine multiply)."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


_mul_hi: Any = intrinsic(_mul_hi_typed)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _round_to_odd(g_hi: Any, g_lo: Any, cp: Any) -> Any:
    """floor(g·cp / 2^127) for the 128-bit g, its last bit set when the part of the product
    below (from bit 64 on) is not zero: the scaled value, rounded to odd."""
    x_hi = _mul_hi(g_lo, cp)
    y_hi = _mul_hi(g_hi, cp)
    y_lo = g_hi * cp + x_hi
    if y_lo < x_hi:
        y_hi = y_hi + _ONE
    r = (y_hi << _ONE) | (y_lo >> _S63)
    if y_lo != _ZERO:
        r = r | _ONE
    return r


@numba.njit(cache=True, inline="always", error_model="numpy")
def _to_decimal(mant: Any, biased: Any) -> tuple[Any, Any]:
    """(d, e) with d·10^e the shortest decimal that reads back as the positive finite double
    of mantissa field ``mant`` and exponent field ``biased`` (and, of those, the closest)."""
    if biased != _ZERO:
        c = _HIDDEN | mant
        q = np.int64(biased) - 1075
        if -52 <= q <= 0:  # an integer below 2^53: its digits are exact
            f = c >> _U(-q)
            if (f << _U(-q)) == c:
                return f, 0
    else:
        c = mant
        q = np.int64(-1074)
    even = (c & _ONE) == _ZERO
    closer = mant == _ZERO and biased > _ONE  # the interval below is half as wide
    cb = c << _TWO
    cbl = cb - _TWO + (_ONE if closer else _ZERO)
    cbr = cb + _TWO
    k = (q * 1262611 - (524031 if closer else 0)) // 4194304  # floor(log10(2^q)), or (3/4)·2^q
    h = q + (-k * 1741647) // 524288  # q + floor(log2(10^-k)): 0..3
    i = -k - _E_MIN
    g_hi = _G_HI[i]
    g_lo = _G_LO[i]
    sh = _U(h)
    vbl = _round_to_odd(g_hi, g_lo, cbl << sh)
    vb = _round_to_odd(g_hi, g_lo, cb << sh)
    vbr = _round_to_odd(g_hi, g_lo, cbr << sh)
    lower = vbl if even else vbl + _ONE
    upper = vbr if even else vbr - _ONE
    s = vb >> _TWO
    if s >= _TEN:
        sp = s // _TEN
        up_in = lower <= _U(40) * sp
        wp_in = _U(40) * sp + _U(40) <= upper
        if up_in != wp_in:
            return (sp + _ONE if wp_in else sp), k + 1
    u_in = lower <= _FOUR * s
    w_in = _FOUR * s + _FOUR <= upper
    if u_in != w_in:
        return (s + _ONE if w_in else s), k
    mid = _FOUR * s + _TWO
    if vb > mid or (vb == mid and (s & _ONE) != _ZERO):
        return s + _ONE, k
    return s, k


def _store_typed(typingctx: Any, buf: Any, pos: Any, word: Any) -> Any:
    """Store the uint64 ``word`` at byte ``pos`` of the uint8 array ``buf``, unaligned (its
    bytes in memory order: little-endian, the lowest first)."""
    sig = types.void(buf, types.int64, types.uint64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        array = context.make_array(signature.args[0])(context, builder, args[0])
        where = builder.bitcast(builder.gep(array.data, [args[1]]), ir.IntType(64).as_pointer())
        builder.store(args[2], where, align=1)
        return context.get_dummy_value()

    return sig, codegen


_store8: Any = intrinsic(_store_typed)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _eight(x: Any) -> Any:
    """The 8 decimal digits of x < 10^8 (zero-padded) as ASCII bytes in one uint64, the first
    digit in the lowest byte: split into 4-, 2- and 1-digit lanes by multiplying, no loop."""
    high = x // _E4
    y = high | ((x - high * _E4) << _S32)
    h = ((y * _U(10486)) >> _U(20)) & _U(0x0000007F0000007F)  # each 32-bit lane // 100
    y = h | ((y - h * _HUNDRED) << _U(16))
    h = ((y * _U(103)) >> _U(10)) & _U(0x000F000F000F000F)  # each 16-bit lane // 10
    y = h | ((y - h * _TEN) << _U(8))
    return y + _U(0x3030303030303030)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _put_digits(buf: Any, pos: int, d: Any, n: int) -> int:
    """Write the n decimal digits of d (n at least its length: zero-padded) at buf[pos:];
    return the end. Eight digits a store: up to 7 bytes past the end are overwritten (the
    buffer has room, and what comes next is written over them)."""
    if n > 16:
        top = d // _E16
        d = d - top * _E16
        _store8(buf, pos, _eight(top) >> _U(8 * (24 - n)))
        pos += n - 16
        n = 16
    if n > 8:
        high = d // _E8
        _store8(buf, pos, _eight(high) >> _U(8 * (16 - n)))
        _store8(buf, pos + n - 8, _eight(d - high * _E8))
    else:
        _store8(buf, pos, _eight(d) >> _U(8 * (8 - n)))
    return pos + n


@numba.njit(cache=True, inline="always", error_model="numpy")
def _n_digits(d: Any) -> int:
    """How many decimal digits d has (at least 1): a double's shortest digits are mostly 16
    or 17, so counting starts from the top."""
    n = 20
    while n > 1 and d < _POW10[n - 1]:
        n -= 1
    return n


@numba.njit(cache=True, inline="always", error_model="numpy")
def _put_float(buf: Any, pos: int, bits: Any) -> int:
    """Write ``repr`` of the double with these bits at buf[pos:]; return the end."""
    biased = (bits >> _S52) & _EXP
    mant = bits & _MANT
    if biased == _EXP:
        if mant != _ZERO:
            buf[pos] = ord("n")
            buf[pos + 1] = ord("a")
            buf[pos + 2] = ord("n")
            return pos + 3
        if (bits >> _S63) != _ZERO:
            buf[pos] = _MINUS
            pos += 1
        buf[pos] = ord("i")
        buf[pos + 1] = ord("n")
        buf[pos + 2] = ord("f")
        return pos + 3
    if (bits >> _S63) != _ZERO:
        buf[pos] = _MINUS
        pos += 1
    if biased == _ZERO and mant == _ZERO:
        buf[pos] = _D0
        buf[pos + 1] = _DOT
        buf[pos + 2] = _D0
        return pos + 3
    d, e = _to_decimal(mant, biased)
    while d % _E8 == _ZERO:  # drop the trailing zeros: 8, 4, 2, then 1 at a time
        d = d // _E8
        e += 8
    if d % _E4 == _ZERO:
        d = d // _E4
        e += 4
    if d % _HUNDRED == _ZERO:
        d = d // _HUNDRED
        e += 2
    if d % _TEN == _ZERO:
        d = d // _TEN
        e += 1
    n = _n_digits(d)
    point = n + e  # the value is 0.DIGITS · 10^point
    if point <= -4 or point > 16:  # d.ddde+XX, as repr
        _put_digits(buf, pos + 1, d, n)
        buf[pos] = buf[pos + 1]
        if n > 1:
            buf[pos + 1] = _DOT
            pos += n + 1
        else:
            pos += 1
        x = point - 1
        buf[pos] = _E
        buf[pos + 1] = _MINUS if x < 0 else _PLUS
        x = -x if x < 0 else x
        return _put_digits(buf, pos + 2, _U(x), 3 if x >= 100 else 2)
    if point <= 0:  # 0.000ddd
        buf[pos] = _D0
        buf[pos + 1] = _DOT
        pos += 2
        for _ in range(-point):
            buf[pos] = _D0
            pos += 1
        return _put_digits(buf, pos, d, n)
    if point >= n:  # ddd000.0
        pos = _put_digits(buf, pos, d, n)
        for _ in range(point - n):
            buf[pos] = _D0
            pos += 1
        buf[pos] = _DOT
        buf[pos + 1] = _D0
        return pos + 2
    _put_digits(buf, pos + 1, d, n)  # ddd.ddd: the digits, then the integer part moved left
    for j in range(pos, pos + point):
        buf[j] = buf[j + 1]
    buf[pos + point] = _DOT
    return pos + n + 1


@numba.njit(cache=True, inline="always", error_model="numpy")
def _put_int(buf: Any, pos: int, v: Any) -> int:
    """Write ``str`` of the int64 v at buf[pos:]; return the end."""
    if v < 0:
        buf[pos] = _MINUS
        pos += 1
        m = _U(0) - _U(v)  # the magnitude, also of -2^63
    else:
        m = _U(v)
    return _put_digits(buf, pos, m, _n_digits(m))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _format_rows(first: Any, floats: Any, ints: Any, buf: Any) -> int:
    """Rows ``first[r], floats[r, :]..., ints[r, :]...`` as CSV lines into buf; the length.
    ``first`` and ``floats`` are the bits of float64 arrays (uint64 views)."""
    pos = 0
    for r in range(first.shape[0]):
        pos = _put_float(buf, pos, first[r])
        for j in range(floats.shape[1]):
            buf[pos] = _COMMA
            pos = _put_float(buf, pos + 1, floats[r, j])
        for j in range(ints.shape[1]):
            buf[pos] = _COMMA
            pos = _put_int(buf, pos + 1, ints[r, j])
        buf[pos] = _NL
        pos += 1
    return pos


def format_rows(first: npt.NDArray[np.float64], floats: npt.NDArray[np.float64],
                ints: npt.NDArray[np.int64]) -> npt.NDArray[np.uint8]:
    """CSV lines (ASCII bytes) of the rows ``first[r], *floats[r], *ints[r]``, each ending in
    ``\\n``: floats as ``repr`` writes them, ints as ``str``, as ``csv.writer`` writes them."""
    from loopworks.sim.arrays import compiled_arg

    n = first.shape[0]
    f = compiled_arg(floats).reshape(n, -1)
    i = compiled_arg(ints, np.int64).reshape(n, -1)
    width = (1 + f.shape[1]) * (FORMATTED_MAX + 1) + i.shape[1] * (INT_MAX + 1)
    buf = np.empty(n * width + 8, dtype=np.uint8)  # 8: room for the last 8-byte store
    t = compiled_arg(first)
    end = _format_rows(t.view(np.uint64), f.view(np.uint64), i, buf)
    return buf[:end]


def float_text(values: npt.NDArray[np.float64]) -> list[str]:
    """Each value as ``repr`` writes it, through the compiled formatter (for tests)."""
    flat = np.asarray(values, dtype=np.float64).ravel()
    none = np.empty((flat.size, 0))
    text = format_rows(flat, none, none.astype(np.int64)).tobytes().decode("ascii")
    return text.split("\n")[:-1]
