"""Synthetic sequences for paper 2.2: a textured C-shape turning on a textured background.

Coordinates follow ``docs/data-formats.md``: ``x`` is the column, ``y`` the row,
pixel centres at integers. A point of the object at ``(x, y)`` in frame 0 is at
``(xi, eta) + R(omega t) ((x, y) - (xi, eta))`` in frame ``t``, with
``R(a) = [[cos a, -sin a], [sin a, cos a]]``; its velocity is
``(-omega (y - eta), omega (x - xi))``, the paper's IRC equation.

Each pixel integrates the scene over a ``supersample x supersample`` grid of sub-pixel
points (a box camera), so object edges are anti-aliased and sub-pixel motion is visible.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from replication.errors import InputError

PHOTOS = ("camera", "brick", "grass", "gravel", "moon", "text", "coins", "page")


def procedural_texture(shape, *, rng, scale=2.0, low=0.15, high=0.85):
    """Smoothed white noise rescaled to ``[low, high]``.

    Parameters
    ----------
    shape : (H, W) tuple
    rng : numpy.random.Generator
    scale : float
        Standard deviation (pixels) of the Gaussian that smooths the noise: the texture's
        grain size.

    Returns
    -------
    texture : (H, W) ndarray of float64
    """
    noise = ndimage.gaussian_filter(rng.standard_normal(shape), scale, mode="wrap")
    noise = (noise - noise.min()) / max(np.ptp(noise), 1e-12)
    return low + (high - low) * noise


def photo_texture(name, shape, *, low=0.1, high=0.9, blur=1.0):
    """A grey photograph shipped with scikit-image, cropped or tiled to ``shape``.

    Parameters
    ----------
    name : str
        One of :data:`PHOTOS` (``skimage.data`` function names).
    shape : (H, W) tuple
    blur : float
        Gaussian blur (pixels) standing for the camera's optics.

    Returns
    -------
    texture : (H, W) ndarray of float64 in ``[low, high]``
    """
    from skimage import color, data

    if name not in PHOTOS:
        raise InputError(f"texture '{name}': unknown photograph; expected one of "
                         + ", ".join(PHOTOS) + " or 'procedural'")
    image = np.asarray(getattr(data, name)(), dtype=float)
    if image.ndim == 3:
        image = color.rgb2gray(image[..., :3] / 255.0) * 255.0
    reps = (-(-shape[0] // image.shape[0]), -(-shape[1] // image.shape[1]))
    image = np.tile(image, reps)[: shape[0], : shape[1]]
    image = ndimage.gaussian_filter(image, blur, mode="reflect")
    image = (image - image.min()) / max(np.ptp(image), 1e-12)
    return low + (high - low) * image


def make_texture(spec, shape, *, rng):
    """Texture from a config ``spec``: ``{kind: procedural, scale}`` or ``{kind: NAME}``.

    Parameters
    ----------
    spec : dict
    shape : (H, W)
    rng : np.random.Generator
    """
    kind = spec.get("kind", "procedural")
    if kind == "procedural":
        return procedural_texture(shape, rng=rng, scale=float(spec.get("scale", 2.0)),
                                  low=float(spec.get("low", 0.15)),
                                  high=float(spec.get("high", 0.85)))
    return photo_texture(kind, shape, low=float(spec.get("low", 0.1)),
                         high=float(spec.get("high", 0.9)), blur=float(spec.get("blur", 1.0)))


def c_shape_mask(x, y, *, center, r_inner, r_outer, gap_deg, gap_dir_deg=0.0):
    """Membership of points in a C-shape (an annulus with an angular gap).

    Parameters
    ----------
    x, y : ndarray, same shape
        Points in frame-0 (object) coordinates.
    center : (2,) sequence
        ``(x, y)`` of the annulus centre.
    r_inner, r_outer : float
        Radii of the annulus (pixels).
    gap_deg : float
        Full angular width of the gap (degrees), centred on ``gap_dir_deg`` (0 = towards
        ``+x``, 90 = towards ``+y``, i.e. down on screen).

    Returns
    -------
    inside : ndarray of bool, shape of ``x``
    """
    dx, dy = x - center[0], y - center[1]
    radius = np.hypot(dx, dy)
    angle = np.angle(np.exp(1j * (np.arctan2(dy, dx) - np.deg2rad(gap_dir_deg))))
    in_gap = np.abs(angle) < np.deg2rad(gap_deg) / 2
    return (radius >= r_inner) & (radius <= r_outer) & ~in_gap


def render_sequence(*, shape, xi, eta, omega, n_frames, c_shape, object_texture,
                    background_texture, supersample=3):
    """Frames of a C-shape turning about ``(xi, eta)`` at ``omega`` rad/frame.

    Parameters
    ----------
    shape : (H, W) tuple
    xi, eta : float
        Rotation centre (x = column, y = row).
    omega : float
        Rotation per frame (rad); ``omega > 0`` turns clockwise on screen.
    n_frames : int
    c_shape : dict
        Keyword arguments of :func:`c_shape_mask` (frame-0 geometry).
    object_texture, background_texture : (H, W) ndarray
        Texture of the object in frame-0 coordinates, and of the static background.
    supersample : int
        Sub-pixel points per pixel along each axis.

    Returns
    -------
    frames : (T, H, W) ndarray of float64
        Noise-free intensities.
    labels : (T, H, W) ndarray of uint8
        1 where more than half of a pixel is covered by the object, else 0.
    """
    item = {"xi": xi, "eta": eta, "omega": omega, "mask_kwargs": c_shape,
            "texture": object_texture}
    return render_objects(shape=shape, objects=[item], background_texture=background_texture,
                          n_frames=n_frames, supersample=supersample)


def render_objects(*, shape, objects, background_texture, n_frames, supersample=3):
    """Frames and label masks of several objects turning about their own centres.

    Parameters
    ----------
    shape : (H, W) tuple
    objects : list of dict
        Each ``{xi, eta, omega, mask_kwargs, texture}``: rotation centre and speed,
        :func:`c_shape_mask` keywords of the frame-0 shape, and an ``(H, W)`` texture in
        frame-0 coordinates.
    background_texture : (H, W) ndarray
    n_frames : int
    supersample : int
        Sub-pixel points per pixel and axis (a box camera).

    Returns
    -------
    frames : (T, H, W) ndarray of float64
    labels : (T, H, W) ndarray of uint8
        ``k + 1`` where more than half of a pixel shows object ``k``, else 0.
    """
    height, width = shape
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    rows, cols = np.mgrid[0:height, 0:width].astype(float)
    frames = np.zeros((n_frames, height, width))
    coverage = np.zeros((len(objects) + 1, n_frames, height, width))
    for oy in offsets:
        for ox in offsets:
            x, y = cols + ox, rows + oy
            background = ndimage.map_coordinates(background_texture, [y, x], order=3,
                                                  mode="reflect")
            for t in range(n_frames):
                value, owner = background.copy(), np.zeros(shape, dtype=np.int64)
                for k, item in enumerate(objects):
                    angle = -item["omega"] * t   # the point seen at (x, y) came from R(-omega t)
                    dx, dy = x - item["xi"], y - item["eta"]
                    x0 = item["xi"] + np.cos(angle) * dx - np.sin(angle) * dy
                    y0 = item["eta"] + np.sin(angle) * dx + np.cos(angle) * dy
                    inside = c_shape_mask(x0, y0, **item["mask_kwargs"])
                    texture = ndimage.map_coordinates(item["texture"], [y0, x0], order=3,
                                                      mode="reflect")
                    value = np.where(inside, texture, value)
                    owner = np.where(inside, k + 1, owner)
                frames[t] += value
                for k in range(len(objects) + 1):
                    coverage[k, t] += owner == k
    n_points = supersample * supersample
    best = np.argmax(coverage, axis=0)
    labels = np.where(np.take_along_axis(coverage, best[None], 0)[0] > n_points / 2, best, 0)
    return frames / n_points, labels.astype(np.uint8)


def degrade(frames, *, noise_sigma=0.0, bits=None, rng=None):
    """Add Gaussian noise then quantise, as a camera would.

    Parameters
    ----------
    frames : (T, H, W) ndarray
        Intensities in ``[0, 1]``.
    noise_sigma : float
        Standard deviation of the additive noise (intensity units, e.g. ``2 / 255``).
    bits : int or None
        Quantise to ``2**bits - 1`` levels (after clipping to ``[0, 1]``); None keeps floats.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    frames : (T, H, W) ndarray of float64
    """
    frames = np.asarray(frames, dtype=float)
    if noise_sigma > 0:
        frames = frames + noise_sigma * np.random.default_rng(rng).standard_normal(frames.shape)
    if bits is not None:
        levels = 2 ** int(bits) - 1
        frames = np.round(np.clip(frames, 0.0, 1.0) * levels) / levels
    return frames


def make_sequence(spec, *, rng):
    """A sequence from one config ``spec`` (see ``configs/experiment/motion_data.yaml``).

    Parameters
    ----------
    spec : dict
    rng : np.random.Generator
        Draws the textures and the noise.

    Returns
    -------
    frames : (T, H, W) ndarray of float64
    labels : (T, H, W) ndarray of uint8
    truth : dict
        ``{"objects": [{"label": 1, "xi", "eta", "omega"}]}`` (data-formats.md).
    """
    shape = tuple(int(v) for v in spec.get("shape", (256, 256)))
    xi, eta = (float(v) for v in spec["center"])
    omega = float(spec["omega"])
    rng = np.random.default_rng(rng)
    object_texture = make_texture(spec.get("object_texture", {}), shape, rng=rng)
    background_texture = make_texture(spec.get("background_texture", {}), shape, rng=rng)
    c_shape = dict(spec["c_shape"])
    c_shape["center"] = tuple(float(v) for v in c_shape["center"])
    frames, labels = render_sequence(shape=shape, xi=xi, eta=eta, omega=omega,
                                     n_frames=int(spec.get("n_frames", 2)), c_shape=c_shape,
                                     object_texture=object_texture,
                                     background_texture=background_texture,
                                     supersample=int(spec.get("supersample", 3)))
    frames = degrade(frames, noise_sigma=float(spec.get("noise_sigma", 0.0)),
                     bits=spec.get("bits"), rng=rng)
    truth = {"objects": [{"label": 1, "xi": xi, "eta": eta, "omega": omega}]}
    return frames, labels, truth
