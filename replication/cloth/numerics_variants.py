"""Readings of the cloth model's numerics that the paper leaves open (issue 12, Table 1).

The paper (section 3) does not give its time step, how often or in which order Provot's
deformation constraint is applied, whether the model is damped, nor the floating-point
precision. The suite's contract (docs/cloth-model.md) fixes them; this module offers other
readings for the Table 1 sensitivity study (``table1_reading``), and only for it: the
suite's model (``model.py``, ``kernels.py``) is not changed.

:class:`Numerics` (config block ``numerics``):

- ``dt``: the model's time step; ``null`` is the data's frame interval. One frame of the
  data is covered by ``frame_dt / dt`` steps (an integer).
- ``constraint_passes``: passes of the deformation constraint per step (contract: 1).
- ``constraint``: ``jacobi`` (contract: every over-stretched spring proposes a correction
  computed from the same positions, each particle moves by the mean of its proposals) or
  ``gauss_seidel`` (springs in order, each correction applied at once, as a sequential
  projection does).
- ``damping``: linear damping coefficient ``c`` of ``-c v`` (``null``: the data's, 0).
- ``dtype``: ``float64`` (contract) or ``float32``: state, forces and corrections stored in
  single precision, rounded at every write (as C ``float`` variables with expressions
  evaluated in double, which is what K&R C compilers of 1995 did).

With the defaults the step is exactly the contract's: same operations in the same order
(``tests/cloth/test_numerics_variants.py`` holds it bit for bit to ``kernels.py``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numba import njit, prange

from replication.cloth.costs import ClothCost
from replication.cloth.io import Trajectory
from replication.cloth.kernels import add_scaled, propose_correction
from replication.errors import check

CONSTRAINTS = ("jacobi", "gauss_seidel")
DTYPES = ("float64", "float32")


@dataclass(frozen=True)
class Numerics:
    """One reading of the model's numerics; the defaults are the contract's."""

    dt: float | None = None
    constraint_passes: int = 1
    constraint: str = "jacobi"
    damping: float | None = None
    dtype: str = "float64"

    @classmethod
    def from_config(cls, cfg):
        """From the config block ``numerics`` (keys of this class plus ``reference``)."""
        cfg = {key: value for key, value in (cfg or {}).items() if key != "reference"}
        unknown = set(cfg) - set(cls.__dataclass_fields__)
        check(not unknown, f"numerics: unknown setting(s) {sorted(unknown)}; expected some "
                           f"of {sorted(cls.__dataclass_fields__)} and reference")
        numerics = cls(**cfg)
        numerics.validate()
        return numerics

    def validate(self):
        """Refuse readings the step cannot run (InputError naming the setting)."""
        check(self.dt is None or (np.isfinite(self.dt) and self.dt > 0),
              f"numerics.dt={self.dt}: expected a positive time step or null")
        check(isinstance(self.constraint_passes, int) and self.constraint_passes >= 0,
              f"numerics.constraint_passes={self.constraint_passes}: expected an integer >= 0")
        check(self.constraint in CONSTRAINTS,
              f"numerics.constraint={self.constraint!r}: expected one of {CONSTRAINTS}")
        check(self.damping is None or (np.isfinite(self.damping) and self.damping >= 0),
              f"numerics.damping={self.damping}: expected a coefficient >= 0 or null")
        check(self.dtype in DTYPES, f"numerics.dtype={self.dtype!r}: expected one of {DTYPES}")

    @property
    def is_contract(self):
        """Whether this reading is the contract's step (every setting at its default)."""
        return self == Numerics()

    def as_dict(self):
        return asdict(self)

    def substeps(self, frame_dt):
        """Model steps per data frame: ``frame_dt / dt`` (refused unless an integer)."""
        if self.dt is None:
            return 1
        ratio = frame_dt / self.dt
        steps = int(round(ratio))
        check(steps >= 1 and abs(ratio - steps) < 1e-9 * max(1.0, ratio),
              f"numerics.dt={self.dt}: the data's frame interval {frame_dt} is not a whole "
              "number of steps; expected dt = frame interval / integer")
        return steps

    def kernel_args(self, scene, frame_dt):
        """Scene arguments of the variant kernels: the scene's, with this reading's dt,
        damping and precision, then steps per frame, passes and Gauss-Seidel flag."""
        dtype = np.dtype(self.dtype)
        steps = self.substeps(frame_dt)
        damping = scene.damping if self.damping is None else self.damping
        return (scene.spring_a, scene.spring_b, scene.spring_type, scene.free,
                scene.mass.astype(dtype), scene.gravity.astype(dtype), float(damping),
                float(frame_dt / steps), steps, int(self.constraint_passes),
                self.constraint == "gauss_seidel")


