"""Rigid-motion segmentation, the whole of paper 2.3: discs, snakes, restricted accumulation.

1. The EA of 2.3.2 (:mod:`replication.motion.segment.disc_ea`) gives discs with rotations; its final
   20% best are kept, and those better explained by no motion than by their rotation are
   dropped (the static background).
2. Each disc grows into a region by a radial snake (2.3.3,
   :mod:`replication.motion.segment.snakes`).
   With ``snake.rounds = 2`` (not in the paper, whose order is ``rounds = 1``) the snake
   is run a second time from the same disc with the rotation refined by step 3, then step 3
   again: an EA disc's rotation is often only roughly right, which stops its snake early.
3. Each region's rotation is re-estimated by the accumulation of 2.2 (``irc.sweep``) with
   votes from the region's pixels only, over ``omega`` values around the disc's ``omega``
   (2.3.4); regions whose refined rotations share a centre (and speed) are one object,
   whose rotation is accumulated again over the union of its regions. Optionally (beyond
   the paper) that rotation is refined by ``irc.refine`` (iterative warping), and the
   object's mask grown by snakes from extra seeds (:func:`grow_from_seeds`).
4. Optionally (``assign.enabled``, beyond the paper) every object's mask is replaced by a
   per-pixel assignment of the pixels to the motions found (:mod:`.assignment`), and its
   rotation accumulated again over that mask (:func:`assign_pixels`).

With ``pyramid.enabled`` (beyond the paper; frames of any size) steps 1-4 run on the top
level of a pyramid and each object's rotation is refined level by level up to the input
(:func:`segment_pyramid`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from replication.errors import InputError
from replication.motion import irc, pyramid
from replication.motion.derivatives import PixelDerivatives
from replication.motion.segment import assignment, disc_ea, snakes

SNAKE_DEFAULTS = {"tolerance": 0.3, "ambiguous": 0.15, "empty_cost": 0.2,
                  "ambiguous_cost": 0.0, "n_sectors": 64,
                  "rho_max": 120, "kappa": 0.05, "steps": [8, 4, 2, 1], "iterations": 20,
                  "deflate": False, "rounds": 1}
ACCUMULATION_DEFAULTS = {
    "omega_window": 0.5,      # explore omega_i (1 -/+ this), and at least +/- omega_step
    "omega_step": 0.005,
    "omega_count": 41,
    "cell": 1.0,              # accumulator cell, pixels
    "window": 40.0,           # accumulator: the region's bounding box plus this, pixels
    "min_pixels": 50,         # regions with fewer voting pixels are dropped
    "max_pixels": 4000,       # at most this many voting pixels (evenly strided), for speed
    "refine": False,          # not in the paper: irc.refine (warping) after the accumulation
    "refine_max_px": 5.0,     # ... kept only if it moves the centre less than this, pixels
}
MERGE_DEFAULTS = {"centre_px": 8.0, "omega_rel": 0.25, "min_area": 150,
                  "extra_seeds": 0,        # not in the paper: extra snakes per object (below)
                  "seed_sigma": 4.0,      # pixels
                  "seed_density": 0.5}
PYRAMID_DEFAULTS = {          # not in the paper: frames of any size (segment_pyramid)
    "enabled": False,
    "coarse_side": 256,       # segment the first pyramid level with sides <= this, pixels
    "refine_pixels": 50000,   # sampled pixels per frame pair and object on finer levels
    "level_iterations": 10,   # warping iterations per finer level
    "refine_threshold": 0.15,  # gradient >= this x its 99th percentile, on finer levels
    "tukey_c": 1.0,           # normal-flow residual scale, pixels/frame
}
# the additions to the paper that the study's "pipeline" uses; "faithful" switches them off
FAITHFUL = {"ea": {"project_fresh": False, "reject_static": False},
            "snake": {"deflate": False, "rounds": 1},
            "accumulation": {"refine": False}, "merge": {"extra_seeds": 0},
            "assign": {"enabled": False}}
GROUPS = {"ea": disc_ea.DEFAULTS, "snake": SNAKE_DEFAULTS,
          "accumulation": ACCUMULATION_DEFAULTS, "merge": MERGE_DEFAULTS,
          "assign": assignment.DEFAULTS, "pyramid": PYRAMID_DEFAULTS}


def settings_from(method):
    """Defaults of every step updated by a config's ``method`` block.

    ``method`` is ``{search: paper|nichega, ea: {...}, snake: {...}, accumulation: {...},
    merge: {...}, assign: {...}, pyramid: {...}, nichega: {...}}``; unknown groups or keys
    are refused.

    Raises
    ------
    InputError
        Naming the unknown key and the known ones.
    """
    method = dict(method or {})
    settings = {"search": method.pop("search", "paper"), "nichega": method.pop("nichega", {})}
    if settings["search"] not in ("paper", "nichega"):
        raise InputError(f"method.search: '{settings['search']}'; expected paper or nichega")
    unknown = sorted(set(method) - set(GROUPS))
    if unknown:
        raise InputError(f"method: unknown group(s) {unknown}; expected some of "
                         + ", ".join([*GROUPS, "search", "nichega"]))
    for group, defaults in GROUPS.items():
        given = dict(method.get(group) or {})
        bad = sorted(set(given) - set(defaults))
        if bad:
            raise InputError(f"method.{group}: unknown setting(s) {bad}; expected some of "
                             + ", ".join(defaults))
        settings[group] = {**defaults, **given}
    _check_ranges(settings)
    try:
        disc_ea.check_settings(settings["ea"])
    except ValueError as error:
        raise InputError(f"method.ea.{error}") from None
    try:
        assignment.check_settings(settings["assign"])
    except ValueError as error:
        raise InputError(f"method.assign.{error}") from None
    return settings


# settings that count something: integers >= 1
COUNTS = {"snake": ("n_sectors", "iterations", "rounds", "rho_max"),
          "accumulation": ("omega_count", "max_pixels")}


def _check_ranges(settings):
    """Numbers of the snake, accumulation and merge groups are >= 0, counts >= 1, the
    restricted sweep at most ``limits.max_sweep_values`` values."""
    from replication.guard import LIMITS

    for group in ("snake", "accumulation", "merge"):
        for key, value in settings[group].items():
            if isinstance(value, bool) or key == "steps":
                continue
            where = f"method.{group}.{key}={value!r}"
            if key in COUNTS.get(group, ()):
                if not (isinstance(value, int) and value >= 1):
                    raise InputError(f"{where}: expected an integer >= 1")
            elif isinstance(value, (int, float)) and not (math.isfinite(value) and value >= 0):
                raise InputError(f"{where}: expected a finite number >= 0")
    for key, low in (("coarse_side", 32), ("refine_pixels", 100), ("level_iterations", 1)):
        value = settings["pyramid"][key]
        if not isinstance(value, int) or isinstance(value, bool) or value < low:
            raise InputError(f"method.pyramid.{key}={value!r}: expected an integer >= {low}")
    threshold, tukey = settings["pyramid"]["refine_threshold"], settings["pyramid"]["tukey_c"]
    if not (isinstance(threshold, (int, float)) and 0 < threshold < 1):
        raise InputError(f"method.pyramid.refine_threshold={threshold!r}: expected a fraction "
                         "in (0, 1)")
    if not (isinstance(tukey, (int, float)) and math.isfinite(tukey) and tukey > 0):
        raise InputError(f"method.pyramid.tukey_c={tukey!r}: expected a number > 0")
    if not isinstance(settings["pyramid"]["enabled"], bool):
        raise InputError(f"method.pyramid.enabled={settings['pyramid']['enabled']!r}: "
                         "expected true or false")
    count, limit = settings["accumulation"]["omega_count"], LIMITS["max_sweep_values"]
    if count > limit:
        raise InputError(f"method.accumulation.omega_count={count}: expected at most "
                         f"limits.max_sweep_values={limit:g}")


def dense_to_pixels(data):
    """The used pixels of :class:`~replication.motion.segment.disc_ea.DiscData` as
    :class:`~replication.motion.derivatives.PixelDerivatives` (pair by pair, row-major)."""
    pair, rows, cols = np.nonzero(data.used)
    return PixelDerivatives(x=cols.astype(float), y=rows.astype(float),
                            gx=data.gx[pair, rows, cols], gy=data.gy[pair, rows, cols],
                            gt=data.gt[pair, rows, cols], pair=pair.astype(np.int64))


def _subset(pixels, keep):
    return PixelDerivatives(pixels.x[keep], pixels.y[keep], pixels.gx[keep], pixels.gy[keep],
                            pixels.gt[keep], pixels.pair[keep])


def omega_values(omega, settings):
    """The restricted sweep around ``omega``: ``(omega_count,)`` values, none of them 0."""
    half = max(settings["omega_window"] * abs(omega), settings["omega_step"])
    values = np.linspace(omega - half, omega + half, int(settings["omega_count"]))
    return values[np.abs(values) > 1e-6]


def window_grid(mask, shape, settings, margin):
    """Accumulator over the bounding box of ``mask`` plus ``window`` pixels (within the
    image plus ``margin``)."""
    rows, cols = np.nonzero(mask)
    height, width = shape
    pad, cell = settings["window"], settings["cell"]
    x0 = max(cols.min() - pad, -margin)
    y0 = max(rows.min() - pad, -margin)
    x1 = min(cols.max() + pad, width - 1 + margin)
    y1 = min(rows.max() + pad, height - 1 + margin)
    return irc.Grid(x0=float(x0), y0=float(y0), cell=float(cell),
                    nx=int(math.floor((x1 - x0) / cell)) + 1,
                    ny=int(math.floor((y1 - y0) / cell)) + 1)


def restricted_accumulation(pixels, mask, omega, settings, *, margin, omegas=None):
    """Paper 2.3.4: the accumulation of 2.2 with the votes of ``mask``'s pixels only.

    Parameters
    ----------
    pixels : PixelDerivatives
        All pixels with a sufficient gradient.
    mask : (H, W) ndarray of bool
    omega : float
        The region's starting rotation speed (non-zero).
    settings : dict
        :data:`ACCUMULATION_DEFAULTS` keys.
    margin : float
        How far outside the image a centre may lie, pixels.
    omegas : (m,) array_like, optional
        The sweep instead of the one around ``omega`` (:func:`omega_values`).

    Returns
    -------
    dict or None
        ``xi, eta, omega, peak, pixels`` and the ``grid``; None if the region has fewer than
        ``min_pixels`` voting pixels.
    """
    inside = mask[pixels.y.astype(np.int64), pixels.x.astype(np.int64)]
    if np.count_nonzero(inside) < settings["min_pixels"]:
        return None
    index = np.flatnonzero(inside)
    index = index[:: max(1, -(-index.size // int(settings["max_pixels"])))]
    chosen = _subset(pixels, index)
    grid = window_grid(mask, mask.shape, settings, margin)
    if omegas is None:
        omegas = omega_values(omega, settings)
    best = irc.paper_estimate(irc.sweep(chosen, omegas, grid))
    best["pixels"] = int(np.count_nonzero(inside))
    best["grid"] = grid
    return best


def merge_groups(estimates, settings):
    """Groups of regions sharing a centre: union-find on ``|centre difference| <=
    centre_px`` and ``|omega difference| <= omega_rel * max |omega|``.

    Returns
    -------
    list of list of int
        Region indices per group, in order of first member.
    """
    parent = list(range(len(estimates)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, a in enumerate(estimates):
        for j in range(i):
            b = estimates[j]
            near = math.hypot(a["xi"] - b["xi"], a["eta"] - b["eta"]) <= settings["centre_px"]
            speed = abs(a["omega"] - b["omega"]) <= settings["omega_rel"] * max(
                abs(a["omega"]), abs(b["omega"]))
            if near and speed:
                parent[root(i)] = root(j)
    groups = {}
    for i in range(len(estimates)):
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


def _refined(frames, found, settings):
    """The other motion module's warping refinement of one object's rotation (beyond the
    paper: it removes the accumulation's bias on omega); ``{}`` if it fails or moves the
    centre by more than ``refine_max_px``."""
    ea = settings["ea"]
    better = irc.refine(frames, found["xi"], found["eta"], found["omega"], found["mask"],
                        sigma=ea["sigma"], relative_threshold=ea["relative_threshold"])
    values = [better["xi"], better["eta"], better["omega"]]
    moved = math.hypot(better["xi"] - found["xi"], better["eta"] - found["eta"])
    if not all(math.isfinite(v) for v in values) or moved > \
            settings["accumulation"]["refine_max_px"]:
        return {}
    return {"xi": better["xi"], "eta": better["eta"], "omega": better["omega"],
            "spread": better["spread"]}


def grow_from_seeds(data, found, settings):
    """Extra radial snakes for one object (not in the paper; ``extra_seeds = 0`` is the
    paper): a radial snake is star-shaped around its centre and cannot cover a C-shape from
    one disc. With the object's final rotation, the pixels that follow it but lie outside
    its mask are smoothed by a Gaussian of ``seed_sigma`` pixels; where that density peaks
    above ``seed_density``, a snake starts from a small disc and its region joins the mask.

    Returns
    -------
    mask : (H, W) ndarray of bool
    """
    from scipy import ndimage

    merge, snake = settings["merge"], dict(settings["snake"])
    snake.pop("rounds", None)
    snake["steps"] = tuple(int(v) for v in snake["steps"])
    mask = found["mask"].copy()
    score = snakes.support(data, found["xi"], found["eta"], found["omega"],
                           tolerance=snake["tolerance"], ambiguous=snake["ambiguous"],
                           empty_cost=snake["empty_cost"],
                           ambiguous_cost=snake["ambiguous_cost"])
    for _ in range(int(merge["extra_seeds"])):
        density = ndimage.gaussian_filter(((score > 0.5) & ~mask).astype(float),
                                          merge["seed_sigma"])
        row, col = np.unravel_index(int(np.argmax(density)), density.shape)
        if density[row, col] < merge["seed_density"]:
            break
        start = [float(col), float(row), 2.0 * merge["seed_sigma"], found["xi"], found["eta"],
                 found["omega"]]
        mask |= snakes.radial_snake(data, start, **snake)["mask"]
    return mask


def _merged_objects(objects, settings):
    """Objects of one motion (:func:`merge_groups`) as one: the union of their masks, the
    rotation of the largest."""
    merged = []
    for group in merge_groups(objects, settings):
        members = sorted(group, key=lambda i: -objects[i]["area"])
        merged.append({**objects[members[0]], "mask": np.logical_or.reduce(
            [objects[i]["mask"] for i in members])})
    return merged


def rescued_objects(data, pixels, objects, settings, smoothed=None):
    """Objects the disc search missed (not in the paper; ``assign.rescue = 0`` is off).

    Each region that no motion found explains (:func:`assignment.unexplained_regions`) gets
    the paper's single-rotation accumulation (2.2) over its own pixels: a sweep of
    ``omega`` over the EA's bounds, then the restricted sweep around the best peak.
    ``smoothed``: :func:`assignment.smoothed_hypotheses` of ``objects``, if computed.

    Returns
    -------
    list of dict
        ``xi, eta, omega, peak, area, mask, regions ([]), grid``.
    """
    ea, acc = settings["ea"], settings["accumulation"]
    found = []
    for region in assignment.unexplained_regions(data, objects, settings["assign"],
                                                 smoothed):
        omegas = irc.omega_sweep(ea["omega_min"], ea["omega_max"], 2 * int(acc["omega_count"]))
        first = restricted_accumulation(pixels, region, 0.0, acc, margin=ea["margin"],
                                        omegas=omegas[np.abs(omegas) >= ea["omega_eps"]])
        if first is None:
            continue
        best = restricted_accumulation(pixels, region, first["omega"], acc,
                                       margin=ea["margin"])
        found.append({"xi": best["xi"], "eta": best["eta"], "omega": best["omega"],
                      "peak": best["peak"], "area": int(np.count_nonzero(region)),
                      "mask": region, "regions": [], "grid": best["grid"],
                      "accumulation": {k: best[k] for k in ("xi", "eta", "omega")}})
    return found


def assign_pixels(frames, data, pixels, objects, settings):
    """Step 4 (not in the paper): objects whose final rotations share a centre (and speed,
    as in :func:`merge_groups`) become one, with the union of their masks and the rotation
    of the largest; regions no motion explains may add objects (:func:`rescued_objects`,
    merged the same way); each object's mask then comes from :func:`assignment.assign`,
    and an object whose new mask has fewer than ``merge.min_area`` pixels or less than
    ``assign.keep_share`` of its former mask is dropped and the rest assigned again; with
    ``assign.reestimate`` its rotation is accumulated again over the new mask (then refined
    if ``accumulation.refine``).

    Returns
    -------
    list of dict
        The objects, with ``mask``, ``area`` and possibly ``xi, eta, omega, peak, grid``
        replaced; ``snake_mask`` holds the mask before.
    """
    objects = _merged_objects(objects, settings["merge"])
    smoothed = assignment.smoothed_hypotheses(data, objects, settings["assign"])
    rescued = rescued_objects(data, pixels, objects, settings, smoothed)
    if rescued:
        objects = _merged_objects(objects + rescued, settings["merge"])
        smoothed = None
    while True:   # a motion that keeps too little of its region is dropped; assign again
        masks = assignment.assign(data, objects, settings["assign"], smoothed)
        smoothed = None
        area = np.array([np.count_nonzero(m) for m in masks])
        keep = (area >= settings["merge"]["min_area"]) & (
            area >= settings["assign"]["keep_share"] * np.array(
                [np.count_nonzero(o["mask"]) for o in objects]))
        if keep.all():
            break
        objects = [o for o, k in zip(objects, keep) if k]
    kept = []
    for found, mask in zip(objects, masks):
        found = {**found, "mask": mask, "area": int(np.count_nonzero(mask)),
                 "snake_mask": found["mask"]}
        if settings["assign"]["reestimate"]:
            again = restricted_accumulation(pixels, mask, found["omega"],
                                            settings["accumulation"],
                                            margin=settings["ea"]["margin"])
            if again is not None:
                found.update({k: again[k] for k in ("xi", "eta", "omega", "peak", "grid")})
                if settings["accumulation"]["refine"]:
                    found.update(_refined(frames, found, settings))
        kept.append(found)
    return kept


def search_discs(data, settings, rng):
    """Step 1: the retained discs ``(n, 6)`` of the chosen search, and its evaluations."""
    if settings["search"] == "nichega":
        from replication.motion.segment.baselines import nichega_discs

        return nichega_discs(data, settings["ea"], settings["nichega"], rng)
    found = disc_ea.DiscEA(data, settings["ea"], rng=rng).run()
    return found["retained"], found["evaluations"]


def segment_pyramid(frames, settings, rng):
    """Coarse to fine (beyond the paper): :func:`segment` on the top level of a pyramid
    (:func:`replication.motion.pyramid.levels`, sides of at most ``pyramid.coarse_side``
    unless the shorter one would fall under half of it),
    then each object's rotation refined on every finer level up to the input
    (:func:`replication.motion.pyramid.refine_levels`, from its mask eroded by ``3 sigma``)
    and its mask carried to the input's pixels (nearest top-level pixel).

    Settings in pixels (disc radii, margins, windows, areas) are in top-level pixels. Frames
    no larger than ``coarse_side`` give exactly :func:`segment`'s answer.

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    settings : dict
        From :func:`settings_from` (``pyramid`` group).
    rng : numpy.random.Generator or int or None
        Drives the disc search only.

    Returns
    -------
    dict
        :func:`segment`'s keys, ``objects`` in input pixels (``mask`` (H, W), ``area``,
        ``xi, eta, omega`` refined, ``levels`` the answer after each finer level, ``top``
        the rotation found on the top level), the rest (``discs``, ``regions``,
        ``pixels``, ...) on the top level; ``seconds`` adds ``pyramid`` (building it) and
        ``levels`` (refining); ``pyramid``: ``factor``, ``shapes``, ``frames`` (the top
        level's) and ``top_objects`` (the objects on the top level, for drawing).
    """
    from replication.motion.single import erode

    start = time.perf_counter()
    options = settings["pyramid"]
    levels = pyramid.levels(frames, int(options["coarse_side"]))
    factor = 2 ** (len(levels) - 1)
    built = time.perf_counter()
    found = segment(levels[-1], {**settings, "pyramid": {**options, "enabled": False}}, rng)
    refined_at = time.perf_counter()
    top_objects = found["objects"]
    objects = top_objects
    if factor > 1:
        erosion = math.ceil(3 * settings["ea"]["sigma"])
        answers = pyramid.refine_levels(levels, top_objects,
                                        [erode(o["mask"], erosion) for o in top_objects],
                                        {**options, "sigma": settings["ea"]["sigma"]})
        objects = []
        for item, answer in zip(top_objects, answers):
            mask = pyramid.upsample_mask(item["mask"], factor, frames.shape[1:])
            objects.append({**item, "xi": answer["xi"], "eta": answer["eta"],
                            "omega": answer["omega"], "spread": answer.get("spread"),
                            "mask": mask,
                            "area": int(np.count_nonzero(mask)), "levels": answer["levels"],
                            "top": {k: float(item[k]) for k in ("xi", "eta", "omega")}})
    seconds = {"pyramid": built - start, **found["seconds"],
               "levels": time.perf_counter() - refined_at}
    return {**found, "objects": objects, "seconds": seconds,
            "pyramid": {"factor": factor, "shapes": [list(v.shape[1:]) for v in levels],
                        "frames": levels[-1], "top_objects": top_objects}}


def segment(frames, settings, rng):
    """The whole pipeline on one sequence (:func:`segment_pyramid` when
    ``pyramid.enabled``).

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    settings : dict
        From :func:`settings_from`.
    rng : numpy.random.Generator or int or None
        Drives the disc search only; the rest is deterministic.

    Returns
    -------
    dict
        ``objects``: list of ``{xi, eta, omega, area, mask ((H, W) bool), peak, regions}``
        (with ``assign.enabled`` also ``snake_mask``, the mask before the assignment);
        ``discs`` (retained, (n, 6)), ``rotating`` ((n,) bool), ``regions`` (per rotating
        disc: snake ``rho``, ``centre``, ``mask``, refined estimate or None), ``seconds``
        per step (search, snakes, accumulation, assign), ``evaluations``.
    """
    if settings["pyramid"]["enabled"]:
        return segment_pyramid(frames, settings, rng)
    ea = settings["ea"]
    clock = [time.perf_counter()]
    data = disc_ea.disc_data(frames, sigma=ea["sigma"],
                             relative_threshold=ea["relative_threshold"], power=ea["power"])
    pixels = dense_to_pixels(data)
    discs, evaluations = search_discs(data, settings, np.random.default_rng(rng))
    rotating, _ = disc_ea.rotating_discs(discs, data, ea)
    clock.append(time.perf_counter())
    snake = dict(settings["snake"])
    snake["steps"] = tuple(int(s) for s in snake["steps"])
    rounds = int(snake.pop("rounds"))
    regions = [snakes.radial_snake(data, disc, **snake) for disc in discs[rotating]]
    clock.append(time.perf_counter())
    for k, disc in enumerate(discs[rotating]):
        for round_index in range(rounds):
            if round_index > 0 and regions[k]["estimate"] is not None:
                # not in the paper: the snake again with the refined rotation
                better = regions[k]["estimate"]
                regions[k] = snakes.radial_snake(
                    data, [*disc[:3], better["xi"], better["eta"], better["omega"]], **snake)
            regions[k]["estimate"] = restricted_accumulation(
                pixels, regions[k]["mask"], disc[5], settings["accumulation"],
                margin=ea["margin"])
    good = [i for i, region in enumerate(regions) if region["estimate"] is not None]
    objects = []
    for group in merge_groups([regions[i]["estimate"] for i in good], settings["merge"]):
        members = [good[i] for i in group]
        mask = np.logical_or.reduce([regions[i]["mask"] for i in members])
        if np.count_nonzero(mask) < settings["merge"]["min_area"]:
            continue
        omega = float(np.median([regions[i]["estimate"]["omega"] for i in members]))
        final = restricted_accumulation(pixels, mask, omega, settings["accumulation"],
                                        margin=ea["margin"])
        if final is None:
            continue
        found = {"xi": final["xi"], "eta": final["eta"], "omega": final["omega"],
                 "peak": final["peak"], "area": int(np.count_nonzero(mask)), "mask": mask,
                 "regions": members, "grid": final["grid"],
                 "accumulation": {k: final[k] for k in ("xi", "eta", "omega")}}
        if settings["accumulation"]["refine"]:
            found.update(_refined(frames, found, settings))
        if settings["merge"]["extra_seeds"] > 0:
            found["mask"] = grow_from_seeds(data, found, settings)
            found["area"] = int(np.count_nonzero(found["mask"]))
        objects.append(found)
    clock.append(time.perf_counter())
    if settings["assign"]["enabled"]:
        objects = assign_pixels(frames, data, pixels, objects, settings)
    clock.append(time.perf_counter())
    steps = ("search", "snakes", "accumulation", "assign")
    return {"objects": objects, "discs": discs, "rotating": rotating, "regions": regions,
            "evaluations": evaluations, "pixels": pixels,
            "seconds": {s: clock[k + 1] - clock[k] for k, s in enumerate(steps)}}
