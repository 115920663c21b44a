"""Checks at the command line's boundary (docs/results.md, "Refusals and warnings").

Before any work, a run's resolved config is checked against its experiment's own config
(the values the experiment file gives, before any override): an override must have the
type of the value it replaces (an integer stays an integer, a boolean a boolean, a number a
finite number), ``seed`` is an integer >= 0, ``resume``, ``strict`` and ``force`` are
booleans, ``progress`` is one of ``auto, bar, plain, none``, ``out`` is a non-empty folder
outside the committed ``results/`` (unless ``force=true``), ``data.path`` is a regular
file or a folder of regular files no larger than ``limits.max_input_mb``. Every refusal
is an :class:`InputError` (one line, exit 2).

:data:`LIMITS` holds the size and time limits of the running command (the config's
``limits`` block), read by the data readers.
"""

from __future__ import annotations

import math
import os
import stat
import tempfile
from pathlib import Path

from replication.errors import InputError, check
from replication.progress import check_environment, check_mode
from replication.provenance import PROJECT_ROOT

# defaults of the config's ``limits`` block (configs/config.yaml)
DEFAULT_LIMITS = {
    "max_seconds": 21600,         # a run stops with an error after this many seconds
    "max_input_mb": 2048,         # data.path (file, or folder in all) at most this large
    "max_frame_pixels": 4194304,  # image frames at most 2048 x 2048 pixels
    "max_sweep_values": 100000,   # omega_count and other grid sizes
}
LIMITS = dict(DEFAULT_LIMITS)

BOOLEAN_KEYS = ("resume", "strict", "force")
# config keys naming output folders besides ``out`` (staged like ``out``, replication.cli)
OUTPUT_KEYS = ("figure_dir", "figures_dir", "data_dir")


def set_limits(limits):
    """Set :data:`LIMITS` from a config's ``limits`` block (validated)."""
    limits = {} if limits is None else limits
    check(isinstance(limits, dict), f"limits={limits!r}: expected a mapping")
    unknown = sorted(set(limits) - set(DEFAULT_LIMITS))
    check(not unknown, f"limits.{unknown[0] if unknown else ''}: unknown limit; expected "
                       + ", ".join(DEFAULT_LIMITS))
    merged = dict(DEFAULT_LIMITS)
    for key, value in limits.items():
        if value is None:
            continue
        check(isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value) and value > 0,
              f"limits.{key}={show(value)}: expected a number > 0")
        merged[key] = value
    LIMITS.clear()
    LIMITS.update(merged)
    return merged


