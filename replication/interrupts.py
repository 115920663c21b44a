"""Signals around compiled code.

A ``KeyboardInterrupt`` (Ctrl-C) or the time limit's exception raised while numba's
dispatcher is in Python (unpickling, type dispatch) surfaces as ``SystemError: ...
returned a result with an exception set``, or worse. :func:`deferred` holds SIGINT,
SIGTERM and SIGALRM during a compiled call and delivers them right after it.

An interrupt raised where Python cannot propagate it (in a ``__del__`` or a weakref
callback, such as the module locks' during an import: "Exception ignored in ...") is lost,
and the run goes on. :func:`interruptible` sends such a signal again, so it surfaces at the
next line of ordinary code.
"""

from __future__ import annotations

import _thread
import signal
import sys
import threading
from contextlib import contextmanager

HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)
AGAIN_AFTER = 0.05  # seconds before a swallowed interrupt is sent again


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM during a run; ``signum`` is the signal."""

    def __init__(self, signum=signal.SIGINT):
        super().__init__()
        self.signum = signum


@contextmanager
def interruptible(terminate=False):
    """Interrupts during the block are not lost where Python swallows exceptions.

    A ``KeyboardInterrupt`` (or :class:`Interrupted`) that reaches ``sys.unraisablehook``
    (raised inside a ``__del__`` or a weakref callback, e.g. while a module is imported)
    is not printed as "Exception ignored": its signal is sent again, so it is raised at
    the next line of ordinary code. With ``terminate``, SIGTERM raises
    :class:`Interrupted` in the main thread (a caller's ``except KeyboardInterrupt`` then
    cleans up) instead of ending the process on the spot. Outside the main thread the
    block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous_hook = sys.unraisablehook

    def send_again(unraisable):
        error = unraisable.exc_value
        if isinstance(error, KeyboardInterrupt):
            # from another thread, a moment later: a signal sent from here is handled
            # here, inside the hook, and lost again
            again = threading.Timer(AGAIN_AFTER, _thread.interrupt_main,
                                    args=(getattr(error, "signum", signal.SIGINT),))
            again.daemon = True
            again.start()
        else:
            previous_hook(unraisable)

    def raise_interrupted(signum, frame):
        raise Interrupted(signum)

    previous_term = signal.signal(signal.SIGTERM, raise_interrupted) if terminate else None
    sys.unraisablehook = send_again
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        if terminate:
            signal.signal(signal.SIGTERM, previous_term)


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
