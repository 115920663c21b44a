"""The identification engine: base cloth model and plug-in force terms fitted to positions.

One engine serves every workflow that fits the cloth model to a trajectory (the structured
identifier of ``cloth_identify`` and the discrepancy workflow), so a fix serves both.

For a free particle that the deformation constraint leaves alone, one contract step gives
``x_{t+1} - 2 x_t + x_{t-1} = dt^2 (g - c v_t / m + F_springs(x_t) / m + F_extra / m)``, and
the spring force ``k (L - l) d / L = k d - (k l) d / L`` is linear in ``k_t`` and ``k_t l_t``
per spring type; every plug-in term (an effect of the discrepancy library) is linear in its
coefficients. So observed accelerations are a linear regression on particle-frames where
the constraint is inactive; the critical elongation rate ``tau`` only acts through the
constraint and is found by a one-dimensional search of the one-step cost (compiled kernel).

Stages of :func:`fit`:

1. Start (no ``tau`` needed): least squares frame by frame with iterative trimming of the
   particle-frames the constraint moved (outliers of the unconstrained step); the frames
   whose fits explain the data best are then fitted jointly, again with trimming. Done on
   the data as recorded and on positions smoothed in time (Savitzky-Golay), keeping the
   version that explains its data best: raw data win when they are noise-free, smoothed
   ones against noise. This is what keeps every fit out of the cost's wrong valley
   (small K and rest lengths, large tau).
2. ``tau`` by a search of the one-step cost (wide log grid, then zooms).
3. Rounds of: mask of the particle-frames the constraint probably moved (model prediction
   and recorded frame), joint instrumental-variable regression of base and plug-in
   coefficients on the raw data (velocities come from the same noisy positions, so ordinary
   least squares is biased; the instrument of frame ``t`` is the same regressors built
   from frames ``t-2`` and ``t+3``), ``tau`` search again.

A fit whose rest lengths come out well below the recorded ones may be in the cost's wrong
valley: the rounds are run again from other starts (by least quantile of squares, which
finds the few particle-frames the constraint left alone, and stiffer ones), and the fit
with the smallest one-step residuals is kept.

When the constraint is active on nearly every particle-frame (nothing left to regress
on), the fit falls back to least squares through the constraint: the one-step residuals
of the compiled model are minimised over rest lengths, stiffness and ``tau``. A valid
trajectory is never refused.
"""

from __future__ import annotations

import dataclasses
import itertools
from functools import cached_property
from typing import Callable, NamedTuple

import numpy as np
from scipy.optimize import least_squares

from replication.cache import KeptArrays, read_only
from replication.cloth import geometry, kernels
from replication.cloth.costs import ClothCost, structural_length
from replication.cloth.mesh import FAMILY_OF_TYPE, N_TYPES, type_lengths
from replication.cloth.model import ClothParams, step
from replication.errors import InputError
from replication.optim.scan import zoom

LAG_BEFORE = 2
LAG_AFTER = 3
BIG_TAU = 1e9
HAC_LAGS = 2
MASK_MARGIN = 0.25  # of the stretch tau: the mask stays conservative while tau is rough
SMOOTH_WINDOWS = (0, 31)
# A fit whose rest lengths fall below this share of the recorded lengths may sit in the
# cost's wrong valley (too soft, too short, large tau): the rounds are run again from
# starts these many times stiffer (until one ends out of the valley), and the fit with the
# smallest one-step residuals is kept.
VALLEY_REST = 0.9
VALLEY_STIFFER = (2.0, 4.0, 8.0)
# In the valley, starts by least quantile of squares are tried as well (see
# consensus_start): the residual quantile it ranks elemental fits by, how many fits it draws
# (from a generator of this seed: the same data give the same start) and the
# Savitzky-Golay windows of the data versions it runs on (0: as recorded).
CONSENSUS_QUANTILES = (0.05, 0.1)
CONSENSUS_SAMPLES = 400
CONSENSUS_SEED = 0
CONSENSUS_WINDOWS = (0, 7, 11, 31)


class Data(NamedTuple):
    """Arrays of one trajectory prepared for fitting (``T`` frames, ``P`` particles)."""

    trajectory: object
    x: np.ndarray         # (T, P, 3)
    v: np.ndarray         # (T, P, 3)
    target: np.ndarray    # (T, P, 3): a_t - g + c v_t / m, NaN where undefined
    scene: object
    ops: geometry.MeshOperators
    mass: np.ndarray      # (P,)
    free: np.ndarray      # (P,) bool
    h: float
    cache: dict           # quantities of the recorded x computed once (state_frames,
    #                       design, version, ...); a Data with other positions comes from
    #                       prepare(), not _replace

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


class Plugin(NamedTuple):
    """A force term linear in its coefficients: ``basis(q) -> (F, P, 3, m)`` extra
    acceleration per unit coefficient under the nominal mass; ``needs_base``: the columns
    depend on the base model's rest lengths or stiffness (rebuilt every round).

    ``basis`` must be a function of the frames of ``q`` alone, and of ``q.rest`` and
    ``q.k`` only when ``needs_base``: on recorded frames its columns are computed once per
    frame selection (and base model) and shared (:meth:`StateFrames.columns`)."""

    name: str
    basis: Callable
    needs_base: bool = False


class Fit(NamedTuple):
    """A fitted model: base parameters, terms ``[(plugin, theta)]`` and statistics."""

    base: BaseModel
    terms: list
    theta: np.ndarray | None   # all linear coefficients, base first (None: not regressed)
    cov: np.ndarray | None     # cluster-robust covariance of theta
    mask: np.ndarray           # (T, P) particle-frames used by the last regression
    how: str                   # "regression" or "through_constraint"

    def term(self, name):
        """Coefficients of the plug-in called ``name``."""
        return next(np.asarray(theta) for plugin, theta in self.terms if plugin.name == name)


