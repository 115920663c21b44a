"""Fitting the base cloth model and effect terms to positions, exploiting structure.

For a spring that the deformation constraint leaves alone, the contract's force is linear
in ``k_t`` and ``k_t l_t`` per spring type, and every library effect is linear in its
coefficients, so the observed accelerations ``a_t = ((x_{t+1} - x_t)/dt - v_t)/dt`` are a
linear regression on particle-frames where the constraint is inactive. Velocities come
from the same noisy positions, so ordinary least squares is biased (errors in variables,
shared/NOTES.md); the regression is solved by instrumental variables, the instrument of
frame ``t`` being the same regressors built from frames ``t-2`` and ``t+3``, whose noise is
independent of the noise in ``a_t`` (frames ``t-1, t, t+1``). The critical elongation rate
``tau`` only acts through the constraint; it is found by a one-dimensional search of the
paper's one-step cost with the compiled kernel.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from replication.cloth.costs import ClothCost, structural_length
from replication.cloth.model import ClothParams, step
from replication.discrepancy import effects as fx
from replication.discrepancy.geometry import MeshOperators
from replication.errors import InputError

LAG_BEFORE = 2
LAG_AFTER = 3
BIG_TAU = 1e9
PLAUSIBLE_REST = (0.6, 1.5)
HAC_LAGS = 2
MASK_MARGIN = 0.02  # relative: tau may be off by a few percent while the mask is built


class Data(NamedTuple):
    """Arrays of one trajectory prepared for fitting (``T`` frames, ``P`` particles)."""

    trajectory: object
    x: np.ndarray         # (T, P, 3)
    v: np.ndarray         # (T, P, 3)
    target: np.ndarray    # (T, P, 3): a_t - g + c v_t / m, NaN where undefined
    scene: object
    ops: MeshOperators
    mass: np.ndarray      # (P,)
    free: np.ndarray      # (P,) bool
    h: float

    @property
    def n_frames(self):
        return self.x.shape[0]


class BaseModel(NamedTuple):
    """Base-model parameters per spring type: rest, k, tau each (6,)."""

    rest: np.ndarray
    k: np.ndarray
    tau: np.ndarray

    def params(self, pop=1):
        return ClothParams(np.repeat(self.rest[None], pop, 0), np.repeat(self.k[None], pop, 0),
                           np.repeat(self.tau[None], pop, 0))


class Fit(NamedTuple):
    """A fitted model: base parameters, effect terms ``[(name, theta)]`` and statistics."""

    base: BaseModel
    terms: list
    theta: np.ndarray     # all linear coefficients, base first
    cov: np.ndarray       # cluster-robust covariance of theta
    mask: np.ndarray      # (T, P) particle-frames used


def prepare(trajectory):
    """Arrays of a validated :class:`~replication.cloth.io.Trajectory` for fitting."""
    scene = trajectory.scene()
    x = np.ascontiguousarray(trajectory.flat_positions())
    v = np.ascontiguousarray(trajectory.flat_velocities())
    dt = scene.dt
    target = np.full_like(x, np.nan)
    target[:-1] = ((x[1:] - x[:-1]) / dt - v[:-1]) / dt
    target -= scene.gravity[None, None, :]
    target += scene.damping * v / scene.mass[None, :, None]
    return Data(trajectory, x, v, target, scene, MeshOperators(trajectory.n), scene.mass,
                scene.free, structural_length(trajectory))


def base_columns(A, B, mass, model="5"):
    """Regressors of the base model, (F, P, 3, 4) for ``model="5"`` (coefficients
    ``K, K l01, K l23, K l45``) or (F, P, 3, 12) for ``"18"`` (``k_t``, then ``k_t l_t``)."""
    inv_m = 1.0 / mass[None, :, None]
    if model == "5":
        cols = [A.sum(axis=0), -(B[0] + B[1]), -(B[2] + B[3]), -(B[4] + B[5])]
    elif model == "18":
        cols = list(A) + [-b for b in B]
    else:
        raise ValueError(f"model={model!r}: expected '5' or '18'")
    return np.stack([c * inv_m for c in cols], axis=-1)


def n_base(model):
    """Number of linear base coefficients."""
    return 4 if model == "5" else 12


def base_from_theta(theta, model, tau):
    """Rest lengths and stiffnesses per type from linear base coefficients."""
    theta = np.asarray(theta, dtype=float)
    if model == "5":
        K = theta[0]
        rest = (theta[1:4] / K)[[0, 0, 1, 1, 2, 2]]
        k = np.full(6, K)
    else:
        k = theta[:6].copy()
        rest = theta[6:12] / k
    return BaseModel(rest, k, np.broadcast_to(np.asarray(tau, float), (6,)).copy())


def base_to_theta(base, model):
    """Inverse of :func:`base_from_theta` (for 5: the means over each family)."""
    if model == "5":
        K = float(np.mean(base.k))
        return np.array([K, K * base.rest[0], K * base.rest[2], K * base.rest[4]])
    return np.concatenate([base.k, base.k * base.rest])


def design(data, base, effect_names, model):
    """All regressors over all frames: base columns then each effect's, (T, P, 3, m),
    and the column slice of each effect."""
    q = fx.Frames(data.x, data.v, data.ops, data.mass, base.rest, base.k,
                  data.scene.damping)
    A, B = q.sums
    blocks = [base_columns(A, B, data.mass, model)]
    slices, start = {}, blocks[0].shape[-1]
    for name in effect_names:
        cols = fx.get_effect(name).basis(q)
        blocks.append(cols)
        slices[name] = slice(start, start + cols.shape[-1])
        start += cols.shape[-1]
    return np.concatenate(blocks, axis=-1), slices


def usable_frames(frames, n_frames):
    """Frames ``t`` with instruments ``t-2, t+3`` and target ``t+1`` inside the data."""
    frames = np.asarray(frames)
    return frames[(frames - LAG_BEFORE - 1 >= 0) & (frames + LAG_AFTER <= n_frames - 1)]


def cluster_sums(columns, target, frames, mask, *, block=5):
    """Instrumental-variable normal equations summed per cluster of ``block`` frames.

    Parameters
    ----------
    columns : (T, P, 3, m) ndarray
    target : (T, P, 3) ndarray
    frames : (F,) int ndarray of usable frames
    mask : (T, P) bool ndarray
    block : int

    Returns
    -------
    G : (C, m, m) ``sum Z^T Phi``; hz : (C, m) ``sum Z^T y``; labels : (C,) cluster index
    ``t // block`` (consecutive labels are neighbouring blocks of time).
    """
    frames = np.asarray(frames)
    cluster_of = frames // block
    labels, which = np.unique(cluster_of, return_inverse=True)
    m = columns.shape[-1]
    G = np.zeros((labels.size, m, m))
    hz = np.zeros((labels.size, m))
    for row, t in enumerate(frames):
        keep = mask[t]
        phi = columns[t, keep].reshape(-1, m)
        z = 0.5 * (columns[t - LAG_BEFORE, keep] + columns[t + LAG_AFTER, keep]).reshape(-1, m)
        y = target[t, keep].reshape(-1)
        c = which[row]
        G[c] += z.T @ phi
        hz[c] += z.T @ y
    return G, hz, labels


def iv_solve(G, hz, cols=None, clusters=None, labels=None):
    """Solve the summed IV equations on columns ``cols`` and clusters ``clusters``.

    The covariance is a sandwich over clusters; with ``labels``, products of the scores of
    blocks up to ``HAC_LAGS`` apart are added with Bartlett weights (Newey-West): the
    residual noise ``e_{t+1} - 2 e_t + e_{t-1}`` and the instruments' noise are correlated
    across block boundaries, and leaving that out misstates the variances.

    Returns
    -------
    theta : (k,) ndarray
    cov : (k, k) ndarray
    """
    if cols is None:
        cols = np.arange(G.shape[1])
    if clusters is None:
        clusters = np.arange(G.shape[0])
    Gs = G[np.ix_(clusters, cols, cols)]
    hs = hz[np.ix_(clusters, cols)]
    bread = np.linalg.pinv(Gs.sum(axis=0))
    theta = bread @ hs.sum(axis=0)
    scores = hs - Gs @ theta
    n_c = len(clusters)
    meat = scores.T @ scores
    if labels is not None and n_c > 1:
        lab = np.asarray(labels)[clusters]
        position = {int(label): k for k, label in enumerate(lab)}
        for lag in range(1, HAC_LAGS + 1):
            pairs = [(k, position[int(label) + lag]) for k, label in enumerate(lab)
                     if int(label) + lag in position]
            if pairs:
                first, second = np.array(pairs).T
                cross = scores[first].T @ scores[second]
                meat = meat + (1.0 - lag / (HAC_LAGS + 1.0)) * (cross + cross.T)
    meat = meat * n_c / max(n_c - 1, 1)
    return theta, bread @ meat @ bread.T


def one_step_predictions(data, base, terms, frames):
    """Model predictions of frames ``t+1`` from recorded states at ``t``, (F, P, 3)."""
    frames = np.asarray(frames)
    x, v = data.x[frames], data.v[frames]
    q = fx.Frames(x, v, data.ops, data.mass, base.rest, base.k, data.scene.damping)
    extra = fx.extra_force(terms, q)
    x_hat, _ = step(x, v, base.params(len(frames)), data.scene, extra)
    return x_hat


def constraint_mask(data, base, terms, frames, *, margin=MASK_MARGIN):
    """Particle-frames the deformation constraint (probably) leaves alone, (T, P) bool.

    A free particle is excluded at frame ``t`` if a spring touching it is longer than
    ``(1 + tau)(1 - margin) l`` in the unconstrained prediction of ``t+1`` or in the recorded
    frame ``t+1``.
    """
    frames = np.asarray(frames)
    loose = BaseModel(base.rest, base.k, np.full(6, BIG_TAU))
    predicted = one_step_predictions(data, loose, terms, frames)
    mask = np.zeros((data.n_frames, data.x.shape[1]), dtype=bool)
    mask[frames] = data.free[None, :]
    a, b, kind = data.ops.a, data.ops.b, data.ops.kind
    limit = (1.0 + base.tau[kind]) * base.rest[kind] * (1.0 - margin)
    for positions in (predicted, data.x[frames + 1]):
        length = np.linalg.norm(positions[:, b] - positions[:, a], axis=2)
        over = length > limit[None, :]
        hit = np.zeros((len(frames), data.x.shape[1]), dtype=bool)
        rows, springs_over = np.nonzero(over)
        hit[rows, a[springs_over]] = True
        hit[rows, b[springs_over]] = True
        mask[frames] &= ~hit
    return mask


def search_tau(data, base, terms, frames, *, grid=None, max_frames=50, levels=7):
    """The critical elongation rate minimising the one-step cost over ``frames``.

    A log grid around the current value (or a wide one), then ``levels`` zooms of 21
    points around the best value (each a tenth of the last bracket), every grid evaluated
    as one population by the compiled kernel; exact ties go to the smallest ``tau``.
    """
    frames = np.asarray(frames)
    if len(frames) > max_frames:
        frames = frames[np.linspace(0, len(frames) - 1, max_frames).round().astype(int)]
    cost = ClothCost(data.trajectory, frames, h=data.h)
    q = fx.Frames(data.x[frames], data.v[frames], data.ops, data.mass, base.rest, base.k,
                  data.scene.damping)
    extra = fx.extra_force(terms, q)[None]
    if grid is None:
        current = float(base.tau[0])
        coarse = (np.geomspace(current / 1.5, current * 1.5, 21) if current < BIG_TAU
                  else np.geomspace(3e-3, 3.0, 64))
    else:
        coarse = np.asarray(grid)

    def evaluate(taus):
        pop = len(taus)
        params = ClothParams(np.repeat(base.rest[None], pop, 0),
                             np.repeat(base.k[None], pop, 0),
                             np.repeat(np.asarray(taus)[:, None], 6, 1))
        return cost(params, extra)

    values = evaluate(coarse)
    pick = int(np.argmin(values))
    grid_now, best_tau, best_value = coarse, float(coarse[pick]), float(values[pick])
    for _ in range(levels):
        lo = grid_now[max(pick - 1, 0)]
        hi = grid_now[min(pick + 1, len(grid_now) - 1)]
        if hi - lo <= 1e-8 * hi:
            break
        grid_now = np.linspace(lo, hi, 21)
        values = evaluate(grid_now)
        pick = int(np.argmin(values))
        if values[pick] < best_value:
            best_tau, best_value = float(grid_now[pick]), float(values[pick])
    return best_tau


def residual_trim(data, columns, theta, frames, mask, *, factor=6.0):
    """Drop particle-frames whose residual norm exceeds ``factor`` times the median."""
    pred = columns[frames] @ theta
    r = np.linalg.norm(data.target[frames] - pred, axis=2)
    scale = np.median(r[mask[frames]])
    out = mask.copy()
    out[frames] &= r <= factor * scale
    return out


def fit_model(data, frames, effect_names=(), *, model="5", base=None, rounds=2, block=5):
    """Fit base parameters and effect terms on ``frames``.

    Parameters
    ----------
    data : Data
    frames : (F,) int array_like
        Training frames ``t`` (each predicts ``t+1``).
    effect_names : sequence of str
        Library effects to include.
    model : {"5", "18"}
    base : BaseModel, optional
        Starting base model (else a robust fit without the constraint is made first).
    rounds : int
        Alternations of (linear fit, tau search, constraint mask).

    Returns
    -------
    Fit
    """
    frames = usable_frames(frames, data.n_frames)
    effect_names = tuple(effect_names)
    if base is None:
        base = initial_base(data, frames, model=model, block=block, effect_names=effect_names)
    terms = []
    best = None
    for _ in range(rounds):
        mask = constraint_mask(data, base, terms, frames)
        columns, slices = design(data, base, effect_names, model)
        G, hz, labels = cluster_sums(columns, data.target, frames, mask, block=block)
        theta, cov = iv_solve(G, hz, labels=labels)
        nb = n_base(model)
        if not (np.all(np.isfinite(theta)) and np.all(theta[:nb] > 0)):
            break  # constraint mask left too little data: keep the best round so far
        terms = [(name, theta[slices[name]]) for name in effect_names]
        base = base_from_theta(theta[:nb], model, base.tau)
        tau = search_tau(data, base, terms, frames)
        base = BaseModel(base.rest, base.k, np.full(6, tau))
        score = _structure_score(data, base, terms, frames)
        if best is None or score < best[0] or not np.isfinite(best[0]):
            best = (score, Fit(base, terms, theta, cov, mask))
    if best is None:
        raise InputError(f"{data.trajectory.source}: field 'positions': the base model could "
                         "not be fitted (no particle-frames left outside the deformation "
                         "constraint); expected a cloth trajectory as in "
                         "shared/spec/cloth-model.md")
    return best[1]


def _observed_mask(data, lengths, rest, tau, *, margin=MASK_MARGIN):
    """Free particle-frames with no touching spring beyond ``(1 + tau)(1 - margin) l`` in the
    recorded frames ``t+1`` whose spring lengths are ``lengths`` (F, S); (F, P) bool."""
    a, b, kind = data.ops.a, data.ops.b, data.ops.kind
    over = lengths > ((1.0 + tau) * rest[kind] * (1.0 - margin))[None, :]
    hit = np.zeros((lengths.shape[0], data.x.shape[1]), dtype=bool)
    rows, springs_over = np.nonzero(over)
    hit[rows, a[springs_over]] = True
    hit[rows, b[springs_over]] = True
    return data.free[None, :] & ~hit


def typical_lengths(data):
    """Median recorded length of each spring type over all frames, (6,)."""
    step_frames = max(1, data.n_frames // 50)
    x = data.x[::step_frames]
    return np.array([np.median(np.linalg.norm(x[:, data.ops.b[idx]] - x[:, data.ops.a[idx]],
                                              axis=2)) for idx in data.ops.type_slices])


def _plausible(rest, typical, *, low=PLAUSIBLE_REST[0], high=PLAUSIBLE_REST[1]):
    """Rest lengths within ``[low, high]`` times the typical recorded lengths (a cloth is
    neither compressed nor stretched by factors of two): rules out the cost's wrong valley
    of tiny rest lengths, soft springs and large ``tau`` (shared/NOTES.md)."""
    ratio = np.asarray(rest) / typical
    return bool(np.all((ratio >= low) & (ratio <= high)))


def spread_runs(frames, total, *, run=10):
    """About ``total`` frames in runs of ``run`` consecutive frames spread evenly over
    ``frames`` (the structure statistic needs consecutive frames; spreading them keeps the
    late, constrained part of a trajectory in the score)."""
    frames = np.asarray(frames)
    if frames.size <= total:
        return frames
    n_runs = max(total // run, 1)
    starts = np.linspace(0, frames.size - run, n_runs).round().astype(int)
    chosen = np.unique(np.concatenate([frames[s:s + run] for s in starts]))
    return chosen


def _structure_score(data, base, terms, frames):
    """Residual structure ``Q`` of a candidate start (1 = noise only): unlike the one-step
    cost it does not reward the wrong valley, whose errors are smooth in time."""
    from replication.discrepancy.residuals import structure

    frames = np.asarray(frames)
    r = data.x[frames + 1] - one_step_predictions(data, base, terms, frames)
    r[:, ~data.free] = 0.0
    return structure(r, frames, data.free, data.ops.n)["Q"]


def initial_base(data, frames, *, model="5", block=5, taus=None, inner=3, max_frames=30,
                 max_score_frames=60, max_starts=4, effect_names=()):
    """Robust start: profile over ``tau``.

    For each ``tau`` of a coarse grid, alternate an IV fit and the mask of particle-frames
    whose recorded springs stay below ``(1 + tau) l`` and pick ``tau`` on the one-step cost
    (compiled kernel); the ``max_starts`` distinct starts of lowest cost then get ``tau``
    refined (:func:`search_tau`) and the one whose residual structure ``Q`` is smallest is
    kept (the cost alone prefers the wrong valley when the model misses an effect).
    """
    taus = np.geomspace(0.02, 1.0, 13) if taus is None else np.asarray(taus)
    ratio = np.sqrt(taus[1] / taus[0]) if len(taus) > 1 else 1.0
    typical = typical_lengths(data)
    guess = BaseModel(typical, np.ones(6), np.full(6, BIG_TAU))
    columns, slices = design(data, guess, effect_names, model)
    m = columns.shape[-1]
    nb = n_base(model)
    z = 0.5 * (columns[frames - LAG_BEFORE] + columns[frames + LAG_AFTER])
    normal = np.einsum("fpci,fpcj->fpij", z, columns[frames])
    right = np.einsum("fpci,fpc->fpi", z, data.target[frames])
    rest0 = typical
    following = data.x[frames + 1]
    lengths = np.linalg.norm(following[:, data.ops.b] - following[:, data.ops.a], axis=2)
    score_frames = spread_runs(frames, max_score_frames)
    cost_frames = frames if len(frames) <= max_frames else \
        frames[np.linspace(0, len(frames) - 1, max_frames).round().astype(int)]
    cost = ClothCost(data.trajectory, cost_frames, h=data.h)
    best, starts = None, {}
    for tau in taus:
        rest = rest0
        base, terms = None, []
        for _ in range(inner):
            keep = _observed_mask(data, lengths, rest, tau).astype(float)
            lhs = np.einsum("fp,fpij->ij", keep, normal)
            if np.linalg.matrix_rank(lhs) < m:
                break
            theta = np.linalg.solve(lhs, np.einsum("fp,fpi->i", keep, right))
            base = base_from_theta(theta[:nb], model, tau)
            terms = [(name, theta[slices[name]]) for name in effect_names]
            if not (np.all(base.k > 0) and np.all(base.rest > 0)):
                base = None
                break
            rest = base.rest
        if base is None or not _plausible(base.rest, typical):
            continue
        local = np.geomspace(tau / ratio, tau * ratio ** 3, 15)
        params = ClothParams(np.repeat(base.rest[None], local.size, 0),
                             np.repeat(base.k[None], local.size, 0),
                             np.repeat(local[:, None], 6, 1))
        q = fx.Frames(data.x[cost_frames], data.v[cost_frames], data.ops, data.mass,
                      base.rest, base.k, data.scene.damping)
        values = cost(params, fx.extra_force(terms, q)[None])
        pick = int(np.argmin(values))
        key = (round(float(base.k[0]), 4), round(float(local[pick]), 2))
        if key not in starts or values[pick] < starts[key][0]:
            starts[key] = (float(values[pick]),
                           BaseModel(base.rest, base.k, np.full(6, local[pick])), terms)
    for _, candidate, terms in sorted(starts.values(), key=lambda s: s[0])[:max_starts]:
        # Q punishes an imprecise tau wherever the constraint acts: refine it first
        tau = search_tau(data, candidate, terms, frames, max_frames=max_frames, levels=4)
        candidate = BaseModel(candidate.rest, candidate.k, np.full(6, tau))
        score = _structure_score(data, candidate, terms, score_frames)
        if best is None or score < best[0]:
            best = (score, candidate)
    if best is None:
        raise InputError(f"{data.trajectory.source}: field 'positions': no start of the base "
                         "model has positive stiffness and plausible rest lengths; expected a "
                         "cloth trajectory as in shared/spec/cloth-model.md")
    return best[1]
