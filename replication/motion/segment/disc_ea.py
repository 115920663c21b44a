"""The paper's evolutionary rigid-motion detector (section 2.3.2, Fig. 5).

An individual is ``(x, y, r, xi, eta, omega)``: a disc of centre ``(x, y)`` and radius
``r`` (pixels) with a rotation about ``(xi, eta)`` at ``omega`` rad/frame. Its cost is the
paper's normalised IRC residual over the disc's pixels plus ``beta R / (R + r)``::

    Cost(i) = alpha * mean_{disc} min(|-Ix (y - eta_i) + Iy (x - xi_i) + It / omega_i|
                                      * g_ref / |grad I|^2, cap)
              + beta * R / (R + r_i)

where ``r_i`` counts only the disc's part inside the valid image (``sqrt(area / pi)``).

Magnitude and normalisation (the paper's formula sums a signed term, which would let
positive and negative residuals cancel):

- the absolute value: ``|residual| / |grad I|`` is the distance (pixels) from ``(xi, eta)``
  to the pixel's IRC line, so the absolute value is a distance and the cost an L1 fit,
  less swayed than a square by the pixels of other motions inside a disc;
- the paper's "over-normalising" ``|grad I|^2`` denominator is kept (so pixels of weak
  gradient weigh more and discs avoid them, as the paper intends), multiplied by
  ``g_ref`` (the 99th percentile of ``|grad I|``) so the term stays in pixels whatever the
  image contrast;
- each pixel's term is truncated at ``cap`` pixels: the ``1 / omega`` factor makes noise in
  ``It`` arbitrarily large for small ``omega``; a capped vote is what a Hough accumulator
  casts too;
- the mean over the disc's pixels with a sufficient gradient replaces the paper's sum,
  so ``alpha`` does not depend on the texture density and the only size preference is the
  paper's ``beta R / (R + r)`` ("a slight advantage to larger discs"). Discs with fewer
  than ``min_pixels`` such pixels get the worst cost.

Sharing, selection and the four mutations follow the paper; see :class:`DiscEA`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from replication.motion.derivatives import default_border, gradient_threshold, pair_derivatives
from replication.optim.objective import Objective

DEFAULTS = {
    "pop_size": 150,          # paper: 100 to 150 individuals
    "generations": 100,       # paper: 50 to 100
    "keep": 0.2,              # paper: the 20% best are kept
    "r_min": 6.0,             # disc radius bounds, pixels
    "r_max": 40.0,
    "margin": 40.0,           # (xi, eta) may lie this far outside the image, pixels
    "omega_min": -0.05,       # rad/frame (the paper's sweep bounds)
    "omega_max": 0.05,
    "omega_eps": 0.002,       # |omega| below this is pushed to it (the cost divides by omega)
    "alpha": 1.0,
    "beta": 20.0,
    "R": 20.0,                # pixels
    "cap": 30.0,              # per-pixel truncation of the normalised residual, pixels
    "power": 2.0,             # |grad I| exponent of the denominator (paper: 2)
    "min_pixels": 20,
    "sharing": 20.0,          # extra cost per overlap area of pi r_min^2
    "sigma_position": 4.0,    # mutation noise on (x, y), pixels
    "sigma_radius": 0.2,      # mutation noise on log r
    "sigma_omega": 0.01,      # mutation noise on omega, rad/frame
    "damping": 0.05,          # projection mutation: fraction of the way to each line
    "sigma": 1.5,             # derivatives: Gaussian pre-smoothing, pixels
    "relative_threshold": 0.15,
    "motion_ratio": 1.0,      # rotating disc: rotation residual < this x static residual
    "motion_min": 0.1,        # ... and static normal flow above this, pixels/frame
    "size_in_image": True,    # beta term: radius of the disc's part inside the image
    "project_fresh": False,   # true: fresh individuals are projected once (not in the paper)
    "reject_static": False,   # true: motionless discs get the worst cost (not in the paper)
}


@dataclass(frozen=True)
class DiscData:
    """Dense derivatives of every frame pair, shapes ``(P, H, W)``.

    ``used`` marks pixels inside the valid border with a sufficient gradient; ``weight``
    is ``g_ref^(power - 1) / |grad I|^power`` there and 0 elsewhere; ``gnorm`` is
    ``|grad I|``; ``border`` is the width of the invalid border, pixels.
    """

    gx: np.ndarray
    gy: np.ndarray
    gt: np.ndarray
    gnorm: np.ndarray
    used: np.ndarray
    weight: np.ndarray
    border: int = 0

    @property
    def shape(self):
        """``(H, W)`` of the frames."""
        return self.gx.shape[1:]


def disc_data(frames, *, sigma=1.5, relative_threshold=0.15, power=2.0):
    """:class:`DiscData` of a sequence (derivative conventions of ``derivatives.py``).

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    sigma : float
        Gaussian pre-smoothing, pixels.
    relative_threshold : float
        Pixels with ``|grad I|`` below this fraction of its 99th percentile are unused.
    power : float
        Exponent of ``|grad I|`` in the denominator of the normalised residual.
    """
    parts = []
    for t in range(frames.shape[0] - 1):
        gx, gy, gt, valid = pair_derivatives(frames[t], frames[t + 1], sigma=sigma)
        norm = np.hypot(gx, gy)
        reference = gradient_threshold(norm, valid, relative=1.0)
        used = valid & (norm >= relative_threshold * reference) & (norm > 0)
        weight = np.zeros_like(norm)
        weight[used] = reference ** (power - 1.0) / norm[used] ** power
        parts.append((gx, gy, gt, norm, used, weight))
    gx, gy, gt, gnorm, used, weight = (np.ascontiguousarray(np.stack(a)) for a in zip(*parts))
    return DiscData(gx, gy, gt, gnorm, used, weight, default_border(sigma))


@numba.njit(cache=True, nogil=True)
def _row_span(row, x, y, r, width):
    """Columns ``[col0, col1]`` of ``row`` strictly inside the disc (empty if col0 > col1)."""
    half2 = r * r - (row - y) ** 2
    if half2 <= 0.0:
        return 1, 0
    half = math.sqrt(half2)
    col0 = max(0, int(math.floor(x - half)) + 1)
    col1 = min(width - 1, int(math.ceil(x + half)) - 1)
    if (col0 - 1 - x) ** 2 + (row - y) ** 2 < r * r and col0 - 1 >= 0:
        col0 -= 1
    if (col1 + 1 - x) ** 2 + (row - y) ** 2 < r * r and col1 + 1 <= width - 1:
        col1 += 1
    return col0, col1


@numba.njit(cache=True, nogil=True)
def _disc_sums(pop, gx, gy, gt, gnorm, used, weight, cap, flow_cap, border):
    """Per individual: sum of capped normalised residuals, pixel count, sums of the
    normal-flow residual of the rotation and of the motionless hypothesis (px/frame), and
    the number of the disc's pixels inside the valid image (``border`` pixels in).

    Serial on purpose: on this 2-core machine, shared with other jobs, numba's parallel
    loop ran 8 times slower than this one (oversubscribed threads)."""
    n = pop.shape[0]
    n_pairs, height, width = gx.shape
    out = np.zeros((n, 5))
    for i in range(n):
        x, y, r, xi, eta, omega = pop[i, 0], pop[i, 1], pop[i, 2], pop[i, 3], pop[i, 4], pop[i, 5]
        inverse = 1.0 / omega
        row0, row1 = max(0, int(math.floor(y - r))), min(height - 1, int(math.ceil(y + r)))
        total, count, rotation, static, inside = 0.0, 0.0, 0.0, 0.0, 0.0
        for row in range(row0, row1 + 1):
            col0, col1 = _row_span(row, x, y, r, width)
            if border <= row <= height - 1 - border:
                inside += max(0, min(col1, width - 1 - border) - max(col0, border) + 1)
            for p in range(n_pairs):
                for col in range(col0, col1 + 1):
                    if not used[p, row, col]:
                        continue
                    motion = -gx[p, row, col] * (row - eta) + gy[p, row, col] * (col - xi)
                    temporal = gt[p, row, col]
                    total += min(abs(motion + temporal * inverse) * weight[p, row, col], cap)
                    count += 1.0
                    g = gnorm[p, row, col]
                    rotation += min(abs(omega * motion + temporal) / g, flow_cap)
                    static += min(abs(temporal) / g, flow_cap)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = (total, count, rotation,
                                                                 static, inside)
    return out


def disc_statistics(pop, data, *, cap=30.0, flow_cap=3.0):
    """Residual statistics of each individual's disc.

    Parameters
    ----------
    pop : (N, 6) ndarray
        Individuals ``(x, y, r, xi, eta, omega)``, ``omega != 0``.
    data : DiscData
    cap : float
        Truncation of the normalised residual, pixels.
    flow_cap : float
        Truncation of the normal-flow residuals, pixels/frame.

    Returns
    -------
    dict of (N,) ndarrays
        ``residual`` (mean capped normalised residual, pixels), ``pixels`` (count),
        ``inside_radius`` (``sqrt(area / pi)`` of the disc's part inside the valid image),
        ``rotation_flow`` and ``static_flow`` (mean normal-flow residual of the rotation and
        of no motion at all, pixels/frame; NaN for empty discs).
    """
    pop = np.ascontiguousarray(pop, dtype=np.float64)
    sums = _disc_sums(pop, data.gx, data.gy, data.gt, data.gnorm, data.used, data.weight,
                      float(cap), float(flow_cap), int(data.border))
    count = sums[:, 1]
    safe = np.maximum(count, 1.0)
    empty = count == 0
    return {"residual": np.where(empty, cap, sums[:, 0] / safe), "pixels": count,
            "inside_radius": np.sqrt(sums[:, 4] / np.pi),
            "rotation_flow": np.where(empty, np.nan, sums[:, 2] / safe),
            "static_flow": np.where(empty, np.nan, sums[:, 3] / safe)}


def disc_cost(pop, data, settings):
    """The paper's cost of each individual (module docstring), shape ``(N,)``.

    With ``reject_static`` (not in the paper), a disc that is not better explained by its
    rotation than by no motion at all (:func:`rotating_discs`) gets the worst cost
    ``alpha cap + beta``: otherwise small discs of the static background, which fit a fast
    rotation about their own centre, fill the kept 20%.

    Parameters
    ----------
    pop : (N, 3) ndarray
        Discs ``(x, y, r)``.
    data : replication.motion.segment.disc_ea.DiscData
    settings : dict
        The cost settings: ``cap``, ``min_pixels``, ``R``, ``alpha``, ``beta``, and
        ``reject_static`` with ``motion_min``, ``motion_ratio``.
    """
    stats = disc_statistics(pop, data, cap=settings["cap"])
    residual = np.where(stats["pixels"] < settings["min_pixels"], settings["cap"],
                        stats["residual"])
    R = settings["R"]
    # the size advantage counts the disc's part inside the image: a disc centred off the
    # image would otherwise win it with a few pixels
    r = stats["inside_radius"] if settings.get("size_in_image", True) else pop[:, 2]
    cost = settings["alpha"] * residual + settings["beta"] * R / (R + r)
    if settings.get("reject_static", False):
        worst = settings["alpha"] * settings["cap"] + settings["beta"]
        cost = np.where(_is_rotating(stats, settings), cost, worst)
    return cost


def _is_rotating(stats, settings):
    with np.errstate(invalid="ignore"):
        return ((stats["rotation_flow"] < settings["motion_ratio"] * stats["static_flow"])
                & (stats["static_flow"] > settings["motion_min"])
                & (stats["pixels"] >= settings["min_pixels"]))


@numba.njit(cache=True, nogil=True)
def _overlap_pairs(x, y, r):
    """The parts of :func:`overlap_areas` without trigonometry: the ``(N, N)`` areas of
    the pairs where one disc lies within the other, and ``(i, j, d)`` of the pairs whose
    circles cross (a lens), in row-major order.

    Most pairs of a spread population lie farther apart along x or y than ``r1 + r2``:
    they do not overlap whatever ``hypot`` rounds to (it is at least ``|dx|`` and
    ``|dy|``), so it is computed for the other pairs only (the factor keeps the pairs at
    the border of that test on the exact path)."""
    n = x.size
    area = np.zeros((n, n))
    lens_i = np.empty(n * n, dtype=np.int64)
    lens_j = np.empty(n * n, dtype=np.int64)
    lens_d = np.empty(n * n)
    m = 0
    for i in range(n):
        for j in range(n):
            dx, dy = x[i] - x[j], y[i] - y[j]
            reach = r[i] + r[j]
            if not max(abs(dx), abs(dy)) < reach * (1.0 + 1e-9):
                continue
            d = math.hypot(dx, dy)
            if d >= reach:
                continue
            if d <= abs(r[i] - r[j]):
                area[i, j] = np.pi * min(r[i], r[j]) ** 2
            else:
                lens_i[m], lens_j[m], lens_d[m] = i, j, d
                m += 1
    return area, lens_i[:m], lens_j[:m], lens_d[:m]


def overlap_areas(x, y, r):
    """Pairwise intersection areas of discs, shape ``(N, N)`` (diagonal: the disc's area).

    The pairwise tests run compiled (:func:`_overlap_pairs`: as N x N numpy arrays they
    took most of the sharing's time); the lens formula is numpy's, as before.

    Parameters
    ----------
    x, y, r : (N,) ndarray
        Centres and radii, pixels.
    """
    r = np.ascontiguousarray(r, dtype=np.float64)
    area, i, j, d = _overlap_pairs(np.ascontiguousarray(x, dtype=np.float64),
                                   np.ascontiguousarray(y, dtype=np.float64), r)
    r1, r2 = r[i], r[j]
    with np.errstate(invalid="ignore", divide="ignore"):
        a1 = np.arccos(np.clip((d * d + r1 * r1 - r2 * r2) / (2 * d * r1), -1, 1))
        a2 = np.arccos(np.clip((d * d + r2 * r2 - r1 * r1) / (2 * d * r2), -1, 1))
        area[i, j] = np.nan_to_num(r1 * r1 * (a1 - np.sin(2 * a1) / 2)
                                   + r2 * r2 * (a2 - np.sin(2 * a2) / 2))
    return area


def shared_costs(cost, x, y, r, *, coefficient, area_unit):
    """The paper's sharing: for each overlapping pair, the individual of higher (unshared)
    cost gets ``coefficient * overlap / area_unit`` more; the other one is unchanged.

    Ties are broken by index (the lower index counts as better), so the result does not
    depend on the order of equal costs.

    Parameters
    ----------
    cost : (N,) ndarray
    x, y, r : (N,) ndarray
    coefficient : float
    area_unit : float
        Area (pixels^2) that one unit of ``coefficient`` stands for.

    Returns
    -------
    shared : (N,) ndarray
    """
    area = overlap_areas(x, y, r)
    np.fill_diagonal(area, 0.0)
    index = np.arange(cost.size)
    worse = (cost[:, None] > cost[None, :]) | ((cost[:, None] == cost[None, :])
                                               & (index[:, None] > index[None, :]))
    return cost + coefficient * (area * worse).sum(axis=1) / area_unit


@numba.njit(cache=True, nogil=True)
def _disc_cells(pop, used):
    """Per individual, the pixels of its disc used in some frame pair, as ``(pair, row,
    col)`` rows of one array, and where each individual's rows start (N + 1 offsets)."""
    n_pairs, height, width = used.shape
    starts = np.zeros(pop.shape[0] + 1, dtype=np.int64)
    for i in range(pop.shape[0]):
        x, y, r = pop[i, 0], pop[i, 1], pop[i, 2]
        row0, row1 = max(0, int(math.floor(y - r))), min(height - 1, int(math.ceil(y + r)))
        m = 0
        for row in range(row0, row1 + 1):
            col0, col1 = _row_span(row, x, y, r, width)
            for p in range(n_pairs):
                for col in range(col0, col1 + 1):
                    if used[p, row, col]:
                        m += 1
        starts[i + 1] = starts[i] + m
    cells = np.empty((starts[-1], 3), dtype=np.int64)
    for i in range(pop.shape[0]):
        x, y, r = pop[i, 0], pop[i, 1], pop[i, 2]
        row0, row1 = max(0, int(math.floor(y - r))), min(height - 1, int(math.ceil(y + r)))
        m = starts[i]
        for row in range(row0, row1 + 1):
            col0, col1 = _row_span(row, x, y, r, width)
            for p in range(n_pairs):
                for col in range(col0, col1 + 1):
                    if used[p, row, col]:
                        cells[m, 0], cells[m, 1], cells[m, 2] = p, row, col
                        m += 1
    return cells, starts


@numba.njit(cache=True, nogil=True)
def _project(pop, cells, starts, gx, gy, gt, gnorm, damping, cap, uniforms, width):
    """Damped Kaczmarz projections of ``(xi, eta)`` onto the IRC lines of the disc's
    pixels (``cells[starts[i]:starts[i + 1]]``), visited in the random order drawn from
    ``uniforms``: individual ``i``'s ``k``-th swap uses ``uniforms[i, k % width]``.

    Each disc's derivatives are first copied in pixel order to small arrays, which the
    random order then reads (half the time of reading the (P, H, W) maps in that order;
    the same operations on the same values)."""
    out = pop.copy()
    for i in range(pop.shape[0]):
        omega = pop[i, 5]
        first, m = starts[i], starts[i + 1] - starts[i]
        values = np.empty((6, m))    # Ix, Iy, It / omega, |grad I|, row, col
        for k in range(m):
            p, row, col = cells[first + k, 0], cells[first + k, 1], cells[first + k, 2]
            values[0, k], values[1, k] = gx[p, row, col], gy[p, row, col]
            values[2, k], values[3, k] = gt[p, row, col] / omega, gnorm[p, row, col]
            values[4, k], values[5, k] = row, col
        order = np.arange(m)
        for k in range(m - 1, 0, -1):      # Fisher-Yates with the given uniforms
            j = int(uniforms[i, k % width] * (k + 1))
            order[k], order[j] = order[j], order[k]
        xi, eta = out[i, 3], out[i, 4]
        for k in range(m):
            cell = order[k]
            a, b = values[0, cell], values[1, cell]
            residual = -a * (values[4, cell] - eta) + b * (values[5, cell] - xi) \
                + values[2, cell]
            g = values[3, cell]
            if abs(residual) / g > cap:
                continue
            # paper 2.3.2: move (xi, eta) a fraction of the way to the pixel's IRC line
            step = damping * residual / (g * g)
            xi += step * b
            eta -= step * a
        out[i, 3], out[i, 4] = xi, eta
    return out


def _row_uniforms(rng, width, needed):
    """The uniforms of ``rng.random((len(needed), width))`` that are read: the first
    ``needed[i]`` of row ``i``. The rest of each row is skipped, not drawn, where the
    bit generator can jump ahead (PCG64's ``advance``); ``rng`` is left in the same state
    as after the full draw, so the run's later draws are unchanged."""
    generator = rng.bit_generator
    if not hasattr(generator, "advance"):
        return rng.random((len(needed), width))
    # advance() drops a half-used 32-bit draw that random() would have kept: restore it
    state = generator.state
    buffered = (state.get("has_uint32"), state.get("uinteger"))
    rows = np.zeros((len(needed), max(1, int(max(needed, default=1)))))
    for i, count in enumerate(needed):
        rows[i, :count] = rng.random(count)
        generator.advance(width - count)
    state = generator.state
    state["has_uint32"], state["uinteger"] = buffered
    generator.state = state
    return rows


def project_centres(pop, data, rng, *, damping, cap):
    """The projection mutation: ``(xi, eta)`` of each individual moved towards the IRC line
    of each pixel of its disc in turn, by the fraction ``damping`` of the distance.

    Parameters
    ----------
    pop : (N, 6) ndarray
    data : DiscData
    rng : numpy.random.Generator
    damping : float in (0, 1]
    cap : float
        Lines farther than this (pixels) from the current centre are skipped (other
        motions inside the disc).

    Returns
    -------
    (N, 6) ndarray
    """
    pop = np.ascontiguousarray(pop, dtype=np.float64)
    # the visiting orders are drawn as rows of one uniform array this wide (the runs'
    # random streams are defined by it); only each disc's pixel count of a row is read
    width = max(1, int(np.ceil(np.pi * pop[:, 2].max() ** 2)) * data.gx.shape[0] + 1)
    cells, starts = _disc_cells(pop, data.used)
    needed = np.minimum(np.diff(starts), width).tolist()
    uniforms = _row_uniforms(rng, width, needed)
    return _project(pop, cells, starts, data.gx, data.gy, data.gt, data.gnorm,
                    float(damping), float(cap), uniforms, width)


def check_settings(settings):
    """Refuse EA settings that cannot work; ``ValueError`` naming the setting."""
    def need(condition, message):
        if not condition:
            raise ValueError(message)

    need(int(settings["pop_size"]) >= 10,
         f"pop_size={settings['pop_size']}: expected at least 10 individuals")
    need(int(settings["generations"]) >= 1,
         f"generations={settings['generations']}: expected at least 1")
    need(0 < settings["keep"] <= 0.25,
         f"keep={settings['keep']}: expected a fraction in (0, 0.25] (the kept individuals "
         "and their three mutated copies must fit in the population)")
    need(0 < settings["r_min"] < settings["r_max"],
         f"r_min={settings['r_min']}, r_max={settings['r_max']}: expected 0 < r_min < r_max")
    need(settings["omega_min"] < settings["omega_max"],
         f"omega_min={settings['omega_min']}, omega_max={settings['omega_max']}: expected "
         "omega_min < omega_max")
    need(settings["omega_eps"] > 0, f"omega_eps={settings['omega_eps']}: expected > 0")
    need(0 < settings["damping"] <= 1, f"damping={settings['damping']}: expected in (0, 1]")
    for key in ("alpha", "beta", "R", "cap", "sharing", "sigma_position", "sigma_radius",
                "sigma_omega"):
        need(settings[key] >= 0 and (key not in ("R", "cap") or settings[key] > 0),
             f"{key}={settings[key]}: expected a positive value")


class DiscEA:
    """The evolutionary loop of paper 2.3.2 (state: the population and its costs).

    Each generation: costs, the paper's sharing (:func:`shared_costs`), rank selection of
    the ``keep`` fraction of lowest shared cost, then four mutations in parallel and no
    crossover: three altered copies of every kept individual (noise on the disc's position
    and radius; noise on ``omega``; damped projection of ``(xi, eta)`` onto the IRC lines
    of the disc's pixels) and fresh random individuals for the rest of the population.
    With ``project_fresh`` (not in the paper) the fresh individuals are projected once
    before they are scored, so that a random disc on a moving object can compete with the
    small static discs that the kept 20% otherwise fill up with.

    Parameters
    ----------
    data : DiscData
    settings : dict
        Keys of :data:`DEFAULTS`.
    rng : numpy.random.Generator or int or None
    """

    def __init__(self, data, settings, rng=None):
        self.settings = {**DEFAULTS, **settings}
        check_settings(self.settings)
        self.data = data
        self.rng = np.random.default_rng(rng)
        self.n = int(self.settings["pop_size"])
        # the kept and their three mutated copies fit in the population (keep = 0.25 with
        # an odd population rounds up past it otherwise)
        self.n_keep = max(1, min(int(round(self.settings["keep"] * self.n)), self.n // 4))
        height, width = data.shape
        m = self.settings["margin"]
        s = self.settings
        self.lower = np.array([0.0, 0.0, s["r_min"], -m, -m, s["omega_min"]])
        self.upper = np.array([width - 1.0, height - 1.0, s["r_max"], width - 1.0 + m,
                               height - 1.0 + m, s["omega_max"]])
        # every cost goes through the suite's counted objective (one contract for all
        # optimisers, docs/extending.md)
        self.objective = Objective(lambda pop: disc_cost(pop, data, self.settings),
                                   self.lower, self.upper)
        self.population = self.random_individuals(self.n)
        self.costs = self.objective.evaluate(self.population)
        self.shared = self._share()
        self.generation = 0

    @property
    def evaluations(self):
        """Cost evaluations so far (counted by the objective)."""
        return self.objective.n_evals

    def random_individuals(self, count):
        """``count`` individuals drawn uniformly between the bounds, shape ``(count, 6)``."""
        pop = self.lower + self.rng.random((count, 6)) * (self.upper - self.lower)
        return self._repair(pop)

    def _repair(self, pop):
        pop = np.clip(pop, self.lower, self.upper)
        eps = self.settings["omega_eps"]
        small = np.abs(pop[:, 5]) < eps
        pop[small, 5] = np.where(pop[small, 5] < 0, -eps, eps)
        return pop

    def _share(self):
        p = self.population
        return shared_costs(self.costs, p[:, 0], p[:, 1], p[:, 2],
                            coefficient=self.settings["sharing"],
                            area_unit=np.pi * self.settings["r_min"] ** 2)

    def order(self):
        """Indices sorted by shared cost (ties by index), best first, shape ``(N,)``."""
        return np.lexsort((np.arange(self.n), self.shared))

    def step(self):
        """One generation: selection, the four mutations, costs and sharing."""
        s = self.settings
        kept = self.population[self.order()[: self.n_keep]]
        kept_costs = self.costs[self.order()[: self.n_keep]]
        moved = kept.copy()
        moved[:, :2] += self.rng.normal(0.0, s["sigma_position"], (self.n_keep, 2))
        moved[:, 2] *= np.exp(self.rng.normal(0.0, s["sigma_radius"], self.n_keep))
        turned = kept.copy()
        turned[:, 5] += self.rng.normal(0.0, s["sigma_omega"], self.n_keep)
        projected = project_centres(kept, self.data, self.rng, damping=s["damping"],
                                    cap=s["cap"])
        fresh = self.random_individuals(self.n - 4 * self.n_keep)
        if s["project_fresh"]:
            fresh = project_centres(fresh, self.data, self.rng, damping=s["damping"],
                                    cap=s["cap"])
        children = self._repair(np.concatenate([moved, turned, projected, fresh]))
        child_costs = self.objective.evaluate(children)
        self.population = np.concatenate([kept, children])
        self.costs = np.concatenate([kept_costs, child_costs])
        self.shared = self._share()
        self.generation += 1

    def run(self, callback=None):
        """Run ``generations`` generations; ``callback(self)`` after each one.

        Returns
        -------
        dict
            ``population`` (N, 6), ``cost`` and ``shared`` (N,), best first;
            ``retained`` (the paper's final 20% best, ``(n_keep, 6)``); ``evaluations``.
        """
        for _ in range(int(self.settings["generations"])):
            self.step()
            if callback is not None:
                callback(self)
        order = self.order()
        return {"population": self.population[order], "cost": self.costs[order],
                "shared": self.shared[order], "retained": self.population[order[: self.n_keep]],
                "evaluations": self.evaluations}


def rotating_discs(discs, data, settings):
    """Keep the discs whose motion is a rotation rather than no motion at all.

    A disc is rotating when the mean normal-flow residual of its rotation is below
    ``motion_ratio`` times that of the motionless hypothesis, and the latter is above
    ``motion_min`` pixels/frame. (Not in the paper: the cost's ``1 / omega`` normalisation
    lets a disc of the static background fit a fast rotation about its own centre.)

    Parameters
    ----------
    discs : (n, 6) ndarray
    data : DiscData
    settings : dict

    Returns
    -------
    keep : (n,) ndarray of bool
    stats : dict of (n,) ndarrays (see :func:`disc_statistics`)
    """
    stats = disc_statistics(discs, data, cap=settings["cap"])
    return _is_rotating(stats, settings), stats
