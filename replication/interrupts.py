"""Signals around compiled code.

A ``KeyboardInterrupt`` (Ctrl-C) or the time limit's exception raised while numba's
dispatcher is in Python (unpickling, type dispatch) surfaces as ``SystemError: ...
returned a result with an exception set``, or worse. :func:`deferred` holds SIGINT,
SIGTERM and SIGALRM during a compiled call and delivers them right after it.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)


@contextmanager
def deferred():
    """Hold SIGINT, SIGTERM and SIGALRM during the block (a handler that raises inside a
    compiled call leaves it with an exception set: a traceback, not the handler's error);
    deliver them to their previous handlers after it (SIGINT's default raises
    ``KeyboardInterrupt``, SIGTERM's default ends the process). Outside the main thread
    the block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []

    def hold(signum, frame):
        caught.append(signum)

    previous = {signum: signal.signal(signum, hold) for signum in HELD}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    for signum in dict.fromkeys(caught):
        handler = previous[signum]
        if callable(handler):
            handler(signum, None)
        elif signum == signal.SIGINT:
            raise KeyboardInterrupt
        elif signum == signal.SIGTERM and handler == signal.SIG_DFL:
            signal.raise_signal(signum)
