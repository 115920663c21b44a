"""A fixed reference workload, timed, so that timings of different runs can be compared.

This project's 2-core machine is shared: the same forced regeneration took 1031 s one day
and 1412 s another, with every result identical. A time alone therefore cannot say whether
the code or the machine changed. Every record of a suite-wide time (``replicate-all``'s
``regenerate*.json``, the test suite's ``tests.json``, ``replicate experiment=bench``)
also holds :func:`reference_seconds` measured in the same run: two timings compare through
their ratio to it.
"""

from __future__ import annotations

import time

import numpy as np

# sizes of the workload: about 0.08 s per repeat on the project's machine (best of 15:
# within about 2% between calls on an idle machine; best of 5 varied by 20%)
_LOOP = 1_000_000
_ARRAY = 1_000_000


def _workload():
    """Interpreted code (the optimisers' own Python: a loop of float arithmetic) and
    compiled code on one thread (numpy: random numbers, a sort, a square root; no BLAS,
    whose thread count the runs set differently), on fixed data."""
    total = 0.0
    for i in range(_LOOP):
        total += (i % 7) * 0.5
    values = np.sort(np.random.default_rng(0).random(_ARRAY))
    return total + float(np.sqrt(values).sum())


def reference_seconds(repeats=15):
    """Seconds the reference workload takes on this machine now: the best of ``repeats``
    timings (the least disturbed by other processes).

    Parameters
    ----------
    repeats : int
        Timings taken; at least 1.
    """
    best = float("inf")
    for _ in range(max(int(repeats), 1)):
        start = time.perf_counter()
        _workload()
        best = min(best, time.perf_counter() - start)
    return best
