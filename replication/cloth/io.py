"""Cloth trajectory files (docs/data-formats.md): one ``.npz`` per trajectory.

The reader refuses a bad file with one line naming the file, the field, what was found and
what was expected. The writer is deterministic: the same arrays give the same bytes.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from replication.cloth.model import PARAM_NAMES_5, Scene, make_scene
from replication.errors import InputError

REQUIRED = ("positions", "dt", "mass", "gravity", "pinned")
OPTIONAL = ("damping", "velocities", "meta")
_FIXED_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


@dataclass(frozen=True)
class Trajectory:
    """A recorded cloth trajectory. ``positions`` and ``velocities`` are (T, n, n, 3)."""

    positions: np.ndarray
    dt: float
    mass: np.ndarray              # scalar () or (n, n)
    gravity: np.ndarray           # (3,)
    pinned: np.ndarray            # (k, 2) int
    damping: float = 0.0
    velocities: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    source: str = "<memory>"
    stored_as: str = "float64"    # the file's dtype of positions (read as float64)

    @property
    def n(self):
        return self.positions.shape[1]

    @property
    def n_frames(self):
        return self.positions.shape[0]

    def flat_positions(self):
        """Positions as (T, n*n, 3)."""
        return self.positions.reshape(self.n_frames, self.n * self.n, 3)

    def flat_velocities(self):
        """Velocities as (T, n*n, 3): the recorded ones, else (x_t - x_{t-1}) / dt, v_0 = 0."""
        if self.velocities is not None:
            return self.velocities.reshape(self.n_frames, self.n * self.n, 3)
        x = self.flat_positions()
        v = np.zeros_like(x)
        v[1:] = (x[1:] - x[:-1]) / self.dt
        return v

    def scene(self):
        """The model's :class:`Scene` for this data (mesh size, masses, pins, gravity, dt)."""
        return make_scene(self.n, dt=self.dt, mass=self.mass, gravity=self.gravity,
                          damping=self.damping, pinned=self.pinned)


def _fail(path, key, found, expected):
    raise InputError(f"{path}: field '{key}': found {found}; expected {expected}")


def _finite(path, key, array):
    if not np.all(np.isfinite(array)):
        bad = int(np.size(array) - np.count_nonzero(np.isfinite(array)))
        _fail(path, key, f"{bad} NaN or inf value(s)", "finite numbers")


def _real(path, key, array):
    if array.dtype == np.bool_:
        _fail(path, key, "dtype bool", "real numbers (not true/false)")
    if array.dtype == object or not np.issubdtype(array.dtype, np.number):
        _fail(path, key, f"dtype {array.dtype}", "a real numeric array")
    if np.iscomplexobj(array):
        _fail(path, key, f"dtype {array.dtype}", "real numbers")
    return array.astype(float)


def load_npz(path, expected):
    """Every array of the ``.npz`` archive ``path``; one-line :class:`InputError` for a file
    that is not one (a ``.npy`` file, a truncated archive, pickled objects, not UTF-8...).

    Parameters
    ----------
    path : str or Path
    expected : str
        What the file should hold, for the message (``"a cloth trajectory"``).

    Returns
    -------
    dict
        ``{key: ndarray}``.
    """
    reason = None
    try:
        with open(path, "rb") as handle:
            head = handle.read(6)
        if head[:4] not in (b"PK\x03\x04", b"PK\x05\x06") and head != b"\x93NUMPY":
            # numpy takes any other file for a pickle and suggests allow_pickle=True
            raise ValueError(f"it starts with {head!r}, not with a zip archive's b'PK'")
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            reason = f"a single {type(loaded).__name__} (.npy data), not an .npz archive"
        else:
            with loaded as archive:
                return {key: archive[key] for key in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, KeyError,
            UnicodeDecodeError) as error:
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
    raise InputError(f"{path}: cannot be read as .npz ({reason}); expected {expected}")


