"""A structured identifier for the cloth parameters (beyond the paper).

Three stages, each using what the model's structure gives:

1. Linear regression. For a particle that the deformation constraint did not move, one
   model step predicts ``x_{t+1} = x_t + dt v_t + dt^2 F(x_t) / m`` and the spring forces
   ``k (L - l) d / L = k d - (k l) d / L`` are linear in ``k`` and ``k l``. Over many
   frames this is an overdetermined linear system in ``(k_t, k_t l_t)``; particles moved
   by the constraint are outliers, removed by iterative trimming. No cost evaluations.
2. A scan of tau on the cost with ``k`` and ``l`` fixed (batched grid, then a bounded
   one-dimensional refinement per tau), which finds the needle-shaped minimum in tau
   that defeats general optimisers (Figs. 9-10).
3. Local refinement: the paper's EA on a small box around the estimate.

All cost evaluations go through the shared :class:`~replication.optim.objective.Objective`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import savgol_filter

from replication.cloth.identify import EASettings, PaperEA
from replication.cloth.mesh import FAMILY_OF_TYPE, N_TYPES, springs
from replication.errors import check
from replication.optim.objective import BudgetExhausted


def smoothed(trajectory, window, polyorder=3):
    """``trajectory`` with positions smoothed over time (Savitzky-Golay, ``window``
    frames, pinned particles untouched) and velocities re-derived; ``window=0``: as is.

    Against position noise: the one-step regression differentiates positions twice, so
    noise of sd s enters its target with sd of order s / dt^2 (shared/NOTES.md).
    """
    if window == 0:
        return trajectory
    check(window % 2 == 1 and window > polyorder and window <= trajectory.n_frames,
          f"regression.smooth_windows: {window}: expected an odd number of frames above "
          f"{polyorder} and at most {trajectory.n_frames}")
    positions = savgol_filter(trajectory.flat_positions(), window, polyorder, axis=0)
    free = trajectory.scene().free
    positions[:, ~free] = trajectory.flat_positions()[:, ~free]
    return dataclasses.replace(trajectory, velocities=None,
                               positions=positions.reshape(trajectory.positions.shape))


def regression_frames(n_frames, *, first, stride):
    """Frames ``t`` (with ``t - 1 >= 0`` and ``t + 1`` in the data) used by the regression."""
    return np.arange(max(first, 1), n_frames - 1, stride)


def _design(trajectory, frames):
    """Design matrix of the unconstrained step for every free particle and frame.

    Returns
    -------
    A : (R, 12) ndarray
        Columns ``2t`` and ``2t+1`` multiply ``k_t`` and ``k_t l_t`` (per spring type t).
    y : (R,) ndarray
        ``m (x_{t+1} - x_t - dt v_t) / dt^2 - m g - extra`` (the spring force to explain).
    rows : (R,) int ndarray
        Index of the (frame, particle) pair of each row (three rows per pair).
    """
    n, dt = trajectory.n, trajectory.dt
    scene = trajectory.scene()
    a, b, kind = springs(n)
    xs, vs = trajectory.flat_positions(), trajectory.flat_velocities()
    free = np.flatnonzero(scene.free)
    P = n * n
    mass = scene.mass[:, None]
    blocks, targets = [], []
    for t in frames:
        x = xs[t]
        d = x[b] - x[a]
        L = np.linalg.norm(d, axis=1)
        unit = d / L[:, None]
        cols = np.zeros((P, 3, 2 * N_TYPES))
        for s_type in range(N_TYPES):
            sel = kind == s_type
            for c in range(3):
                # force on a: +k d - (k l) d/L ; on b: the opposite
                cols[:, c, 2 * s_type] += np.bincount(a[sel], d[sel, c], P) - np.bincount(
                    b[sel], d[sel, c], P)
                cols[:, c, 2 * s_type + 1] += -np.bincount(a[sel], unit[sel, c], P) + \
                    np.bincount(b[sel], unit[sel, c], P)
        force = mass * (xs[t + 1] - x - dt * vs[t]) / dt ** 2 - mass * scene.gravity[None, :] \
            + scene.damping * vs[t]
        blocks.append(cols[free].reshape(-1, 2 * N_TYPES))
        targets.append(force[free].reshape(-1))
    return np.vstack(blocks), np.concatenate(targets)


def _reduce_columns(A, model):
    """Columns for the 5-parameter model: one K (sum of all k columns) and one K l per
    family; the 18-parameter model keeps ``(k_t, k_t l_t)`` per type."""
    if model == "18":
        return A
    k_col = A[:, 0::2].sum(axis=1, keepdims=True)
    kl = np.stack([A[:, 1::2][:, FAMILY_OF_TYPE == f].sum(axis=1) for f in range(3)], axis=1)
    return np.hstack([k_col, kl])


def _trimmed_fit(A, y, *, trim_rounds, trim_factor):
    """Least squares with iterative trimming of (frame, particle) pairs (3 rows each)
    whose residual norm exceeds ``trim_factor`` times the median of the kept ones."""
    keep = np.ones(y.size // 3, dtype=bool)
    for _ in range(trim_rounds + 1):
        rows = np.repeat(keep, 3)
        theta, *_ = np.linalg.lstsq(A[rows], y[rows], rcond=None)
        residual = np.linalg.norm((A @ theta - y).reshape(-1, 3), axis=1)
        new_keep = residual <= trim_factor * max(np.median(residual[keep]), 1e-300)
        if np.array_equal(new_keep, keep) or new_keep.sum() < A.shape[1]:
            break
        keep = new_keep
    return theta, keep, float(np.median(residual[keep]))


def regress_stiffness(trajectory, *, model="5", frames, trim_rounds=6, trim_factor=10.0,
                      frame_quantile=0.3):
    """Stage 1: ``k`` and rest lengths by trimmed linear least squares.

    Each frame is first fitted alone (with trimming); the ``frame_quantile`` fraction of
    frames whose fits explain the data best (the constraint moved fewest particles there)
    are then fitted jointly, again with trimming.

    Parameters
    ----------
    trajectory : Trajectory
    model : "5" or "18"
    frames : (F,) int array_like
        Candidate frames ``t`` whose step to ``t+1`` enters the regression.
    trim_rounds, trim_factor : int, float
        Rounds of refitting after dropping (frame, particle) pairs whose residual norm is
        above ``trim_factor`` times the median of the kept ones (the constraint's
        outliers).
    frame_quantile : float
        Fraction of candidate frames kept for the joint fit.

    Returns
    -------
    k : (1,) or (6,) ndarray, rest : (3,) or (6,) ndarray, info : dict
    """
    frames = np.asarray(frames)
    per_frame = []
    blocks = []
    for t in frames:
        A, y = _design(trajectory, [t])
        A = _reduce_columns(A, model)
        blocks.append((A, y))
        per_frame.append(_trimmed_fit(A, y, trim_rounds=trim_rounds,
                                      trim_factor=trim_factor)[2])
    n_best = max(1, int(round(frame_quantile * frames.size)))
    chosen = np.sort(np.argsort(per_frame, kind="stable")[:n_best])
    A = np.vstack([blocks[i][0] for i in chosen])
    y = np.concatenate([blocks[i][1] for i in chosen])
    theta, keep, scale = _trimmed_fit(A, y, trim_rounds=trim_rounds, trim_factor=trim_factor)
    if model == "18":
        k, kl = theta[0::2], theta[1::2]
        rest = kl / k
    else:
        k, kl = theta[:1], theta[1:]
        rest = kl / k[0]
    info = {"frames_used": frames[chosen].tolist(), "pairs_used": int(keep.sum()),
            "pairs_total": int(keep.size), "median_residual": scale}
    return k, rest, info


def scan_tau(objective, base, indices, *, n_grid, refine_evals):
    """Stage 2 for one group of tau entries set to a common value: grid over the bounds
    (log-spaced), then a bounded scalar refinement between the grid neighbours of the
    best point. The answer is read from the objective's best-so-far point."""
    indices = list(indices)
    low = objective.lower[indices].max()
    high = objective.upper[indices].min()
    grid = np.geomspace(low, high, n_grid)
    X = np.repeat(base[None, :], n_grid, axis=0)
    X[:, indices] = grid[:, None]
    best = int(np.argmin(objective.evaluate(X)))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, n_grid - 1)]

    def along(tau):
        trial = base.copy()
        trial[indices] = tau
        return float(objective.evaluate(trial[None, :])[0])

    if refine_evals > 0 and hi > lo:
        minimize_scalar(along, bounds=(lo, hi), method="bounded",
                        options={"maxiter": refine_evals, "xatol": 1e-6 * (hi - lo)})