class StateFrames:
    """States ``(x, v)`` of some frames with the quantities plug-ins are built from.

    Parameters
    ----------
    x, v : (F, P, 3) ndarray
    ops : geometry.MeshOperators
    mass : (P,) ndarray
        Nominal (file) mass per particle.
    rest, k : (6,) ndarray
        Current base-model rest lengths and stiffnesses.
    damping : float
        Known linear damping of the data file.
    """

    def __init__(self, x, v, ops, mass, rest, k, damping=0.0, sums=None, memo=None):
        self.x = x
        self.v = v
        self.ops = ops
        self.mass = mass
        self.rest = np.asarray(rest, dtype=float)
        self.k = np.asarray(k, dtype=float)
        self.damping = float(damping)
        if sums is not None:   # spring_sums(ops, x), already computed
            self.__dict__["sums"] = sums
        self._memo = memo      # (kept columns, frames key) of recorded frames, or None

    def columns(self, plugin):
        """``plugin.basis(self)``. On recorded frames (:func:`state_frames`) the columns are
        computed once per frame selection, and per base model when the plug-in
        ``needs_base``, and shared read-only (kept in ``data.cache``, at most
        :data:`COLUMNS_BYTES_KEPT` bytes of them)."""
        if self._memo is None:
            return plugin.basis(self)
        cache, frames_key = self._memo
        key = (plugin.name, plugin.basis, frames_key)
        if plugin.needs_base:
            key += (self.rest.tobytes(), self.k.tobytes())
        return cache.get(key, lambda: plugin.basis(self))

    @cached_property
    def sums(self):
        return geometry.spring_sums(self.ops, self.x)

    @cached_property
    def area_normals(self):
        return geometry.area_normals(self.x, self.ops.n)

    @cached_property
    def inner_force(self):
        """Spring forces plus known damping at the base parameters, (F, P, 3)."""
        A, B = self.sums
        return geometry.spring_force(A, B, self.rest, self.k) - self.damping * self.v

    def per_mass(self, force):
        return force / self.mass[None, :, None]


def smoothed(trajectory, window, polyorder=3):
    """``trajectory`` with positions smoothed over time (Savitzky-Golay, ``window``
    frames, pinned particles untouched) and velocities re-derived; ``window=0``: as is.

    Against position noise: the one-step regression differentiates positions twice, so
    noise of sd s enters its target with sd of order s / dt^2 (docs/pitfalls.md).
    """
    if window == 0 or window > trajectory.n_frames:
        return trajectory
    from scipy.signal import savgol_filter   # here: scipy.signal takes about 1 s to import

    positions = savgol_filter(trajectory.flat_positions(), window, polyorder, axis=0)
    free = trajectory.scene().free
    positions[:, ~free] = trajectory.flat_positions()[:, ~free]
    return dataclasses.replace(trajectory, velocities=None,
                               positions=positions.reshape(trajectory.positions.shape))


def version(data, window):
    """``data`` smoothed over ``window`` frames (:func:`smoothed`) and prepared; ``data``
    itself for ``window=0``. Made once per ``data`` and window and kept in its cache: the
    starts and the tau search of every fit of the same data ask for the same versions.

    Parameters
    ----------
    data : Data
    window : int
        Savitzky-Golay window in frames (0: the data as recorded).
    """
    window = int(window)
    if window == 0:
        return data
    versions = data.cache.setdefault("versions", {})
    if window not in versions:
        versions[window] = prepare(smoothed(data.trajectory, window))
    return versions[window]


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
    return Data(trajectory, x, v, target, scene, geometry.MeshOperators(trajectory.n),
                scene.mass, scene.free, structural_length(trajectory), {})


def n_base(model):
    """Number of linear base coefficients."""
    return 4 if model == "5" else 12


def base_columns(A, B, mass, model="5"):
    """Regressors of the base model, (F, P, 3, 4) for ``model="5"`` (coefficients
    ``K, K l01, K l23, K l45``) or (F, P, 3, 12) for ``"18"`` (``k_t``, then ``k_t l_t``)."""
    inv_m = 1.0 / mass[None, :, None]
    if model == "5":
        cols = [A.sum(axis=0)] + [-sum(B[t] for t in range(N_TYPES) if FAMILY_OF_TYPE[t] == f)
                                  for f in range(3)]
    elif model == "18":
        cols = list(A) + [-b for b in B]
    else:
        raise ValueError(f"model={model!r}: expected '5' or '18'")
    return np.stack([c * inv_m for c in cols], axis=-1)


def base_from_theta(theta, model, tau):
    """Rest lengths and stiffnesses per type from linear base coefficients."""
    theta = np.asarray(theta, dtype=float)
    if model == "5":
        K = theta[0]
        rest = (theta[1:4] / K)[FAMILY_OF_TYPE]
        k = np.full(N_TYPES, K)
    else:
        k = theta[:N_TYPES].copy()
        rest = theta[N_TYPES:2 * N_TYPES] / k
    return BaseModel(rest, k, np.broadcast_to(np.asarray(tau, float), (N_TYPES,)).copy())


SELECTIONS_KEPT = 4   # frame selections whose states state_frames keeps per data
COLUMNS_BYTES_KEPT = 2 ** 28   # plug-in columns kept per data (most recently used first)
DESIGNS_KEPT = 2   # design matrices kept per data (most recently used first)
DESIGNS_BYTES_KEPT = 2 ** 29   # within this many bytes (the newest is always kept)


