"""Progress on stderr for long runs (stdout stays free for results).

:func:`progress` prints one timestamped line. :func:`bar` follows a loop with its count,
rate and time left::

    for seed in bar(range(20), "seeds"):
        ...
    with bar(49, "EA generations") as generations:
        ...
        generations.update()

How it shows depends on the mode (:func:`set_mode`; the ``progress`` config key,
``replicate --progress=MODE``, ``REPLICATION_PROGRESS`` in the environment, in that order):

- ``bar``: a live bar (alive-progress) with count, rate and time left;
- ``plain``: a line ``[  12.3s] seeds 12/100 (3.1/s, 29 s left)`` at most every
  :data:`PLAIN_INTERVAL` seconds, and the last one, ``seeds 100/100 in 32 s (3.1/s)``;
- ``none``: nothing, neither bars nor :func:`progress` lines;
- ``auto`` (the default): ``bar`` when stderr is a terminal (of non-zero width),
  ``plain`` otherwise.

A loop shorter than :data:`PLAIN_INTERVAL` (``bar`` mode: :data:`BAR_DELAY`) shows nothing.
A bar opened inside another one shows as part of it (the text after the outer bar, or the
end of the outer bar's line). Bars show in the main thread of the main process only: worker
processes and threads stay silent.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
import threading
import time
from contextlib import contextmanager

from replication.errors import check

MODES = ("auto", "bar", "plain", "none")
ENVIRONMENT = "REPLICATION_PROGRESS"
PLAIN_INTERVAL = 5.0   # seconds between two plain lines, and before the first
BAR_DELAY = 1.0        # seconds before a live bar appears

_START = time.perf_counter()
_STATE = {"mode": "auto", "last_line": -math.inf}
_OPEN = []             # the bars being shown, outermost first


def check_mode(mode):
    """``mode`` if it is one of :data:`MODES` (``None`` is ``auto``); else InputError."""
    mode = "auto" if mode is None else mode
    check(mode in MODES, f"progress={mode!r}: expected one of {', '.join(MODES)}")
    return mode


def check_environment(environ=None):
    """Refuse a :data:`ENVIRONMENT` value that is not one of :data:`MODES` (unset is
    ``auto``): a misspelt one would otherwise quietly mean ``auto``.

    Parameters
    ----------
    environ : mapping, optional
        The environment (default ``os.environ``).
    """
    value = (os.environ if environ is None else environ).get(ENVIRONMENT)
    check(value is None or value in MODES,
          f"{ENVIRONMENT}={value!r} in the environment: expected one of {', '.join(MODES)} "
          "(or unset)")


def set_mode(mode):
    """Set how progress shows for the rest of the process (see the module docstring)."""
    _STATE["mode"] = check_mode(mode)


@contextmanager
def mode_for(mode):
    """Progress mode ``mode`` during the block, the previous one after it."""
    previous = _STATE["mode"]
    set_mode(mode)
    try:
        yield
    finally:
        _STATE["mode"] = previous


def current_mode():
    """The mode in force: ``bar``, ``plain`` or ``none`` (``auto`` resolved)."""
    mode = _STATE["mode"]
    if mode == "auto":
        mode = os.environ.get(ENVIRONMENT, "auto")
        mode = mode if mode in MODES else "auto"
    if mode == "auto":
        mode = "bar" if _is_terminal(sys.stderr) else "plain"
    return mode


def _is_terminal(stream):
    """A terminal a bar can be drawn on: a tty whose width is not 0 (a pseudo-terminal
    without a size, as some job runners make, shows a bar as nothing)."""
    isatty = getattr(stream, "isatty", None)
    if isatty is None or not isatty():
        return False
    try:
        return os.get_terminal_size(stream.fileno()).columns > 0
    except (AttributeError, OSError, ValueError):  # no file descriptor: width unknown
        return True


def progress(message):
    """Print ``[  12.3s] message`` to stderr, flushed at once (not in mode ``none``)."""
    if current_mode() != "none":
        print(f"[{time.perf_counter() - _START:7.1f}s] {message}", file=sys.stderr,
              flush=True)


def _shown_here():
    return (threading.current_thread() is threading.main_thread()
            and multiprocessing.parent_process() is None)


def duration(seconds):
    """``42 s``, ``3 min 05 s``, ``2 h 07 min``."""
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


def rate_text(count, seconds):
    """Items per second (or per minute when slow), e.g. ``3.1/s``.

    Parameters
    ----------
    count : int
        Steps done.
    seconds : float
        Time they took.
    """
    rate = count / seconds if seconds > 0 else math.inf
    if rate >= 0.1 or rate == 0:
        return f"{rate:.3g}/s" if math.isfinite(rate) else "-/s"
    return f"{60 * rate:.2g}/min"


class Bar:
    """Progress of one loop; made by :func:`bar`.

    Parameters
    ----------
    items : iterable, int or None
        What the loop goes over (iterate the bar), or the number of steps (call
        :meth:`update` in a ``with`` block).
    label : str
        What is counted: ``"seeds"``, ``"omega sweep"``.
    total : int, optional
        Number of steps when ``items`` has no ``len()``.
    """

    def __init__(self, items, label, *, total=None):
        if isinstance(items, int):
            items, total = None, items
        elif total is None and items is not None:
            try:
                total = len(items)
            except TypeError:
                total = None
        self.items, self.label, self.total = items, label, total
        self.count = 0
        self.start = None
        self.mode = "none"
        self._live = None      # the alive-progress bar (outermost bar, mode bar)
        self._live_context = None

    # ------------------------------------------------------------ the loop
    def __iter__(self):
        with self:
            for item in self.items:
                yield item
                self.update()

    def __enter__(self):
        self.start = time.perf_counter()
        self.mode = current_mode() if _shown_here() else "none"
        if self.mode != "none":
            _OPEN.append(self)
        return self

    def __exit__(self, *exc_info):
        self.close(finished=exc_info[0] is None)
        return False

    def update(self, n=1):
        """``n`` more steps done."""
        self.count += n
        if self.mode == "none" or self not in _OPEN:
            return
        elapsed = time.perf_counter() - self.start
        if self.mode == "plain":
            self._plain_line()
        elif _OPEN[0] is self:
            if self._live is not None:
                self._live(n)
            elif elapsed >= BAR_DELAY:
                self._start_live()
        else:
            _OPEN[0].show_inner()

    def close(self, finished=True):
        """End the bar; in mode ``plain`` print its last line when it showed any."""
        if self not in _OPEN:
            return
        outermost = _OPEN[0] is self
        _OPEN.remove(self)
        elapsed = time.perf_counter() - self.start
        if self._live_context is not None:
            self._live_context.__exit__(None, None, None)
            self._live = self._live_context = None
        elif self.mode == "plain" and outermost and finished and elapsed >= PLAIN_INTERVAL:
            progress(f"{self.label} {self._count_text()} in {duration(elapsed)} "
                     f"({rate_text(self.count, elapsed)})")
        if _OPEN and self.mode == "bar":
            _OPEN[0].show_inner()

    # ------------------------------------------------------------ what shows
    def _count_text(self):
        return f"{self.count}/{self.total}" if self.total is not None else f"{self.count}"

    def status(self):
        """``label 12/100 (3.1/s, 29 s left)``: the count, the rate and the time left."""
        elapsed = time.perf_counter() - self.start
        parts = [rate_text(self.count, elapsed)]
        if self.total is not None:
            if self.count > 0:
                left = (self.total - self.count) * elapsed / self.count
                parts.append(f"{duration(left)} left")
            else:
                parts.append("time left unknown")
        return f"{self.label} {self._count_text()} ({', '.join(parts)})"

    def _plain_line(self):
        now = time.perf_counter()
        if (now - _OPEN[0].start >= PLAIN_INTERVAL
                and now - _STATE["last_line"] >= PLAIN_INTERVAL):
            _STATE["last_line"] = now
            progress(" | ".join(bar.status() for bar in _OPEN))

    def _start_live(self):
        from alive_progress import alive_bar

        self._live_context = alive_bar(self.total, title=self.label, file=sys.stderr,
                                       force_tty=True, refresh_secs=0.2, length=30,
                                       enrich_print=False)
        self._live = self._live_context.__enter__()
        if self.count and self.total:
            self._live(self.count, skipped=True)  # done before the bar: not in its rate
        elif self.count:
            self._live(self.count)

    def show_inner(self):
        """Show the bars opened inside this one after its live bar."""
        if self._live is None and time.perf_counter() - self.start >= BAR_DELAY:
            self._start_live()
        if self._live is not None:
            inner = [bar.status() for bar in _OPEN[1:]]
            self._live.text = " | ".join(inner) if inner else ""


def bar(items, label, *, total=None):
    """A :class:`Bar` over ``items`` (an iterable, or a number of steps) named ``label``.

    Parameters
    ----------
    items : iterable or int
        What the loop goes over (iterate the bar), or its number of steps (then use it in a
        ``with`` block and call :meth:`Bar.update`).
    label : str
        What is counted (``"seeds"``).
    total : int, optional
        Number of steps when ``items`` has no ``len()`` (a generator).
    """
    return Bar(items, label, total=total)
