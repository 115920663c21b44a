"""Baselines for rigid-motion segmentation (paper 2.3).

- :func:`nichega_discs`: pymoo's niching GA (``NicheGA``) on the same disc cost as the
  paper's EA (:func:`replication.motion.segment.disc_ea.disc_cost`), same population and number of
  cost evaluations (pymoo may overshoot by part of a generation; the count is returned);
  the rest of the pipeline is unchanged.
- :func:`flow_ransac_segment`: a classical pipeline without the IRC equation: TV-L1 optical
  flow, then sequential RANSAC of rigid motions on the moving pixels.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from replication.motion.baselines import flow_field, rigid_fit
from replication.motion.segment import disc_ea
from replication.optim.objective import Objective

NICHEGA_DEFAULTS = {"norm_niche_size": 0.05}
FLOW_DEFAULTS = {"motion_min": 0.25, "tolerance": 0.3, "samples": 300, "min_inliers": 300,
                 "max_models": 6, "max_points": 6000, "closing": 3, "min_area": 150}


def nichega_discs(data, ea_settings, nichega_settings, rng):
    """pymoo ``NicheGA`` on the disc cost; returns the best ``keep`` fraction of its final
    population (as the paper's EA retains its 20% best) and the evaluations made.

    Parameters
    ----------
    data : DiscData
    ea_settings : dict
        :data:`replication.motion.segment.disc_ea.DEFAULTS` keys (bounds, cost, budget).
    nichega_settings : dict
        ``norm_niche_size`` (NicheGA's clearing radius in the normalised design space).
    rng : numpy.random.Generator
        Draws pymoo's integer seed.

    Returns
    -------
    discs : (n_keep, 6) ndarray
    evaluations : int
    """
    from pymoo.algorithms.soo.nonconvex.ga_niching import NicheGA
    from pymoo.optimize import minimize

    from replication.optim.pymoo_adapters import BatchedProblem

    settings = {**disc_ea.DEFAULTS, **ea_settings}
    options = {**NICHEGA_DEFAULTS, **(nichega_settings or {})}
    template = disc_ea.DiscEA(data, {**settings, "generations": 1}, rng=0)
    # scored through the suite's counted objective, like every optimiser; the count is
    # the objective's (pymoo's own termination may overshoot by part of a generation)
    objective = Objective(lambda X: disc_ea.disc_cost(template._repair(X), data, settings),
                          template.lower, template.upper)
    algorithm = NicheGA(pop_size=int(settings["pop_size"]),
                        norm_niche_size=float(options["norm_niche_size"]))
    seed = int(rng.integers(2**31 - 1))
    # the paper's EA's budget: the first population, then the non-kept 80% each generation
    budget = template.n + (template.n - template.n_keep) * int(settings["generations"])
    result = minimize(BatchedProblem(objective), algorithm, ("n_eval", budget), seed=seed,
                      verbose=False)
    pop = template._repair(result.pop.get("X").astype(float))
    cost = result.pop.get("F")[:, 0]
    order = np.lexsort((np.arange(cost.size), cost))
    n_keep = max(1, int(round(settings["keep"] * pop.shape[0])))
    return pop[order[:n_keep]], objective.n_evals


def _two_point_rotation(p, q):
    """``(xi, eta, omega)`` of the rigid map taking points ``p (2, 2)`` to ``q (2, 2)``."""
    a, b = p[1] - p[0], q[1] - q[0]
    omega = math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1])
    if abs(omega) < 1e-4:
        return None
    c, s = math.cos(omega), math.sin(omega)
    rotation = np.array([[c, -s], [s, c]])
    centre = np.linalg.solve(np.eye(2) - rotation, q[0] - rotation @ p[0])
    return float(centre[0]), float(centre[1]), omega


def rotation_residual(points, flow, xi, eta, omega):
    """Distance (pixels) between each flow vector and the rotation's displacement.

    Parameters
    ----------
    points : (n, 2) ndarray
        ``(x, y)``.
    flow : (n, 2) ndarray
        ``(u, v)`` displacement along x and y.
    """
    c, s = math.cos(omega), math.sin(omega)
    dx, dy = points[:, 0] - xi, points[:, 1] - eta
    u = xi + c * dx - s * dy - points[:, 0]
    v = eta + s * dx + c * dy - points[:, 1]
    return np.hypot(u - flow[:, 0], v - flow[:, 1])


def sequential_ransac(points, flow, settings, rng):
    """Rigid motions found one after another by RANSAC on flow vectors.

    Each round draws ``samples`` pairs of points, keeps the rotation with most inliers
    (flow within ``tolerance`` pixels), refits it robustly on its inliers
    (:func:`replication.motion.baselines.rigid_fit`), removes them and starts again, until
    fewer than ``min_inliers`` points follow the best rotation or ``max_models`` are found.

    Parameters
    ----------
    points : (N, 2) ndarray
        ``(x, y)`` of the flow vectors.
    flow : (N, 2) ndarray
        ``(u, v)`` per point, pixels/frame.
    settings : dict
        ``samples``, ``tolerance``, ``min_inliers``, ``max_models``...
    rng : np.random.Generator

    Returns
    -------
    list of dict
        ``xi, eta, omega, inliers`` (indices into ``points``).
    """
    remaining = np.arange(points.shape[0])
    models = []
    while len(models) < int(settings["max_models"]) and remaining.size >= 2:
        best, best_count = None, 0
        picks = rng.integers(remaining.size, size=(int(settings["samples"]), 2))
        for i, j in picks:
            if i == j:
                continue
            idx = remaining[[i, j]]
            model = _two_point_rotation(points[idx], points[idx] + flow[idx])
            if model is None:
                continue
            count = np.count_nonzero(rotation_residual(points[remaining], flow[remaining],
                                                       *model) < settings["tolerance"])
            if count > best_count:
                best, best_count = model, count
        if best is None or best_count < settings["min_inliers"]:
            break
        inliers = remaining[rotation_residual(points[remaining], flow[remaining], *best)
                            < settings["tolerance"]]
        models.append({"xi": best[0], "eta": best[1], "omega": best[2], "inliers": inliers})
        remaining = np.setdiff1d(remaining, inliers)
    return models


def flow_ransac_segment(frames, settings, rng):
    """TV-L1 flow, then sequential RANSAC of rigid motions on the moving pixels.

    Parameters
    ----------
    frames : (T, H, W) ndarray
        The first pair is used.
    settings : dict
        :data:`FLOW_DEFAULTS` keys.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    list of dict
        Objects ``xi, eta, omega, area, mask ((H, W) bool)``, in the order found; the mask
        is the moving pixels that follow the model and no earlier one, closed by
        ``closing`` pixels, holes filled; the rotation is refitted on it.
    """
    settings = {**FLOW_DEFAULTS, **settings}
    rng = np.random.default_rng(rng)
    u, v = flow_field(frames[0], frames[1], method="tvl1")
    moving = np.hypot(u, v) >= settings["motion_min"]
    moving[:4], moving[-4:], moving[:, :4], moving[:, -4:] = False, False, False, False
    rows, cols = np.nonzero(moving)
    if rows.size > settings["max_points"]:
        keep = np.sort(rng.choice(rows.size, int(settings["max_points"]), replace=False))
        rows, cols = rows[keep], cols[keep]
    points = np.stack([cols, rows], axis=1).astype(float)
    flow = np.stack([u[rows, cols], v[rows, cols]], axis=1)
    all_rows, all_cols = np.nonzero(moving)
    all_points = np.stack([all_cols, all_rows], axis=1).astype(float)
    all_flow = np.stack([u[moving], v[moving]], axis=1)
    taken = np.zeros(all_rows.size, dtype=bool)
    objects = []
    structure = ndimage.generate_binary_structure(2, 1)
    for model in sequential_ransac(points, flow, settings, rng):
        follows = ~taken & (rotation_residual(all_points, all_flow, model["xi"], model["eta"],
                                              model["omega"]) < settings["tolerance"])
        taken |= follows
        mask = np.zeros(frames.shape[1:], dtype=bool)
        mask[all_rows[follows], all_cols[follows]] = True
        mask = ndimage.binary_fill_holes(
            ndimage.binary_closing(mask, structure, iterations=int(settings["closing"])))
        if np.count_nonzero(mask) < settings["min_area"]:
            continue
        refit = rigid_fit(u, v, mask & moving)
        if not all(np.isfinite([refit["xi"], refit["eta"], refit["omega"]])):
            refit = model
        objects.append({"xi": refit["xi"], "eta": refit["eta"], "omega": refit["omega"],
                        "area": int(np.count_nonzero(mask)), "mask": mask})
    return objects
