"""Compiled kernels of the cloth step (numba). One implementation of the step.

``_step_into`` is the whole time step of docs/cloth-model.md for one parameter set;
the drivers below run it over a population (``prange``), over time (rollouts) or over
recorded frames (one-step prediction errors for the paper's costs).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def add_scaled(array, i, scale, d0, d1, d2):
    """``array[i] += scale * (d0, d1, d2)`` (``-scale`` subtracts: the same numbers, IEEE
    negation being exact)."""
    array[i, 0] += scale * d0
    array[i, 1] += scale * d1
    array[i, 2] += scale * d2


@njit(cache=True, fastmath=False, nogil=True)
def _step_into(x, v, rest, k, tau, extra, sa, sb, st, free, mass, gravity, damping, dt,
               force, corr, count, x_out, v_out):
    """One semi-implicit Euler step with Provot's deformation constraint.

    x, v : (P, 3) state at time t; rest, k, tau : (6,) per spring type;
    extra : (P, 3) external force added to gravity, damping and springs (effect plug-ins);
    sa, sb, st : (S,) spring ends and types; free : (P,) bool; mass : (P,);
    force, corr : (P, 3) and count : (P,) scratch; x_out, v_out : (P, 3) results.
    """
    _predict_into(x, v, rest, k, extra, sa, sb, st, free, mass, gravity, damping, dt, force,
                  x_out)
    _constrain_into(x, rest, tau, sa, sb, st, free, dt, corr, count, x_out, v_out)


@njit(cache=True, fastmath=False, nogil=True)
def _predict_into(x, v, rest, k, extra, sa, sb, st, free, mass, gravity, damping, dt, force,
                  x_out):
    """Steps 1-2 of :func:`_step_into`: forces, then ``x' = x + dt v'`` into ``x_out``
    (tau plays no part before the constraint)."""
    n_particles = x.shape[0]
    n_springs = sa.shape[0]
    for p in range(n_particles):
        for c in range(3):
            force[p, c] = mass[p] * gravity[c] - damping * v[p, c] + extra[p, c]
    # spring forces f_a = k (L - l) d / L, f_b = -f_a
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
    # 1-2: v' = v + dt F / m (zero on pinned), x' = x + dt v'
    for p in range(n_particles):
        for c in range(3):
            if free[p]:
                vel = v[p, c] + dt * force[p, c] / mass[p]
            else:
                vel = 0.0
            x_out[p, c] = x[p, c] + dt * vel


@njit(cache=True, fastmath=False, nogil=True)
def _constrain_into(x, rest, tau, sa, sb, st, free, dt, corr, count, x_out, v_out):
    """Steps 3-4 of :func:`_step_into` on ``x_out`` = x' (changed in place into x''):
    the deformation constraint, then ``v'' = (x'' - x) / dt`` into ``v_out``."""
    n_particles = x.shape[0]
    n_springs = sa.shape[0]
    for p in range(n_particles):
        for c in range(3):
            corr[p, c] = 0.0
        count[p] = 0.0
    # 3: one Jacobi pass of the deformation constraint on x'
    for s in range(n_springs):
        a = sa[s]
        b = sb[s]
        t = st[s]
        d0 = x_out[b, 0] - x_out[a, 0]
        d1 = x_out[b, 1] - x_out[a, 1]
        d2 = x_out[b, 2] - x_out[a, 2]
        length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        limit = (1.0 + tau[t]) * rest[t]
        if length > limit:
            propose_correction(a, b, d0, d1, d2, length, limit, free, corr, count)
    _apply_into(x, free, dt, corr, count, x_out, v_out)


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def propose_correction(a, b, d0, d1, d2, length, limit, free, corr, count):
    """Add one over-stretched spring's proposals to ``corr`` and ``count`` (a Jacobi pass
    of the deformation constraint): ``d = x_b - x_a``, ``length = |d| > limit``. A
    Gauss-Seidel pass (numerics_variants.py) passes the positions as ``corr``."""
    excess = (length - limit) / length
    free_a = free[a]
    free_b = free[b]
    if free_a and free_b:
        share = 0.5 * excess
        add_scaled(corr, a, share, d0, d1, d2)
        add_scaled(corr, b, -share, d0, d1, d2)
        count[a] += 1.0
        count[b] += 1.0
    elif free_a:
        add_scaled(corr, a, excess, d0, d1, d2)
        count[a] += 1.0
    elif free_b:
        add_scaled(corr, b, -excess, d0, d1, d2)
        count[b] += 1.0


@njit(cache=True, fastmath=False, nogil=True)
def _apply_into(x, free, dt, corr, count, x_out, v_out):
    """Step 3 (end) and 4 on ``x_out``: the mean of the proposals added; ``v'' = (x'' - x)
    / dt`` into ``v_out``, zero on pinned particles."""
    n_particles = x.shape[0]
    for p in range(n_particles):
        if count[p] > 0.0:
            for c in range(3):
                x_out[p, c] += corr[p, c] / count[p]
        for c in range(3):
            if free[p]:
                v_out[p, c] = (x_out[p, c] - x[p, c]) / dt
            else:
                v_out[p, c] = 0.0


@njit(cache=True, parallel=True)
def step_batch(x, v, rest, k, tau, extra, sa, sb, st, free, mass, gravity, damping, dt):
    """One step for each row of a batch: x, v, extra (B, P, 3); rest, k, tau (B, 6).

    Parameters
    ----------
    x, v, extra : (B, P, 3) ndarray
        Positions, velocities and external forces of each row.
    rest, k, tau : (B, 6) ndarray
        Per-type rest lengths, stiffnesses and critical elongation rates.
    sa, sb, st, free, mass, gravity, damping, dt
        The scene, as ``Scene.kernel_args()`` gives it: spring ends and types (S,), free
        particles (P,) bool, masses (P,), gravity (3,), linear damping, time step.
    """
    n_batch, n_particles = x.shape[0], x.shape[1]
    x_out = np.empty_like(x)
    v_out = np.empty_like(v)
    for i in prange(n_batch):
        force = np.empty((n_particles, 3))
        corr = np.empty((n_particles, 3))
        count = np.empty(n_particles)
        _step_into(x[i], v[i], rest[i], k[i], tau[i], extra[i], sa, sb, st, free, mass,
                   gravity, damping, dt, force, corr, count, x_out[i], v_out[i])
    return x_out, v_out


@njit(cache=True, parallel=True)
def rollout_batch(x0, v0, rest, k, tau, n_steps, sa, sb, st, free, mass, gravity,
                  damping, dt):
    """``n_steps`` steps from (x0, v0) (B, P, 3); returns positions and velocities
    of shape (B, n_steps + 1, P, 3), frame 0 being the initial state.

    Parameters
    ----------
    x0, v0 : (B, P, 3) ndarray
        Initial positions and velocities.
    rest, k, tau : (B, 6) ndarray
    n_steps : int
    sa, sb, st, free, mass, gravity, damping, dt
        The scene, as ``Scene.kernel_args()`` gives it: spring ends and types (S,), free
        particles (P,) bool, masses (P,), gravity (3,), linear damping, time step.
    """
    n_batch, n_particles = x0.shape[0], x0.shape[1]
    xs = np.empty((n_batch, n_steps + 1, n_particles, 3))
    vs = np.empty((n_batch, n_steps + 1, n_particles, 3))
    for i in prange(n_batch):
        force = np.empty((n_particles, 3))
        corr = np.empty((n_particles, 3))
        count = np.empty(n_particles)
        extra = np.zeros((n_particles, 3))
        xs[i, 0] = x0[i]
        vs[i, 0] = v0[i]
        for t in range(n_steps):
            _step_into(xs[i, t], vs[i, t], rest[i], k[i], tau[i], extra, sa, sb, st, free, mass,
                       gravity, damping, dt, force, corr, count, xs[i, t + 1], vs[i, t + 1])
    return xs, vs


@njit(cache=True, fastmath=False, nogil=True)
def _error(x_hat, v_hat, x_next, v_next, dtc):
    """``sum_p |x^_p - x_p|^2 + dtc^2 |v^_p - v_p|^2``; ``inf`` when not finite."""
    total = 0.0
    for p in range(x_hat.shape[0]):
        for c in range(3):
            dx = x_hat[p, c] - x_next[p, c]
            dv = v_hat[p, c] - v_next[p, c]
            total += dx * dx + dtc * dtc * dv * dv
    if not np.isfinite(total):
        total = np.inf
    return total


@njit(cache=True, parallel=True)
def one_step_errors(xs, vs, frames, rest, k, tau, extra, dtc, sa, sb, st, free, mass,
                    gravity, damping, dt):
    """Paper 3.3: predict frame t+1 from the recorded state at frame t.

    Returns ``e`` : (B, F) with ``e = sum_p |x^_p - x_p|^2 + dtc^2 |v^_p - v_p|^2`` (not
    yet normalised); a non-finite prediction gives ``inf``.

    Parameters
    ----------
    xs, vs : (T, P, 3) ndarray
        Recorded positions and velocities.
    frames : (F,) int ndarray
        Values of ``t``.
    rest, k, tau : (B, 6) ndarray
    extra : (EB, EF, P, 3) ndarray
        External forces; ``EB`` in {1, B}, ``EF`` in {1, F} (a size-1 axis is shared).
    dtc : float
        Weight of velocity errors.
    sa, sb, st, free, mass, gravity, damping, dt
        The scene, as ``Scene.kernel_args()`` gives it: spring ends and types (S,), free
        particles (P,) bool, masses (P,), gravity (3,), linear damping, time step.
    """
    n_batch = rest.shape[0]
    n_frames = frames.shape[0]
    n_particles = xs.shape[1]
    errors = np.empty((n_batch, n_frames))
    for job in prange(n_batch * n_frames):
        i = job // n_frames
        f = job % n_frames
        t = frames[f]
        force = np.empty((n_particles, 3))
        corr = np.empty((n_particles, 3))
        count = np.empty(n_particles)
        x_hat = np.empty((n_particles, 3))
        v_hat = np.empty((n_particles, 3))
        ei = i if extra.shape[0] > 1 else 0
        ef = f if extra.shape[1] > 1 else 0
        _step_into(xs[t], vs[t], rest[i], k[i], tau[i], extra[ei, ef], sa, sb, st, free, mass,
                   gravity, damping, dt, force, corr, count, x_hat, v_hat)
        errors[i, f] = _error(x_hat, v_hat, xs[t + 1], vs[t + 1], dtc)
    return errors


@njit(cache=True, parallel=True)
def one_step_errors_tau(xs, vs, frames, rest, k, tau, extra, dtc, sa, sb, st, free, mass,
                        gravity, damping, dt):
    """:func:`one_step_errors` of one (rest, k) under many tau: ``e`` (B, F), equal bit for
    bit to ``one_step_errors`` with ``rest`` and ``k`` repeated over the batch.

    Per frame, the forces, the Euler step, the springs of x' and every particle's error
    terms without the constraint (no tau in them) are computed once. Per tau, only the
    springs that can be over a limit of the batch are compared with the limits (a spring
    no longer than its type's smallest limit is over none), and only the particles their
    proposals move are stepped again; the error is summed over every particle in the
    order of :func:`_error`, so that the numbers are the same.

    Parameters
    ----------
    xs, vs : (T, P, 3) ndarray
    frames : (F,) int ndarray
    rest, k : (6,) ndarray
    tau : (B, 6) ndarray
    extra : (1, EF, P, 3) ndarray
        External forces shared by the batch; ``EF`` in {1, F}.
    dtc, sa, sb, st, free, mass, gravity, damping, dt
        As :func:`one_step_errors`.
    """
    n_batch = tau.shape[0]
    n_frames = frames.shape[0]
    n_particles = xs.shape[1]
    n_springs = sa.shape[0]
    n_types = rest.size
    errors = np.empty((n_batch, n_frames))
    shared_frame = extra.shape[1] == 1
    # the smallest limit of each type over the batch: (1 + tau) l grows with tau
    lowest = np.empty(n_types)
    for kind in range(n_types):
        lowest[kind] = np.inf
        for i in range(n_batch):
            limit = (1.0 + tau[i, kind]) * rest[kind]
            if limit < lowest[kind]:   # (a NaN limit is over no spring, and not lowest)
                lowest[kind] = limit
    for job in prange(n_frames):
        f = np.int64(job)
        t = frames[f]
        x_now = xs[t]
        x_next = xs[t + 1]
        v_next = vs[t + 1]
        force = np.empty((n_particles, 3))
        corr = np.zeros((n_particles, 3))
        count = np.zeros(n_particles)
        x_pred = np.empty((n_particles, 3))
        terms = np.empty((n_particles, 3))
        d = np.empty((n_springs, 3))
        length = np.empty(n_springs)
        candidates = np.empty(n_springs, dtype=np.int64)
        limits = np.empty(n_types)
        ef = np.int64(0) if shared_frame else f
        _predict_into(x_now, vs[t], rest, k, extra[0, ef], sa, sb, st, free, mass, gravity,
                      damping, dt, force, x_pred)
        # the springs of x' (the Jacobi pass reads x' alone), as _constrain_into computes
        # them, and those that may be over a limit of the batch
        n_candidates = 0
        for s in range(n_springs):
            d[s, 0] = x_pred[sb[s], 0] - x_pred[sa[s], 0]
            d[s, 1] = x_pred[sb[s], 1] - x_pred[sa[s], 1]
            d[s, 2] = x_pred[sb[s], 2] - x_pred[sa[s], 2]
            length[s] = np.sqrt(d[s, 0] * d[s, 0] + d[s, 1] * d[s, 1] + d[s, 2] * d[s, 2])
            if length[s] > lowest[st[s]]:
                candidates[n_candidates] = s
                n_candidates += 1
        # each particle's error terms when no proposal moves it (_apply_into, _error)
        unconstrained = 0.0
        for p in range(n_particles):
            for c in range(3):
                vel = (x_pred[p, c] - x_now[p, c]) / dt if free[p] else 0.0
                dx = x_pred[p, c] - x_next[p, c]
                dv = vel - v_next[p, c]
                terms[p, c] = dx * dx + dtc * dtc * dv * dv
                unconstrained += terms[p, c]
        if not np.isfinite(unconstrained):
            unconstrained = np.inf
        for i in range(n_batch):
            for kind in range(n_types):
                limits[kind] = (1.0 + tau[i, kind]) * rest[kind]
            hits = 0
            for j in range(n_candidates):
                s = candidates[j]
                limit = limits[st[s]]
                if length[s] > limit:
                    propose_correction(sa[s], sb[s], d[s, 0], d[s, 1], d[s, 2], length[s],
                                       limit, free, corr, count)
                    hits += 1
            if hits == 0:
                errors[i, f] = unconstrained
                continue
            # the error over every particle in order: the moved ones stepped again (and
            # their scratch cleared for the next tau), the others' terms as computed
            total = 0.0
            for p in range(n_particles):
                if count[p] > 0.0:
                    for c in range(3):
                        position = x_pred[p, c] + corr[p, c] / count[p]
                        vel = (position - x_now[p, c]) / dt if free[p] else 0.0
                        dx = position - x_next[p, c]
                        dv = vel - v_next[p, c]
                        total += dx * dx + dtc * dtc * dv * dv
                        corr[p, c] = 0.0
                    count[p] = 0.0
                else:
                    total += terms[p, 0]
                    total += terms[p, 1]
                    total += terms[p, 2]
            errors[i, f] = total if np.isfinite(total) else np.inf
    return errors


@njit(cache=True, fastmath=False, nogil=True)
def stretched_ends(positions, sa, sb, limit):
    """Particles at an end of a spring longer than its limit, per frame: (F, P) bool.

    Parameters
    ----------
    positions : (F, P, 3) ndarray
    sa, sb : (S,) int ndarray
        Spring ends.
    limit : (S,) ndarray
        Length above which a spring counts as stretched (strictly).
    """
    n_frames, n_particles = positions.shape[0], positions.shape[1]
    hit = np.zeros((n_frames, n_particles), dtype=np.bool_)
    for f in range(n_frames):
        for s in range(sa.shape[0]):
            a = sa[s]
            b = sb[s]
            d0 = positions[f, b, 0] - positions[f, a, 0]
            d1 = positions[f, b, 1] - positions[f, a, 1]
            d2 = positions[f, b, 2] - positions[f, a, 2]
            if np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > limit[s]:
                hit[f, a] = True
                hit[f, b] = True
    return hit
