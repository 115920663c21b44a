"""The bounded store of read-only arrays (replication/cache.py)."""

import threading

import numpy as np
import pytest

from replication.cache import KeptArrays


def test_a_value_is_made_once_and_shared_read_only():
    kept, calls = KeptArrays(max_entries=2), []

    def make():
        calls.append(1)
        return np.arange(4.0), (np.ones(2), np.zeros(3, int))
    first = kept.get("a", make)
    assert kept.get("a", make) is first and len(calls) == 1
    for array in (first[0], first[1][0], first[1][1]):
        with pytest.raises(ValueError):
            array[0] = 5


def test_a_view_is_copied_before_it_is_kept():
    owner = np.arange(6.0)
    view = KeptArrays().get("v", lambda: owner[2:4])
    owner[2] = -1.0                    # the owner stays writable and its change is not seen
    assert view.tolist() == [2.0, 3.0] and owner.flags.writeable


def test_the_least_recently_used_go_first_when_entries_are_bounded():
    kept = KeptArrays(max_entries=2)
    for key in "abc":
        kept.get(key, lambda: np.zeros(1))
    assert kept.keys() == ["b", "c"]
    kept.get("b", lambda: pytest.fail("b is kept"))   # a use makes it the newest
    kept.get("d", lambda: np.zeros(1))
    assert kept.keys() == ["b", "d"]


def test_bytes_stay_within_the_bound_but_the_newest_value_is_always_kept():
    kept = KeptArrays(max_bytes=100)
    kept.get("small", lambda: np.zeros(5))           # 40 bytes
    kept.get("small2", lambda: np.zeros(5))          # 80
    assert kept.keys() == ["small", "small2"] and kept.nbytes == 80
    kept.get("mid", lambda: np.zeros(4))             # 112: the oldest goes
    assert kept.keys() == ["small2", "mid"] and kept.nbytes == 72
    kept.get("huge", lambda: np.zeros(100))          # alone above the bound: kept alone
    assert kept.keys() == ["huge"] and kept.nbytes == 800
    kept.clear()
    assert len(kept) == 0 and kept.nbytes == 0


def test_threads_share_one_store():
    kept = KeptArrays(max_entries=8)
    seen = []

    def work(i):
        seen.append(kept.get(i % 4, lambda: np.full(3, float(i % 4)))[0])
    threads = [threading.Thread(target=work, args=(i,)) for i in range(32)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(kept.keys()) == [0, 1, 2, 3] and sorted(set(seen)) == [0.0, 1.0, 2.0, 3.0]
    assert kept.nbytes == 4 * 24


def test_a_bound_of_no_entries_is_refused():
    with pytest.raises(ValueError, match="max_entries"):
        KeptArrays(max_entries=0)
