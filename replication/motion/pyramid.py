"""Coarse to fine for frames of any size (beyond the paper): a pyramid and a sampled refinement.

The paper's accumulation casts one vote per accumulator column for every pixel and every
omega, so its cost grows with the cube of the frame side. The pyramid method
(``method.accumulation: pyramid`` of ``motion_single``, :func:`replication.motion.single.
pyramid_rotation`) runs it on a reduced copy of the frames whose side is at most
``coarse_side`` (a wide, short frame keeps a shorter side of at least ``coarse_side // 2``:
:func:`top_shape`; the accumulator no longer grows with the frames), then refines the answer
level by level up to the full resolution with the warping refinement of
:func:`replication.motion.irc.refine` written on a fixed number of sampled pixels, so that
the work at full resolution is a few filters of the frames (linear in their pixels) plus a
fixed number of equations.

Levels: level 0 is the input; level ``k`` has ``factor = 2**k`` and is made from level
``k - 1`` by the binomial filter ``[1, 3, 3, 1] / 8`` and decimation by 2 along each axis (a
Burt-Adelson style reduction: pixel ``i`` of the new level averages pixels ``2i - 1 ..
2i + 2`` of the old one, so its centre is at ``2i + 0.5``). A point at ``x`` on a level of
``factor`` is at ``factor x + (factor - 1) / 2`` in the input; omega is the same on every
level.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from replication.motion import irc
from replication.motion.derivatives import default_border, smooth


def reduce(frames):
    """One pyramid level down: ``[1, 3, 3, 1] / 8`` filter and decimation by 2 on both axes.

    Parameters
    ----------
    frames : (T, H, W) ndarray, H, W >= 2

    Returns
    -------
    reduced : (T, H // 2, W // 2) ndarray of float64
    """
    out = np.asarray(frames, dtype=float)
    for axis in (1, 2):
        half = out.shape[axis] // 2
        padded = np.concatenate([np.take(out, [0], axis=axis),
                                 np.take(out, np.arange(2 * half), axis=axis),
                                 np.take(out, [min(2 * half, out.shape[axis] - 1)], axis=axis)],
                                axis=axis)

        def tap(offset, padded=padded, half=half, axis=axis):
            index = [slice(None)] * 3
            index[axis] = slice(offset, offset + 2 * half, 2)
            return padded[tuple(index)]

        out = (tap(0) + 3.0 * tap(1) + 3.0 * tap(2) + tap(3)) / 8.0
    return out


def levels(frames, coarse_side):
    """The pyramid: level 0 (the input) down to the first level whose sides are both at most
    ``coarse_side`` pixels, or whose shorter side would fall under ``coarse_side // 2``
    (:func:`top_shape`).

    Parameters
    ----------
    frames : (T, H, W) ndarray
    coarse_side : int
        Largest side of the top level, pixels (unless its shorter side would be under
        half of it).

    Returns
    -------
    list of (T, H_k, W_k) ndarray
        ``levels[k]`` has ``factor = 2**k``.
    """
    pyramid = [np.asarray(frames, dtype=float)]
    top = top_shape(pyramid[0].shape[1:], coarse_side)
    while pyramid[-1].shape[1:] != top:
        pyramid.append(reduce(pyramid[-1]))
    return pyramid


def top_shape(shape, coarse_side):
    """``(H, W)`` of the top level :func:`levels` builds for frames of ``shape``: halved
    (:func:`reduce`) until both sides are at most ``coarse_side``, but never to a shorter
    side under ``coarse_side // 2`` (nor under 2). Wide, short frames (88 x 954) keep
    enough rows to vote on: halving until the longer side fits left 22 x 238, on which
    the best peak was hundreds of pixels off where the exact accumulation was right.

    Parameters
    ----------
    shape : (H, W)
    coarse_side : int
    """
    height, width = shape
    floor = max(coarse_side // 2, 2)
    while max(height, width) > coarse_side and min(height, width) // 2 >= floor:
        height, width = height // 2, width // 2
    return height, width


def to_input(value, factor):
    """A coordinate on a level of ``factor`` expressed in input pixels.

    Parameters
    ----------
    value : float or ndarray
        ``x`` or ``y`` in pixels of the level.
    factor : int
        The level's factor (``2**k`` for level ``k``).
    """
    return factor * value + (factor - 1) / 2.0


def to_level(value, factor):
    """An input coordinate expressed in pixels of a level of ``factor``.

    Parameters
    ----------
    value : float or ndarray
        ``x`` or ``y`` in input pixels.
    factor : int
        The level's factor.
    """
    return (value - (factor - 1) / 2.0) / factor


def grid_in_input(grid, factor):
    """The accumulator :class:`~replication.motion.irc.Grid` of a level, in input pixels.

    Parameters
    ----------
    grid : Grid
        In pixels of the level.
    factor : int
        The level's factor.
    """
    return irc.Grid(x0=to_input(grid.x0, factor), y0=to_input(grid.y0, factor),
                    cell=grid.cell * factor, nx=grid.nx, ny=grid.ny)


def sequence_on_level(sequence, frames, factor):
    """``sequence`` as seen on a pyramid level of ``factor`` (for drawing figures there).

    Parameters
    ----------
    sequence : replication.motion.io.Sequence
    frames : (T, h, w) ndarray
        The level's frames.
    factor : int

    Returns
    -------
    Sequence
        With ``frames``, the labels read at the input pixel nearest each level pixel's
        centre, and the truth's centres in the level's pixels.
    """
    height, width = frames.shape[1:]
    labels = sequence.labels
    if labels is not None:
        labels = labels[:, factor // 2::factor, factor // 2::factor][:, :height, :width]
    truth = sequence.truth
    if truth and truth.get("objects"):
        truth = dict(truth, objects=[dict(item, xi=to_level(item["xi"], factor),
                                          eta=to_level(item["eta"], factor))
                                     for item in truth["objects"]])
    return replace(sequence, frames=frames, labels=labels, truth=truth)


def upsample_mask(mask, ratio, shape):
    """``mask`` of a level ``ratio`` times coarser, read at every pixel of a level of
    ``shape = (H, W)`` (nearest coarse pixel; outside the mask is outside).

    Parameters
    ----------
    mask : (h, w) ndarray of bool
    ratio : int
        How many times coarser ``mask``'s level is.
    shape : (H, W) tuple

    Returns
    -------
    (H, W) ndarray of bool
    """
    def nearest(size, coarse_size):
        index = np.rint(to_level(np.arange(size, dtype=float), ratio)).astype(np.int64)
        return np.clip(index, 0, coarse_size - 1), (index >= 0) & (index < coarse_size)

    rows, row_ok = nearest(shape[0], mask.shape[0])
    cols, col_ok = nearest(shape[1], mask.shape[1])
    return mask[rows[:, None], cols[None, :]] & row_ok[:, None] & col_ok[None, :]


@dataclass(frozen=True)
class LevelFrames:
    """One level's frames, filtered once for every object refined on it.

    ``smoothed``: the frames after the Gaussian of ``sigma`` (T arrays (H, W)); per frame
    pair ``t``: ``gradients[t]`` (central differences ``(gx, gy)`` of ``smoothed[t]``),
    ``thresholds[t]`` (the squared gradient threshold) and ``coefficients[t]`` (the spline
    coefficients of ``smoothed[t + 1]``, :func:`spline_coefficients`); ``border``: width
    of the invalid border.
    """

    smoothed: list
    gradients: list
    thresholds: list
    coefficients: list
    border: int


def prepare_level(frames, *, sigma, relative_threshold):
    """Filter one level's frames: smoothing, gradients, thresholds, spline coefficients.

    The threshold of pair ``t`` is ``relative_threshold x`` the 99th percentile of
    ``|grad I|`` of frame ``t`` inside the border, estimated on every other row and column
    (None when no pixel is inside the border).

    Parameters
    ----------
    frames : (T, H, W) ndarray

    Returns
    -------
    LevelFrames
    """
    smoothed = [smooth(frame, sigma) for frame in frames]
    border = default_border(sigma)
    height, width = smoothed[0].shape
    gradients, thresholds = [], []
    for t in range(len(smoothed) - 1):
        gy, gx = np.gradient(smoothed[t])
        squared = (gx * gx + gy * gy)[border: height - border: 2, border: width - border: 2]
        # the 99th percentile of |grad I| is the square root of that of |grad I|**2
        thresholds.append(None if squared.size == 0 else
                          relative_threshold ** 2 * np.percentile(squared, 99.0))
        gradients.append((gx, gy))
    return LevelFrames(smoothed=smoothed, gradients=gradients, thresholds=thresholds,
                       coefficients=[spline_coefficients(s) for s in smoothed[1:]],
                       border=border)


@dataclass(frozen=True)
class PairSample:
    """The sampled pixels of one frame pair ``(t, t + 1)`` on one level.

    ``x, y`` are pixel coordinates in frame ``t``; ``s0`` the smoothed frame ``t`` there,
    ``gx0, gy0`` its central differences, ``s1`` the smoothed frame ``t + 1`` at the same
    pixels (unwarped); ``coefficients`` the cubic-spline coefficients of the smoothed frame
    ``t + 1`` (:func:`spline_coefficients`), sampled after warping. All but
    ``coefficients`` have shape ``(n,)``.
    """

    x: np.ndarray
    y: np.ndarray
    s0: np.ndarray
    gx0: np.ndarray
    gy0: np.ndarray
    s1: np.ndarray
    coefficients: np.ndarray


def _every(candidates, count):
    """At most ``count`` of ``candidates`` (flat indices in row-major order), evenly spread."""
    if candidates.size <= count:
        return candidates
    return candidates[np.linspace(0, candidates.size - 1, count).round().astype(np.int64)]


def sample_pairs(level, regions, ratio, *, max_pixels):
    """The sampled pixels of every frame pair of one level, for one object.

    Candidates of pair ``t`` are the pixels of frame ``t`` inside the border whose
    ``|grad I|`` reaches the level's threshold, inside ``regions[t]`` (the object's pixels in
    frame ``t`` on a level ``ratio`` times coarser); at most ``max_pixels`` of them, evenly
    spread in row-major order, are kept.

    Parameters
    ----------
    level : LevelFrames
    regions : list of (h, w) ndarray of bool
        One per pair.
    ratio : int

    Returns
    -------
    list of PairSample or None
        One per pair (None: no pixel inside the border).
    """
    border = level.border
    height, width = level.smoothed[0].shape
    inner = (slice(border, height - border), slice(border, width - border))
    samples = []
    for t, (gx, gy) in enumerate(level.gradients):
        if level.thresholds[t] is None:
            samples.append(None)
            continue
        squared = (gx * gx + gy * gy)[inner]
        keep = (squared >= level.thresholds[t]) & (squared > 0)
        keep &= upsample_mask(regions[t], ratio, (height, width))[inner]
        rows, cols = np.nonzero(keep)
        chosen = _every(np.arange(rows.size), max_pixels)
        rows, cols = rows[chosen] + border, cols[chosen] + border
        s0, s1 = level.smoothed[t], level.smoothed[t + 1]
        samples.append(PairSample(
            x=cols.astype(float), y=rows.astype(float), s0=s0[rows, cols],
            gx0=gx[rows, cols], gy0=gy[rows, cols], s1=s1[rows, cols],
            coefficients=level.coefficients[t]))
    return samples


# edge padding of the spline coefficients, as scipy's map_coordinates pads (mode "nearest")
SPLINE_PAD = 12


def spline_coefficients(image):
    """Cubic-spline coefficients of ``image`` (H, W) for :func:`sampled_equations`, padded by
    :data:`SPLINE_PAD` edge pixels each side exactly as ``scipy.ndimage.map_coordinates(...,
    order=3, mode="nearest")`` pads before filtering, so that sampling them equals that call.

    Returns
    -------
    (H + 2 SPLINE_PAD, W + 2 SPLINE_PAD) ndarray of float64
    """
    padded = np.pad(np.asarray(image, dtype=float), SPLINE_PAD, mode="edge")
    return ndimage.spline_filter(padded, order=3, mode="nearest")


# offsets of the five samples of frame t + 1 per pixel: the pixel and its 4 neighbours
_OFFSETS = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]], dtype=float)


def sampled_equations(sample, matrix, centre, *, border):
    """The rows of :func:`replication.motion.irc._warped_equations` at sampled pixels.

    Frame ``t + 1`` is read at the warped places of each pixel and of its four neighbours
    (cubic spline), which gives the warped frame and its central differences exactly as the
    dense version computes them on the whole warped image.

    Parameters
    ----------
    sample : PairSample
    matrix : (3, 3) ndarray
        Current rigid map of a point of frame t to frame t + 1.
    centre : (2,) ndarray
        ``(x, y)`` about which the rows' ``domega`` turns.
    border : int
        Warped places closer than this to the frame's edge are left out.

    Returns
    -------
    a : (n, 3) ndarray
    b, static : (n,) ndarray
    keep : (n_sample,) ndarray of bool
        The sampled pixels the rows belong to.
        Normal-flow residual after warping, and without warping (standing still).
    """
    height, width = (size - 2 * SPLINE_PAD for size in sample.coefficients.shape)
    x = sample.x[None, :] + _OFFSETS[:, :1]
    y = sample.y[None, :] + _OFFSETS[:, 1:]
    xw = matrix[0, 0] * x + matrix[0, 1] * y + matrix[0, 2]
    yw = matrix[1, 0] * x + matrix[1, 1] * y + matrix[1, 2]
    values = ndimage.map_coordinates(
        sample.coefficients, [yw.ravel() + SPLINE_PAD, xw.ravel() + SPLINE_PAD], order=3,
        mode="nearest", prefilter=False).reshape(xw.shape)
    gx = 0.5 * (sample.gx0 + 0.5 * (values[1] - values[2]))
    gy = 0.5 * (sample.gy0 + 0.5 * (values[3] - values[4]))
    gt = values[0] - sample.s0
    inside = ((xw[0] >= border) & (xw[0] <= width - 1 - border) & (yw[0] >= border)
              & (yw[0] <= height - 1 - border))
    g = np.hypot(gx, gy)
    keep = inside & (g > 0)
    g, gx, gy = g[keep], gx[keep], gy[keep]
    X, Y = sample.x[keep] - centre[0], sample.y[keep] - centre[1]
    a = np.stack([(gy * X - gx * Y) / g, gx / g, gy / g], axis=1)
    return a, -gt[keep] / g, (sample.s0 - sample.s1)[keep] / g, keep


def refine_sampled(samples, matrix, *, border, tukey_c=1.0, max_iter=10, tol=1e-7,
                   spread=False):
    """The warping refinement of :func:`replication.motion.irc.refine` on sampled pixels.

    Parameters
    ----------
    samples : list of PairSample
        From :func:`sample_pairs` (``None`` entries are skipped).
    matrix : (3, 3) ndarray
        Starting rigid map of a point of frame t to frame t + 1.
    border : int
        Warped places closer than this to the frame's edge are left out.
    tukey_c, max_iter, tol
        As in :func:`~replication.motion.irc.refine`.
    spread : bool
        Also return the block-jackknife ``spread`` of the last step
        (:func:`~replication.motion.irc.rigid_spread`, tiles of ``irc.SPREAD_TILE`` pixels).

    Returns
    -------
    dict
        ``matrix`` (refined), ``iterations``, ``pixels`` (equations with a non-zero weight
        in the last iteration), and with ``spread`` the ``spread`` (or ``None``).
    """
    iterations, used = 0, 0
    for _ in range(max_iter):
        iterations += 1
        centre = np.array(irc.matrix_to_irc(matrix)[:2])
        rows_a, rows_b, weights, kept = [], [], [], []
        for sample in samples:
            if sample is None or sample.x.size == 0:
                continue
            a, b, static, keep = sampled_equations(sample, matrix, centre, border=border)
            rows_a.append(a)
            rows_b.append(b)
            weights.append(irc.tukey_weights(b, tukey_c) * (np.abs(b) <= np.abs(static)))
            kept.append((sample, keep))
        if not rows_a:
            break
        a, b, w = np.concatenate(rows_a), np.concatenate(rows_b), np.concatenate(weights)
        used = int(np.count_nonzero(w))
        if used < 3:
            break
        update, d_omega, shift = irc.rigid_update(a, b, w, centre)
        last = (a, b, w, kept, matrix, centre)
        matrix = matrix @ update
        if abs(d_omega) < tol and shift < 1000 * tol:
            break
    found = {"matrix": matrix, "iterations": iterations, "pixels": used}
    if spread:  # the tiles of the last step's rows, only when asked (the finest level)
        found["spread"] = None
        if used >= 3:
            a, b, w, kept, start, centre = last
            tiles = np.concatenate([irc.spread_tiles(sample.x[keep], sample.y[keep])
                                    for sample, keep in kept])
            found["spread"] = irc.rigid_spread(a, b, w, tiles, start, centre)
    return found


def refine_levels(pyramid, starts, regions, settings):
    """Refine rotations found on the top level on every finer level down to the input.

    Each level's frames are filtered once (:func:`prepare_level`) for all the objects.

    Parameters
    ----------
    pyramid : list of (T, H_k, W_k) ndarray
        From :func:`levels`; ``starts`` and ``regions`` belong to ``pyramid[-1]``.
    starts : list of dict
        Per object, ``xi, eta, omega`` in pixels of the top level.
    regions : list of (h, w) ndarray of bool
        Per object, its pixels in frame 0 of the top level.
    settings : dict
        ``sigma``, ``refine_threshold``, ``tukey_c``, ``refine_pixels``,
        ``level_iterations`` (see :data:`replication.motion.single.DEFAULTS`).

    Returns
    -------
    list of dict
        Per object: ``xi, eta, omega`` (input pixels), ``iterations`` (summed over levels),
        ``pixels`` (equations used on the input level) and ``levels``: per refined level,
        coarse to fine, ``{factor, shape, iterations, pixels, xi, eta, omega}`` (input
        pixels).
    """
    top = len(pyramid) - 1
    factor = 2 ** top
    current = [(start["xi"], start["eta"], start["omega"]) for start in starts]
    answers = [{"iterations": 0, "pixels": 0, "levels": []} for _ in starts]
    for k in range(top - 1, -1, -1):
        level_factor = 2 ** k
        level = prepare_level(pyramid[k], sigma=settings["sigma"],
                              relative_threshold=settings["refine_threshold"])
        for index, (xi, eta, omega) in enumerate(current):
            # the same point of the scene, from the level above to this one
            xi = to_level(to_input(xi, 2 * level_factor), level_factor)
            eta = to_level(to_input(eta, 2 * level_factor), level_factor)
            # the object's region of frame 0 carried to each frame, on the top level
            on_top = irc.rigid_matrix(to_level(to_input(xi, level_factor), factor),
                                      to_level(to_input(eta, level_factor), factor), omega)
            moved = [irc.move_region(regions[index], on_top, t)
                     for t in range(len(level.gradients))]
            samples = sample_pairs(level, moved, factor // level_factor,
                                   max_pixels=int(settings["refine_pixels"]))
            found = refine_sampled(samples, irc.rigid_matrix(xi, eta, omega),
                                   border=level.border, tukey_c=settings["tukey_c"],
                                   max_iter=int(settings["level_iterations"]),
                                   spread=k == 0)
            current[index] = irc.matrix_to_irc(found["matrix"])
            answer = answers[index]
            if k == 0:
                answer["spread"] = found["spread"]
            answer["iterations"] += found["iterations"]
            answer["pixels"] = found["pixels"]
            answer["levels"].append({
                "factor": level_factor, "shape": list(pyramid[k].shape[1:]),
                "iterations": found["iterations"], "pixels": found["pixels"],
                "xi": to_input(current[index][0], level_factor),
                "eta": to_input(current[index][1], level_factor),
                "omega": current[index][2]})
    for (xi, eta, omega), answer in zip(current, answers):
        answer.update(xi=float(xi), eta=float(eta), omega=float(omega))
    return answers
