"""Per-pixel motion assignment once every object's rotation is known (not in the paper).

The paper's regions are radial snakes (2.3.3): star-shaped around their disc's centre, so a
C-shaped object whose rotation centre lies in its own hole cannot be followed, and an object
with large textureless patches (brick) leaves them out. Once the objects' rotations
``(xi, eta, omega)`` are known, each pixel with a gradient can instead be labelled by the
motion among ``{static, object 1..k}`` that best explains its neighbourhood:

1. normal-flow residuals ``e_h = |omega_h (-Ix (y - eta_h) + Iy (x - xi_h)) + It| / |grad I|``
   (pixels/frame, capped at ``cap``) of every hypothesis ``h`` (``h = 0``: no motion), mean
   over frame pairs;
2. averaged over a Gaussian neighbourhood of ``sigma`` pixels, over the pixels with a
   gradient only (normalised convolution): ``S_h``;
3. a pixel with a gradient goes to object ``k`` when ``S_k`` is the smallest and lower than
   every other hypothesis by ``margin`` pixels/frame; it is confidently static when ``S_0``
   is lower than every object's by ``margin``; otherwise it is undecided (near a rotation
   centre every hypothesis is slow); undecided patches and patches without a gradient join
   the object whose labels ring them (:func:`fill_undecided`);
4. each object's labelled pixels are closed morphologically (a disc of ``closing`` pixels),
   only the connected parts that overlap the object's snake region (by at least
   ``min_overlap`` times the largest overlap of a part) are kept, and enclosed
   holes are filled except where confidently static or labelled with another object: the
   textureless interior of an object and the slow pixels round its own rotation centre are
   inside it.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

DEFAULTS = {
    "enabled": False,     # not in the paper: replace each object's mask by the assignment
    "sigma": 3.0,         # neighbourhood, pixels
    "cap": 1.0,           # per-pixel residual cap, pixels/frame
    "weight_power": 2.0,  # each pixel's residual weighted by |grad I| to this power
    "margin": 0.05,       # a label needs a residual this much below the others, pixels/frame
    "reach": 2,           # an undecided patch touches a label within this, pixels
    "share": 0.6,         # ... and goes to an object touching this share of it, or more
    "flat_first": True,   # flat patches (no gradient) are joined first, on their own
    "closing": 3,         # radius of the closing disc, pixels
    "min_overlap": 0.2,   # a connected part is kept if its overlap with the snake mask is
                          # at least this share of the largest part's overlap
    "keep_share": 0.3,    # an object keeping less of its snake mask is dropped
    "reestimate": True,   # the restricted accumulation again over the assigned mask
    "rescue": 2,          # at most this many regions no motion explains become objects
    "rescue_residual": 0.3,   # ... where every smoothed residual is above this, px/frame
    "rescue_area": 400,   # ... with at least this many pixels
}


POSITIVE = ("sigma", "cap", "share", "rescue_residual")
AT_LEAST_ZERO = ("weight_power", "margin", "reach", "closing", "min_overlap", "keep_share",
                 "rescue", "rescue_area")


def check_settings(settings):
    """Refuse a setting out of range.

    Raises
    ------
    ValueError
        Naming the setting, the value and what is expected.
    """
    for key in POSITIVE:
        if not settings[key] > 0:
            raise ValueError(f"{key}={settings[key]}: expected a value > 0")
    for key in AT_LEAST_ZERO:
        if not settings[key] >= 0:
            raise ValueError(f"{key}={settings[key]}: expected a value >= 0")
    if settings["share"] > 1 or settings["min_overlap"] > 1:
        raise ValueError(f"share={settings['share']}, min_overlap={settings['min_overlap']}: "
                         "expected shares of at most 1")


def residual_maps(data, motions, *, cap=1.0):
    """Capped normal-flow residuals of each hypothesis, mean over frame pairs.

    Parameters
    ----------
    data : replication.motion.segment.disc_ea.DiscData
    motions : sequence of (xi, eta, omega)
        The objects' rotations; the static hypothesis is added first.
    cap : float
        Pixels/frame.

    Returns
    -------
    (1 + len(motions), H, W) ndarray
        0 where no frame pair has a gradient.
    """
    n_pairs, height, width = data.gx.shape
    rows, cols = np.mgrid[0:height, 0:width].astype(float)
    count = data.used.sum(axis=0)
    maps = np.zeros((1 + len(motions), height, width))
    for p in range(n_pairs):
        g = np.where(data.used[p], data.gnorm[p], 1.0)
        for h, (xi, eta, omega) in enumerate([(0.0, 0.0, 0.0), *motions]):
            flow = omega * (-data.gx[p] * (rows - eta) + data.gy[p] * (cols - xi))
            error = np.minimum(np.abs(flow + data.gt[p]) / g, cap)
            maps[h] += np.where(data.used[p], error, 0.0)
    return maps / np.maximum(count, 1)


def smoothed_residuals(maps, weight, sigma):
    """Normalised convolution of ``maps`` (M, H, W) with the pixel weights ``weight``
    (H, W), 0 for pixels without a gradient.

    Parameters
    ----------
    maps : (M, H, W) ndarray
        One residual map per hypothesis.
    weight : (H, W) ndarray
    sigma : float
        Gaussian neighbourhood, pixels.
    """
    total = ndimage.gaussian_filter(weight, sigma)
    out = np.stack([ndimage.gaussian_filter(weight * m, sigma) for m in maps])
    return out / np.maximum(total, 1e-12)


def label_pixels(smoothed, used, margin):
    """Step 3: ``labels`` (H, W) int (``k >= 1`` object, 0 static, -1 undecided or no
    gradient) and ``static`` (H, W) bool, the confidently static pixels.

    Parameters
    ----------
    smoothed : (1 + K, H, W) ndarray
        ``S_h`` of the static hypothesis (0) and of each object.
    used : (H, W) bool ndarray
        Pixels with a gradient.
    margin : float
        How much lower the best ``S_h`` must be than the second for a decision.
    """
    order = np.sort(smoothed, axis=0)
    best = np.argmin(smoothed, axis=0)
    clear = (order[1] - order[0]) >= margin if smoothed.shape[0] > 1 else np.ones_like(used)
    labels = np.where(used & clear, best, -1)
    return labels, labels == 0


def fill_undecided(labels, valid, n_objects, *, reach=2, share=0.6, flat=None):
    """Undecided connected patches (no gradient, or no clear motion) joined to an object.

    A 4-connected patch of ``labels == -1`` inside ``valid`` goes to object ``k`` when the
    patch's pixels within ``reach`` of a pixel labelled ``k`` are at least ``share`` of its
    pixels within ``reach`` of any label (static, any object, or the invalid border): a
    brick's flat face ringed by its mortar joins the brick, a flat sky that also borders
    the static background does not. With ``flat`` (the pixels without a gradient), the
    flat patches are joined first, on their own, then the remaining undecided patches: an
    object's outer edge can be undecided (a circular edge turning about its centre has no
    normal flow), and would otherwise connect a flat face inside to the outside.

    Parameters
    ----------
    labels : (H, W) int ndarray
        From :func:`label_pixels`.
    valid : (H, W) bool ndarray
        Pixels away from the border.
    n_objects : int
    reach : int
        Pixels.
    share : float
    flat : (H, W) bool ndarray, optional

    Returns
    -------
    (H, W) ndarray of int
        ``labels`` with the joined patches relabelled.
    """
    passes = [valid] if flat is None else [valid & flat, valid]
    for candidates in passes:
        labels = _join_patches(labels, (labels == -1) & candidates, valid, n_objects,
                               reach, share)
    return labels


def _join_patches(labels, candidates, valid, n_objects, reach, share):
    """One pass of :func:`fill_undecided` over the patches of ``candidates``."""
    patches, n = ndimage.label(candidates)
    if n == 0:
        return labels
    near = _disc(reach)
    index = np.arange(1, n + 1)
    touch = [ndimage.sum(ndimage.binary_dilation(~valid, near), patches, index)]
    for h in range(n_objects + 1):
        touch.append(ndimage.sum(ndimage.binary_dilation(labels == h, near), patches, index))
    touch = np.array(touch)              # (2 + n_objects, n): border, static, objects
    best = np.argmax(touch, axis=0)
    joined = (best >= 2) & (touch[best, np.arange(n)] >= share * touch.sum(axis=0))
    lookup = np.concatenate([[-1], np.where(joined, best - 1, -1)])
    return np.where(patches > 0, lookup[patches], labels)


def _disc(radius):
    r = int(radius)
    rows, cols = np.mgrid[-r:r + 1, -r:r + 1]
    return rows ** 2 + cols ** 2 <= radius ** 2


def object_mask(labels, static, k, snake_mask, *, closing=3, min_overlap=0.5):
    """Step 4 for object ``k``: its (H, W) bool mask (computed within the bounding box of
    the object's labels plus a margin, which gives the same result faster).

    Parameters
    ----------
    labels : (H, W) int ndarray
    static : (H, W) bool ndarray
    k : int
        The object's label (>= 1).
    snake_mask : (H, W) bool ndarray
        The object's snake region.
    closing : int
        Disc radius of the morphological closing, pixels.
    min_overlap : float
    """
    full = np.zeros(labels.shape, dtype=bool)
    rows, cols = np.nonzero(labels == k)
    if rows.size == 0:
        return full
    pad = 2 * int(closing) + 2
    box = (slice(max(rows.min() - pad, 0), rows.max() + pad + 1),
           slice(max(cols.min() - pad, 0), cols.max() + pad + 1))
    labels, static, snake_mask = labels[box], static[box], snake_mask[box]
    mask = labels == k
    if closing > 0:
        mask = ndimage.binary_closing(mask, structure=_disc(closing), border_value=0)
    parts, n = ndimage.label(mask)
    if n == 0:
        return full
    inside = ndimage.sum(snake_mask, parts, index=np.arange(1, n + 1))
    keep = np.flatnonzero((inside > 0) & (inside >= min_overlap * inside.max())) + 1
    mask = np.isin(parts, keep)
    other = (labels >= 1) & (labels != k)
    full[box] = mask | (ndimage.binary_fill_holes(mask) & ~static & ~other)
    return full


def smoothed_hypotheses(data, objects, settings):
    """Steps 1-2: ``S_h`` (1 + len(objects), H, W) and the pixels with a gradient (H, W).

    Parameters
    ----------
    data : replication.motion.segment.disc_ea.DiscData
    objects : list of dict
        ``xi, eta, omega`` of each object.
    settings : dict
        :data:`DEFAULTS` keys.
    """
    motions = [(o["xi"], o["eta"], o["omega"]) for o in objects]
    used = data.used.any(axis=0)
    maps = residual_maps(data, motions, cap=settings["cap"])
    gnorm = np.where(data.used, data.gnorm, 0.0).max(axis=0)
    weight = np.where(used, (gnorm / gnorm[used].max()) ** settings["weight_power"], 0.0)
    return smoothed_residuals(maps, weight, settings["sigma"]), used


def unexplained_regions(data, objects, settings, smoothed=None):
    """Regions that neither the static background nor any object's motion explains.

    Pixels with a gradient whose every smoothed residual ``S_h`` is above
    ``rescue_residual``, closed by a disc of ``closing`` pixels; the connected parts of at
    least ``rescue_area`` pixels, at most ``rescue`` of them, largest first.

    ``smoothed``: :func:`smoothed_hypotheses` of the same objects, if already computed.

    Parameters
    ----------
    data : replication.motion.segment.disc_ea.DiscData
    objects : list of dict
    settings : dict
        :data:`DEFAULTS` keys.
    smoothed : tuple, optional

    Returns
    -------
    list of (H, W) ndarray of bool
    """
    if int(settings["rescue"]) <= 0:
        return []
    smoothed, used = smoothed or smoothed_hypotheses(data, objects, settings)
    moving = used & (smoothed.min(axis=0) > settings["rescue_residual"])
    if settings["closing"] > 0:
        moving = ndimage.binary_closing(moving, structure=_disc(settings["closing"]))
    parts, n = ndimage.label(moving)
    sizes = ndimage.sum(moving, parts, index=np.arange(1, n + 1))
    order = [i + 1 for i in np.argsort(-sizes) if sizes[i] >= settings["rescue_area"]]
    return [parts == i for i in order[: int(settings["rescue"])]]


def assign(data, objects, settings, smoothed=None):
    """Every object's mask from the per-pixel assignment (see the module docstring).

    Parameters
    ----------
    data : replication.motion.segment.disc_ea.DiscData
    objects : list of dict
        ``xi, eta, omega, mask`` (the snake regions).
    settings : dict
        :data:`DEFAULTS` keys.
    smoothed : tuple, optional
        :func:`smoothed_hypotheses` of the same objects, if already computed.

    Returns
    -------
    list of (H, W) ndarray of bool
        One mask per object, disjoint.
    """
    if not objects:
        return []
    smoothed, used = smoothed or smoothed_hypotheses(data, objects, settings)
    labels, static = label_pixels(smoothed, used, settings["margin"])
    valid = np.zeros_like(used)
    b = int(data.border)
    valid[b:used.shape[0] - b, b:used.shape[1] - b] = True
    labels = fill_undecided(labels, valid, len(objects), reach=settings["reach"],
                            share=settings["share"],
                            flat=~used if settings["flat_first"] else None)
    masks = [object_mask(labels, static, k, o["mask"], closing=settings["closing"],
                         min_overlap=settings["min_overlap"])
             for k, o in enumerate(objects, 1)]
    taken = np.zeros_like(used)
    for k, mask in enumerate(masks):   # filled holes may overlap another object: first wins
        masks[k] = mask & ~taken
        taken |= masks[k]
    return masks