@njit(cache=True, fastmath=False, nogil=True)
def _project(x_out, rest, tau, sa, sb, st, free, corr, count, passes, gauss_seidel):
    """Provot's deformation constraint on ``x_out``, ``passes`` times: a Jacobi pass (the
    contract's, mean of the proposals) or a Gauss-Seidel pass (each spring at once)."""
    n_particles = x_out.shape[0]
    n_springs = sa.shape[0]
    for _ in range(passes):
        if not gauss_seidel:
            for p in range(n_particles):
                for c in range(3):
                    corr[p, c] = 0.0
                count[p] = 0.0
        for s in range(n_springs):
            a = sa[s]
            b = sb[s]
            t = st[s]
            d0 = x_out[b, 0] - x_out[a, 0]
            d1 = x_out[b, 1] - x_out[a, 1]
            d2 = x_out[b, 2] - x_out[a, 2]
            length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            limit = (1.0 + tau[t]) * rest[t]
            if length > limit and gauss_seidel:   # each spring moves its ends at once
                propose_correction(a, b, d0, d1, d2, length, limit, free, x_out, count)
            elif length > limit:   # Jacobi (the contract's): proposals, averaged after the pass
                propose_correction(a, b, d0, d1, d2, length, limit, free, corr, count)
        if not gauss_seidel:
            for p in range(n_particles):
                if count[p] > 0.0:
                    for c in range(3):
                        x_out[p, c] += corr[p, c] / count[p]


@njit(cache=True, fastmath=False, nogil=True)
def _variant_step_into(x, v, rest, k, tau, sa, sb, st, free, mass, gravity, damping, dt,
                       passes, gauss_seidel, force, corr, count, x_out, v_out):
    """One step of the reading: the contract's ``_step_into`` (kernels.py) with
    ``passes`` constraint passes, Jacobi or Gauss-Seidel; arrays in the reading's dtype."""
    n_particles = x.shape[0]
    n_springs = sa.shape[0]
    for p in range(n_particles):
        for c in range(3):
            force[p, c] = mass[p] * gravity[c] - damping * v[p, c]
    for s in range(n_springs):
        a = sa[s]
        b = sb[s]
        t = st[s]
        d0 = x[b, 0] - x[a, 0]
        d1 = x[b, 1] - x[a, 1]
        d2 = x[b, 2] - x[a, 2]
        length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length > 0.0:
            scale = k[t] * (length - rest[t]) / length
            add_scaled(force, a, scale, d0, d1, d2)
            add_scaled(force, b, -scale, d0, d1, d2)
    for p in range(n_particles):
        for c in range(3):
            if free[p]:
                vel = v[p, c] + dt * force[p, c] / mass[p]
            else:
                vel = 0.0
            x_out[p, c] = x[p, c] + dt * vel
    _project(x_out, rest, tau, sa, sb, st, free, corr, count, passes, gauss_seidel)
    for p in range(n_particles):
        for c in range(3):
            if free[p]:
                v_out[p, c] = (x_out[p, c] - x[p, c]) / dt
            else:
                v_out[p, c] = 0.0


