"""The cloth identification problem shared by every identifier (paper 3.3).

Search space (bounds per parameter), the objective (the paper's cost as an
:class:`~replication.optim.objective.Objective`, with residuals for least squares) and the
scoring of an answer against known true parameters. Nothing here needs a file's ``meta``:
the truth is only passed in to score.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replication.cloth import regression
from replication.cloth.costs import ClothCost, make_cost
from replication.cloth.mesh import FAMILY_OF_TYPE, N_TYPES, type_lengths
from replication.cloth.model import PARAM_NAMES_5, PARAM_NAMES_18, params_from_vectors, step
from replication.cloth.noise import (
    SIGMA_FLOOR_H,
    data_noise_sigma,
    excess_power,
    noise_sigma,
    robust_residual_sigma,
)
from replication.errors import InputError, check
from replication.optim.objective import Objective
from replication.sequences import (describe_repeats, first_few, repeated_frames, rounding_step,
                                   still_points)

MODELS = ("5", "18")


@dataclass(frozen=True)
class SearchSpace:
    """Box bounds and names of a cloth parameter vector.

    ``lower, upper`` : (n_var,); ``observed_rest`` : (n_var,) with the mean observed
    length of each rest-length entry (``nan`` for K and tau), used to draw initial rest
    lengths "around the average length values observed on the reference data" (paper 3.3).
    """

    model: str
    names: tuple
    lower: np.ndarray
    upper: np.ndarray
    observed_rest: np.ndarray

    @property
    def n_var(self):
        return self.lower.size

    @property
    def rest_mask(self):
        """(n_var,) bool: which entries are rest lengths."""
        return np.isfinite(self.observed_rest)


def _check_interval(name, interval):
    check(isinstance(interval, (list, tuple)) and len(interval) == 2,
          f"bounds.{name}={interval!r}: expected [low, high]")
    low, high = (float(v) for v in interval)
    check(np.isfinite(low) and np.isfinite(high) and low < high,
          f"bounds.{name}=[{low}, {high}]: low >= high; expected low < high")
    return low, high


def search_space(trajectory, bounds, *, model="5"):
    """Bounds of the 5- or 18-parameter model on ``trajectory``.

    Parameters
    ----------
    trajectory : Trajectory
    bounds : dict
        ``rest: [low, high]`` as factors on the mean observed length per spring family
        (5) or type (18), ``K: [low, high]`` and ``tau: [low, high]`` absolute.
    model : "5" or "18"
    """
    check(model in MODELS, f"model={model!r}: expected '5' or '18'")
    rest_low, rest_high = _check_interval("rest", bounds.get("rest"))
    k_low, k_high = _check_interval("K", bounds.get("K"))
    tau_low, tau_high = _check_interval("tau", bounds.get("tau"))
    check(rest_low > 0 and k_low > 0 and tau_low > 0,
          f"bounds: rest {rest_low}, K {k_low}, tau {tau_low}: expected positive lower bounds")
    observed = type_lengths(trajectory.flat_positions(), trajectory.n)
    if model == "5":
        rest = np.array([observed[FAMILY_OF_TYPE == f].mean() for f in range(3)])
        n_k, names = 1, PARAM_NAMES_5
    else:
        rest, n_k, names = observed, N_TYPES, PARAM_NAMES_18
    nan = np.full(2 * n_k, np.nan)
    lower = np.r_[rest * rest_low, np.full(n_k, k_low), np.full(n_k, tau_low)]
    upper = np.r_[rest * rest_high, np.full(n_k, k_high), np.full(n_k, tau_high)]
    return SearchSpace(model, tuple(names), lower, upper, np.r_[rest, nan])


def random_population(space, size, rng, *, rest_spread):
    """Paper 3.3 initialisation: uniform in the bounds, rest lengths uniform within
    ``+-rest_spread`` (relative) of the observed mean lengths, clipped to the bounds.

    Parameters
    ----------
    space : SearchSpace
    size : int
    rng : np.random.Generator
    rest_spread : float
        Relative spread of the initial rest lengths.

    Returns
    -------
    (size, n_var) ndarray
    """
    X = space.lower + rng.random((size, space.n_var)) * (space.upper - space.lower)
    mask = space.rest_mask
    around = space.observed_rest[mask] * (1.0 + rest_spread
                                          * (2.0 * rng.random((size, mask.sum())) - 1.0))
    X[:, mask] = np.clip(around, space.lower[mask], space.upper[mask])
    return X


def cost_from_config(trajectory, cost_cfg):
    """The paper's cost (``cost_cfg.kind`` "small" or "full", or "frames" with an explicit
    list ``cost_cfg.frames``) on ``trajectory``.

    Parameters
    ----------
    trajectory : Trajectory
    cost_cfg : dict
        ``kind`` and ``frame`` / ``start``, ``window`` / ``frames`` (docs/experiments.md).
    """
    kind = cost_cfg.get("kind", "small")
    check(kind in ("small", "full", "frames"),
          f"cost.kind={kind!r}: expected 'small', 'full' or 'frames' (with +cost.frames=[t, ...])")
    if kind == "frames":
        given = cost_cfg.get("frames")
        check(isinstance(given, list) and all(isinstance(t, int) and not isinstance(t, bool)
                                              for t in given),
              f"cost.frames={given!r}: cost.kind=frames needs a list of frame indices "
              "(+cost.frames=[t, ...])")
        frames = np.asarray(given, dtype=np.int64)
        check(frames.size > 0, "cost.frames: expected at least one frame index")
        if frames.min() < 0 or frames.max() > trajectory.n_frames - 2:
            raise InputError(
                f"cost.frames: frame index {int(frames.max())} is outside the data: "
                f"expected 0 <= t <= {trajectory.n_frames - 2} for the "
                f"{trajectory.n_frames}-frame file")
        return ClothCost(trajectory, frames)
    return make_cost(trajectory, kind, frame=cost_cfg.get("frame", 150),
                     start=cost_cfg.get("start", 100), window=cost_cfg.get("window", 50))


def residual_function(cost):
    """Residuals of ``cost`` (a ClothCost): ``(X: (pop, n_var)) -> (pop, m)`` whose squared
    norm equals ``cost`` (the normalised position and ``dtc``-weighted velocity errors of
    every predicted frame)."""
    xs, vs, frames = cost.xs, cost.vs, cost.frames
    root = np.sqrt(cost.norm)

    def residuals(X):
        params = params_from_vectors(X)
        pop, n_frames = params.pop, frames.size
        tile = [np.repeat(p, n_frames, axis=0) for p in params]
        rows = type(params)(*tile)
        x0 = np.tile(xs[frames], (pop, 1, 1))
        v0 = np.tile(vs[frames], (pop, 1, 1))
        x1, v1 = step(x0, v0, rows, cost.scene)
        dx = x1 - np.tile(xs[frames + 1], (pop, 1, 1))
        dv = cost.dtc * (v1 - np.tile(vs[frames + 1], (pop, 1, 1)))
        r = np.concatenate([dx.reshape(pop, -1), dv.reshape(pop, -1)], axis=1) / root
        r[~np.all(np.isfinite(r), axis=1)] = np.inf
        return r

    return residuals


def cloth_objective(cost, space, *, budget=None, with_residuals=False):
    """The cost as an :class:`Objective` over ``space`` (counted, budgeted).

    Parameters
    ----------
    cost : ClothCost
    space : SearchSpace
    budget : int, optional
        Evaluations allowed (then ``BudgetExhausted``).
    with_residuals : bool
        Also give per-frame residuals (for least squares).
    """
    def fun(X):
        return cost(params_from_vectors(X))

    residuals = residual_function(cost) if with_residuals else None
    return Objective(fun, space.lower, space.upper, budget=budget, residuals=residuals,
                     names=space.names)


def finite_best(objective):
    """The best point ``objective`` has seen; an :class:`InputError` when none of its costs
    was finite (the model's arithmetic overflowed at every parameter vector tried: the
    data's scales, not the search, are at fault).

    Parameters
    ----------
    objective : Objective
        After at least one evaluation.
    """
    if objective.best_point is None:
        raise InputError(
            f"every one of the {objective.n_evals} parameter vectors tried gave a non-finite "
            "cost: the model's step overflows on these data; check the file's dt, gravity, "
            "mass and damping against its positions' length unit (docs/data-formats.md)")
    return objective.best_point


# what an answer's diagnostics warn about (docs/experiments.md, "Warnings of an answer")
NOISE_WARN_H = 3e-4   # estimated position noise (units of h) above which answers are biased
NOISE_STRONG_H = 3e-3  # ... above which K is tens of % off and tau near its own size
MEANINGLESS_NOISE_H = 0.1   # ... above which the frames show no motion step to step
MISFIT_WARN = 3.0     # residuals this many times what the estimated noise explains
_MARGIN = 10          # frames on each side of the cost's frames for the residual check


def diagnose(cost, best, space):
    """What the data say about an answer ``best`` beyond its cost (JSON-ready).

    - ``undetermined``: the tau entries the cost does not determine (setting one to 1e6
      leaves the cost bit for bit unchanged, so no spring of its types reaches its limit
      in the cost's frames and every larger value has the same cost: a lower bound only),
      and the stiffnesses whose doubling or halving changes the cost by less than about
      8 x ``6 noise^2`` (normalised like the cost, whose velocity errors repeat the
      position errors): the data do not show their force.
    - ``noise_h``, ``misfit`` and ``residual_frames``: :func:`residual_fit`.

    Parameters
    ----------
    cost : ClothCost
    best : (n_var,) array_like
    space : SearchSpace
    """
    best = np.asarray(best, dtype=float)
    taus = [i for i, name in enumerate(space.names) if name.startswith("tau")]
    stiff = [i for i, name in enumerate(space.names) if name[0] in "kK"]
    X = np.repeat(best[None, :], 1 + len(taus) + 2 * len(stiff), axis=0)
    for row, i in enumerate(taus, start=1):
        X[row, i] = 1e6
    for row, i in enumerate(stiff):
        X[1 + len(taus) + 2 * row, i] *= 2.0
        X[2 + len(taus) + 2 * row, i] *= 0.5
    costs = cost(params_from_vectors(X))
    undetermined = [space.names[i] for row, i in enumerate(taus, start=1)
                    if costs[row] == costs[0]]
    sigma, fit = _residual_fit(cost, best)
    # a stiffness is not determined when doubling or halving it changes the cost by less
    # than one parameter's chi-square threshold (about 4) times the noise of a residual
    # (6 sigma^2 per coordinate, normalised as the cost is), counted twice: with
    # velocities derived from positions and dtc = dt, each velocity error dtc dv equals
    # its position error
    threshold = 4.0 * 2.0 * 6.0 * sigma ** 2 / cost.norm
    changes = np.abs(costs[1 + len(taus):] - costs[0]).reshape(-1, 2).max(axis=1)
    undetermined += [space.names[i] for i, change in zip(stiff, changes)
                     if not change > threshold]
    return {"undetermined": undetermined, **fit}


def residual_fit(cost, best):
    """How well the model at ``best`` explains the data around the cost's frames
    (JSON-ready):

    - ``noise_h``: position noise (units of ``h``, floored at ``SIGMA_FLOOR_H``) estimated
      from the one-step residuals of ``best`` (:func:`replication.cloth.regression.
      residuals`) on the cost's frames and ``_MARGIN`` frames around them, over the
      particle-frames the constraint leaves alone (:func:`~replication.cloth.regression.
      constraint_mask`; :func:`replication.cloth.noise.noise_sigma`).
    - ``misfit``: the mean squared residual of every free particle over the ``6 noise^2``
      that white noise alone gives (:func:`replication.cloth.noise.excess_power`): near 1
      (or below) when the model explains the data up to noise, far above for a local
      optimum, data in other units, or an effect the model lacks.
    - ``data_noise_h``: the position noise the data show without any model
      (:func:`replication.cloth.noise.data_noise_sigma`, robust: the median absolute
      fourth difference in time over the same frames), and ``robust_misfit``: the square
      of the typical one-step residual (:func:`~replication.cloth.noise.
      robust_residual_sigma`) over it, 0 when the residuals are below ``SIGMA_FLOOR_H``.
      Near 1 or below when the model explains the data up to noise; both ``None`` with
      fewer than 5 frames around the cost's. ``misfit`` measures
      the noise on the residuals themselves, so an answer far off whose residuals look
      like noise (a wrong tau that turns the constraint off leaves kinks everywhere) can
      pass it; ``robust_misfit`` compares with the data instead. Strongly uneven noise
      (some particles 100 x noisier than the rest) raises it too: the noisy particles'
      springs pass their noise to their neighbours' residuals.
    - ``residual_frames``: the first and last frame of those residuals.
    - ``motion_h`` and ``position_noise_h``: how far the free particles move over all
      frames and the noise the data show, model-free (:func:`motion_and_noise`); a cloth
      that moves no more than its noise determines nothing (:func:`still_cloth_warning`).

    Parameters
    ----------
    cost : ClothCost
    best : (n_var,) array_like
    """
    return _residual_fit(cost, np.asarray(best, dtype=float))[1]


def _residual_fit(cost, best):
    """``(sigma, residual_fit dict)``: :func:`residual_fit` and the noise in length units."""
    data = regression.prepare(cost.trajectory)
    params = params_from_vectors(best[None, :])
    base = regression.BaseModel(params.rest[0], params.k[0], params.tau[0])
    frames = np.arange(max(int(cost.frames.min()) - _MARGIN, 0),
                       min(int(cost.frames.max()) + _MARGIN, data.n_frames - 2) + 1)
    r = regression.residuals(data, base, (), frames)
    masked = regression.usable_frames(frames, data.n_frames)
    mask = (regression.constraint_mask(data, base, (), masked, noisy=True)[frames]
            if masked.size else np.zeros(r.shape[:2], dtype=bool))
    sigma = max(noise_sigma(r, frames, data.free, mask if mask.any() else None),
                SIGMA_FLOOR_H * data.h)
    # the fourth differences centred on the residuals' frames
    positions = cost.trajectory.positions
    window = positions[max(frames[0] - 2, 0): frames[-1] + 3]
    data_h, robust = None, None   # fewer than 5 frames: no fourth difference
    if len(window) >= 5:
        data_sigma = data_noise_sigma(window.reshape(len(window), -1, 3), data.free)
        typical = robust_residual_sigma(r, data.free)
        floor = SIGMA_FLOOR_H * data.h
        robust = ((max(typical, floor) / max(data_sigma, floor)) ** 2
                  if typical > floor else 0.0)
        data_h = data_sigma / data.h
    motion_h, noise_h = motion_and_noise(data)
    return sigma, {"noise_h": sigma / data.h, "misfit": excess_power(r, data.free, sigma),
                   "data_noise_h": data_h, "robust_misfit": robust,
                   "residual_frames": [int(frames[0]), int(frames[-1])],
                   "motion_h": motion_h, "position_noise_h": noise_h,
                   "repeated_frames": repeated_frames(positions),
                   "rounding_step_h": rounding_step_h(positions, data.h),
                   "unlisted_pins": unlisted_pins(cost.trajectory)}


def meaningless_noise_warning(noise_h):
    """The warning that the frames do not show one cloth's motion step to step, or None.

    ``noise_h`` is the position noise (units of ``h``) estimated from a fitted model's
    one-step residuals (:func:`replication.cloth.noise.noise_sigma`); above
    :data:`MEANINGLESS_NOISE_H` no fit to the frames means anything. One check for every
    workflow that fits the cloth model (``cloth_identify``, the discrepancy workflow).
    """
    if not noise_h > MEANINGLESS_NOISE_H:
        return None
    return (f"the positions carry noise of about {noise_h:.2g} h (estimated "
            f"from the residuals), more than {MEANINGLESS_NOISE_H:g} of a spring: the frames "
            "do not show one cloth's motion step to step (frames out of order or from "
            "different runs, another dt, positions in other units?); the answer means "
            "nothing")


STILL_FACTOR = 5.0    # free particles moving less than this many noise sds show no motion


def motion_and_noise(data):
    """``(motion_h, noise_h)``: the free particles' RMS displacement about their mean
    positions over all frames (the median over particles) and the position noise the data
    show without a model (:func:`replication.cloth.regression.position_noise`), both in
    units of ``h``; white noise alone gives about one noise sd of motion.

    Parameters
    ----------
    data : regression.Data
    """
    x = data.x[:, data.free]
    motion = float(np.median(np.sqrt(np.mean((x - x.mean(axis=0)) ** 2, axis=(0, 2)))))
    return motion / data.h, regression.position_noise(data) / data.h


def still_cloth_warning(motion_h, noise_h):
    """The warning that the frames show no motion beyond the position noise
    (:func:`motion_and_noise`), or None: a cloth at rest (or noise only) moves less than
    :data:`STILL_FACTOR` noise sds, and no parameter is determined by such frames whatever
    a fit returns. One check for every workflow that fits the cloth model (frames
    identical to the last bit are refused when the file is read). ``noise_h``: the smaller
    of the model-free estimate and the fit's residual one (motion that changes within a
    few frames reads as noise to the first, not to a model that explains it)."""
    if motion_h > STILL_FACTOR * noise_h:
        return None
    return (f"the free particles move {motion_h:.2g} h RMS about their mean positions over "
            f"the frames, no more than {STILL_FACTOR:g} x the position noise the data show "
            f"({noise_h:.2g} h): the frames show no motion that determines the parameters "
            "(a cloth at rest, or noise only); the answer means nothing")


# positions rounded to a step below this (units of h) are not looked for: a float's own
# resolution (float32 at a few h from the origin: about 1e-6 h)
SMALLEST_ROUNDING_H = 1e-5


def rounding_step_h(positions, h):
    """The step the positions are rounded to, in units of ``h``
    (:func:`replication.sequences.rounding_step`), or None.

    Parameters
    ----------
    positions : (T, n, n, 3) ndarray
    h : float
        The mesh's structural rest length.
    """
    step = rounding_step(positions, SMALLEST_ROUNDING_H * h)
    return None if step is None else step / h


def repeated_frames_warning(frames, rounding_h=None):
    """The warning that frames repeat the frame before while the cloth moves after them
    (:func:`replication.sequences.repeated_frames`), or None. One check for every workflow
    that fits the cloth model: the model steps ``dt`` from each frame to the next, so a
    repeat reads as a still step and a double one (a misfit, noise, or an effect that is
    not there). ``rounding_h``: the positions' rounding step (:func:`rounding_step_h`),
    under which slow motion repeats frames by itself."""
    if not frames:
        return None
    if rounding_h is not None:
        return (f"{describe_repeats(frames)} while the cloth moves after them, and the "
                f"positions are rounded to steps of {rounding_h:.3g} h: where the cloth "
                "moves less than a step between frames (as it starts from rest) the frame "
                "repeats, so these repeats may be the rounding's, not a capture's. Rounding "
                f"this coarse is noise of about {rounding_h / np.sqrt(12):.2g} h per "
                "coordinate, held over frames where the motion is slow, which the model "
                "reads as a misfit or as an effect that is not there; record the positions "
                "more finely, or start the trajectory where the motion exceeds a step")
    return (f"{describe_repeats(frames)} "
            "while the cloth moves after them: a capture that dropped or repeated frames, "
            "or frames from before the motion began? The model steps dt from each frame to "
            "the next, so each repeat reads as a misfit, as noise or as an effect that is "
            "not there; cut the trajectory at them (or restore the missing frames) before "
            "reading the answer")


def unlisted_pins(trajectory):
    """Free particles ``[i, j]`` that never move, to the last bit, in any frame while the
    cloth moves (:func:`replication.sequences.still_points`): pins the file's ``pinned``
    does not list (the pinned ones that move are refused when the file is read).

    Parameters
    ----------
    trajectory : replication.cloth.io.Trajectory
    """
    positions = trajectory.positions
    n = positions.shape[1]
    free = trajectory.scene().free
    return [list(divmod(p, n)) for p in still_points(positions.reshape(len(positions), -1, 3))
            if free[p]]


def unlisted_pins_warning(particles):
    """The warning that free particles never move (:func:`unlisted_pins`), or None. One
    check for every workflow that fits the cloth model: the model moves every free
    particle, so a pin it does not know of reads as a misfit or as an effect that is not
    there."""
    if not particles:
        return None
    shown = first_few([f"({i}, {j})" for i, j in particles])
    return (f"{len(particles)} free particle(s) ({shown}) never move, to the last bit, "
            "while the cloth moves: pins the file's 'pinned' does not list? The model "
            "moves every free particle, so each such pin reads as a misfit or as an effect "
            "that is not there; add them to 'pinned' (as (i, j), docs/data-formats.md) "
            "before reading the answer")


def diagnostic_warnings(diagnostics, best, names):
    """One line per finding of :func:`diagnose` a user should act on."""
    best = dict(zip(names, np.asarray(best, dtype=float)))
    warnings = [
        f"{name}={best[name]:.6g} is not determined by the data: doubling or halving it "
        "changes the cost by less than the position noise does (no spring stretches "
        "enough in the cost's frames for its force to show)"
        for name in diagnostics["undetermined"] if name[0] in "kK"]
    warnings += [
        f"{name}={best[name]:.6g} is not determined by the cost: no spring of its type "
        f"reaches (1 + {name}) x its rest length in the cost's frames, so with the other "
        f"parameters as found every {name} >= {best[name]:.6g} has the same cost (a lower "
        "bound only if they are right; a cost on "
        "frames where the cloth is more stretched, set by cost.frame, cost.frames or "
        "cost.kind=full, may determine it)"
        for name in diagnostics["undetermined"] if name.startswith("tau")]
    if diagnostics["misfit"] > MISFIT_WARN:
        warnings.append(
            f"the model at these parameters leaves one-step residuals "
            f"{diagnostics['misfit']:.3g} x what the position noise explains (in power; "
            f"{np.sqrt(6.0 * diagnostics['misfit']) * diagnostics['noise_h']:.2g} h RMS per "
            "coordinate): the answer "
            "is off (approximate, or a local optimum), the data are in other units or "
            "another dt, or the model lacks an effect (the discrepancy workflow finds which)")
    elif (diagnostics.get("robust_misfit") or 0.0) > MISFIT_WARN:
        warnings.append(
            f"the model at these parameters leaves typical one-step residuals "
            f"{diagnostics['robust_misfit']:.3g} x (in power) the noise the data show "
            f"without a model ({diagnostics['data_noise_h']:.2g} h): the answer is off "
            "(approximate, or a local optimum), the model lacks an effect, or the noise "
            "is far from even across particles")
    for first in reversed([repeated_frames_warning(diagnostics.get("repeated_frames"),
                                                   diagnostics.get("rounding_step_h")),
                           unlisted_pins_warning(diagnostics.get("unlisted_pins"))]):
        if first is not None:   # first: they explain the lines that follow
            warnings.insert(0, first)
    still = (still_cloth_warning(diagnostics["motion_h"],
                                 min(diagnostics["position_noise_h"], diagnostics["noise_h"]))
             if "motion_h" in diagnostics else None)
    if still is not None:
        warnings.append(still)
    meaningless = meaningless_noise_warning(diagnostics["noise_h"])
    if meaningless is not None:
        warnings.append(meaningless)
    elif diagnostics["noise_h"] > NOISE_STRONG_H:
        warnings.append(
            f"the positions carry noise of about {diagnostics['noise_h']:.2g} h (estimated "
            "from the residuals): the one-step cost is strongly biased at this noise, expect "
            "K off by tens of % and tau off by as much as its own size (REPORT.md, "
            "parameter errors against position noise)")
    elif diagnostics["noise_h"] > NOISE_WARN_H:
        warnings.append(
            f"the positions carry noise of about {diagnostics['noise_h']:.2g} h (estimated "
            "from the residuals): the one-step cost is biased under noise, expect errors "
            "of several % or more in K and tau (REPORT.md, parameter errors against "
            "position noise)")
    return warnings


def truth_vector(trajectory, model="5"):
    """True parameter vector from ``trajectory.meta['true_params']`` (synthetic data only;
    used to score, never to identify), or ``None``.

    Parameters
    ----------
    trajectory : Trajectory
    model : "5" or "18"
    """
    true = trajectory.meta.get("true_params") if trajectory.meta else None
    if not true:
        return None
    five = np.array([true[name] for name in PARAM_NAMES_5], dtype=float)
    if model == "5":
        return five
    params = params_from_vectors(five)
    return np.r_[params.rest[0], params.k[0], params.tau[0]]


def relative_errors(vector, truth):
    """Signed relative errors ``vector / truth - 1`` per parameter.

    Parameters
    ----------
    vector, truth : (n_var,) array_like
    """
    return np.asarray(vector, float) / np.asarray(truth, float) - 1.0


def is_success(vector, truth, rtol):
    """All parameters within ``rtol`` (relative) of the truth.

    Parameters
    ----------
    vector, truth : (n_var,) array_like
    rtol : float
    """
    return bool(np.all(np.abs(relative_errors(vector, truth)) <= rtol))


def named(vector, names, cost=None):
    """A parameter vector as ``{name: value}`` (plus ``cost``); 18-parameter vectors as
    ``{rest: [6], k: [6], tau: [6]}`` (docs/results.md).

    Parameters
    ----------
    vector : (5,) or (18,) array_like
    names : sequence of str
    cost : float, optional
    """
    vector = np.asarray(vector, float)
    if len(names) == 18:
        out = {"rest": vector[0:6].tolist(), "k": vector[6:12].tolist(),
               "tau": vector[12:18].tolist()}
    else:
        out = dict(zip(names, vector.tolist()))
    if cost is not None:
        out["cost"] = float(cost)
    return out