def _kept(data, name, **bounds):
    """The :class:`~replication.cache.KeptArrays` ``name`` of ``data``, made on first use."""
    if name not in data.cache:
        data.cache[name] = KeptArrays(**bounds)
    return data.cache[name]


def _recorded_states(data, frames):
    """Positions, velocities and spring sums of the recorded ``frames`` (all frames when
    None), computed once and kept in ``data.cache``, shared by every base model's states.
    Those of all frames are kept for good; of the frame selections (read-only copies), the
    :data:`SELECTIONS_KEPT` most recently used (a least-squares fit asks for the same frames
    hundreds of times)."""
    if frames is None:
        if "states" not in data.cache:
            data.cache["states"] = (data.x, data.v,
                                    read_only(geometry.spring_sums(data.ops, data.x)))
        return data.cache["states"]

    def states():
        x = data.x[frames]
        return x, data.v[frames], geometry.spring_sums(data.ops, x)

    selections = _kept(data, "selections", max_entries=SELECTIONS_KEPT)
    return selections.get(frames.tobytes(), states)


def state_frames(data, base, frames=None):
    """:class:`StateFrames` of ``frames`` (all frames when None) at the ``base`` model.

    Positions, velocities and spring sums depend on the recorded data alone: those of all
    frames and of the last few frame selections are kept per ``data``
    (:func:`_recorded_states`) and shared by every base model's states, and so are the
    plug-in columns computed on them (:meth:`StateFrames.columns`).
    """
    frames = _frame_index(frames)
    x, v, sums = _recorded_states(data, frames)
    columns = _kept(data, "columns", max_bytes=COLUMNS_BYTES_KEPT)
    return StateFrames(x, v, data.ops, data.mass, base.rest, base.k, data.scene.damping,
                       sums=sums, memo=(columns, None if frames is None else frames.tobytes()))


def _frame_index(frames):
    """``frames`` (a 1-D index array or mask, or None for all frames) as an index array."""
    if frames is None:
        return None
    frames = np.asarray(frames)
    if frames.ndim != 1:
        raise ValueError(f"frames of shape {frames.shape}: expected a 1-D index array "
                         "or mask")
    if frames.dtype == bool:
        frames = np.flatnonzero(frames)
    return frames.astype(np.intp, copy=False)


class Columns:
    """Regressors (F, P, 3, m) held as their blocks side by side (base columns, then each
    plug-in's), read like the array of the blocks concatenated without making it: a
    selection of frames and particles is gathered from each block and joined, and
    ``[..., cut]`` of one block's columns is that block. Both give the very numbers (and
    layout) the concatenated array gives. Anything else reads the concatenated array.
    ``widths`` holds the number of columns of each block."""

    ndim = 4

    def __init__(self, blocks):
        self.blocks = tuple(blocks)
        self.widths = _block_widths(self.blocks)
        self.shape = self.blocks[0].shape[:-1] + (int(self.widths.sum()),)
        self._starts = np.r_[0, np.cumsum(self.widths)]

    def __getitem__(self, index):
        if not isinstance(index, tuple):
            index = (index,)
        if len(index) == 2 and index[0] is Ellipsis and isinstance(index[1], slice):
            start, stop, step = index[1].indices(self.shape[-1])
            for block, first in zip(self.blocks, self._starts):
                if step == 1 and start == first and stop == first + block.shape[-1]:
                    return block
        elif len(index) < self.ndim and not any(i is Ellipsis or i is None for i in index):
            # leading axes only: each block's selection, joined along the columns
            return np.concatenate([block[index] for block in self.blocks], axis=-1)
        return np.asarray(self)[index]

    def __array__(self, dtype=None, copy=None):
        if copy is False:   # numpy 2's request for no copy: the joined array is always new
            raise ValueError("Columns: reading the blocks as one array makes a copy")
        whole = np.concatenate(self.blocks, axis=-1)
        return whole if dtype is None else whole.astype(dtype, copy=False)


def design(data, base, plugins, model, frames=None):
    """Regressors of base and plug-ins on ``frames`` (all when None): (F, P, 3, m), and the
    column slice of each plug-in.

    Without a plug-in that ``needs_base``, the regressors depend on the recorded frames
    alone (the base columns are spring sums of the recorded positions): they are made once
    per plug-ins, model and frames and shared read-only (kept in ``data.cache``, the
    :data:`DESIGNS_KEPT` most recently used within :data:`DESIGNS_BYTES_KEPT`), since every
    round of every start of a fit asks for the same ones. With one, they change with the
    base: they come as :class:`Columns`, whose blocks are never copied into one array.

    Parameters
    ----------
    data : Data
    base : BaseModel
        Rest lengths and stiffnesses the plug-ins that ``needs_base`` are built at.
    plugins : sequence of Plugin
    model : {"5", "18"}
    frames : (F,) int or bool array_like, optional
    """
    plugins = tuple(plugins)
    frames = _frame_index(frames)
    if any(plugin.needs_base for plugin in plugins):
        columns = Columns(_design_blocks(data, base, plugins, model, frames))
        return columns, _plugin_slices(plugins, columns.widths)
    key = (model, tuple((plugin.name, plugin.basis) for plugin in plugins),
           None if frames is None else frames.tobytes())

    def make():
        blocks = _design_blocks(data, base, plugins, model, frames)
        return np.concatenate(blocks, axis=-1), _block_widths(blocks)

    columns, widths = _kept(data, "designs", max_entries=DESIGNS_KEPT,
                            max_bytes=DESIGNS_BYTES_KEPT).get(key, make)
    return columns, _plugin_slices(plugins, widths)


