"""The paper's costs (section 3.3; docs/cloth-model.md "Costs").

Frame ``t+1`` is predicted from the recorded state at frame ``t`` by one model step;
``e_t = sum_p |x^_p - x_p|^2 + dtc^2 |v^_p - v_p|^2``, divided by ``n^2 h^2``. The full cost
sums ``e_t`` over 50 consecutive frames, the small cost uses one frame (default 150).
"""

from __future__ import annotations

import numpy as np

from replication.cloth import kernels
from replication.cloth.mesh import type_lengths
from replication.cloth.model import ClothParams
from replication.errors import InputError

SMALL_FRAME = 150
FULL_START = 100
FULL_WINDOW = 50


def structural_length(trajectory):
    """``h`` for normalising costs: mean structural spring length in the first frame
    (exactly the contract's ``h`` for data that starts from the flat sheet)."""
    lengths = type_lengths(trajectory.positions[0], trajectory.n)
    return float(lengths[:2].mean())


def cost_frames(kind, n_frames, *, frame=SMALL_FRAME, start=FULL_START, window=FULL_WINDOW):
    """Frames ``t`` whose prediction of ``t+1`` enters the cost.

    ``kind`` is ``"small"`` (one frame) or ``"full"`` (``window`` frames from ``start``).

    Parameters
    ----------
    kind : "small" or "full"
    n_frames : int
        Frames in the data (every ``t + 1`` must exist).
    frame : int
        The small cost's frame.
    start, window : int
        The full cost's first frame and number of frames.
    """
    if kind == "small":
        frames = np.array([frame])
    elif kind == "full":
        if window < 1:
            raise InputError(f"cost.window={window}: expected at least 1 frame")
        frames = np.arange(start, start + window)
    else:
        raise InputError(f"cost.kind={kind!r}: expected 'small' or 'full'")
    if frames.min() < 0 or frames.max() > n_frames - 2:
        setting = (f"cost.frame={frame}" if kind == "small"
                   else f"cost.start={start}, cost.window={window}")
        raise InputError(
            f"{setting} ({kind} cost): frame index "
            f"t={int(frames.min() if frames.min() < 0 else frames.max())} is outside the "
            f"data: t and t+1 must be frames of the {n_frames}-frame file "
            f"(0 <= t <= {n_frames - 2}); set {setting.split('=')[0]}= for shorter data"
        )
    return frames.astype(np.int64)


class ClothCost:
    """One-step prediction cost of a parameter population on a recorded trajectory.

    Parameters
    ----------
    trajectory : Trajectory
    frames : (F,) int array_like
        Values of ``t``; each predicts frame ``t+1`` from the recorded frame ``t``.
    dtc : float, optional
        The paper's "arbitrary coefficient" on velocity errors (default: the data's dt).
    h : float, optional
        Normalisation length (default: :func:`structural_length`).
    """

    def __init__(self, trajectory, frames, *, dtc=None, h=None):
        self.trajectory = trajectory
        self.scene = trajectory.scene()
        self.frames = np.ascontiguousarray(frames, dtype=np.int64)
        cost_frames_checked = (self.frames.min() >= 0
                               and self.frames.max() <= trajectory.n_frames - 2)
        if not cost_frames_checked:
            raise InputError(f"cost frames {self.frames.min()}..{self.frames.max()} outside "
                             f"0..{trajectory.n_frames - 2} of {trajectory.source}")
        self.dtc = float(trajectory.dt if dtc is None else dtc)
        self.h = float(structural_length(trajectory) if h is None else h)
        self.norm = trajectory.n ** 2 * self.h ** 2
        self.xs = np.ascontiguousarray(trajectory.flat_positions())
        self.vs = np.ascontiguousarray(trajectory.flat_velocities())
        self._no_force = np.zeros((1, 1, self.xs.shape[1], 3))

    def frame_errors(self, params: ClothParams, extra_force=None):
        """Normalised ``e_t`` per individual and frame, shape (pop, F); ``inf`` if the
        prediction is not finite.

        ``extra_force`` : (pop or 1, F or 1, n*n, 3), optional: external forces (effect
        plug-ins) per individual and cost frame, added before integration.

        Parameters
        ----------
        params : ClothParams
            ``(pop, 6)`` per-type parameters.
        extra_force : ndarray, optional
            Shape ``(pop or 1, F or 1, n*n, 3)``.
        """
        if extra_force is None:
            extra_force = self._no_force
        extra_force = np.ascontiguousarray(extra_force, dtype=float)
        errors = kernels.one_step_errors(self.xs, self.vs, self.frames, params.rest,
                                         params.k, params.tau, extra_force, self.dtc,
                                         *self.scene.kernel_args())
        return errors / self.norm

    def __call__(self, params: ClothParams, extra_force=None):
        """Cost per individual, shape (pop,)."""
        return self.frame_errors(params, extra_force).sum(axis=1)

    def tau_costs(self, rest, k, tau, extra_force=None):
        """Cost of one parameter set under each row of ``tau``, shape (B,): the same
        numbers as calling the cost on ``rest`` and ``k`` repeated B times, with the
        forces computed once per frame (a tau search's batch).

        Parameters
        ----------
        rest, k : (6,) ndarray
            Per-type rest lengths and stiffnesses.
        tau : (B, 6) ndarray
            Per-type critical elongation rates, one row per candidate.
        extra_force : ndarray, optional
            Shape ``(1, F or 1, n*n, 3)``: shared by every candidate.
        """
        if extra_force is None:
            extra_force = self._no_force
        extra_force = np.ascontiguousarray(extra_force, dtype=float)
        if extra_force.shape[0] != 1:
            raise ValueError("tau_costs: the external force must be shared by the batch "
                             f"(first axis 1), got shape {extra_force.shape}")
        errors = kernels.one_step_errors_tau(
            self.xs, self.vs, self.frames, np.ascontiguousarray(rest, dtype=float),
            np.ascontiguousarray(k, dtype=float), np.ascontiguousarray(tau, dtype=float),
            extra_force, self.dtc, *self.scene.kernel_args())
        return (errors / self.norm).sum(axis=1)


def make_cost(trajectory, kind="small", *, frame=SMALL_FRAME, start=FULL_START,
              window=FULL_WINDOW, dtc=None, h=None):
    """The paper's small (``kind="small"``) or full (``kind="full"``) cost on ``trajectory``.

    Parameters
    ----------
    trajectory : Trajectory
    kind : "small" or "full"
    frame, start, window : int
        As :func:`cost_frames`.
    dtc : float, optional
        Weight of velocity errors (default: the data's ``dt``).
    h : float, optional
        Normalisation length (default: the mean structural length).

    Returns
    -------
    ClothCost
        Callable: ``cost(params) -> (pop,)``.
    """
    try:
        frames = cost_frames(kind, trajectory.n_frames, frame=frame, start=start,
                             window=window)
    except InputError as error:
        raise InputError(f"{trajectory.source}: {error}") from None
    return ClothCost(trajectory, frames, dtc=dtc, h=h)
