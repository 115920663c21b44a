"""Progress lines on stderr for long runs (stdout stays free for results)."""

import sys
import time

_START = time.perf_counter()


def progress(message):
    """Print ``[  12.3s] message`` to stderr, flushed at once."""
    print(f"[{time.perf_counter() - _START:7.1f}s] {message}", file=sys.stderr, flush=True)
