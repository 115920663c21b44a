"""Position noise of cloth data from one-step residuals (shared by the identifiers'
diagnostics and the discrepancy workflow).

With white position noise of standard deviation ``sigma`` and a right model, the one-step
residual ``r_t = x_{t+1} - x^_{t+1}`` is ``e_{t+1} - 2 e_t + e_{t-1}`` (for particles the
constraint leaves alone): lag-0 and lag-1 autocovariances ``6 sigma^2`` and ``-4 sigma^2``,
so ``sigma^2 = (gamma_0 - gamma_1) / 10`` even when a smooth structured residual is added.
"""

from __future__ import annotations

import numpy as np

# Floor of the noise standard deviation (units of h): on noise-free data the residuals of
# a right model are round-off, and structure is measured against this floor instead.
SIGMA_FLOOR_H = 1e-7


def runs(frames):
    """Split sorted frames into runs of consecutive values: list of index arrays."""
    frames = np.asarray(frames)
    breaks = np.flatnonzero(np.diff(frames) != 1) + 1
    return np.split(np.arange(frames.size), breaks)


def noise_sigma(r, frames, free, mask=None):
    """Position-noise standard deviation from lag-0/lag-1 autocovariances of residuals
    (over particle-frames in ``mask`` (F, P) when given)."""
    use = np.ones(r.shape[:2], dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    use = use & free[None, :]
    g0, g1, count0, count1 = 0.0, 0.0, 0, 0
    for idx in runs(frames):
        block, keep = r[idx], use[idx]
        g0 += float(np.sum(block[keep] ** 2))
        count0 += 3 * int(keep.sum())
        if len(idx) > 1:
            both = keep[1:] & keep[:-1]
            g1 += float(np.sum((block[1:] * block[:-1])[both]))
            count1 += 3 * int(both.sum())
    gamma0 = g0 / max(count0, 1)
    gamma1 = g1 / max(count1, 1)
    return float(np.sqrt(max(gamma0 - gamma1, 0.0) / 10.0))


MAD_TO_SD = 1.4826  # a Gaussian's standard deviation over its median absolute deviation


def robust_residual_sigma(r, free):
    """Position noise from the median absolute one-step residual of the ``free`` particles
    (``r`` (F, P, 3); white noise gives residuals of variance ``6 sigma^2``): what most
    particle-frames show, not the few where a constraint acts or a model error peaks.

    Parameters
    ----------
    r : (F, P, 3) ndarray
    free : (P,) bool ndarray
    """
    return float(np.median(np.abs(r[:, free])) * MAD_TO_SD / np.sqrt(6.0))


def data_noise_sigma(positions, free):
    """Position noise from the data alone, without a model: the median absolute fourth
    difference in time of the ``free`` particles' positions ``(F, P, 3)`` (white noise gives
    variance ``70 sigma^2``). The motion's own fourth differences add to it, so on smooth
    noise-free data it is an upper bound near the motion's smoothness (about 1e-7 to 1e-6 h
    for the reference runs).

    Parameters
    ----------
    positions : (F, P, 3) ndarray
    free : (P,) bool ndarray
    """
    x = np.asarray(positions)[:, free]
    fourth = x[4:] - 4 * x[3:-1] + 6 * x[2:-2] - 4 * x[1:-3] + x[:-4]
    return float(np.median(np.abs(fourth)) * MAD_TO_SD / np.sqrt(70.0))


def excess_power(r, free, sigma):
    """Mean squared one-step residual of the ``free`` particles over the ``6 sigma^2`` that
    white position noise of standard deviation ``sigma`` alone gives (module docstring):
    near 1 when the model explains the data up to noise; ``inf`` for non-finite residuals.

    Parameters
    ----------
    r : (F, P, 3) ndarray
    free : (P,) bool ndarray
    sigma : float
    """
    mean_square = float(np.mean(r[:, free] ** 2))
    if not np.isfinite(mean_square):
        return float("inf")
    return mean_square / max(6.0 * sigma ** 2, 1e-300)
