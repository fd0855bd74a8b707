"""The slow stage's order for work stealing (tests/conftest.py's ``worksteal_order``)."""

from __future__ import annotations

from conftest import worksteal_order


def test_each_worker_share_starts_longest_and_balances():
    seconds = {"a": 100.0, "b": 90.0, "c": 50.0, "d": 45.0, "e": 10.0, "f": 5.0, "g": 1.0}
    items = list("gfedcba")  # collection order: shortest first
    out = worksteal_order(items, seconds.get, 2)
    assert sorted(out) == sorted(items)
    first, second = out[:3], out[3:]  # pytest-xdist hands 7 // 2 = 3 to the first worker
    for share in (first, second):
        assert [seconds[x] for x in share] == sorted((seconds[x] for x in share), reverse=True)
    assert {first[0], second[0]} == {"a", "b"}  # the two longest start at once
    assert abs(sum(map(seconds.get, first)) - sum(map(seconds.get, second))) <= 45.0


def test_unknown_tests_count_as_short():
    """A test without a recorded duration counts as 0 s: after the known ones, on the less
    loaded worker first (here the second, while the first holds the 9 s test)."""
    out = worksteal_order(["x", "y", "long", "z"], lambda t: {"long": 9.0}.get(t, 0.0), 2)
    assert out == ["long", "z", "x", "y"]
