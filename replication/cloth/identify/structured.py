"""A structured identifier for the cloth parameters (beyond the paper).

Three stages, each using what the model's structure gives:

1. The identification engine (:func:`replication.cloth.regression.fit`, shared with the
   discrepancy workflow): for a particle that the deformation constraint did not move,
   the spring forces ``k (L - l) d / L = k d - (k l) d / L`` are linear in ``k`` and
   ``k l``, so rest lengths and stiffnesses come from a regression of the observed
   accelerations (robust to the constraint and to position noise), and tau from a
   one-dimensional search. No evaluations of the objective.
2. A scan of tau on the cost with ``k`` and ``l`` fixed (a batched grid, then batched
   zooms: the engine's one-dimensional search, :mod:`replication.optim.scan`), which
   finds the needle-shaped minimum in tau that defeats general optimisers (Figs. 9-10).
3. Local refinement: the paper's EA on a small box around the estimate.

All cost evaluations go through the shared :class:`~replication.optim.objective.Objective`.
"""

from __future__ import annotations

import weakref

import numpy as np

from replication.cloth import regression
from replication.cloth.identify.ea import EASettings, PaperEA
from replication.cloth.identify.problem import finite_best
from replication.cloth.mesh import FAMILY_OF_TYPE, N_TYPES
from replication.errors import check
from replication.optim.objective import BudgetExhausted
from replication.optim.scan import zoom

ZOOM_POINTS = 7   # values per zoom of the tau scan: 3x narrower per 7 evaluations


def check_settings(settings):
    """Refuse structured-identifier settings it cannot run with (InputError naming the
    setting, as ``structured.GROUP.KEY``); see :func:`structured_identify`."""
    def integer(group, key, low, what, default=None):
        got = (settings.get(group) or {}).get(key, default)
        check(isinstance(got, int) and not isinstance(got, bool) and got >= low,
              f"structured.{group}.{key}={got!r}: expected {what}")

    integer("regression", "first", 0, "a frame index >= 0")
    integer("regression", "stride", 1, "an integer >= 1")
    integer("tau_scan", "n_grid", 2, "an integer >= 2 (grid points)")
    integer("tau_scan", "refine_evals", 0, "an integer >= 0 (evaluations)")
    integer("tau_scan", "cycles", 1, "an integer >= 1", default=1)
    box = (settings.get("refine") or {}).get("box")
    check(isinstance(box, (int, float)) and not isinstance(box, bool) and 0 < box < 1,
          f"structured.refine.box={box!r}: expected a relative half-width in (0, 1)")
    EASettings.from_config((settings.get("refine") or {}).get("ea") or {})


def regression_frames(n_frames, *, first, stride):
    """Frames ``t`` (with ``t - 1 >= 0`` and ``t + 1`` in the data) used by the regression.

    Parameters
    ----------
    n_frames : int
    first, stride : int
    """
    return np.arange(max(first, 1), n_frames - 1, stride)


def scan_tau(objective, base, indices, *, n_grid, refine_evals, points=ZOOM_POINTS):
    """Stage 2 for one group of tau entries set to a common value: a log grid over the
    bounds, then zooms of ``points`` values around the best one
    (:func:`replication.optim.scan.zoom`, the identification engine's tau search too)
    while ``refine_evals`` evaluations last. The answer is read from the objective's
    best-so-far point.

    Parameters
    ----------
    objective : Objective
    base : (n_var,) ndarray
        The other parameters, fixed.
    indices : list of int
        The tau entries set to the scanned value.
    n_grid : int
        Grid points.
    refine_evals : int
        Evaluations of the zooms (``refine_evals // points`` zooms).
    points : int
        Values per zoom (each zoom shrinks the bracket by ``(points - 1) / 2``).
    """
    indices = list(indices)
    low = objective.lower[indices].max()
    high = objective.upper[indices].min()

    def along(taus):
        X = np.repeat(base[None, :], len(taus), axis=0)
        X[:, indices] = np.asarray(taus)[:, None]
        return objective.evaluate(X)

    zoom(along, np.geomspace(low, high, n_grid), levels=int(refine_evals) // points,
         points=points)


def tau_groups(model, n_var):
    """Groups of tau indices scanned together: all taus, then (18 parameters) each spring
    family's pair, then each type. A spring's clamp changes its particles' mean correction
    (Jacobi pass), so taus of one family are coupled and are scanned jointly first.

    Parameters
    ----------
    model : "5" or "18"
    n_var : int
    """
    if model != "18":
        return [[n_var - 1]]
    first = n_var - N_TYPES
    families = [[first + t for t in range(N_TYPES) if FAMILY_OF_TYPE[t] == f]
                for f in range(3)]
    return [list(range(first, n_var)), *families, *[[i] for i in range(first, n_var)]]


_FITS = {}   # id(trajectory) -> (weak reference, {(frames, model): regression.Fit})


def engine_fit(trajectory, frames, model):
    """The engine's fit of ``trajectory`` on ``frames``: computed once per trajectory
    object, frames and model in a process (it uses no random numbers and no evaluations,
    so every seed of a study on the same data shares it); forgotten with the trajectory.
    """
    key = id(trajectory)
    ref, fits = _FITS.get(key, (None, None))
    if ref is None or ref() is not trajectory:
        fits = {}
        _FITS[key] = (weakref.ref(trajectory, lambda _, key=key: _FITS.pop(key, None)), fits)
    which = (np.asarray(frames).tobytes(), model)
    if which not in fits:
        fits[which] = regression.fit(regression.prepare(trajectory), frames, model=model)
    return fits[which]


def structured_identify(trajectory, objective, space, *, rng, settings):
    """Regression, tau scan and EA refinement (see the module docstring).

    Parameters
    ----------
    trajectory : Trajectory
    objective : Objective over ``space`` (the cost the answer is judged on)
    space : SearchSpace
    rng : np.random.Generator
    settings : dict
        Checked by :func:`check_settings` (``solve`` does it):
        ``regression: {first, stride}`` (frames of the engine's regression),
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
    fitted = engine_fit(trajectory, frames, model)
    reg_info = {"how": fitted.how, "tau": float(fitted.base.tau[0]),
                "particle_frames_used": int(fitted.mask.sum())}
    if model == "18":
        rest, k, tau = fitted.base.rest, fitted.base.k, fitted.base.tau
    else:
        rest = fitted.base.rest[[0, 2, 4]]
        k, tau = fitted.base.k[:1], fitted.base.tau[:1]
    x = np.clip(np.r_[rest, k, tau], objective.lower, objective.upper)
    objective.evaluate(x[None, :])
    info = {"regression": reg_info, "regression_vector": x.tolist()}
    scan = settings["tau_scan"]
    try:
        # coordinate-wise scans, repeated: with several taus, one scan's answer depends
        # on the others' current values
        for _ in range(int(scan.get("cycles", 1))):
            for group in tau_groups(model, space.n_var):
                scan_tau(objective, x, group, n_grid=scan["n_grid"],
                         refine_evals=scan["refine_evals"])
                x = finite_best(objective).copy()
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
