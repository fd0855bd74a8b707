"""``"%.17g"`` CSV rows compiled with numba: the bytes of
:func:`identification.csvformat.format_rows_reference` (Python's ``%``), ~20x faster
(~70 ns per number on the reproduction's predictions).

Per number x (nonzero, finite, 1e−280 ≤ |x| ≤ 1e280):

1. the 17 significant digits N = round(|x|·10^k), k = 16 − X, X the decimal exponent: y =
   |x|·10^k is computed in double-double arithmetic (Dekker's error-free product of |x| and
   the double-double 10^k, a table made from exact rationals), error below 2^−45; X starts at
   an estimate of ⌊log10|x|⌋ from the binary exponent and the table, and is corrected until
   10^16 ≤ y < 10^17 (so the estimate only costs time when it is off); a rounding up to 10^17
   carries into X, as printf's does; the digits are written two at a time from a table;
2. C's ``%g`` layout with precision 17: fixed notation for −4 ≤ X ≤ 16, else ``d.ddde±XX``;
   trailing zeros and a bare point removed; zero is ``0`` / ``-0``.

Every number the fast path cannot decide exactly — y within 1e−9 of a half-integer (the
rounding), NaN, ±inf, magnitudes outside 1e−280 … 1e280 — is formatted by Python's ``%``
itself and spliced in, so the output equals the reference byte for byte for every double
(``tests/test_csvformat.py``).  Registered by :func:`omni_app.accel.install`.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .alpha_kernel import _jit

_K_MIN, _K_MAX = -270, 300     # 10^k table: k = 16 − X for 1e-280 <= |x| <= 1e280, and ±1
_LIMIT_LO, _LIMIT_HI = 1e-280, 1e280
_SPLIT = 134217729.0           # 2^27 + 1 (Dekker's split)
_MAX_LEN = 26                  # bytes per number: the longest %.17g (24) and a separator


def _table() -> tuple[np.ndarray, np.ndarray]:
    """10^k as double-double for k in [_K_MIN, _K_MAX]: hi = round(10^k), lo = round(10^k − hi),
    from exact rationals."""
    hi = np.empty(_K_MAX - _K_MIN + 1)
    lo = np.empty_like(hi)
    for i, k in enumerate(range(_K_MIN, _K_MAX + 1)):
        exact = Fraction(10) ** k
        h = float(exact)
        hi[i] = h
        lo[i] = float(exact - Fraction(h))
    return hi, lo


_HI, _LO = _table()
#: "00", "01", ..., "99" as ASCII bytes (two digits per lookup)
_PAIRS = np.frombuffer(b"".join(b"%02d" % i for i in range(100)), dtype=np.uint8).copy()


@_jit
def _digits(ax, X, hi_t, lo_t):
    """(⌊y⌋, round(y), ambiguous) of y = ax·10^(16 − X)."""
    k = 16 - X
    ph = hi_t[k - _K_MIN]
    pl = lo_t[k - _K_MIN]
    p = ax * ph
    c = _SPLIT * ax
    ah = c - (c - ax)
    al = ax - ah
    c = _SPLIT * ph
    bh = c - (c - ph)
    bl = ph - bh
    err = ((ah * bh - p) + ah * bl + al * bh) + al * bl     # ax·ph − p, exactly
    t = err + ax * pl                                        # y = p + t
    f = math.floor(p)
    r = (p - f) + t
    fr = math.floor(r)
    ambiguous = abs((r - fr) - 0.5) < 1e-9
    fi = np.int64(f)
    return fi + np.int64(fr), fi + np.int64(math.floor(r + 0.5)), ambiguous


@_jit
def _format(data, hi_t, lo_t, pairs, out, slow_elem, slow_pos):
    """Write the rows of ``data`` into ``out``; returns (bytes written, number of slow
    elements); a slow element (flat index into ``slow_elem``) is left out, its place
    (``slow_pos``: offset in ``out``) to be filled by the caller."""
    n, m = data.shape
    pos = 0
    n_slow = 0
    dig = np.empty(17, dtype=np.uint8)
    for i in range(n):
        for j in range(m):
            x = data[i, j]
            ax = abs(x)
            if x == 0.0:
                if math.copysign(1.0, x) < 0:
                    out[pos] = 45
                    pos += 1
                out[pos] = 48
                pos += 1
            else:
                ok = ax >= _LIMIT_LO and ax <= _LIMIT_HI       # False for NaN, inf
                if ok:
                    # ⌊log10 ax⌋ from the binary exponent (then corrected below if off by one)
                    m2, e2 = math.frexp(ax)
                    X = np.int64(math.floor((e2 - 1) * 0.30102999566398120))
                    if X + 1 - _K_MIN >= 0 and X + 1 <= _K_MAX and ax >= hi_t[X + 1 - _K_MIN]:
                        X += 1
                    F, N, amb = _digits(ax, X, hi_t, lo_t)
                    for _ in range(3):                 # the exponent: 10^16 <= y < 10^17
                        if F < 10**16:
                            X -= 1
                        elif F >= 10**17:
                            X += 1
                        else:
                            break
                        F, N, amb = _digits(ax, X, hi_t, lo_t)
                    ok = (not amb) and F >= 10**16 and F < 10**17
                if not ok:
                    slow_elem[n_slow] = i * m + j
                    slow_pos[n_slow] = pos
                    n_slow += 1
                else:
                    if N == 10**17:                    # rounded up to the next power of ten
                        N = 10**16
                        X += 1
                    # 17 digits = 9 + 8, two at a time from a table (32-bit divisions)
                    hi = np.uint32(N // 100000000)
                    lo = np.uint32(N - np.int64(hi) * 100000000)
                    for q in range(4):
                        r = lo % np.uint32(100)
                        lo //= np.uint32(100)
                        dig[16 - 2 * q] = pairs[2 * r + 1]
                        dig[15 - 2 * q] = pairs[2 * r]
                    for q in range(4):
                        r = hi % np.uint32(100)
                        hi //= np.uint32(100)
                        dig[8 - 2 * q] = pairs[2 * r + 1]
                        dig[7 - 2 * q] = pairs[2 * r]
                    dig[0] = 48 + hi
                    d = 17                              # significant digits kept
                    while dig[d - 1] == 48:
                        d -= 1
                    if x < 0:
                        out[pos] = 45
                        pos += 1
                    if X >= 0 and X <= 16:             # fixed, integer part X + 1 digits
                        for q in range(X + 1):
                            out[pos] = dig[q]
                            pos += 1
                        if d > X + 1:
                            out[pos] = 46
                            pos += 1
                            for q in range(X + 1, d):
                                out[pos] = dig[q]
                                pos += 1
                    elif X < 0 and X >= -4:           # fixed, "0." and -X-1 zeros
                        out[pos] = 48
                        out[pos + 1] = 46
                        pos += 2
                        for q in range(-X - 1):
                            out[pos] = 48
                            pos += 1
                        for q in range(d):
                            out[pos] = dig[q]
                            pos += 1
                    else:                              # d.ddde±XX
                        out[pos] = dig[0]
                        pos += 1
                        if d > 1:
                            out[pos] = 46
                            pos += 1
                            for q in range(1, d):
                                out[pos] = dig[q]
                                pos += 1
                        out[pos] = 101
                        out[pos + 1] = 45 if X < 0 else 43
                        pos += 2
                        e = -X if X < 0 else X
                        if e >= 100:
                            out[pos] = 48 + e // 100
                            pos += 1
                        out[pos] = 48 + (e // 10) % 10
                        out[pos + 1] = 48 + e % 10
                        pos += 2
            out[pos] = 10 if j == m - 1 else 44
            pos += 1
    return pos, n_slow


def format_rows(data: np.ndarray) -> bytes:
    """``identification.csvformat.format_rows_reference(data)``, compiled (``data``: 2-D
    float64)."""
    data = np.ascontiguousarray(data, dtype=np.float64)
    size = data.size
    out = np.empty(size * _MAX_LEN, dtype=np.uint8)
    slow_elem = np.empty(size, dtype=np.int64)
    slow_pos = np.empty(size, dtype=np.int64)
    end, n_slow = _format(data, _HI, _LO, _PAIRS, out, slow_elem, slow_pos)
    if n_slow == 0:
        return out[:end].tobytes()
    flat = data.ravel()
    parts, prev = [], 0
    for e, p in zip(slow_elem[:n_slow].tolist(), slow_pos[:n_slow].tolist()):
        parts.append(out[prev:p].tobytes())
        parts.append(("%.17g" % flat[e]).encode("ascii"))
        prev = p
    parts.append(out[prev:end].tobytes())
    return b"".join(parts)
