"""One rotation centre end to end: the paper's accumulation (2.2), then the refinement.

``accumulation: exact`` (the default) votes at full resolution, as the paper does;
``accumulation: pyramid`` votes on a reduced copy of the frames and refines level by level
(:mod:`replication.motion.pyramid`), for frames of any size.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import ndimage

from replication.errors import InputError
from replication.motion import irc, pyramid
from replication.motion.derivatives import sequence_derivatives

DEFAULTS = {
    "sigma": 1.5,                 # Gaussian pre-smoothing, pixels
    "relative_threshold": 0.3,    # gradient norm >= this x its 99th percentile
    "refine_threshold": 0.15,     # the same inside the refinement's region
    "omega_min": -0.05,           # the paper's sweep, rad/frame
    "omega_max": 0.05,
    "omega_count": 100,           # 0 excluded
    "margin": 0.0,                # accumulator beyond the image, pixels
    "cell": 1.0,                  # accumulator cell, pixels
    "region_tol": 3.0,            # a pixel verifies the equation: line within this, pixels
    "blob_sigma": 3.0,            # blob detection window, pixels
    "blob_level": 0.3,            # fraction of verifying pixels in the window
    "region_erode": None,         # erode the region before refining, pixels (None: 3 sigma)
    "tukey_c": 1.0,               # refinement: normal-flow residual scale, pixels/frame
    "rounds": 2,                  # refinement rounds (region re-detected between rounds)
    "coarse_count": 24,           # fast variant: omega values of the coarse sweep
    "coarse_cell": 2.0,           # fast variant: accumulator cell, pixels
    "accumulation": "exact",      # exact: the paper's, at full resolution | pyramid
    "coarse_side": 256,           # pyramid: vote on the first level with sides <= this
    "refine_pixels": 50000,       # pyramid: sampled pixels per frame pair on finer levels
    "level_iterations": 10,       # pyramid: warping iterations per finer level
}

ACCUMULATIONS = ("exact", "pyramid")


def settings_from(method):
    """:data:`DEFAULTS` updated by a config's ``method`` block (dict or None).

    Raises
    ------
    InputError
        For a key that is not a setting of the method.
    """
    method = dict(method or {})
    unknown = sorted(set(method) - set(DEFAULTS))
    if unknown:
        raise InputError(f"method: unknown setting(s) {unknown}; expected some of "
                         + ", ".join(DEFAULTS))
    settings = dict(DEFAULTS)
    settings.update(method)
    if settings["accumulation"] not in ACCUMULATIONS:
        raise InputError(f"method.accumulation={settings['accumulation']!r}: expected one of "
                         + ", ".join(ACCUMULATIONS))
    for key, low in (("coarse_side", 32), ("refine_pixels", 100), ("level_iterations", 1)):
        value = settings[key]
        if not isinstance(value, int) or isinstance(value, bool) or value < low:
            raise InputError(f"method.{key}={value!r}: expected an integer >= {low}")
    return settings


def warm_up():
    """Compile (or load from numba's cache) the voting kernels before anything is timed."""
    frames = np.random.default_rng(0).random((2, 48, 48))
    paper_method(frames, settings_from({"omega_count": 4}))


def paper_method(frames, settings):
    """The paper's accumulation: derivatives, threshold, sweep, best peak.

    Parameters
    ----------
    frames : (T, H, W) ndarray
    settings : dict
        Keys of :data:`DEFAULTS`.

    Returns
    -------
    estimate : dict
        ``{xi, eta, omega, peak}`` at the best peak.
    table : dict
        ``F(omega)``: ``omega, xi, eta, peak, votes`` arrays of shape ``(m,)``.
    pixels : PixelDerivatives
    grid : Grid
    """
    pixels = sequence_derivatives(frames, sigma=settings["sigma"],
                                  relative_threshold=settings["relative_threshold"])
    grid = irc.image_grid(frames.shape[1:], margin=settings["margin"], cell=settings["cell"])
    omegas = irc.omega_sweep(settings["omega_min"], settings["omega_max"],
                             int(settings["omega_count"]))
    table = irc.sweep(pixels, omegas, grid)
    return irc.paper_estimate(table), table, pixels, grid


def erode(region, radius):
    """``region`` (H, W) bool eroded by a disc of ``radius`` pixels.

    Smoothing mixes the object with the static background within about ``3 sigma`` of
    its edge; those pixels move partly and would bias the refinement towards no motion.
    """
    radius = int(round(radius))
    if radius <= 0:
        return region
    rows, cols = np.mgrid[-radius: radius + 1, -radius: radius + 1]
    return ndimage.binary_erosion(region, rows ** 2 + cols ** 2 <= radius ** 2)


def refined_method(frames, start, pixels, settings):
    """Refinement from the paper's estimate ``start``: blob region, warping, robust LS.

    The region is eroded by ``region_erode`` pixels before use. The first round's region
    is the blob of pixels verifying the IRC equation at ``start`` (paper Fig. 4); later
    rounds re-detect it as the blob of pixels that follow the refined motion after warping
    better than standing still.

    Returns
    -------
    dict
        ``xi, eta, omega, iterations, pixels`` and ``region`` ((H, W) bool, the last one).
    """
    shape = frames.shape[1:]
    region = irc.blob_region(pixels, start["xi"], start["eta"], start["omega"], shape,
                             tol=settings["region_tol"], blob_sigma=settings["blob_sigma"],
                             level=settings["blob_level"])
    current = dict(start)
    iterations = 0
    erosion = settings["region_erode"]
    erosion = math.ceil(3 * settings["sigma"]) if erosion is None else erosion
    for round_index in range(int(settings["rounds"])):
        if round_index > 0:
            region = irc.density_blob(current["consistent"], current["gradient"],
                                      blob_sigma=settings["blob_sigma"],
                                      level=settings["blob_level"])
        current = irc.refine(frames, current["xi"], current["eta"], current["omega"],
                             erode(region, erosion),
                             sigma=settings["sigma"],
                             relative_threshold=settings["refine_threshold"],
                             tukey_c=settings["tukey_c"])
        iterations += current["iterations"]
    return {"xi": current["xi"], "eta": current["eta"], "omega": current["omega"],
            "iterations": iterations, "pixels": current["pixels"], "region": region,
            "spread": current.get("spread")}


def find_rotation(frames, settings):
    """Paper estimate, refined estimate and timings for one sequence.

    ``settings["accumulation"] == "pyramid"`` hands over to :func:`pyramid_rotation`.

    Returns
    -------
    dict
        ``paper`` ({xi, eta, omega, peak}), ``refined`` ({xi, eta, omega, iterations,
        pixels}), ``seconds`` ({paper, refined}), and the working arrays ``table``,
        ``pixels``, ``grid``, ``region``.
    """
    if settings["accumulation"] == "pyramid":
        return pyramid_rotation(frames, settings)
    start = time.perf_counter()
    paper, table, pixels, grid = paper_method(frames, settings)
    middle = time.perf_counter()
    refined = refined_method(frames, paper, pixels, settings)
    end = time.perf_counter()
    region = refined.pop("region")
    return {"paper": paper, "refined": refined,
            "seconds": {"paper": middle - start, "refined": end - middle},
            "table": table, "pixels": pixels, "grid": grid, "region": region}


def pyramid_rotation(frames, settings):
    """Coarse to fine: the paper's accumulation and refinement on the top level of a
    pyramid, then the sampled refinement on every finer level (beyond the paper).

    The top level is the first whose sides are at most ``coarse_side`` pixels (or whose
    shorter side would next fall under ``coarse_side // 2``:
    :func:`replication.motion.pyramid.top_shape`), so the
    accumulator and the number of voting pixels do not grow with the frames; ``cell`` is in
    pixels of that level, ``margin`` in input pixels (divided by the level's factor).
    Frames no larger than ``coarse_side`` give exactly the ``exact`` method's answer.

    Parameters
    ----------
    frames : (T, H, W) ndarray
    settings : dict
        Keys of :data:`DEFAULTS` (``coarse_side``, ``refine_pixels``, ``level_iterations``
        and those of the exact method).

    Returns
    -------
    dict
        As :func:`find_rotation`, in input pixels: ``paper`` (the top level's best peak),
        ``refined`` (after the input level), ``seconds`` ({pyramid, paper, refined}:
        building the pyramid, accumulation on the top level, refinement on every level),
        ``table`` and ``grid`` (the top level's sweep and accumulator, in input pixels),
        ``pixels`` and ``region`` (the top level's voting pixels and region, in its own
        pixels), and ``pyramid``: ``factor``, ``shapes`` (per level), ``levels`` (the
        answer after each finer level, see :func:`~replication.motion.pyramid.
        refine_levels`) and ``top`` (the top level's ``frames``, ``paper``, ``refined``,
        ``table`` and ``grid`` in its own pixels, for drawing).
    """
    start = time.perf_counter()
    levels = pyramid.levels(frames, int(settings["coarse_side"]))
    factor = 2 ** (len(levels) - 1)
    built = time.perf_counter()
    top_settings = dict(settings, margin=settings["margin"] / factor)
    paper, table, pixels, grid = paper_method(levels[-1], top_settings)
    voted = time.perf_counter()
    top = refined_method(levels[-1], paper, pixels, top_settings)
    region = top.pop("region")
    erosion = settings["region_erode"]
    erosion = math.ceil(3 * settings["sigma"]) if erosion is None else erosion
    fine = pyramid.refine_levels(levels, [top], [erode(region, erosion)], settings)[0]
    end = time.perf_counter()
    refined = {key: fine[key] for key in ("xi", "eta", "omega", "iterations", "pixels")}
    refined["iterations"] += top["iterations"]
    refined["spread"] = fine.get("spread")
    if factor == 1:
        refined = dict(top)
    in_input = {"xi": float(pyramid.to_input(paper["xi"], factor)),
                "eta": float(pyramid.to_input(paper["eta"], factor)),
                "omega": paper["omega"], "peak": paper["peak"]}
    table_input = dict(table, xi=pyramid.to_input(table["xi"], factor),
                       eta=pyramid.to_input(table["eta"], factor))
    return {"paper": in_input, "refined": refined,
            "seconds": {"pyramid": built - start, "paper": voted - built,
                        "refined": end - voted},
            "table": table_input, "grid": pyramid.grid_in_input(grid, factor),
            "pixels": pixels, "region": region,
            "pyramid": {"factor": factor,
                        "shapes": [list(level.shape[1:]) for level in levels],
                        "levels": fine["levels"],
                        "top": {"frames": levels[-1], "paper": paper, "refined": top,
                                "table": table, "grid": grid}}}


def coarse_then_refined(frames, settings):
    """The fast variant: a coarse sweep (``coarse_count`` values of omega, cells of
    ``coarse_cell`` pixels) as the starting point of the same refinement.

    The refinement corrects omega and the centre, so the start need only be close; the
    coarse sweep casts about ``(100 / 24) x 2 x 2 = 8`` times fewer votes than the paper's.

    Returns
    -------
    dict
        ``coarse`` (its best peak), ``refined`` and ``seconds`` ({coarse, refined}).
    """
    coarse_settings = dict(settings, omega_count=settings["coarse_count"],
                           cell=settings["coarse_cell"])
    start = time.perf_counter()
    coarse, _, pixels, _ = paper_method(frames, coarse_settings)
    middle = time.perf_counter()
    refined = refined_method(frames, coarse, pixels, settings)
    end = time.perf_counter()
    refined.pop("region")
    return {"coarse": coarse, "refined": refined,
            "seconds": {"coarse": middle - start, "refined": end - middle}}


def errors(estimate, truth):
    """Centre error (pixels), omega error and |omega| error (% of the true |omega|).

    ``omega_pct = 100 (omega - omega_true) / |omega_true|``;
    ``omega_magnitude_pct = 100 (|omega| - |omega_true|) / |omega_true|`` (positive: the
    rotation speed is overestimated, whatever its sign).
    """
    centre = float(np.hypot(estimate["xi"] - truth["xi"], estimate["eta"] - truth["eta"]))
    scale = abs(truth["omega"])
    omega = float(100.0 * (estimate["omega"] - truth["omega"]) / scale)
    magnitude = float(100.0 * (abs(estimate["omega"]) - scale) / scale)
    return {"centre_px": centre, "omega_pct": omega, "omega_magnitude_pct": magnitude}
