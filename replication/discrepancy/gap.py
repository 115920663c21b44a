"""The gap between model and data on held-out frames: one step and multi-step rollouts."""

from __future__ import annotations

import numpy as np

from replication.cloth.model import step
from replication.cloth.regression import StateFrames, extra_force
from replication.discrepancy.residuals import residuals

SMOOTH_HALF = 3
STARTS = ("recorded", "centred")


def split_frames(n_frames, *, block=25, every=4):
    """Training frames and held-out blocks: block ``k`` (frames ``k*block`` on) is held
    out when ``k % every == every - 1``; every block is whole and made of frames that have
    a next frame (``0..n_frames-2``), so a last block that would reach frame
    ``n_frames - 1`` starts one frame earlier. Training frames keep 3 frames away from
    held-out ones (instruments).

    Returns
    -------
    train : (F,) int ndarray; held_out : list of (B,) int ndarrays (frames of each block)
    """
    frames = np.arange(n_frames - 1)   # each with a next frame
    held = []
    for k in range(every - 1, n_frames // block, every):
        start = min(k * block, frames.size - block)
        if not held or start > held[-1][-1]:
            held.append(frames[start:start + block])
    near = np.zeros(n_frames, dtype=bool)
    for chunk in held:
        near[max(chunk[0] - 3, 0):min(chunk[-1] + 4, n_frames)] = True
    return frames[~near[frames]], held


def start_state(x, t, dt, how):
    """Initial state of a rollout at frame ``t``: ``(x0, v0)`` each (P, 3).

    ``how="recorded"``: the recorded position and last difference (the contract's state,
    exact without noise); ``how="centred"``: value and slope of a quadratic least-squares
    fit to frames ``t-3..t+3`` (less noisy; frames after ``t`` are not scored).
    """
    if how not in ("recorded", "centred"):
        raise ValueError(f"how={how!r}: expected 'recorded' or 'centred'")
    before, after = (1, 0) if how == "recorded" else (SMOOTH_HALF, SMOOTH_HALF)
    if not before <= t < x.shape[0] - after:
        raise ValueError(f"t={t}: a {how!r} start needs frames t-{before}..t+{after} of the "
                         f"{x.shape[0]} frames")
    if how == "recorded":
        return x[t].copy(), (x[t] - x[t - 1]) / dt
    lags = np.arange(-SMOOTH_HALF, SMOOTH_HALF + 1) * dt
    weights = np.linalg.pinv(np.stack([np.ones_like(lags), lags, lags ** 2], axis=1))
    window = x[t - SMOOTH_HALF:t + SMOOTH_HALF + 1]
    return np.einsum("k,kpc->pc", weights[0], window), np.einsum("k,kpc->pc", weights[1], window)


def rollout_error(data, fit, held_out, *, start="recorded"):
    """RMS position error (units of ``h``) of rollouts over the held-out blocks.

    Each block is rolled out from a state estimated at its first frame (:func:`start_state`)
    for the block's length, the effect terms recomputed from the state at every step; the
    error is over free particles and the predicted frames after ``SMOOTH_HALF``.
    """
    starts = [int(chunk[0]) for chunk in held_out
              if SMOOTH_HALF + 1 <= chunk[0] <= data.n_frames - len(chunk) - 1]
    if not starts:
        return float("nan")
    horizon = min(len(chunk) for chunk in held_out)
    states = [start_state(data.x, t, data.scene.dt, start) for t in starts]
    x = np.stack([s[0] for s in states])
    v = np.stack([s[1] for s in states])
    x[:, ~data.free] = data.x[starts][:, ~data.free]
    v[:, ~data.free] = 0.0
    params = fit.base.params(len(starts))
    total, count = 0.0, 0
    for lag in range(1, horizon + 1):
        q = StateFrames(x, v, data.ops, data.mass, fit.base.rest, fit.base.k,
                        data.scene.damping)
        x, v = step(x, v, params, data.scene, extra_force(fit.terms, q))
        if not np.all(np.isfinite(x)):
            return float("inf")
        if lag <= SMOOTH_HALF:
            continue
        diff = x[:, data.free] - data.x[np.array(starts) + lag][:, data.free]
        total += float(np.sum(diff ** 2))
        count += diff[..., 0].size
    return float(np.sqrt(total / count) / data.h)


def one_step_error(data, fit, held_out):
    """RMS one-step prediction error (units of ``h``) over the held-out frames."""
    frames = np.concatenate([chunk[:-1] for chunk in held_out]) if held_out else np.zeros(0, int)
    return one_step_rms(data, fit, frames)


def one_step_rms(data, fit, frames):
    """RMS length of the free particles' one-step residuals (units of ``h``) on ``frames``
    (those with a frame before and after); NaN without any."""
    frames = np.asarray(frames, dtype=int)
    frames = frames[(frames >= 1) & (frames <= data.n_frames - 2)]
    if frames.size == 0:
        return float("nan")
    r = residuals(data, fit, frames)[:, data.free]
    return float(np.sqrt(np.mean(np.sum(r ** 2, axis=2))) / data.h)


def max_strain(data, rest, frames):
    """Largest elongation ``L / l - 1`` of any spring on ``frames`` (recorded positions,
    rest lengths ``rest`` (6,) per type); NaN without frames."""
    frames = np.asarray(frames, dtype=int)
    if frames.size == 0:
        return float("nan")
    x = data.x[frames]
    lengths = np.linalg.norm(x[:, data.ops.b] - x[:, data.ops.a], axis=2)
    return float(np.max(lengths / np.asarray(rest)[data.ops.kind][None, :]) - 1.0)
