"""Where model and data disagree: one-step residuals, their noise floor and structure.

The one-step residual of frame ``t`` is ``r_t = x_{t+1} - x^_{t+1}``, the recorded position
minus the model's prediction from the recorded state at ``t``. With white position noise of
standard deviation ``sigma`` and a correct model it is ``e_{t+1} - 2 e_t + e_{t-1}`` (for
particles the constraint leaves alone): lag-0 and lag-1 autocovariances ``6 sigma^2`` and
``-4 sigma^2``, so ``sigma^2 = (gamma_0 - gamma_1) / 10`` even when a smooth structured
residual is added. Sums of ``r_t`` over a window of consecutive frames telescope to four noise
terms (variance ``4 sigma^2``), whatever the window length, while a missing effect grows with
it: the structure statistic ``Q`` compares window sums, averaged over patches of the mesh,
to that noise floor (``Q`` near 1: nothing but noise).
"""

from __future__ import annotations

import numpy as np

from replication.cloth import regression
from replication.cloth.geometry import normals
from replication.cloth.noise import SIGMA_FLOOR_H, excess_power, noise_sigma, runs


def residuals(data, fit, frames):
    """One-step residuals ``x_{t+1} - x^_{t+1}`` (F, P, 3) of a fit, zero on pinned
    particles."""
    return regression.residuals(data, fit.base, fit.terms, frames)


