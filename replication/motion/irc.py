"""The IRC equation, the paper's accumulation (2.2) and a refinement by iterative warping.

IRC equation (paper 2.1), for a pixel ``(x, y)`` with derivatives ``Ix, Iy, It``
(conventions in :mod:`replication.motion.derivatives`)::

    -omega Ix (y - eta) + omega Iy (x - xi) + It = 0

For a fixed ``omega`` the candidate centres ``(xi, eta)`` of one pixel form the straight
line through ``(x, y) - s (-Iy, Ix)`` with ``s = It / (omega |grad I|^2)``, parallel to the
gradient ``(Ix, Iy)``. The accumulation votes once per accumulator column (or row, for
steep lines) along that line, as a Hough transform does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage

from replication.interrupts import deferred
from replication.motion.derivatives import (
    default_border,
    gradient_threshold,
    smooth,
    spatial_gradient,
)


@dataclass(frozen=True)
class Grid:
    """The accumulation space: cell ``(j, i)`` has centre ``(x0 + i cell, y0 + j cell)``."""

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    def centre(self, j, i):
        """``(xi, eta)`` of cell ``(j, i)``."""
        return self.x0 + i * self.cell, self.y0 + j * self.cell

    def near_edge(self, x, y, cells=0.5):
        """Whether ``(x, y)`` lies within ``cells`` cells of the grid's border (a peak
        there may be the cut-off slope of one outside the grid)."""
        right, bottom = self.centre(self.ny - 1, self.nx - 1)
        reach = cells * self.cell
        return bool(min(abs(x - self.x0), abs(x - right)) < reach
                    or min(abs(y - self.y0), abs(y - bottom)) < reach)


def image_grid(shape, *, margin=0.0, cell=1.0):
    """Accumulator covering the image ``shape = (H, W)`` plus ``margin`` pixels each side."""
    height, width = shape
    nx = int(math.floor((width - 1 + 2 * margin) / cell)) + 1
    ny = int(math.floor((height - 1 + 2 * margin) / cell)) + 1
    return Grid(x0=-margin, y0=-margin, cell=float(cell), nx=nx, ny=ny)


@numba.njit(cache=True, nogil=True)
def _span(start, slope, n_steps, n_cells):
    """A range of steps ``[low, high)`` within ``[0, n_steps)`` that holds every step ``k``
    with ``0 <= floor(start + k slope) < n_cells`` (one step wider each side, for safety);
    :func:`_steps_inside` then solves the exact range in fixed point."""
    if slope == 0.0:
        if 0.0 <= start < n_cells:
            return 0, n_steps
        return 0, 0
    a = (0.0 - start) / slope
    b = (n_cells - start) / slope
    low = max(min(a, b), -1.0)
    high = min(max(a, b), n_steps + 1.0)
    return max(0, int(math.floor(low)) - 1), min(n_steps, int(math.ceil(high)) + 1)


_FIXED_BITS = 20  # fixed-point fraction bits of the line walk (error < 256 / 2**20 cell)


@numba.njit(cache=True, nogil=True)
def _steps_inside(position, increment, n, limit):
    """Steps ``k`` in ``[0, n)`` with ``0 <= position + k increment < limit`` (integers)."""
    k_lo, k_hi = 0, n
    if increment > 0:
        if position < 0:
            k_lo = (-position + increment - 1) // increment
        if position + (n - 1) * increment >= limit:
            k_hi = min(n, (limit - 1 - position) // increment + 1)
    elif increment < 0:
        if position >= limit:
            k_lo = (position - limit) // (-increment) + 1
        if position + (n - 1) * increment < 0:
            k_hi = min(n, position // (-increment) + 1)
    elif position < 0 or position >= limit:
        return 0, 0
    return k_lo, k_hi


@numba.njit(cache=True, nogil=True)
def _walk(flat, start, slope, n_steps, n_cells):
    """Vote in cell ``(floor(start + step * slope), step)`` for every step inside the grid.

    ``flat`` is a C-ordered ``(n_cells, n_steps)`` accumulator, flattened: consecutive
    steps vote in neighbouring memory (the same cache line for many steps, as
    ``|slope| <= 1``; 10% faster than across it on a 150 x 150 grid, 35% on 256 x 256).
    The walk is in fixed point and its range is solved exactly beforehand, so the loop has
    no bounds test; unsigned offsets spare numba's negative-index wrap-around. Returns the
    number of votes.
    """
    low, high = _span(start, slope, n_steps, n_cells)
    if high <= low:
        return 0
    increment = np.int64(slope * (1 << _FIXED_BITS))
    position = np.int64(math.floor((start + low * slope) * (1 << _FIXED_BITS)))
    k_lo, k_hi = _steps_inside(position, increment, high - low,
                               np.int64(n_cells) << _FIXED_BITS)
    if k_hi <= k_lo:
        return 0
    position += k_lo * increment
    step = np.uint64(low + k_lo)
    stride = np.uint64(n_steps)
    for _ in range(k_lo, k_hi):
        flat[np.uint64(position >> _FIXED_BITS) * stride + step] += 1
        position += increment
        step += np.uint64(1)
    return k_hi - k_lo


@numba.njit(cache=True, nogil=True)
def _vote(acc, acc_t, x, y, gx, gy, gt, omega, x0, y0, cell):
    """Add one vote per column (or row) along each pixel's IRC line; return the vote count.

    Shallow lines vote in ``acc`` (ny, nx) column by column, steep ones in the transposed
    ``acc_t`` (nx, ny) row by row, each along its contiguous axis (:func:`_walk`); the
    accumulation space is ``acc + acc_t.T``. Both must be C-contiguous.
    """
    ny, nx = acc.shape
    flat, flat_t = acc.ravel(), acc_t.ravel()
    votes = 0
    for k in range(x.size):
        g2 = gx[k] * gx[k] + gy[k] * gy[k]
        s = -gt[k] / (omega * g2)
        # a point of the line, in cell units
        cx = (x[k] - s * gy[k] - x0) / cell
        cy = (y[k] + s * gx[k] - y0) / cell
        if abs(gx[k]) >= abs(gy[k]):
            slope = gy[k] / gx[k]
            votes += _walk(flat, cy - cx * slope + 0.5, slope, nx, ny)
        else:
            slope = gx[k] / gy[k]
            votes += _walk(flat_t, cx - cy * slope + 0.5, slope, ny, nx)
    return votes


@numba.njit(cache=True, parallel=True)
def _sweep(x, y, gx, gy, gt, omegas, x0, y0, cell, ny, nx, template):
    n = omegas.size
    peak = np.zeros(n, dtype=np.int64)
    where = np.zeros(n, dtype=np.int64)
    votes = np.zeros(n, dtype=np.int64)
    for m in numba.prange(n):
        acc = np.zeros((ny, nx), dtype=template.dtype)
        acc_t = np.zeros((nx, ny), dtype=template.dtype)
        votes[m] = _vote(acc, acc_t, x, y, gx, gy, gt, omegas[m], x0, y0, cell)
        best, best_j, best_i = -1, 0, 0
        for j in range(ny):
            for i in range(nx):
                value = np.int64(acc[j, i]) + np.int64(acc_t[i, j])
                if value > best:
                    best, best_j, best_i = value, j, i
        peak[m] = best
        where[m] = best_j * nx + best_i
    return peak, where, votes


def _counter_dtype(n_pixels):
    """int16 counters when they cannot overflow (a line votes at most once per cell, so a
    cell holds at most ``n_pixels`` votes), else int32: half the memory traffic."""
    return np.int16 if n_pixels <= np.iinfo(np.int16).max else np.int32


def _as_arrays(pixels):
    return (np.ascontiguousarray(pixels.x, dtype=np.float64),
            np.ascontiguousarray(pixels.y, dtype=np.float64),
            np.ascontiguousarray(pixels.gx, dtype=np.float64),
            np.ascontiguousarray(pixels.gy, dtype=np.float64),
            np.ascontiguousarray(pixels.gt, dtype=np.float64))


def accumulate(pixels, omega, grid):
    """The accumulation space for one ``omega`` (paper 2.2, Fig. 3).

    Parameters
    ----------
    pixels : PixelDerivatives
        Pixels with a sufficient gradient (n of them).
    omega : float
        Rotation speed (rad/frame), non-zero.
    grid : Grid

    Returns
    -------
    acc : (grid.ny, grid.nx) ndarray of int32
        Votes per cell.
    """
    if omega == 0:
        raise ValueError("omega=0: the IRC lines are undefined for omega = 0; use omega != 0")
    dtype = _counter_dtype(len(pixels))
    acc = np.zeros((grid.ny, grid.nx), dtype=dtype)
    acc_t = np.zeros((grid.nx, grid.ny), dtype=dtype)
    _vote(acc, acc_t, *_as_arrays(pixels), float(omega), grid.x0, grid.y0, grid.cell)
    return acc.astype(np.int32) + acc_t.T


_VOTES_PER_CALL = 20_000_000  # per thread and compiled call of _sweep: ~20 ms


def _omegas_per_thread(n_pixels, grid):
    """How many accumulations one thread makes per :func:`_sweep` call: as many as fit in
    ``_VOTES_PER_CALL`` votes (a line votes at most ``max(nx, ny)`` times), at least 1."""
    return max(1, _VOTES_PER_CALL // max(1, n_pixels * max(grid.nx, grid.ny)))


def sweep(pixels, omegas, grid):
    """The paper's ``F: omega -> (xi, eta, peak value)`` over a sweep of ``omega``.

    Parameters
    ----------
    pixels : PixelDerivatives
    omegas : (m,) array_like
        Non-zero rotation speeds (rad/frame).
    grid : Grid

    Returns
    -------
    dict
        ``omega, xi, eta, peak, votes``: ``(m,)`` arrays; the maximum cell of each
        accumulator (the first in row-major order on ties) and the votes cast.
    """
    omegas = np.ascontiguousarray(omegas, dtype=np.float64)
    if np.any(omegas == 0):
        raise ValueError("omegas: contains 0; the paper's sweep excludes omega = 0")
    template = np.zeros(1, dtype=_counter_dtype(len(pixels)))
    arrays = _as_arrays(pixels)
    # a few omegas per compiled call: Ctrl-C (raised only between calls) ends a long sweep
    # within a few accumulations, and no interrupt lands inside the parallel region; small
    # accumulations go several to a thread per call: each call's signal handling
    # (interrupts.deferred, ~70 us) cost a fifth of a 3000-pixel restricted accumulation
    chunk = numba.get_num_threads() * _omegas_per_thread(len(pixels), grid)
    parts = []
    for start in range(0, omegas.size, chunk):
        with deferred():
            parts.append(_sweep(*arrays, omegas[start:start + chunk], grid.x0, grid.y0,
                                grid.cell, grid.ny, grid.nx, template))
    peak, where, votes = (np.concatenate([part[k] for part in parts]) if parts
                          else np.zeros(0, dtype=np.int64) for k in range(3))
    j, i = np.divmod(where, grid.nx)
    xi, eta = grid.centre(j, i)
    return {"omega": omegas, "xi": np.asarray(xi, dtype=float),
            "eta": np.asarray(eta, dtype=float), "peak": peak, "votes": votes}


def paper_estimate(table):
    """The best peak of a sweep (paper 2.2): ``{xi, eta, omega, peak}``."""
    best = int(np.argmax(table["peak"]))
    return {"xi": float(table["xi"][best]), "eta": float(table["eta"][best]),
            "omega": float(table["omega"][best]), "peak": int(table["peak"][best])}


def omega_sweep(low, high, count):
    """About ``count`` values of ``omega`` evenly spread over ``[low, high]``, 0 excluded.

    ``count + 1`` evenly spaced values are made and 0 removed when it falls on that grid
    (the paper's ``-0.05 .. 0.05`` with 100 values has a step of 0.001); otherwise
    ``count`` evenly spaced values, less 0 if it is one of them (an odd ``count`` over a
    symmetric range then gives ``count - 1`` values).

    Returns
    -------
    omegas : (m,) ndarray, m = count or count - 1
    """
    scale = max(abs(low), abs(high))
    values = np.linspace(low, high, count + 1)
    zero = np.abs(values) <= 1e-12 * scale
    if not zero.any():
        values = np.linspace(low, high, count)
        zero = np.abs(values) <= 1e-12 * scale
    return values[~zero]


def line_distance(pixels, xi, eta, omega):
    """Distance (pixels) from ``(xi, eta)`` to each pixel's IRC line at ``omega``.

    ``|-Ix (y - eta) + Iy (x - xi) + It / omega| / |grad I|``: zero where the pixel
    verifies the IRC equation exactly (paper Fig. 4).

    Returns
    -------
    distance : (n,) ndarray
    """
    residual = -pixels.gx * (pixels.y - eta) + pixels.gy * (pixels.x - xi) + pixels.gt / omega
    return np.abs(residual) / pixels.gradient_norm


def translation_fit(pixels, tolerance):
    """The translation ``(u, v)`` (pixels/frame) that best explains ``Ix u + Iy v + It = 0``
    over the moving pixels (normal flow ``|It| / |grad I|`` of at least ``tolerance``),
    the share of ``pixels`` that move, and the share of the moving ones whose normal-flow
    residual ``|Ix u + Iy v + It| / |grad I|`` it leaves under ``tolerance``: both near 1
    when the whole scene moves by one translation (a camera pan), not by rotations.

    Returns
    -------
    u, v, moving, explained : float
    """
    norm = pixels.gradient_norm
    moving = pixels.normal_flow >= tolerance
    if not np.any(moving):
        return 0.0, 0.0, 0.0, 0.0
    a = np.stack([pixels.gx[moving], pixels.gy[moving]], axis=1)
    (u, v), *_ = np.linalg.lstsq(a, -pixels.gt[moving], rcond=None)
    residual = np.abs(a @ np.array([u, v]) + pixels.gt[moving]) / norm[moving]
    return float(u), float(v), float(np.mean(moving)), float(np.mean(residual < tolerance))


def rigid_matrix(xi, eta, omega):
    """``(3, 3)`` homogeneous map of a point of frame t to frame t + 1."""
    c, s = math.cos(omega), math.sin(omega)
    rotation = np.array([[c, -s], [s, c]])
    matrix = np.eye(3)
    matrix[:2, :2] = rotation
    matrix[:2, 2] = (np.eye(2) - rotation) @ np.array([xi, eta])
    return matrix


def matrix_to_irc(matrix):
    """``(xi, eta, omega)`` of a ``(3, 3)`` rigid map (its angle and fixed point)."""
    omega = math.atan2(matrix[1, 0], matrix[0, 0])
    c, s = math.cos(omega), math.sin(omega)
    rotation = np.array([[c, -s], [s, c]])
    xi, eta = np.linalg.solve(np.eye(2) - rotation, matrix[:2, 2])
    return float(xi), float(eta), float(omega)


SPREAD_TILE = 16  # pixels: side of the tiles the jackknife of :func:`refine` leaves out
SPREAD_GROUPS = 64  # at most this many solves: more tiles are dealt out into this many groups


def spread_tiles(x, y):
    """Label of the ``SPREAD_TILE``-pixel square tile holding each pixel ``(x, y)``.

    Parameters
    ----------
    x, y : (n,) array_like
        Pixel coordinates (column, row).
    """
    column = np.floor(np.asarray(x) / SPREAD_TILE).astype(np.int64)
    row = np.floor(np.asarray(y) / SPREAD_TILE).astype(np.int64)
    return row * 1_000_003 + column


def tukey_weights(residual, c):
    """Tukey biweight of ``residual / c``: ``(1 - r^2)^2`` inside ``|r| < 1``, else 0."""
    r = residual / c
    return np.where(np.abs(r) < 1, (1 - r * r) ** 2, 0.0)


def _warped_equations(s0, s1, matrix, centre, *, border, relative_threshold):
    """Rows ``a . (domega, p, q) = b`` in normal-flow units for one pair, warped by ``matrix``.

    Returns ``(a (n, 3), b (n,), static (n,), mask (H, W))``; ``static`` is the
    normal-flow residual of the motionless hypothesis (no warping) at the same pixels.
    """
    height, width = s0.shape
    rows, cols = np.mgrid[0:height, 0:width].astype(float)
    xw = matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2]
    yw = matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2]
    s1w = ndimage.map_coordinates(s1, [yw, xw], order=3, mode="nearest")
    gx, gy = spatial_gradient(0.5 * (s0 + s1w))
    gt = s1w - s0
    inside = ((xw >= border) & (xw <= width - 1 - border) & (yw >= border)
              & (yw <= height - 1 - border))
    valid = np.zeros_like(inside)
    valid[border: height - border, border: width - border] = True
    valid &= inside
    norm = np.hypot(gx, gy)
    mask = valid & (norm >= gradient_threshold(norm, valid, relative=relative_threshold))
    mask &= norm > 0
    X, Y = cols[mask] - centre[0], rows[mask] - centre[1]
    g = norm[mask]
    a = np.stack([(gy[mask] * X - gx[mask] * Y) / g, gx[mask] / g, gy[mask] / g], axis=1)
    return a, -gt[mask] / g, (s0 - s1)[mask] / g, mask


def blob_region(pixels, xi, eta, omega, shape, *, tol=3.0, blob_sigma=3.0, level=0.3):
    """The region of pixels verifying the IRC equation, as a blob (paper Fig. 4).

    A pixel verifies the equation when its IRC line passes within ``tol`` pixels of
    ``(xi, eta)``. The region is where, in a Gaussian window of ``blob_sigma`` pixels, at
    least the fraction ``level`` of the pixels with a sufficient gradient verify it; this
    removes the isolated static pixels whose lines happen to pass near the centre.

    Parameters
    ----------
    pixels : PixelDerivatives
    xi, eta, omega : float
    shape : (H, W) tuple

    Returns
    -------
    region : (H, W) ndarray of bool
    """
    verify = np.zeros(shape, dtype=bool)
    gradient = np.zeros(shape, dtype=bool)
    rows, cols = pixels.y.astype(np.int64), pixels.x.astype(np.int64)
    near = line_distance(pixels, xi, eta, omega) < tol
    verify[rows[near], cols[near]] = True
    gradient[rows, cols] = True
    return density_blob(verify, gradient, blob_sigma=blob_sigma, level=level)


def density_blob(verify, gradient, *, blob_sigma=3.0, level=0.3):
    """Where at least ``level`` of the ``gradient`` pixels near a point ``verify`` a motion.

    Parameters
    ----------
    verify, gradient : (H, W) ndarray of bool
        Pixels that verify the motion, and pixels with a sufficient gradient.
    blob_sigma : float
        Standard deviation (pixels) of the Gaussian window.

    Returns
    -------
    blob : (H, W) ndarray of bool
    """
    density = (ndimage.gaussian_filter(verify.astype(float), blob_sigma)
               / np.maximum(ndimage.gaussian_filter(gradient.astype(float), blob_sigma),
                            1e-12))
    return density > level


def move_region(region, matrix, steps):
    """``region`` of frame 0 carried ``steps`` frames forward by the rigid ``matrix``."""
    if steps == 0:
        return region
    inverse = np.linalg.matrix_power(np.linalg.inv(matrix), steps)
    rows, cols = np.mgrid[0:region.shape[0], 0:region.shape[1]].astype(float)
    x0 = inverse[0, 0] * cols + inverse[0, 1] * rows + inverse[0, 2]
    y0 = inverse[1, 0] * cols + inverse[1, 1] * rows + inverse[1, 2]
    return ndimage.map_coordinates(region.astype(float), [y0, x0], order=0, cval=0.0) > 0.5


def rigid_update(a, b, weights, centre):
    """One weighted least-squares step of the warping refinement.

    Solves ``a . (domega, p, q) = b`` with weights ``weights`` (rows of
    :func:`_warped_equations`: a rotation ``domega`` about ``centre`` plus a shift
    ``(p, q)``) and returns the small rigid motion as a matrix to compose into the estimate.

    Parameters
    ----------
    a : (n, 3) ndarray
    b, weights : (n,) ndarray
    centre : (2,) ndarray
        ``(x, y)`` about which ``domega`` turns.

    Returns
    -------
    update : (3, 3) ndarray
    d_omega : float
    shift : float
        ``|(p, q)|``, pixels.
    """
    root = np.sqrt(weights)
    (d_omega, p, q), *_ = np.linalg.lstsq(a * root[:, None], b * root, rcond=None)
    return _update_matrix(d_omega, p, q, centre), float(d_omega), math.hypot(p, q)


def _update_matrix(d_omega, p, q, centre):
    """The rigid map of a rotation ``d_omega`` about ``centre`` followed by a shift."""
    c, s = math.cos(d_omega), math.sin(d_omega)
    update = np.eye(3)
    update[:2, :2] = [[c, -s], [s, c]]
    update[:2, 2] = np.array([p, q]) + centre - update[:2, :2] @ centre
    return update


def rigid_spread(a, b, weights, blocks, matrix, centre):
    """Block-jackknife standard deviations of ``(xi, eta, omega)`` after a refinement step.

    The equations of one block (``blocks``: a label per row, e.g. a square tile of the
    frame) are left out in turn and the step is solved again; neighbouring pixels share
    their noise through the smoothing, so whole tiles are left out, not single pixels.
    Only blocks holding weighted rows count; more than ``SPREAD_GROUPS`` of them are dealt
    out into that many groups (the ``k``-th in group ``k mod SPREAD_GROUPS``), and the
    groups are left out in turn.

    Parameters
    ----------
    a, b, weights
        The last step's equations, as given to :func:`rigid_update`.
    blocks : (n,) ndarray of int
        Block label of each row.
    matrix : (3, 3) ndarray
        The estimate the last step started from.
    centre : (2,) ndarray
        The centre of that step.

    Returns
    -------
    dict or None
        ``xi_sd``, ``eta_sd``, ``omega_sd`` and ``blocks`` (the number of blocks or groups
        left out in turn); ``None`` with fewer than 4 of them holding weighted rows.
    """
    weighted = weights > 0  # rows of zero weight (outside the object) count for nothing
    a, b, weights = a[weighted], b[weighted], weights[weighted]
    labels, blocks = np.unique(blocks[weighted], return_inverse=True)
    if labels.size > SPREAD_GROUPS:  # a grouped jackknife: whole tiles, dealt out in turn
        blocks = blocks % SPREAD_GROUPS
    labels = np.unique(blocks)
    if labels.size < 4:
        return None
    # the normal equations of each block; leaving one out subtracts its share
    size = int(blocks.max()) + 1
    wa = a * weights[:, None]
    normal = np.array([[np.bincount(blocks, wa[:, i] * a[:, j], size) for j in range(3)]
                       for i in range(3)])
    right = np.array([np.bincount(blocks, wa[:, i] * b, size) for i in range(3)])
    all_normal, all_right = normal.sum(axis=2), right.sum(axis=1)
    replicates = []
    for label in labels:
        kept_normal = all_normal - normal[:, :, label]
        kept_right = all_right - right[:, label]
        try:
            d_omega, p, q = np.linalg.solve(kept_normal, kept_right)
        except np.linalg.LinAlgError:
            continue
        replicates.append(matrix_to_irc(matrix @ _update_matrix(d_omega, p, q, centre)))
    if len(replicates) < 4:
        return None
    values = np.array(replicates)
    k = len(values)
    sd = np.sqrt((k - 1) / k * ((values - values.mean(0)) ** 2).sum(0))
    return {"xi_sd": float(sd[0]), "eta_sd": float(sd[1]), "omega_sd": float(sd[2]),
            "blocks": k}


def refine(frames, xi, eta, omega, region, *, sigma=1.5, relative_threshold=0.15,
           tukey_c=1.0, max_iter=30, tol=1e-7):
    """Refine ``(xi, eta, omega)`` by iterative warping and robust least squares.

    Each iteration warps frame t + 1 back by the current rotation, writes the IRC equation
    of the small remaining motion (a rotation ``domega`` about the current centre plus a
    shift ``(p, q)``) for every pixel of ``region`` with a sufficient gradient, weights the
    equations by Tukey's biweight of the normal-flow residual and composes the solution
    into the estimate. This removes both the bias of the paper's omega (read too fast
    through the image derivatives: the central-difference gradient, the frame difference
    and noise, as :mod:`replication.experiments.omega_bias` measures) and the linearisation
    bias of the IRC equation for motions of several pixels.

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    xi, eta, omega : float
        Starting point, e.g. the paper's estimate; ``omega != 0``.
    region : (H, W) ndarray of bool
        The object's pixels in frame 0 (e.g. :func:`blob_region`); carried to later frames
        by the current estimate.
    sigma : float
        Gaussian pre-smoothing (pixels).
    relative_threshold : float
        Gradient threshold as in :func:`~replication.motion.derivatives.sequence_derivatives`.
    tukey_c : float
        Tukey's constant (pixels/frame of normal flow).
    max_iter : int
    tol : float
        Stop when ``|domega| < tol`` and the shift is below ``1000 tol`` pixels.

    Returns
    -------
    dict
        ``xi, eta, omega`` (refined), ``iterations``, ``pixels`` (equations with a
        non-zero weight in the last iteration), and for the first pair at the start of the
        last iteration ``gradient`` ((H, W) bool, pixels with a sufficient gradient) and
        ``consistent`` ((H, W) bool, those whose warped normal-flow residual is below
        ``tukey_c`` and below half the residual of the motionless hypothesis).
    """
    smoothed = [smooth(frame, sigma) for frame in frames]
    border = default_border(sigma)
    matrix = rigid_matrix(xi, eta, omega)
    iterations, used = 0, 0
    consistent = gradient = np.zeros(frames.shape[1:], dtype=bool)
    for _ in range(max_iter):
        iterations += 1
        centre = np.array(matrix_to_irc(matrix)[:2])
        rows_a, rows_b, weights, masks = [], [], [], []
        for t in range(len(smoothed) - 1):
            a, b, static, mask = _warped_equations(smoothed[t], smoothed[t + 1], matrix, centre,
                                           border=border,
                                           relative_threshold=relative_threshold)
            masks.append(mask)
            inside = move_region(region, matrix, t)[mask]
            if t == 0:
                gradient = mask
                consistent = np.zeros_like(mask)
                # follows the current motion, and clearly better than standing still
                consistent[mask] = (np.abs(b) < tukey_c) & (np.abs(b) < 0.5 * np.abs(static))
            rows_a.append(a)
            rows_b.append(b)
            # pixels better explained by standing still (static background) are left out
            weights.append(tukey_weights(b, tukey_c) * inside * (np.abs(b) <= np.abs(static)))
        a, b, w = np.concatenate(rows_a), np.concatenate(rows_b), np.concatenate(weights)
        used = int(np.count_nonzero(w))
        if used < 3:
            break
        update, d_omega, shift = rigid_update(a, b, w, centre)
        last = (a, b, w, masks, matrix, centre)
        matrix = matrix @ update
        if abs(d_omega) < tol and shift < 1000 * tol:
            break
    xi_r, eta_r, omega_r = matrix_to_irc(matrix)
    spread = None
    if used >= 3:  # the tiles of the last step's rows (boolean masks index row-major)
        a, b, w, masks, start, centre = last
        tiles = np.concatenate([spread_tiles(*np.nonzero(m)[::-1]) for m in masks])
        spread = rigid_spread(a, b, w, tiles, start, centre)
    return {"xi": xi_r, "eta": eta_r, "omega": omega_r, "iterations": iterations,
            "pixels": used, "gradient": gradient, "consistent": consistent,
            "spread": spread}
