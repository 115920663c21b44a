"""Ctrl-C around compiled code.

A ``KeyboardInterrupt`` raised while numba's dispatcher is in Python (unpickling, type
dispatch) surfaces as ``SystemError: ... returned a result with an exception set`` or
worse. :func:`deferred` holds SIGINT during a compiled call and raises the interrupt
right after it.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager


@contextmanager
def deferred():
    """Hold Ctrl-C (SIGINT) during the block; raise ``KeyboardInterrupt`` after it when
    one arrived. Outside the main thread the block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []

    def hold(signum, frame):
        caught.append(signum)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt
