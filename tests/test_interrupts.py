"""Interrupts that Python swallows are sent again (replication.interrupts.interruptible).

A signal whose handler raises inside a ``__del__`` or a weakref callback (the module locks'
during an import: CI at eb0ed92) was printed as "Exception ignored in ..." and lost: the run
went on. Each test runs in a process of its own, since it signals that process.
"""

import signal
import subprocess
import sys
import textwrap

import pytest

from tests.conftest import ROOT

SCRIPT = textwrap.dedent("""
    import os, signal, sys, time
    from replication.interrupts import interruptible

    class Late:
        def __del__(self):
            os.kill(os.getpid(), {signum})
            for _ in range(1000):  # the handler runs here, inside __del__
                pass

    try:
        with interruptible(terminate=True):
            Late()
            start = time.monotonic()
            while time.monotonic() - start < 10:
                time.sleep(0.01)
            print("went on")
    except KeyboardInterrupt as error:
        print("interrupted", type(error).__name__, getattr(error, "signum", None))
        sys.exit(130)
""")


def run(script):
    # SIGINT as in a terminal: a shell starts background jobs (`bash run.sh test &`, nohup)
    # with SIGINT ignored, their children inherit that, and Python then installs no
    # handler: the signal would be lost before interruptible could see it
    return subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                          text=True, timeout=60,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_swallowed_in_a_del_is_raised_again(signum):
    done = run(SCRIPT.format(signum=int(signum)))
    assert done.returncode == 130, done.stdout + done.stderr
    name = "Interrupted" if signum == signal.SIGTERM else "KeyboardInterrupt"
    assert done.stdout.split() == ["interrupted", name,
                                   str(int(signum)) if signum == signal.SIGTERM else "None"]
    assert "Exception ignored" not in done.stderr


def test_other_swallowed_errors_are_still_printed_and_the_hooks_restored():
    script = textwrap.dedent("""
        import signal, sys
        from replication.interrupts import interruptible

        class Broken:
            def __del__(self):
                raise ValueError("in __del__")

        hook = sys.unraisablehook
        term = signal.getsignal(signal.SIGTERM)
        with interruptible(terminate=True):
            Broken()
        print(sys.unraisablehook is hook, signal.getsignal(signal.SIGTERM) == term)
    """)
    done = run(script)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True"]
    assert "Exception ignored" in done.stderr and "ValueError: in __del__" in done.stderr