def tau_groups(model, n_var):
    """Groups of tau indices scanned together: all taus, then (18 parameters) each spring
    family's pair, then each type. A spring's clamp changes its particles' mean correction
    (Jacobi pass), so taus of one family are coupled and are scanned jointly first."""
    if model != "18":
        return [[n_var - 1]]
    first = n_var - N_TYPES
    families = [[first + t for t in range(N_TYPES) if FAMILY_OF_TYPE[t] == f]
                for f in range(3)]
    return [list(range(first, n_var)), *families, *[[i] for i in range(first, n_var)]]


def structured_identify(trajectory, objective, space, *, rng, settings):
    """Regression, tau scan and EA refinement (see the module docstring).

    Parameters
    ----------
    trajectory : Trajectory
    objective : Objective over ``space`` (the cost the answer is judged on)
    space : SearchSpace
    rng : np.random.Generator
    settings : dict
        ``regression: {first, stride, trim_rounds, trim_factor, frame_quantile,
        smooth_windows}``,
        ``tau_scan: {n_grid, refine_evals, cycles}``,
        ``refine: {box (relative half-width), ea: {...EASettings}}``.

    Returns
    -------
    best : (n_var,) ndarray, info : dict
    """
    model = space.model
    reg = settings["regression"]
    frames = regression_frames(trajectory.n_frames, first=reg["first"], stride=reg["stride"])
    check(frames.size > 0, f"regression.first={reg['first']}: no frame of the "
                           f"{trajectory.n_frames}-frame data left for the regression")
    # one fit per smoothing window; keep the one that explains its data best
    fits = []
    for window in reg.get("smooth_windows", [0]):
        k, rest, reg_info = regress_stiffness(smoothed(trajectory, int(window)), model=model,
                                              frames=frames, trim_rounds=reg["trim_rounds"],
                                              trim_factor=reg["trim_factor"],
                                              frame_quantile=reg["frame_quantile"])
        fits.append((reg_info["median_residual"], int(window), k, rest, reg_info))
    _, window, k, rest, reg_info = min(fits, key=lambda fit: fit[0])
    reg_info["smooth_window"] = window
    n_tau = 6 if model == "18" else 1
    # start with every constraint inactive (tau at its upper bound), then scan each tau
    tau_start = objective.upper[-n_tau:]
    x = np.clip(np.r_[rest, k, tau_start], objective.lower, objective.upper)
    info = {"regression": reg_info, "regression_vector": x.tolist()}
    scan = settings["tau_scan"]
    try:
        # coordinate-wise scans, repeated: with several taus, one scan's answer depends
        # on the others' current values
        for _ in range(int(scan.get("cycles", 1))):
            for group in tau_groups(model, space.n_var):
                scan_tau(objective, x, group, n_grid=scan["n_grid"],
                         refine_evals=scan["refine_evals"])
                x = objective.best_point.copy()
        info["scan_vector"] = x.tolist()
        info["evals_after_scan"] = objective.n_evals
        refine = settings["refine"]
        ea_settings = EASettings.from_config(refine["ea"])
        if ea_settings.generations > 0:
            box = float(refine["box"])
            lower = np.maximum(objective.lower, x * (1 - box))
            upper = np.minimum(objective.upper, x * (1 + box))
            initial = lower + rng.random((ea_settings.pop_size, x.size)) * (upper - lower)
            initial[0] = x
            local = _BoxedObjective(objective, lower, upper)
            ea = PaperEA(local, ea_settings, rng, initial).run()
            info["refine_history"] = [h["best"] for h in ea.history]
    except BudgetExhausted:
        pass
    best = objective.best_point if objective.best_point is not None else x
    return np.asarray(best), info


class _BoxedObjective:
    """The same objective (same counter, same trace) seen through a smaller box."""

    def __init__(self, objective, lower, upper):
        self.inner = objective
        self.lower, self.upper = lower, upper

    @property
    def n_var(self):
        return self.inner.n_var

    @property
    def n_evals(self):
        return self.inner.n_evals

    def evaluate(self, X):
        return self.inner.evaluate(X)
