"""The CSV number format (identification.csvformat.format_rows): ``"%.17g"`` per number, so
every double is read back bit for bit (the dataset contract: numbers round-trip exactly)."""

import numpy as np

from identification.csvformat import format_rows
from identification.dataset import Run, read_run, write_run


def _edge_values():
    v = [0.0, -0.0, 1.0, 0.5, 0.1, 0.3, 1e-4, 1e-5, 9.999999999999999e-5, 1e15, 1e16, 1e17,
         123456789012345678.0, 99999999999999984.0, 1e22, 1e23, 2.0**53, 2.0**53 + 2, 0.001,
         1e16 - 2, 12345.678, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
         1e280, 1e-280, 1.0000000000000002, 0.99999999999999989]
    for k in range(-324, 309):                     # powers of ten and their neighbours
        p = 10.0 ** k
        v += [p, np.nextafter(p, 0.0), np.nextafter(p, np.inf)]
    v = np.array(v)
    return np.concatenate([v, -v])


def _random_values(n=20000, seed=3):
    rng = np.random.default_rng(seed)
    x = np.concatenate([
        rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n),          # all magnitudes
        rng.integers(-2**63, 2**63 - 1, n, dtype=np.int64).view(np.float64),  # any bits
        rng.integers(-2**40, 2**40, n) / 2.0 ** rng.integers(0, 80, n),       # dyadic: ties
        np.arange(n) * 1e-3,                                                  # sample times
    ])
    return x[np.isfinite(x)]


def test_format_is_percent_17g():
    x = np.array([[0.001, -2.5e-07, 3.0], [np.nan, -0.0, 1e300]])
    assert format_rows(x) == b"0.001,-2.4999999999999999e-07,3\nnan,-0,1.0000000000000001e+300\n"
    assert format_rows(np.zeros((0, 4))) == b""


def test_every_double_round_trips():
    x = np.concatenate([_edge_values(), _random_values()])
    back = np.array([float(s) for s in format_rows(x[:, None]).decode("ascii").split()])
    np.testing.assert_array_equal(back.view(np.int64), x.view(np.int64))  # bit for bit, signs too


def test_run_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n) * 1e-3
    run = Run("r1", t, 0.05 * np.sin(t), rng.normal(0, 0.01, n), rng.normal(0, 1, n),
              {"kind": "sine", "gamma1_deg": 30.0, "gamma2_deg": 100.0, "kp": 2.0,
               "frequency_hz": 1.0, "amplitude_rad": 0.05}, extra={"x": rng.normal(0, 1e-9, n)})
    write_run(tmp_path, run)
    back = read_run(tmp_path / "r1.csv")
    for k in ("t", "r", "theta", "v"):
        np.testing.assert_array_equal(getattr(back, k), getattr(run, k))
    np.testing.assert_array_equal(back.extra["x"], run.extra["x"])
