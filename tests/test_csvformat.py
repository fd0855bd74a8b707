"""The compiled "%.17g" CSV formatter (omni_app.csv_kernel) against Python's % formatting
(identification.csvformat.format_rows_reference): the same bytes for every double, and the
dataset and prediction writers giving the same files with and without it.  Bytes, on any CPU:
"%.17g" of a double is exactly specified (the correctly rounded 17 significant digits), and the
kernel computes it in exact integer and double-double arithmetic, deferring to Python's % where
it cannot decide; a formatter that differs in one digit is wrong, not rounded differently."""

import numpy as np
import pytest

from identification import csvformat
from identification.csvformat import format_rows, format_rows_reference
from identification.dataset import Run, write_run
from omni_app.csv_kernel import format_rows as format_rows_kernel


def _edge_values():
    v = [0.0, -0.0, 1.0, 0.5, 0.1, 0.3, 1e-4, 1e-5, 9.999999999999999e-5, 1e15, 1e16, 1e17,
         123456789012345678.0, 99999999999999984.0, 1e22, 1e23, 2.0**53, 2.0**53 + 2, 0.001,
         1e16 - 2, 12345.678, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
         np.nan, np.inf, -np.inf, 1e280, 1e-280, 1.0000000000000002, 0.99999999999999989]
    for k in range(-324, 309):                     # powers of ten and their neighbours
        p = 10.0 ** k
        v += [p, np.nextafter(p, 0.0), np.nextafter(p, np.inf)]
    v = np.array(v)
    return np.concatenate([v, -v])


def _random_values(n=60000, seed=3):
    rng = np.random.default_rng(seed)
    return np.concatenate([
        rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n),          # all magnitudes
        rng.uniform(-1, 1, n),
        rng.integers(-2**63, 2**63 - 1, n, dtype=np.int64).view(np.float64),  # any bits
        rng.integers(-2**40, 2**40, n) / 2.0 ** rng.integers(0, 80, n),       # dyadic: ties
        rng.integers(-10**6, 10**6, n) * 10.0 ** rng.integers(-20, 20, n),    # short decimals
        np.arange(n) * 1e-3,                                                  # sample times
    ])


@pytest.mark.parametrize("ncols", [1, 2, 4, 5])
def test_kernel_equals_python_format(ncols):
    for x in (_edge_values(), _random_values()):
        x = x[: x.size - x.size % ncols].reshape(-1, ncols)
        assert format_rows_kernel(x) == format_rows_reference(x)


def test_reference_is_percent_17g():
    x = np.array([[0.001, -2.5e-07, 3.0], [np.nan, -0.0, 1e300]])
    assert format_rows_reference(x) == b"0.001,-2.4999999999999999e-07,3\nnan,-0,1.0000000000000001e+300\n"
    assert format_rows_kernel(x) == format_rows_reference(x)
    assert format_rows_kernel(np.zeros((0, 4))) == b""


def test_writers_same_bytes_with_and_without_kernel(tmp_path):
    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n) * 1e-3
    run = Run("r1", t, 0.05 * np.sin(t), rng.normal(0, 0.01, n), rng.normal(0, 1, n),
              {"kind": "sine", "gamma1_deg": 30.0, "gamma2_deg": 100.0, "kp": 2.0,
               "frequency_hz": 1.0, "amplitude_rad": 0.05}, extra={"x": rng.normal(0, 1e-9, n)})
    previous = csvformat.set_kernel(None)
    try:
        (tmp_path / "a").mkdir()
        write_run(tmp_path / "a", run)
        csvformat.set_kernel(format_rows_kernel)
        (tmp_path / "b").mkdir()
        write_run(tmp_path / "b", run)
        assert format_rows(np.ones((2, 2))) == b"1,1\n1,1\n"
    finally:
        csvformat.set_kernel(previous)
    for name in ("r1.csv", "r1.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