# coordinates beyond this (in the data's length unit) overflow the model's arithmetic
MAX_COORDINATE = 1e9
# a mesh spanning less than this (in the data's length unit) loses its lengths' digits in
# their squares (1e-200 squares to 0: "particles at the same place")
MIN_EXTENT = 1e-9
# dt, mass, damping and gravity's components beyond this (and dt and masses under its
# inverse) make the model's arithmetic (dt^2, forces over masses) overflow or lose every
# digit: the identifier's costs all come out infinite
MAX_SCALE = 1e9


def _within_scale(path, key, values, what, positive=False):
    """Refuse ``values`` of magnitude over :data:`MAX_SCALE` (and, when ``positive``, under
    its inverse): the model's arithmetic overflows or loses every digit with them."""
    values = np.abs(np.asarray(values, dtype=float))
    largest, smallest = float(values.max()), float(values.min())
    low = 1.0 / MAX_SCALE if positive else 0.0
    if largest > MAX_SCALE or (positive and smallest < low):
        found = largest if largest > MAX_SCALE else smallest
        bounds = (f"between {low:g} and {MAX_SCALE:g}" if positive
                  else f"of magnitude at most {MAX_SCALE:g}")
        _fail(path, key, f"{found:.3g}", f"{what} {bounds} (in the data's units; rescale "
              "the units otherwise: beyond this the model's arithmetic overflows)")


def _check_motion(path, positions, pinned):
    """Refuse coincident neighbours, a cloth that never moves and pinned particles that
    move (more than half a structural spring)."""
    first = positions[0]
    h = np.linalg.norm(first[:, 1:] - first[:, :-1], axis=-1)
    if not np.all(h > 0):
        i, j = np.argwhere(~(h > 0))[0]
        _fail(path, "positions", f"particles ({i}, {j}) and ({i}, {j + 1}) at the same place "
              "in frame 0", "a mesh whose neighbouring particles are apart")
    h = float(np.mean(h))
    moved = float(np.max(np.abs(positions - first)))
    if moved <= 1e-12 * h:
        _fail(path, "positions", f"the same positions in all {positions.shape[0]} frames "
              "(no motion)", "a moving cloth (identification needs motion)")
    if len(pinned):
        track = positions[:, pinned[:, 0], pinned[:, 1]]
        drift = np.linalg.norm(track - track[:1], axis=-1).max(axis=0)
        worst = int(np.argmax(drift))
        if drift[worst] > 0.5 * h:
            i, j = pinned[worst]
            _fail(path, "positions", f"pinned particle ({i}, {j}) moving by "
                  f"{drift[worst] / h:.3g} h", "a cloth whose pinned particles stay in "
                  "place (within 0.5 h)")