def _block_widths(blocks):
    """The number of columns of each block, as an int array."""
    return np.array([block.shape[-1] for block in blocks], dtype=np.intp)


def _plugin_slices(plugins, widths):
    """``{plugin name: column slice}`` of the blocks of ``widths`` (base, then plug-ins)."""
    ends = np.cumsum(widths)
    return {plugin.name: slice(int(start), int(stop))
            for plugin, start, stop in zip(plugins, ends[:-1], ends[1:])}


def _design_blocks(data, base, plugins, model, frames):
    """The blocks of the regressors: base columns, then each plug-in's. The base columns
    depend on the recorded frames alone and are kept per model and frames (the last
    :data:`SELECTIONS_KEPT`)."""
    q = state_frames(data, base, frames)

    def base_block():
        A, B = q.sums
        return base_columns(A, B, data.mass, model)

    return [_kept(data, "base_columns", max_entries=SELECTIONS_KEPT).get(
        (model, None if frames is None else frames.tobytes()), base_block),
        *(q.columns(plugin) for plugin in plugins)]


def extra_force(terms, q):
    """Total force of fitted terms ``[(plugin, theta)]`` on the frames ``q``, (F, P, 3)."""
    total = np.zeros_like(q.x)
    for plugin, theta in terms:
        total += q.columns(plugin) @ np.asarray(theta, dtype=float)
    return total * q.mass[None, :, None]


def usable_frames(frames, n_frames):
    """Frames ``t`` with instruments ``t-2, t+3`` and target ``t+1`` inside the data."""
    frames = np.asarray(frames)
    return frames[(frames - LAG_BEFORE - 1 >= 0) & (frames + LAG_AFTER <= n_frames - 1)]


def one_step_predictions(data, base, terms, frames):
    """Model predictions of frames ``t+1`` from recorded states at ``t``, (F, P, 3)."""
    frames = np.asarray(frames)
    q = state_frames(data, base, frames)
    x_hat, _ = step(q.x, q.v, base.params(len(frames)), data.scene, extra_force(terms, q))
    return x_hat


def residuals(data, base, terms, frames):
    """One-step residuals ``x_{t+1} - x^_{t+1}`` (F, P, 3), zero on pinned particles."""
    frames = np.asarray(frames)
    r = data.x[frames + 1] - one_step_predictions(data, base, terms, frames)
    r[:, ~data.free] = 0.0
    return r


