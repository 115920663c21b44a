"""Progress bars: count, rate and time left; plain lines off a terminal; silent when asked.

The tests run with ``REPLICATION_PROGRESS=none`` (tests/conftest.py); each case here sets
the mode it checks. ``PLAIN_INTERVAL`` and ``BAR_DELAY`` are set to 0 so that short loops
show what long ones do.
"""

import io
import os
import re
import sys
import time
from pathlib import Path

import pytest

from replication import progress
from replication.regenerate import run_scheduled

from .test_bad_input import assert_refused, redirected, replicate

ROOT = Path(__file__).resolve().parent.parent
SEQUENCE = ROOT / "synthetic_data" / "motion" / "acc12_three_frames.npz"
LINE = r"\[ *[\d.]+s\] "


@pytest.fixture
def fast(monkeypatch):
    monkeypatch.setattr(progress, "PLAIN_INTERVAL", 0.0)
    monkeypatch.setattr(progress, "BAR_DELAY", 0.0)


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


def test_plain_lines_show_nested_counts_rates_and_time_left(fast, capsys):
    with progress.mode_for("plain"):
        for _ in progress.bar(range(3), "seeds"):
            with progress.bar(4, "EA generations") as generations:
                for _ in range(4):
                    time.sleep(0.002)
                    generations.update()
    lines = capsys.readouterr().err.splitlines()
    assert re.fullmatch(LINE + r"seeds 0/3 \([\d.]+/s, time left unknown\) \| "
                        r"EA generations 1/4 \([\d.]+/s, 0 s left\)", lines[0]), lines
    assert re.fullmatch(LINE + r"seeds 1/3 \([\d.]+/s, 0 s left\)", lines[4]), lines
    assert re.fullmatch(LINE + r"seeds 3/3 in 0 s \([\d.]+/s\)", lines[-1]), lines


def test_plain_lines_are_spaced_and_short_loops_print_nothing(capsys):
    with progress.mode_for("plain"):
        for _ in progress.bar(range(50), "quick"):
            pass
        progress.progress("a message")
    assert capsys.readouterr().err.splitlines()[-1].endswith("] a message")


def test_live_bar_on_a_terminal(fast, monkeypatch):
    terminal = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    monkeypatch.delenv(progress.ENVIRONMENT)
    assert progress.current_mode() == "bar"
    for _ in progress.bar(range(20), "omega sweep"):
        time.sleep(0.02)
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", terminal.getvalue())
    assert re.search(r"omega sweep .* \d+/20 \[\d+%\] in [\d.]+s \(~[\d.]+s, [\d.]+/s\)",
                     text), text                                  # count, time left, rate
    assert re.search(r"20/20 \[100%\] in [\d.]+s \([\d.]+/s\)", text), text


def test_none_shows_nothing(fast, capsys):
    with progress.mode_for("none"):
        for _ in progress.bar(range(5), "seeds"):
            progress.progress("hidden")
    assert capsys.readouterr().err == ""


def test_mode_comes_from_the_setting_then_the_environment(monkeypatch):
    monkeypatch.setenv(progress.ENVIRONMENT, "plain")
    assert progress.current_mode() == "plain"
    with progress.mode_for("none"):
        assert progress.current_mode() == "none"
    assert progress.current_mode() == "plain"
    with pytest.raises(ValueError, match="progress='maybe': expected one of auto, bar"):
        progress.set_mode("maybe")


def test_replicate_shows_the_omega_sweep_with_time_left(fast, tmp_path, capsys):
    args = [*redirected("motion_single", tmp_path / "work"), f"data.path={SEQUENCE}",
            "method.omega_count=40", "figures=false"]
    status, err = replicate(capsys, "--progress=plain", *args)
    assert status == 0, err
    assert re.search(LINE + r"omega sweep 20/40 \([\d.]+/s, \d+ s left\)", err), err
    assert re.search(LINE + r"omega sweep 40/40 in \d+ s \([\d.]+/s\)", err), err
    status, err = replicate(capsys, "--quiet", *args, f"out={tmp_path / 'quiet'}")
    assert status == 0 and not re.search(LINE, err), err     # no bar, no progress lines
    assert progress.current_mode() == "none"                  # tests: none by default


def test_bad_progress_setting_is_refused(tmp_path, capsys):
    status, err = replicate(capsys, *redirected("fig08_mesh", tmp_path / "work"),
                            "--progress=maybe")
    assert_refused(status, err, "progress='maybe': expected one of auto, bar, plain, none",
                   tmp_path)


def test_replicate_all_counts_finished_experiments(fast, tmp_path, capsys):
    blocks = {"a": {}, "b": {}}
    command = [sys.executable, "-c", "import os; print(os.environ['REPLICATION_PROGRESS'])"]
    with progress.mode_for("plain"):
        run_scheduled(list(blocks), blocks, jobs=1, expected={},
                      command_for=lambda name: command, log_dir=tmp_path, echo=False)
    err = capsys.readouterr().err
    assert re.search(LINE + r"experiments 1/2 \([\d.]+/s, \d+ s left\)", err), err
    assert (tmp_path / "a.log").read_text() == "plain\n"     # the experiments' own lines


def test_a_terminal_without_a_width_gets_plain_lines(monkeypatch):
    class SizelessTerminal(FakeTerminal):
        def fileno(self):
            return 2

    monkeypatch.setattr(sys, "stderr", SizelessTerminal())
    monkeypatch.delenv(progress.ENVIRONMENT)
    monkeypatch.setattr(progress.os, "get_terminal_size", lambda fd: os.terminal_size((0, 0)))
    assert progress.current_mode() == "plain"
