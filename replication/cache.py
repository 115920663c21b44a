"""A bounded store of read-only arrays, most recently used kept.

Hot loops that ask for the same derived arrays again and again (a snake's polar maps, the
regression's recorded states and plug-in columns) keep them in a :class:`KeptArrays`: each
value is made once by the caller's ``make()``, frozen (``writeable = False``, so that every
user shares it safely) and dropped, oldest use first, once the store holds more than its
bound. The newest value is always kept, however large.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np


def read_only(value):
    """``value`` (an array or a tuple of them, nested) with every array read-only. An array
    that is a view of another is copied first: what is shared must own its memory, or a
    write to the other array would change it."""
    if isinstance(value, tuple):
        return tuple(read_only(item) for item in value)
    if not isinstance(value, np.ndarray) or value.base is not None:
        value = np.array(value)
    value.flags.writeable = False
    return value


def _nbytes(value):
    if isinstance(value, tuple):
        return sum(_nbytes(item) for item in value)
    return value.nbytes


class KeptArrays:
    """Values (arrays, or tuples of arrays) by hashable key, made once and kept read-only.

    Parameters
    ----------
    max_bytes : int, optional
        Keep at most this many bytes of arrays (the newest value is kept even beyond it).
    max_entries : int, optional
        Keep at most this many values.

    Safe to share between threads: two threads that ask for a missing key at once may both
    make it; one of the two equal values is kept.
    """

    def __init__(self, *, max_bytes=None, max_entries=None):
        if max_entries is not None and max_entries < 1:
            raise ValueError(f"max_entries={max_entries}: expected at least 1")
        self.max_bytes = max_bytes
        self.max_entries = max_entries
        self._values = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def __len__(self):
        return len(self._values)

    def __contains__(self, key):
        return key in self._values

    def keys(self):
        """Keys, least recently used first."""
        return list(self._values)

    @property
    def nbytes(self):
        """Bytes of the kept arrays."""
        return self._bytes

    def get(self, key, make):
        """The value kept for ``key``, or ``make()`` frozen and kept.

        Parameters
        ----------
        key : hashable
            Names the value: everything it depends on.
        make : callable
            ``make()`` returns the value (an array, or a tuple of arrays, nested), called
            only when ``key`` is not kept.
        """
        with self._lock:
            if key in self._values:
                self._values.move_to_end(key)
                return self._values[key]
        value = read_only(make())
        with self._lock:
            if key in self._values:
                self._bytes -= _nbytes(self._values.pop(key))
            self._values[key] = value
            self._bytes += _nbytes(value)
            while len(self._values) > 1 and self._over():
                self._bytes -= _nbytes(self._values.popitem(last=False)[1])
        return value

    def _over(self):
        return ((self.max_bytes is not None and self._bytes > self.max_bytes)
                or (self.max_entries is not None and len(self._values) > self.max_entries))

    def clear(self):
        with self._lock:
            self._values.clear()
            self._bytes = 0