def constraint_mask(data, base, terms, frames, *, margin=MASK_MARGIN, noisy=False):
    """Particle-frames the deformation constraint (probably) leaves alone, (T, P) bool.

    A free particle is excluded at frame ``t`` if a spring touching it is longer than
    ``(1 + tau (1 - margin)) l`` in the recorded frames ``t-2``, ``t+2`` or ``t+3`` (whose
    noise is independent of the regression's target at ``t``) and, unless ``noisy``, in
    the unconstrained prediction of ``t+1`` and the recorded frame ``t+1`` (on noisy data
    selecting on those frames would select on the target's noise and bias the fit). The
    margin keeps the mask conservative while ``tau`` is rough: constrained
    particle-frames must not get in (they pull the fit towards the wrong valley).
    """
    frames = np.asarray(frames)
    sources = [data.x[frames - LAG_BEFORE], data.x[frames + 2], data.x[frames + LAG_AFTER]]
    if not noisy:
        loose = BaseModel(base.rest, base.k, np.full(N_TYPES, BIG_TAU))
        sources += [one_step_predictions(data, loose, terms, frames), data.x[frames + 1]]
    mask = np.zeros((data.n_frames, data.x.shape[1]), dtype=bool)
    mask[frames] = data.free[None, :]
    a, b, kind = data.ops.a, data.ops.b, data.ops.kind
    limit = (1.0 + base.tau[kind] * (1.0 - margin)) * base.rest[kind]
    for positions in sources:
        mask[frames] &= ~kernels.stretched_ends(np.ascontiguousarray(positions), a, b, limit)
    return mask


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
    ``t // block`` (consecutive labels are neighbouring blocks of time); count : int
    particle-frames used.
    """
    frames = np.asarray(frames)
    labels, which = np.unique(frames // block, return_inverse=True)
    m = columns.shape[-1]
    G = np.zeros((labels.size, m, m))
    hz = np.zeros((labels.size, m))
    count = 0
    for row, t in enumerate(frames):
        keep = mask[t]
        count += int(keep.sum())
        phi = columns[t, keep].reshape(-1, m)
        z = 0.5 * (columns[t - LAG_BEFORE, keep] + columns[t + LAG_AFTER, keep]).reshape(-1, m)
        G[which[row]] += z.T @ phi
        hz[which[row]] += z.T @ target[t, keep].reshape(-1)
    return G, hz, labels, count


def iv_solve(G, hz, cols=None, clusters=None, labels=None):
    """Solve the summed IV equations on columns ``cols`` and clusters ``clusters``.

    The covariance is a sandwich over clusters; with ``labels``, products of the scores of
    blocks up to ``HAC_LAGS`` apart are added with Bartlett weights (Newey-West): the
    residual noise ``e_{t+1} - 2 e_t + e_{t-1}`` and the instruments' noise are correlated
    across block boundaries.

    Returns
    -------
    theta : (k,) ndarray
    cov : (k, k) ndarray
    """
    cols = np.arange(G.shape[1]) if cols is None else cols
    clusters = np.arange(G.shape[0]) if clusters is None else clusters
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


def search_tau(data, base, terms, frames, *, max_frames=50, levels=9):
    """The critical elongation rate minimising the one-step cost over ``frames``.

    A log grid around the current value (or a wide one when it is :data:`BIG_TAU`), then
    ``levels`` zooms of 21 points around the best value (:func:`replication.optim.scan.zoom`),
    each grid one population of the compiled kernel; exact ties go to the smallest ``tau``.
    """
    frames = np.asarray(frames)
    if len(frames) > max_frames:
        frames = frames[np.linspace(0, len(frames) - 1, max_frames).round().astype(int)]
    cost = ClothCost(data.trajectory, frames, h=data.h)
    extra = extra_force(terms, state_frames(data, base, frames))[None]
    current = float(base.tau[0])
    grid = (np.geomspace(current / 1.5, current * 1.5, 21) if current < BIG_TAU
            else np.geomspace(3e-3, 3.0, 64))

    def evaluate(taus):
        return cost.tau_costs(base.rest, base.k,
                              np.repeat(np.asarray(taus)[:, None], N_TYPES, 1), extra)

    return zoom(evaluate, grid, levels=levels, points=21)[0]


def position_noise(data):
    """Position-noise standard deviation (units of length) from the data alone.

    Second differences ``x_{t+1} - 2 x_t + x_{t-1}`` of white noise of sd ``sigma`` have
    lag-0 and lag-1 autocovariances ``6 sigma^2`` and ``-4 sigma^2``, so ``sigma^2 =
    (gamma_0 - gamma_1) / 10`` while smooth motion adds about as much to both; the median
    over free particles keeps constraint events out.
    """
    if "position_noise" not in data.cache:   # once per data
        x = data.x[:, data.free]
        if x.shape[0] < 5:
            sigma = 0.0
        else:
            second = x[2:] - 2.0 * x[1:-1] + x[:-2]
            gamma0 = np.mean(second * second, axis=(0, 2))
            gamma1 = np.mean(second[1:] * second[:-1], axis=(0, 2))
            sigma = float(np.sqrt(max(np.median(gamma0 - gamma1), 0.0) / 10.0))
        data.cache["position_noise"] = sigma
    return data.cache["position_noise"]


NOISY_H = 1e-4   # position noise (units of h) above which the data count as noisy


def is_noisy(data, *, noise_h=NOISY_H):
    """Whether the position noise estimated from the data is above ``noise_h`` h."""
    return position_noise(data) > noise_h * data.h


def tau_data(data, *, window=11):
    """The version of the data the tau search runs on: as recorded when the position noise
    is below :data:`NOISY_H` (exact on noise-free data), else smoothed over ``window`` frames
    (the one-step cost on noisy states prefers a far too small tau)."""
    if not is_noisy(data) or window > data.n_frames:
        return data
    return version(data, window)


def typical_lengths(data):
    """Median recorded length of each spring type over about 50 frames, (6,); computed
    once per ``data`` (every start and round of a fit asks for them)."""
    if "typical_lengths" not in data.cache:
        x = data.x[::max(1, data.n_frames // 50)]
        data.cache["typical_lengths"] = read_only(type_lengths(x, data.ops.n,
                                                               statistic="median"))
    return data.cache["typical_lengths"].copy()


def _trimmed_lstsq(A, y, *, rounds=6, factor=10.0):
    """Least squares with iterative trimming of particles (3 rows each) whose residual
    norm exceeds ``factor`` times the median of the kept ones; (theta, median residual)."""
    keep = np.ones(y.size // 3, dtype=bool)
    theta = np.zeros(A.shape[1])
    residual = np.linalg.norm(y.reshape(-1, 3), axis=1)
    for _ in range(rounds + 1):
        rows = np.repeat(keep, 3)
        theta = np.linalg.lstsq(A[rows], y[rows], rcond=None)[0]
        residual = np.linalg.norm((A @ theta - y).reshape(-1, 3), axis=1)
        new_keep = residual <= factor * max(np.median(residual[keep]), 1e-300)
        if np.array_equal(new_keep, keep) or new_keep.sum() * 3 < 2 * A.shape[1]:
            break
        keep = new_keep
    return theta, float(np.median(residual[keep]))


def trimmed_start(data, frames, plugins, *, model="5", max_frames=60, quantile=0.3):
    """Stage 1: base (and base-free plug-in) coefficients by trimmed least squares.

    Returns
    -------
    theta : (m,) ndarray over base columns and ``plugins``; scale : float median residual
    of the kept particle-frames (comparable between data versions), or None when the
    regression is degenerate.
    """
    frames = usable_frames(frames, data.n_frames)
    if frames.size > max_frames:
        frames = frames[np.linspace(0, frames.size - 1, max_frames).round().astype(int)]
    if frames.size == 0:
        return None, None
    guess = BaseModel(typical_lengths(data), np.ones(N_TYPES), np.full(N_TYPES, BIG_TAU))
    columns, _ = design(data, guess, plugins, model, frames)
    free = data.free
    m = columns.shape[-1]
    blocks, scales = [], []
    for row, t in enumerate(frames):
        A = columns[row][free].reshape(-1, m)
        y = data.target[t][free].reshape(-1)
        blocks.append((A, y))
        scales.append(_trimmed_lstsq(A, y)[1] if A.shape[0] >= 2 * m else np.inf)
    n_best = max(1, int(round(quantile * frames.size)))
    chosen = np.argsort(scales, kind="stable")[:n_best]
    A = np.vstack([blocks[i][0] for i in chosen])
    y = np.concatenate([blocks[i][1] for i in chosen])
    if np.linalg.matrix_rank(A) < m:
        return None, None
    return _trimmed_lstsq(A, y)


def _valid(theta, model):
    nb = n_base(model)
    return theta is not None and np.all(np.isfinite(theta)) and np.all(theta[:nb] > 0)


def _widths(data, plugins):
    base = BaseModel(typical_lengths(data), np.ones(N_TYPES), np.full(N_TYPES, BIG_TAU))
    q = state_frames(data, base, [0])
    return [q.columns(plugin).shape[-1] for plugin in plugins]


def _split(theta, plugins, widths, model, tau):
    """Base model and terms from coefficients over the base and ``plugins`` (those with
    ``needs_base`` absent from ``theta`` start at zero)."""
    nb = n_base(model)
    base = base_from_theta(theta[:nb], model, tau)
    terms, at = [], nb
    for plugin, width in zip(plugins, widths):
        if plugin.needs_base:
            terms.append((plugin, np.zeros(width)))
        else:
            terms.append((plugin, np.asarray(theta[at:at + width])))
            at += width
    return base, terms


def trimmed_starts(data, frames, plugins, model, smooth_windows):
    """Stage 1, robust to the constraint: the best trimmed least-squares start over the
    smoothing windows, as (base with tau = BIG_TAU, terms), or None."""
    free_plugins = [p for p in plugins if not p.needs_base]
    best = None
    for window in smooth_windows:
        theta, scale = trimmed_start(version(data, window), frames, free_plugins,
                                     model=model)
        if _valid(theta, model) and (best is None or scale < best[0]):
            best = (scale, theta)
    if best is None:
        return None
    return _split(best[1], plugins, _widths(data, plugins), model, BIG_TAU)


def conservative_start(data, frames, plugins, model, *, tau=0.05, block=5):
    """Stage 1, robust to noise: one IV regression on the particle-frames whose recorded
    springs (frames ``t-2``, ``t+2``, ``t+3``) are all shorter than ``(1 + tau)`` times
    0.99 of their type's median recorded length (far from any plausible constraint), or
    None."""
    free_plugins = [p for p in plugins if not p.needs_base]
    guess = BaseModel(0.99 * typical_lengths(data), np.ones(N_TYPES), np.full(N_TYPES, tau))
    mask = constraint_mask(data, guess, [], frames, margin=0.0, noisy=True)
    columns, _ = design(data, guess, free_plugins, model)
    G, hz, labels, count = cluster_sums(columns, data.target, frames, mask, block=block)
    if count * 3 < 30 * columns.shape[-1] or labels.size < 2:
        return None
    theta, _ = iv_solve(G, hz, labels=labels)
    if not _valid(theta, model):
        return None
    return _split(theta, plugins, _widths(data, plugins), model, BIG_TAU)


def consensus_start(data, frames, plugins, model, *, quantile=CONSENSUS_QUANTILES[0],
                    n_samples=CONSENSUS_SAMPLES, seed=CONSENSUS_SEED, max_frames=60):
    """Stage 1 where the constraint moves most particle-frames: the 5-parameter base by
    least quantile of squares, as (base with tau = BIG_TAU, terms at zero), or None.

    The unconstrained step holds exactly on the particle-frames the constraint left alone,
    however few they are, and on no others: trimming around a median (:func:`trimmed_start`)
    fits the constrained majority instead when the constraint moves more than half of
    them. Here ``n_samples`` fits of the base coefficients to two particle-frames drawn at
    random are ranked by the ``quantile`` of all particle-frames' residual norms, and the
    best one is refined by refits on the particle-frames within 3 times that quantile. On
    noise-free data it finds the rest lengths and stiffness to round-off whenever more than
    ``quantile`` of the particle-frames are unconstrained. Plug-in terms start at zero;
    ``model="18"`` (12 base coefficients) gives None. The coefficients are computed once
    per ``data`` and arguments (kept in its cache) and shared by every set of plug-ins.

    Parameters
    ----------
    data : Data
    frames : (F,) int array_like
        Training frames (at most ``max_frames`` of them, evenly spread, are used).
    plugins : sequence of Plugin
    model : {"5", "18"}
    quantile : float
        Share of the particle-frames the ranking reads (below the unconstrained share).
    n_samples : int
        Elemental fits drawn.
    seed : int
        Seed of the draws.
    """
    if model != "5":
        return None
    frames = usable_frames(frames, data.n_frames)
    if frames.size > max_frames:
        frames = frames[np.linspace(0, frames.size - 1, max_frames).round().astype(int)]
    # the base coefficients do not depend on the plug-ins: every fit of the same data (the
    # discrepancy workflow fits one per set of effects) shares them
    kept = data.cache.setdefault("consensus", {})
    common = (frames.astype(np.intp).tobytes(), int(n_samples), int(seed))
    if common + (float(quantile),) not in kept:
        # the other quantiles of CONSENSUS_QUANTILES rank the same draws: ranked at once
        quantiles = [float(quantile)] + [float(q) for q in CONSENSUS_QUANTILES
                                         if common + (float(q),) not in kept
                                         and float(q) != float(quantile)]
        thetas = _consensus_thetas(data, frames, model, quantiles, n_samples, seed)
        kept.update({common + (q,): theta for q, theta in zip(quantiles, thetas)})
    theta = kept[common + (float(quantile),)]
    if theta is None:
        return None
    widths = _widths(data, plugins)
    free_width = sum(w for p, w in zip(plugins, widths) if not p.needs_base)
    return _split(np.r_[theta, np.zeros(free_width)], plugins, widths, model, BIG_TAU)


def _consensus_thetas(data, frames, model, quantiles, n_samples, seed):
    """:func:`consensus_start`'s base coefficients on ``frames`` for each of ``quantiles``
    (or None), from one set of draws: each quantile's ranking is the one it would have alone
    (``np.quantile`` of several quantiles gives each as it gives it alone)."""
    guess = BaseModel(typical_lengths(data), np.ones(N_TYPES), np.full(N_TYPES, BIG_TAU))
    columns, _ = design(data, guess, (), model, frames)
    m = columns.shape[-1]
    A = columns[:, data.free].reshape(-1, 3, m)            # one (3, m) block per particle-frame
    y = data.target[frames][:, data.free].reshape(-1, 3)
    usable = np.all(np.isfinite(A), axis=(1, 2)) & np.all(np.isfinite(y), axis=1)
    A, y = A[usable], y[usable]
    if A.shape[0] < 2:
        return [None] * len(quantiles)

    def norms(theta):
        return np.linalg.norm(np.einsum("nij,j->ni", A, theta) - y, axis=1)

    rng = np.random.default_rng(seed)
    best = [None] * len(quantiles)
    for _ in range(n_samples):
        pick = rng.choice(A.shape[0], 2, replace=False)
        theta = np.linalg.lstsq(A[pick].reshape(-1, m), y[pick].reshape(-1), rcond=None)[0]
        if not _valid(theta, model):
            continue
        scores = np.quantile(norms(theta), quantiles)
        for k, score in enumerate(scores.tolist()):
            if best[k] is None or score < best[k][0]:
                best[k] = (score, theta)
    return [None if found is None else _consensus_refined(norms, A, y, found[1], quantile,
                                                          model)
            for found, quantile in zip(best, quantiles)]


def _consensus_refined(norms, A, y, theta, quantile, model):
    """Refits of ``theta`` on the particle-frames within 3 times the ``quantile`` of the
    residual norms (:func:`consensus_start`)."""
    m = A.shape[-1]
    for _ in range(10):
        r = norms(theta)
        keep = r <= max(3.0 * float(np.quantile(r, quantile)), 1e-300)
        if keep.sum() * 3 < 2 * m:
            break
        refit = np.linalg.lstsq(A[keep].reshape(-1, m), y[keep].reshape(-1), rcond=None)[0]
        if not _valid(refit, model):
            break
        theta = refit
    return read_only(theta)


def check_cloth(data, *, spread=2.0, tolerance=0.01):
    """Refuse positions that are not a cloth: more than ``tolerance`` of the structural
    spring-frames longer or shorter than ``spread`` times their type's median length."""
    x = data.x[::max(1, data.n_frames // 100)]
    outside = []
    for t in (0, 1):
        idx = data.ops.type_slices[t]
        length = np.linalg.norm(x[:, data.ops.b[idx]] - x[:, data.ops.a[idx]], axis=2)
        ratio = length / max(float(np.median(length)), 1e-300)
        outside.append(np.mean((ratio > spread) | (ratio < 1.0 / spread)))
    worst = float(max(outside))
    if not np.isfinite(worst) or worst > tolerance:
        raise InputError(f"{data.trajectory.source}: field 'positions': {100 * worst:.0f}% of "
                         f"the structural springs are more than {spread:g}x longer or shorter "
                         "than their median; expected a cloth trajectory (docs/cloth-model.md)")


def fit(data, frames, plugins=(), *, model="5", rounds=3, block=5,
        smooth_windows=SMOOTH_WINDOWS, min_rows_per_coefficient=30):
    """Fit the base model and plug-in terms jointly on ``frames`` (see module docstring).

    Parameters
    ----------
    data : Data
    frames : (F,) int array_like
        Training frames ``t`` (each predicts ``t+1``).
    plugins : sequence of Plugin
    model : {"5", "18"}
    rounds : int
        Rounds of (constraint mask, IV regression, tau search).
    smooth_windows : sequence of int
        Savitzky-Golay windows tried by the start (0: the data as recorded).

    Returns
    -------
    Fit

    Raises
    ------
    InputError
        When the positions are not a cloth (:func:`check_cloth`).
    """
    check_cloth(data)
    plugins = tuple(plugins)
    frames = usable_frames(frames, data.n_frames)
    if frames.size == 0:
        return fit_through_constraint(data, frames, plugins, model=model)
    options = {"model": model, "rounds": rounds, "block": block,
               "min_rows_per_coefficient": min_rows_per_coefficient}
    for make_start in (conservative_start, trimmed_starts):
        started = (make_start(data, frames, plugins, model) if make_start is conservative_start
                   else make_start(data, frames, plugins, model, smooth_windows))
        if started is None:
            continue
        fitted = _rounds(data, frames, plugins, started, **options)
        if fitted is not None:
            return _out_of_valley(data, frames, plugins, started, fitted, options)
    # no round from those starts: the constraint may move most particle-frames
    fitted = _from_starts(data, frames, plugins, options,
                          _consensus_starts(data, frames, plugins, model))
    if fitted is not None:
        return fitted
    # nothing outside the constraint to regress on: fit through it
    return fit_through_constraint(data, frames, plugins, model=model)


def _rounds(data, frames, plugins, started, *, model, rounds, block,
            min_rows_per_coefficient):
    """Stages 2 and 3 from a start: tau search, then rounds of (mask, IV, tau); the last
    valid round, or None when not one round had data and physical coefficients."""
    base, terms = started
    for_tau = tau_data(data)
    noisy = for_tau is not data
    base = base._replace(tau=np.full(N_TYPES, search_tau(for_tau, base, terms, frames)))
    nb = n_base(model)
    best = None
    for _ in range(rounds):
        mask = constraint_mask(data, base, terms, frames, noisy=noisy)
        columns, slices = design(data, base, plugins, model)
        G, hz, labels, count = cluster_sums(columns, data.target, frames, mask, block=block)
        if count * 3 < min_rows_per_coefficient * columns.shape[-1] or labels.size < 2:
            break
        theta, cov = iv_solve(G, hz, labels=labels)
        if not _valid(theta, model):
            break
        terms = [(plugin, theta[slices[plugin.name]]) for plugin in plugins]
        base = base_from_theta(theta[:nb], model, base.tau)
        base = base._replace(tau=np.full(N_TYPES, search_tau(for_tau, base, terms, frames)))
        best = Fit(base, terms, theta, cov, mask, "regression")
    return best


def one_step_cost(data, candidate, frames):
    """Sum of squared one-step residuals of a fit over ``frames`` (free particles; ``inf``
    when not finite): what competing fits of one data set are ranked by.

    Parameters
    ----------
    data : Data
    candidate : Fit
    frames : (F,) int array_like
    """
    r = residuals(data, candidate.base, candidate.terms, frames)[:, data.free]
    total = float(np.sum(r ** 2))
    return total if np.isfinite(total) else np.inf


def in_valley(data, candidate):
    """Whether a fit may be in the cost's wrong valley: a rest length below
    :data:`VALLEY_REST` of its type's recorded length.

    Parameters
    ----------
    data : Data
    candidate : Fit
    """
    return bool(np.any(candidate.base.rest < VALLEY_REST * typical_lengths(data)))


def _consensus_starts(data, frames, plugins, model):
    """The starts of :func:`consensus_start` on each data version of
    :data:`CONSENSUS_WINDOWS`, with each quantile of :data:`CONSENSUS_QUANTILES` (lazily:
    each version is smoothed only when its turn comes)."""
    for window in CONSENSUS_WINDOWS:
        for quantile in CONSENSUS_QUANTILES:
            yield consensus_start(version(data, window), frames, plugins, model,
                                  quantile=quantile)


def _from_starts(data, frames, plugins, options, starts, best=None):
    """``best``, or the rounds from ``starts`` (None entries skipped) when they end with
    smaller one-step residuals on ``frames``, tried in turn until one ends out of the
    valley; None when ``best`` is None and no start ends with a valid round."""
    best_cost = np.inf if best is None else one_step_cost(data, best, frames)
    for started in starts:
        fitted = None if started is None else _rounds(data, frames, plugins, started,
                                                      **options)
        if fitted is None:
            continue
        fitted_cost = one_step_cost(data, fitted, frames)
        if fitted_cost < best_cost:
            best, best_cost = fitted, fitted_cost
        if not in_valley(data, fitted):
            break
    return best


def _out_of_valley(data, frames, plugins, started, fitted, options):
    """``fitted``, or the rounds from other starts when those end with smaller one-step
    residuals on ``frames``; run only when the rest lengths came out well below the
    recorded ones (:func:`in_valley`). A start can lead the rounds into the wrong valley:
    where the constraint moves most particle-frames, every start by trimming fits the
    constrained ones, and noise and the constraint both bias a start's stiffness down.
    Tried in turn until one ends out of the valley: the starts of :func:`consensus_start`,
    then starts :data:`VALLEY_STIFFER` times stiffer than ``started``.
    """
    if not in_valley(data, fitted):
        return fitted
    base, terms = started
    stiffer = ((base._replace(k=base.k * factor), terms) for factor in VALLEY_STIFFER)
    starts = itertools.chain(_consensus_starts(data, frames, plugins, options["model"]),
                             stiffer)
    return _from_starts(data, frames, plugins, options, starts, best=fitted)


def fit_through_constraint(data, frames, plugins=(), *, model="5", start=None,
                           max_frames=40):
    """Fallback: least squares of the one-step residuals, constraint included, over the
    log of the 5-parameter base (rest per family, K, tau) and the linear plug-in
    coefficients, from ``start`` or from the recorded lengths and a grid of stiffness."""
    frames = usable_frames(frames, data.n_frames)
    if frames.size == 0:
        frames = np.arange(1, data.n_frames - 1)
    if frames.size > max_frames:
        frames = frames[np.linspace(0, frames.size - 1, max_frames).round().astype(int)]
    widths = [p.basis(state_frames(data, BaseModel(typical_lengths(data), np.ones(6),
                                                   np.ones(6)), [0])).shape[-1]
              for p in plugins]

    def unpack(z):
        rest = np.exp(z[:3])[FAMILY_OF_TYPE]
        base = BaseModel(rest, np.full(N_TYPES, np.exp(z[3])), np.full(N_TYPES, np.exp(z[4])))
        terms, at = [], 5
        for plugin, width in zip(plugins, widths):
            terms.append((plugin, z[at:at + width]))
            at += width
        return base, terms

    def fun(z):
        base, terms = unpack(z)
        r = residuals(data, base, terms, frames)[:, data.free].ravel() / data.h
        return np.where(np.isfinite(r), r, 1e3)

    if start is not None:
        z0s = [np.r_[np.log(start.base.rest[[0, 2, 4]]), np.log(start.base.k[0]),
                     np.log(min(start.base.tau[0], 3.0)), np.zeros(sum(widths))]]
    else:
        typical = typical_lengths(data)[[0, 2, 4]]
        z0s = [np.r_[np.log(typical / 1.05), np.log(K), np.log(0.3), np.zeros(sum(widths))]
               for K in (0.5, 2.0, 8.0)]
    best = None
    for z0 in z0s:
        solution = least_squares(fun, z0, x_scale=1.0, max_nfev=200 * len(z0))
        if best is None or solution.cost < best.cost:
            best = solution
    base, terms = unpack(best.x)
    return Fit(base, terms, None, None, np.zeros((data.n_frames, data.x.shape[1]), bool),
               "through_constraint")