def read_trajectory(path):
    """Read and validate a trajectory ``.npz``.

    Raises
    ------
    InputError
        One line naming the file, the field, what was found and what was expected.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"path: a {type(path).__name__}; expected the path of a trajectory "
                         ".npz (a str or pathlib.Path)")
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file; expected a trajectory .npz "
                         "(docs/data-formats.md)")
    if path.is_dir():
        raise InputError(f"{path}: is a folder; expected a trajectory .npz file")
    return _validated(load_npz(path, "a trajectory file as in docs/data-formats.md"), path)


def check_trajectory(trajectory):
    """The reader's checks on a :class:`Trajectory` made in memory (not read from a file):
    the same :class:`InputError` lines, naming ``trajectory.source``.

    Returns
    -------
    Trajectory
        With float arrays and int64 pins, as :func:`read_trajectory` returns them.
    """
    raw = {"positions": np.asarray(trajectory.positions), "dt": np.asarray(trajectory.dt),
           "mass": np.asarray(trajectory.mass), "gravity": np.asarray(trajectory.gravity),
           "pinned": np.asarray(trajectory.pinned), "damping": np.asarray(trajectory.damping)}
    if trajectory.velocities is not None:
        raw["velocities"] = np.asarray(trajectory.velocities)
    where = ("trajectory (made in memory)" if trajectory.source == "<memory>"
             else trajectory.source)
    meta = trajectory.meta
    if not isinstance(meta, dict):
        _fail(where, "meta", f"a {type(meta).__name__}", "a dict")
    _check_truth(where, meta.get("true_params"))
    return replace(_validated(raw, where), meta=meta, source=trajectory.source)


def _validated(raw, path):
    """The :class:`Trajectory` of the arrays ``raw`` (``{key: ndarray}`` of an ``.npz``),
    checked as docs/data-formats.md says; ``path`` names them in messages."""
    for key in REQUIRED:
        if key not in raw:
            _fail(path, key, "no such key (keys: " + ", ".join(sorted(raw)) + ")",
                  "a required key of a trajectory file")

    positions = _real(path, "positions", raw["positions"])
    if positions.ndim != 4 or positions.shape[3] != 3 or positions.shape[1] != positions.shape[2]:
        _fail(path, "positions", f"shape {positions.shape}", "(T, n, n, 3)")
    n_frames, n = positions.shape[0], positions.shape[1]
    if n_frames < 3:
        _fail(path, "positions", f"T = {n_frames} frames", "T >= 3")
    if n < 3:
        _fail(path, "positions", f"n = {n} particles per side", "n >= 3")
    _finite(path, "positions", positions)
    largest = float(np.max(np.abs(positions)))
    if largest > MAX_COORDINATE:
        _fail(path, "positions", f"a coordinate of magnitude {largest:.3g}",
              f"coordinates within +-{MAX_COORDINATE:g}")
    extent = float(np.max(np.ptp(positions[0].reshape(-1, 3), axis=0)))
    if 0 < extent < MIN_EXTENT:
        _fail(path, "positions", f"a mesh spanning {extent:.3g} in frame 0",
              f"a mesh spanning at least {MIN_EXTENT:g} in the data's length unit (rescale "
              "positions and gravity, e.g. to metres or millimetres)")

    dt = _real(path, "dt", raw["dt"])
    if dt.shape != ():
        _fail(path, "dt", f"shape {dt.shape}", "a scalar")
    _finite(path, "dt", dt)
    if dt <= 0:
        _fail(path, "dt", f"{float(dt)}", "a time step > 0")
    _within_scale(path, "dt", dt, "a time step", positive=True)

    mass = _real(path, "mass", raw["mass"])
    if mass.shape not in ((), (n, n)):
        _fail(path, "mass", f"shape {mass.shape}", f"a scalar or ({n}, {n})")
    _finite(path, "mass", mass)
    if np.any(mass <= 0):
        _fail(path, "mass", f"minimum {float(mass.min())}", "masses > 0")
    _within_scale(path, "mass", mass, "masses", positive=True)

    gravity = _real(path, "gravity", raw["gravity"])
    if gravity.shape != (3,):
        _fail(path, "gravity", f"shape {gravity.shape}", "(3,)")
    _finite(path, "gravity", gravity)
    _within_scale(path, "gravity", gravity, "components")

    pinned = raw["pinned"]
    if pinned.size == 0 and pinned.ndim <= 2 and pinned.shape[-1:] in ((0,), (2,)):
        pinned = np.zeros((0, 2), np.int64)  # nothing pinned: [] has no integer dtype
    if not np.issubdtype(pinned.dtype, np.integer):
        _fail(path, "pinned", f"dtype {pinned.dtype}", "integers (i, j)")
    if pinned.ndim != 2 or pinned.shape[1] != 2:
        _fail(path, "pinned", f"shape {pinned.shape}", "(k, 2)")
    outside = (pinned < 0) | (pinned >= n)
    if np.any(outside):
        row = pinned[np.any(outside, axis=1)][0]
        _fail(path, "pinned", f"index ({row[0]}, {row[1]})",
              f"indices inside the {n}x{n} mesh (0..{n - 1})")
    pinned = pinned.astype(np.int64)
    _check_motion(path, positions, pinned)

    damping = 0.0
    if "damping" in raw:
        value = _real(path, "damping", raw["damping"])
        if value.shape != ():
            _fail(path, "damping", f"shape {value.shape}", "a scalar")
        _finite(path, "damping", value)
        if value < 0:
            _fail(path, "damping", f"{float(value)}", "a damping coefficient >= 0")
        _within_scale(path, "damping", value, "a damping coefficient")
        damping = float(value)

    velocities = None
    if "velocities" in raw:
        velocities = _real(path, "velocities", raw["velocities"])
        if velocities.shape != positions.shape:
            _fail(path, "velocities", f"shape {velocities.shape}",
                  f"the shape of positions {positions.shape}")
        _finite(path, "velocities", velocities)

    meta = {}
    if "meta" in raw:
        try:
            meta = json.loads(str(raw["meta"]))
        except json.JSONDecodeError as error:
            _fail(path, "meta", f"invalid JSON ({error.msg})", "a JSON string")
        if not isinstance(meta, dict):
            _fail(path, "meta", f"JSON {type(meta).__name__}", "a JSON object")
        _check_truth(path, meta.get("true_params"))

    return Trajectory(positions=positions, dt=float(dt), mass=mass, gravity=gravity,
                      pinned=pinned, damping=damping, velocities=velocities, meta=meta,
                      source=str(path), stored_as=str(raw["positions"].dtype))


def _positive_number(value):
    """A JSON number that is a positive finite float (not a boolean, not 10**400)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return bool(0.0 < float(value) < np.inf)
    except OverflowError:
        return False