@njit(cache=True, fastmath=False, nogil=True)
def _frame_into(x, v, rest, k, tau, sa, sb, st, free, mass, gravity, damping, dt, steps,
                passes, gauss_seidel, force, corr, count, x_mid, v_mid, x_out, v_out):
    """``steps`` steps of the reading from (x, v): one frame of the data."""
    if steps == 1:
        _variant_step_into(x, v, rest, k, tau, sa, sb, st, free, mass, gravity, damping, dt,
                           passes, gauss_seidel, force, corr, count, x_out, v_out)
        return
    x_mid[:] = x
    v_mid[:] = v
    for _ in range(steps):
        _variant_step_into(x_mid, v_mid, rest, k, tau, sa, sb, st, free, mass, gravity,
                           damping, dt, passes, gauss_seidel, force, corr, count, x_out,
                           v_out)
        x_mid[:] = x_out
        v_mid[:] = v_out


@njit(cache=True, parallel=True)
def variant_one_step_errors(xs, vs, frames, rest, k, tau, dtc, sa, sb, st, free, mass,
                            gravity, damping, dt, steps, passes, gauss_seidel):
    """``kernels.one_step_errors`` under a reading (no extra force): ``e`` (B, F), the
    prediction of frame t+1 from the recorded frame t, in the dtype of ``xs``.

    Parameters
    ----------
    xs, vs : (T, P, 3) ndarray
        Recorded positions and velocities in the reading's dtype.
    frames : (F,) int ndarray
    rest, k, tau : (B, 6) ndarray in the reading's dtype
    dtc : float
    sa, sb, st, free, mass, gravity, damping, dt, steps, passes, gauss_seidel
        As :meth:`Numerics.kernel_args` gives them.
    """
    n_batch = rest.shape[0]
    n_frames = frames.shape[0]
    n_particles = xs.shape[1]
    errors = np.empty((n_batch, n_frames))
    for job in prange(n_batch * n_frames):
        i = job // n_frames
        f = job % n_frames
        t = frames[f]
        force = np.empty((n_particles, 3), dtype=xs.dtype)
        corr = np.empty((n_particles, 3), dtype=xs.dtype)
        count = np.empty(n_particles, dtype=xs.dtype)
        x_mid = np.empty((n_particles, 3), dtype=xs.dtype)
        v_mid = np.empty((n_particles, 3), dtype=xs.dtype)
        x_hat = np.empty((n_particles, 3), dtype=xs.dtype)
        v_hat = np.empty((n_particles, 3), dtype=xs.dtype)
        _frame_into(xs[t], vs[t], rest[i], k[i], tau[i], sa, sb, st, free, mass, gravity,
                    damping, dt, steps, passes, gauss_seidel, force, corr, count, x_mid,
                    v_mid, x_hat, v_hat)
        total = 0.0
        for p in range(n_particles):
            for c in range(3):
                dx = np.float64(x_hat[p, c]) - np.float64(xs[t + 1, p, c])
                dv = np.float64(v_hat[p, c]) - np.float64(vs[t + 1, p, c])
                total += dx * dx + dtc * dtc * dv * dv
        if not np.isfinite(total):
            total = np.inf
        errors[i, f] = total
    return errors


@njit(cache=True)
def variant_rollout(x0, v0, rest, k, tau, n_frames, sa, sb, st, free, mass, gravity,
                    damping, dt, steps, passes, gauss_seidel):
    """One parameter set rolled out for ``n_frames - 1`` frames of ``steps`` steps each:
    positions and velocities (n_frames, P, 3) in the dtype of ``x0``, frame 0 = (x0, v0).

    Parameters
    ----------
    x0, v0 : (P, 3) ndarray
    rest, k, tau : (6,) ndarray
    n_frames : int
    sa, sb, st, free, mass, gravity, damping, dt, steps, passes, gauss_seidel
        As :meth:`Numerics.kernel_args` gives them.
    """
    n_particles = x0.shape[0]
    xs = np.empty((n_frames, n_particles, 3), dtype=x0.dtype)
    vs = np.empty((n_frames, n_particles, 3), dtype=x0.dtype)
    force = np.empty((n_particles, 3), dtype=x0.dtype)
    corr = np.empty((n_particles, 3), dtype=x0.dtype)
    count = np.empty(n_particles, dtype=x0.dtype)
    x_mid = np.empty((n_particles, 3), dtype=x0.dtype)
    v_mid = np.empty((n_particles, 3), dtype=x0.dtype)
    xs[0] = x0
    vs[0] = v0
    for t in range(n_frames - 1):
        _frame_into(xs[t], vs[t], rest, k, tau, sa, sb, st, free, mass, gravity, damping, dt,
                    steps, passes, gauss_seidel, force, corr, count, x_mid, v_mid, xs[t + 1],
                    vs[t + 1])
    return xs, vs


