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

from replication.discrepancy import effects as fx
from replication.discrepancy.fit import one_step_predictions
from replication.discrepancy.geometry import normals


def residuals(data, fit, frames):
    """One-step residuals ``x_{t+1} - x^_{t+1}`` (F, P, 3), zero on pinned particles."""
    frames = np.asarray(frames)
    r = data.x[frames + 1] - one_step_predictions(data, fit.base, fit.terms, frames)
    r[:, ~data.free] = 0.0
    return r


def runs(frames):
    """Split sorted frames into runs of consecutive values: list of index arrays."""
    frames = np.asarray(frames)
    breaks = np.flatnonzero(np.diff(frames) != 1) + 1
    return np.split(np.arange(frames.size), breaks)


def noise_sigma(r, frames, free):
    """Position-noise standard deviation from lag-0/lag-1 autocovariances of residuals."""
    g0, g1, count0, count1 = 0.0, 0.0, 0, 0
    for idx in runs(frames):
        block = r[idx][:, free]
        g0 += float(np.sum(block * block))
        count0 += block.size
        if len(idx) > 1:
            g1 += float(np.sum(block[1:] * block[:-1]))
            count1 += block[1:].size
    gamma0 = g0 / max(count0, 1)
    gamma1 = g1 / max(count1, 1)
    return float(np.sqrt(max(gamma0 - gamma1, 0.0) / 10.0))


def patch_labels(n, patch):
    """Patch index of every particle for square patches of ``patch x patch`` particles."""
    i, j = np.divmod(np.arange(n * n), n)
    per_row = -(-n // patch)
    return (i // patch) * per_row + (j // patch)


def window_sums(r, frames, window):
    """Sums of residuals over non-overlapping windows of consecutive frames.

    Returns
    -------
    sums : (W, P, 3) ndarray; starts : (W,) first frame of each window
    """
    sums, starts = [], []
    frames = np.asarray(frames)
    for idx in runs(frames):
        for k in range(len(idx) // window):
            chunk = idx[k * window:(k + 1) * window]
            sums.append(r[chunk].sum(axis=0))
            starts.append(int(frames[chunk[0]]))
    if not sums:
        return np.zeros((0,) + r.shape[1:]), np.zeros(0, dtype=int)
    return np.stack(sums), np.array(starts)


def structure(r, frames, free, n, *, window=10, patch=4, directions=None):
    """Structure statistic ``Q`` of residuals and its break-downs.

    Parameters
    ----------
    r : (F, P, 3) ndarray
    frames : (F,) int ndarray
    free : (P,) bool
    n : int
    directions : (F, P, 3) unit vectors, optional (e.g. normals) for a normal/tangential split

    Returns
    -------
    dict with ``sigma``, ``Q`` (all), ``Q_by_window`` (W,), ``Q_by_patch`` (patches,),
    ``Q_by_component`` {x, y, z}, and ``Q_normal``/``Q_tangential`` when ``directions``.
    """
    sigma = noise_sigma(r, frames, free)
    sums, starts = window_sums(r, frames, window)
    labels = patch_labels(n, patch)[free]
    n_patch = labels.max() + 1
    counts = np.bincount(labels, minlength=n_patch).astype(float)
    var = 4.0 * sigma ** 2 + 1e-300

    def q_of(s):  # s: (W, Pfree, c) -> (W, patch, c) normalised squares
        means = np.stack([np.stack([np.bincount(labels, s[w, :, c], n_patch) / counts
                                    for c in range(s.shape[2])], axis=-1)
                          for w in range(s.shape[0])]) if s.size else np.zeros((0, n_patch, 1))
        return means ** 2 * counts[None, :, None] / var

    q = q_of(sums[:, free])
    out = {"sigma": sigma, "Q": float(q.mean()) if q.size else 0.0,
           "Q_by_window": q.mean(axis=(1, 2)).tolist(), "window_starts": starts.tolist(),
           "Q_by_patch": q.mean(axis=(0, 2)).tolist(),
           "Q_by_component": dict(zip("xyz", q.mean(axis=(0, 1)).tolist()))}
    if directions is not None:
        dsum, _ = window_sums(np.sum(r * directions, axis=2, keepdims=True), frames, window)
        qn = q_of(dsum[:, free])
        out["Q_normal"] = float(qn.mean()) if qn.size else 0.0
        out["Q_tangential"] = float((q.sum(axis=2) - qn[..., 0]).mean() / 2) if q.size else 0.0
    return out


def where(data, fit, frames, *, window=10, patch=4):
    """Localisation summary of the residuals of ``fit`` on ``frames`` (JSON-ready).

    Maps over the mesh (RMS of window sums per particle, in units of the noise floor), over
    time (``Q`` per window), by direction (normal, tangential, vertical), and correlations
    of the residual with velocity (from earlier frames, free of the residual's noise),
    strain and height.
    """
    frames = np.asarray(frames)
    r = residuals(data, fit, frames)
    nrm = normals(data.x[frames], data.ops.n)
    summary = structure(r, frames, data.free, data.ops.n, window=window, patch=patch,
                        directions=nrm)
    sigma = summary["sigma"]
    sums, _ = window_sums(r, frames, window)
    per_particle = np.sqrt(np.mean(np.sum(sums ** 2, axis=2), axis=0) / 3.0) \
        / max(2.0 * sigma, 1e-300)
    vertical, _ = window_sums(r[..., 2:3], frames, window)
    dt = data.scene.dt
    accel = r / dt ** 2
    lagged_v = data.v[np.maximum(frames - 2, 0)]
    q = fx.Frames(data.x[frames], data.v[frames], data.ops, data.mass, fit.base.rest,
                  fit.base.k)
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
        "excess_power": float(np.mean(r[:, free] ** 2) / max(6.0 * sigma ** 2, 1e-300)),
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