def _check_truth(path, truth):
    """``meta.true_params``, when present, scores answers: each of the 5-parameter model's
    values must be a positive finite number (other keys are free)."""
    if truth is None:
        return
    expected = "true_params: {" + ", ".join(PARAM_NAMES_5) + "} as positive numbers"
    if not isinstance(truth, dict):
        _fail(path, "meta", f"true_params of JSON type {type(truth).__name__}", expected)
    for name in PARAM_NAMES_5:
        value = truth.get(name)
        if not _positive_number(value):
            _fail(path, "meta", f"true_params.{name}={json.dumps(value)[:40]}", expected)


def write_npz_deterministic(path, arrays):
    """Write ``arrays`` (name -> array) as an uncompressed ``.npz`` with fixed zip times,
    so that identical arrays always give identical bytes.

    Parameters
    ----------
    path : str or Path
    arrays : dict
        ``{name: array_like}``; written in key order.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as archive:
        for name in sorted(arrays):
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, np.asarray(arrays[name]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_FIXED_ZIP_TIME)
            info.external_attr = 0o644 << 16
            archive.writestr(info, buffer.getvalue())
    tmp.replace(path)


def write_trajectory(path, trajectory):
    """Write a :class:`Trajectory` as docs/data-formats.md says (deterministic bytes).

    Parameters
    ----------
    path : str or Path
    trajectory : Trajectory
    """
    arrays = {
        "positions": np.asarray(trajectory.positions, dtype=float),
        "dt": np.float64(trajectory.dt),
        "mass": np.asarray(trajectory.mass, dtype=float),
        "gravity": np.asarray(trajectory.gravity, dtype=float),
        "pinned": np.asarray(trajectory.pinned, dtype=np.int64),
        "damping": np.float64(trajectory.damping),
        "meta": np.array(json.dumps(trajectory.meta, sort_keys=True)),
    }
    if trajectory.velocities is not None:
        arrays["velocities"] = np.asarray(trajectory.velocities, dtype=float)
    write_npz_deterministic(path, arrays)


def trajectory_from_rollout(positions, scene: Scene, *, meta=None, velocities=None):
    """Wrap simulated positions (T, n*n, 3) as a :class:`Trajectory` of ``scene``.

    Parameters
    ----------
    positions : (T, n*n, 3) ndarray
    scene : Scene
        Gives ``n``, ``dt``, masses, gravity, damping and the pinned particles.
    meta : dict, optional
        Stored as the file's ``meta`` JSON (``true_params`` for synthetic data).
    velocities : (T, n*n, 3) ndarray, optional
        Stored when given; else derived from positions by the reader.
    """
    n = scene.n
    positions = np.asarray(positions).reshape(-1, n, n, 3)
    mass = scene.mass.reshape(n, n)
    if np.all(mass == mass.flat[0]):
        mass = np.float64(mass.flat[0])
    return Trajectory(positions=positions, dt=scene.dt, mass=mass, gravity=scene.gravity,
                      pinned=scene.pinned, damping=scene.damping,
                      velocities=None if velocities is None else
                      np.asarray(velocities).reshape(-1, n, n, 3),
                      meta=dict(meta or {}))