def patch_labels(n, patch):
    """Patch index of every particle for square patches of ``patch x patch`` particles."""
    i, j = np.divmod(np.arange(n * n), n)
    per_row = -(-n // patch)
    return (i // patch) * per_row + (j // patch)


def window_sums(r, frames, window, mask=None):
    """Sums of residuals over non-overlapping windows of consecutive frames.

    Returns
    -------
    sums : (W, P, 3) ndarray; starts : (W,) first frame of each window; complete : (W, P)
    bool, the particle is in ``mask`` (F, P) at every frame of the window (all True
    without a mask): only then do the noise terms of the sum telescope.
    """
    if int(window) < 2:   # one residual is e_{t+1} - 2 e_t + e_{t-1}: 6 sigma^2, not 4
        raise ValueError(f"window={window}: expected at least 2 frames (sums of fewer do "
                         "not telescope to four noise terms)")
    sums, starts, complete = [], [], []
    frames = np.asarray(frames)
    for idx in runs(frames):
        for k in range(len(idx) // window):
            chunk = idx[k * window:(k + 1) * window]
            sums.append(r[chunk].sum(axis=0))
            starts.append(int(frames[chunk[0]]))
            complete.append(np.ones(r.shape[1], dtype=bool) if mask is None
                            else np.all(mask[chunk], axis=0))
    if not sums:
        return (np.zeros((0,) + r.shape[1:]), np.zeros(0, dtype=int),
                np.zeros((0, r.shape[1]), dtype=bool))
    return np.stack(sums), np.array(starts), np.stack(complete)


def structure(r, frames, free, n, *, window=10, patch=4, directions=None, floor=0.0,
              mask=None, sigma=None):
    """Structure statistic ``Q`` of residuals and its break-downs.

    Parameters
    ----------
    r : (F, P, 3) ndarray
    frames : (F,) int ndarray
    free : (P,) bool
    n : int
    directions : (F, P, 3) unit vectors, optional (e.g. normals) for a normal/tangential split
    floor : float
        Smallest noise standard deviation used (noise-free data).
    mask : (F, P) bool, optional
        Particle-frames outside the deformation constraint: a window sum counts only where
        the particle is in the mask at every frame of the window. The constraint's
        residuals are sensitive to tiny errors of ``tau`` and would dominate ``Q``. An
        empty mask, or one that no particle fills for a whole window, is not used.

    Returns
    -------
    dict with ``sigma``, ``mask_dropped`` (the mask was not used, see ``mask``), ``Q`` (the
    larger of ``Q_patch``, over patches of ``patch x patch``
    particles, and ``Q_sheet``, over the whole sheet), ``Q_by_window`` (W,), ``Q_by_patch``
    (patches,),
    ``Q_by_component`` {x, y, z}, and ``Q_normal``/``Q_tangential`` when ``directions``.
    """
    if mask is not None and not np.any(mask):
        mask = None   # a fit through the constraint has no mask: use everything
    sums, starts, complete = window_sums(r, frames, window, mask)
    mask_dropped = mask is not None and len(starts) > 0 and not np.any(complete[:, free])
    if mask_dropped:
        # no particle stays in the mask for a whole window (a rough fit's mask is patchy):
        # Q would be measured on nothing and read 0; use everything instead
        mask = None
        sums, starts, complete = window_sums(r, frames, window)
    sigma = max(noise_sigma(r, frames, free, mask) if sigma is None else sigma, floor)
    labels = patch_labels(n, patch)[free]
    n_patch = labels.max() + 1
    complete = complete[:, free]
    var = 4.0 * sigma ** 2 + 1e-300

    def q_of(s):  # s: (W, Pfree, c) -> (W, patch, c) normalised squares, weights (W, patch)
        if not s.size:
            return np.zeros((0, n_patch, 1)), np.zeros((0, n_patch))
        counts = np.stack([np.bincount(labels, complete[w], n_patch)
                           for w in range(s.shape[0])])
        means = np.stack([np.stack([np.bincount(labels, s[w, :, c] * complete[w], n_patch)
                                    for c in range(s.shape[2])], axis=-1)
                          for w in range(s.shape[0])]) / np.maximum(counts, 1)[..., None]
        return means ** 2 * counts[..., None] / var, (counts > 0).astype(float)

    def mean_over(q, weight, axis):
        w = np.broadcast_to(weight[..., None], q.shape)
        total = np.sum(w, axis=axis)
        return np.sum(q * w, axis=axis) / np.maximum(total, 1e-300)

    q, weight = q_of(sums[:, free])
    has = weight.sum() > 0
    q_patch = float(np.sum(q * weight[..., None]) / (3 * weight.sum())) if has else 0.0
    # the same over the whole sheet: a force acting alike everywhere (a gust, a push)
    # shows there with sqrt(particles) times its single-particle signal-to-noise ratio
    n_complete = complete.sum(axis=1)
    sheet = np.sum(sums[:, free] * complete[..., None], axis=1)
    used = n_complete > 0
    q_sheet = (float(np.mean(sheet[used] ** 2 / (n_complete[used, None] * var)))
               if np.any(used) else 0.0)
    out = {"sigma": sigma, "Q": max(q_patch, q_sheet), "Q_patch": q_patch, "Q_sheet": q_sheet,
           "mask_dropped": bool(mask_dropped),
           "Q_by_window": mean_over(q, weight, (1, 2)).tolist() if has else [],
           "window_starts": starts.tolist(),
           "Q_by_patch": mean_over(q, weight, (0, 2)).tolist() if has else [],
           "Q_by_component": dict(zip("xyz", mean_over(q, weight, (0, 1)).tolist()))
           if has else {}}
    if directions is not None:
        dsum, _, _ = window_sums(np.sum(r * directions, axis=2, keepdims=True), frames, window,
                                 mask)
        qn, _ = q_of(dsum[:, free])
        out["Q_normal"] = float(np.sum(qn[..., 0] * weight) / weight.sum()) if has else 0.0
        out["Q_tangential"] = (float(np.sum((q.sum(axis=2) - qn[..., 0]) * weight)
                                     / (2 * weight.sum())) if has else 0.0)
    return out


def where(data, fit, frames, *, window=10, patch=4, mask=None):
    """Localisation summary of the residuals of ``fit`` on ``frames`` (JSON-ready).

    Maps over the mesh (RMS of window sums per particle, in units of the noise floor), over
    time (``Q`` per window), by direction (normal, tangential, vertical), and correlations
    of the residual with velocity (from earlier frames, free of the residual's noise),
    strain and height.
    """
    frames = np.asarray(frames)
    r = residuals(data, fit, frames)
    nrm = normals(data.x[frames], data.ops.n)
    mask = fit.mask[frames] if mask is None else mask
    summary = structure(r, frames, data.free, data.ops.n, window=window, patch=patch,
                        directions=nrm, floor=SIGMA_FLOOR_H * data.h, mask=mask)
    sigma = summary["sigma"]
    sums, _, _ = window_sums(r, frames, window)
    per_particle = np.sqrt(np.mean(np.sum(sums ** 2, axis=2), axis=0) / 3.0) \
        / max(2.0 * sigma, 1e-300)
    vertical, _, _ = window_sums(r[..., 2:3], frames, window)
    dt = data.scene.dt
    accel = r / dt ** 2
    lagged_v = data.v[np.maximum(frames - 2, 0)]
    q = regression.state_frames(data, fit.base, frames)
    strain_force = np.linalg.norm(q.inner_force, axis=2)
    free = data.free

    def corr(a, b):
        a = a[:, free].ravel()
        b = b[:, free].ravel()
        a = a - a.mean()
        b = b - b.mean()
        return float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b) + 1e-300))

    summary.update({
        "noise_sigma_h": sigma / data.h,
        "one_step_rms_h": float(np.sqrt(np.mean(np.sum(r[:, free] ** 2, axis=2)) / 3) / data.h),
        "excess_power": excess_power(r, free, sigma),
        "map": per_particle.reshape(data.ops.n, data.ops.n).tolist(),
        "Q_vertical_windows": float(np.mean(np.mean(vertical[:, free], axis=1) ** 2
                                            * free.sum() / (4 * sigma ** 2 + 1e-300)))
        if vertical.size else 0.0,
        "correlation": {
            "velocity": corr(np.sum(accel * lagged_v, axis=2),
                             np.sum(lagged_v * lagged_v, axis=2)),
            "velocity_along": corr(accel.reshape(len(frames), -1, 3)[..., 2],
                                   lagged_v[..., 2]),
            "strain_force": corr(np.linalg.norm(accel, axis=2), strain_force),
            "height": corr(np.linalg.norm(accel, axis=2), data.x[frames][..., 2]),
        },
    })
    return summary