def show(value):
    """A config value as the command line spells it: null, true, false, 'text', 1.5."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def _kind(value):
    if isinstance(value, bool):
        return "a boolean (true or false)"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return "null"


def _fits(expected, value):
    """Whether ``value`` may replace ``expected`` (same kind; an integer where a number
    is expected)."""
    if isinstance(expected, bool):
        return isinstance(value, bool)
    if isinstance(expected, int):
        return isinstance(value, int) and not isinstance(value, bool)
    if isinstance(expected, float):
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if isinstance(expected, str):
        return value is None or isinstance(value, (str, int, float)) \
            and not isinstance(value, bool)
    if isinstance(expected, list):
        return isinstance(value, list)
    if isinstance(expected, dict):
        return isinstance(value, dict)
    return True


def check_types(defaults, config, where=""):
    """Refuse values of ``config`` whose kind differs from the experiment's own value in
    ``defaults``, and non-finite numbers where the experiment has a finite one.

    Parameters
    ----------
    defaults : object
        The experiment's value (dict, list or scalar), walked together with ``config``.
    config : object
        The value of the run's config at the same place.
    where : str
        Dotted name of the place, for the message (``method.sigma``).
    """
    if isinstance(defaults, dict) and isinstance(config, dict):
        for key, value in config.items():
            if key in defaults:
                check_types(defaults[key], value, f"{where}.{key}" if where else str(key))
        return
    if isinstance(defaults, list) and isinstance(config, list):
        if not defaults:
            return
        for index, value in enumerate(config):
            model = defaults[index] if index < len(defaults) else defaults[0]
            check_types(model, value, f"{where}[{index}]")
        return
    if not _fits(defaults, config):
        raise InputError(f"{where}={show(config)}: expected {_kind(defaults)} (as in the "
                         f"experiment's config, {defaults!r})")
    if isinstance(config, float) and not math.isfinite(config) \
            and not (isinstance(defaults, float) and not math.isfinite(defaults)):
        raise InputError(f"{where}={show(config)}: expected a finite number")


def inside(path, folder):
    """Whether ``path`` is ``folder`` or below it (both resolved).

    Parameters
    ----------
    path, folder : str or Path
    """
    try:
        Path(path).resolve().relative_to(Path(folder).resolve())
        return True
    except ValueError:
        return False


def protected_folders():
    """Folders a run writes into only with ``force=true``: the committed results."""
    return [PROJECT_ROOT / "results", Path.cwd() / "results"]


COMMITTED = ("results", "figures", "synthetic_data")


def committed_folder(path):
    """The committed folder (``results/``, ``figures/`` or ``synthetic_data/`` of the
    project, or of the working directory) that holds ``path``, or ``None``."""
    for root in dict.fromkeys((PROJECT_ROOT, Path.cwd())):
        for name in COMMITTED:
            if inside(path, root / name):
                return f"{name}/"
    return None


def check_out(out, *, force, key="out"):
    """Refuse an empty ``out`` and, without ``force``, one inside ``results/``.

    Parameters
    ----------
    out : str
        The ``out`` config value.
    force : bool
        ``force=true``: the committed ``results/`` may be written.
    key : str
        The setting that named the folder, for the messages (``hydra.run.dir`` without
        ``out``).
    """
    check(isinstance(out, str), f"{key}={out!r}: expected a folder path")
    check(out.strip() != "", f"{key}=: empty; expected a folder (out=DIR), outside "
                             "results/ unless force=true")
    if not force:
        for folder in protected_folders():
            if inside(out, folder):
                raise InputError(f"{key}={out}: inside results/, the committed results; "
                                 "pass force=true to overwrite them, or out=DIR elsewhere")


def check_writable(out, key="out"):
    """Refuse an output folder that cannot be created or written, without creating it;
    ``key`` names the setting in the messages."""
    out = Path(out)
    probe = out
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise InputError(f"{key}={out}: {probe} is not a folder; expected a folder path")
    try:  # a real write (permissions alone say nothing for root or on /proc), undone
        if probe == out:
            fd, name = tempfile.mkstemp(dir=out, prefix=".write-probe-")
            os.close(fd)
            os.unlink(name)
        else:
            first = out
            while first.parent != probe:
                first = first.parent
            first.mkdir()
            first.rmdir()
    except OSError as error:
        raise InputError(f"{key}={out}: cannot write there ({error.strerror or error})") from None


def input_files(path):
    """The regular files of a data path: ``[path]`` for a file, the files below a folder
    (sorted); refuses a FIFO, socket or device, with one line."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"data.path={path}: no such file or folder")
    if path.is_dir():
        files = []
        for item in sorted(path.rglob("*")):
            mode = item.stat().st_mode
            if stat.S_ISDIR(mode):
                continue
            if not stat.S_ISREG(mode):
                raise InputError(f"{item}: not a regular file (a FIFO, socket or device); "
                                 "expected image frames")
            files.append(item)
        return files
    if not stat.S_ISREG(path.stat().st_mode):
        raise InputError(f"data.path={path}: not a regular file (a FIFO, socket or device); "
                         "expected a data file or folder")
    return [path]


def check_data_path(value):
    """Check ``data.path`` (when set): a string naming a regular file or a folder of them,
    no larger than ``limits.max_input_mb``. Returns the files."""
    if value is None:
        return []
    check(isinstance(value, str) and value.strip() != "",
          f"data.path={value!r}: expected a file or folder path")
    files = input_files(value)
    size = sum(f.stat().st_size for f in files)
    limit = LIMITS["max_input_mb"]
    check(size <= limit * 1e6, f"data.path={value}: {size / 1e6:.0f} MB; expected at most "
                               f"limits.max_input_mb={limit:g} MB")
    return files


def check_config(config, defaults):
    """Every check of this module on a resolved ``config`` (plain dict), before any work.

    ``defaults``: the experiment's config without the command line's overrides.

    Parameters
    ----------
    config : dict
        The resolved config of the run.
    defaults : dict or None
        The experiment's own config (``None``: no type check).
    """
    set_limits(config.get("limits"))
    seed = config.get("seed")
    check(isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0,
          f"seed={show(seed)}: expected an integer >= 0")
    for key in BOOLEAN_KEYS:
        value = config.get(key, False)
        check(isinstance(value, bool), f"{key}={show(value)}: expected true or false")
    check_mode(config.get("progress"))
    check_environment()
    for key in OUTPUT_KEYS:
        value = config.get(key)
        check(not (isinstance(value, str) and value.strip() == ""),
              f"{key}=: empty; expected a folder ({key}=DIR; an empty one would write into "
              "the working directory)")
    if defaults is not None:
        check_types({k: v for k, v in defaults.items() if k not in ("out", "data")},
                    {k: v for k, v in config.items() if k not in ("out", "data")})
    data = config.get("data")
    check(data is None or isinstance(data, dict), f"data={data!r}: expected data.path=PATH")
    check_data_path((data or {}).get("path"))