class VariantCost(ClothCost):
    """The paper's cost (``costs.ClothCost``) with the model step of a reading.

    Parameters
    ----------
    trajectory : Trajectory
    frames : (F,) int array_like
    numerics : Numerics
    dtc, h : float, optional
        As ``ClothCost``.
    """

    def __init__(self, trajectory, frames, numerics, *, dtc=None, h=None):
        super().__init__(trajectory, frames, dtc=dtc, h=h)
        self.numerics = numerics
        dtype = np.dtype(numerics.dtype)
        self._args = numerics.kernel_args(self.scene, trajectory.dt)
        self.xs_model = np.ascontiguousarray(self.xs, dtype=dtype)
        self.vs_model = np.ascontiguousarray(self.vs, dtype=dtype)

    def frame_errors(self, params, extra_force=None):
        """Normalised ``e_t`` per individual and frame, shape (pop, F).

        Parameters
        ----------
        params : ClothParams
        extra_force : None
            Not supported by the variants (must be ``None``).
        """
        check(extra_force is None, "numerics variants: no extra force")
        dtype = self.xs_model.dtype
        rest, k, tau = (np.ascontiguousarray(p, dtype=dtype) for p in params)
        errors = variant_one_step_errors(self.xs_model, self.vs_model, self.frames, rest, k,
                                         tau, self.dtc, *self._args)
        return errors / self.norm


def variant_cost(trajectory, frames, numerics):
    """The paper's cost on ``trajectory`` over ``frames`` under ``numerics``: the suite's
    own :class:`ClothCost` for the contract's reading, else a :class:`VariantCost`.

    Parameters
    ----------
    trajectory : Trajectory
    frames : (F,) int array_like
    numerics : Numerics
    """
    if numerics.is_contract:
        return ClothCost(trajectory, frames)
    return VariantCost(trajectory, frames, numerics)


def regenerate(trajectory, truth_params, numerics):
    """The trajectory that the reading's model makes from ``trajectory``'s first frame
    with its true parameters: same scene and number of frames, one frame per step of the
    reading (frame interval ``numerics.dt``, or the data's when null); positions and
    velocities stored in float64.

    Parameters
    ----------
    trajectory : Trajectory
        A reference run (its frame 0 is the initial state, at rest).
    truth_params : ClothParams
        One parameter set (``(1, 6)`` arrays).
    numerics : Numerics
    """
    frame_dt = trajectory.dt if numerics.dt is None else float(numerics.dt)
    scene = trajectory.scene()
    dtype = np.dtype(numerics.dtype)
    x0 = np.ascontiguousarray(trajectory.flat_positions()[0], dtype=dtype)
    v0 = np.zeros_like(x0)
    rest, k, tau = (np.ascontiguousarray(p[0], dtype=dtype) for p in truth_params)
    xs, vs = variant_rollout(x0, v0, rest, k, tau, trajectory.n_frames,
                             *numerics.kernel_args(scene, frame_dt))
    n = trajectory.n
    damping = trajectory.damping if numerics.damping is None else float(numerics.damping)
    meta = dict(trajectory.meta)
    meta["generator"] = f"numerics_variants.regenerate({numerics.as_dict()})"
    return Trajectory(positions=xs.astype(float).reshape(-1, n, n, 3), dt=frame_dt,
                      mass=trajectory.mass, gravity=trajectory.gravity,
                      pinned=trajectory.pinned, damping=damping,
                      velocities=vs.astype(float).reshape(-1, n, n, 3), meta=meta,
                      source=f"{trajectory.source} (regenerated)")
