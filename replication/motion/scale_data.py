"""Rotating textured frames of any size, made from their definition (for the scale benchmark).

This module is deliberately independent of the methods it serves to test: it imports only
numpy and the standard library's ``math``, so a bug of the method (derivatives, voting,
warping, pyramid) cannot hide itself in the test data.

The scene is defined in units of the frame side (``u`` in ``[0, 1]``), so the same scene
can be rendered at any size ``S``:

- a static background and disc-shaped objects, each textured by a sum of plane waves
  ``sum_k a_k cos(2 pi f_k . u + phi_k)`` whose frequencies are spread evenly in
  log-frequency from ``f_min`` cycles per side upwards, with amplitudes ``~ 1/|f|`` (the
  spectrum of natural images);
- object ``k`` turns about ``(xi, eta)`` (units of the side) at ``omega`` rad/frame: a point
  of the object at ``q`` in frame 0 is at ``c + R(omega t) (q - c)`` in frame ``t``,
  ``R(a) = [[cos a, -sin a], [sin a, cos a]]``, ``x`` to the right, ``y`` downwards
  (docs/data-formats.md), so ``omega > 0`` turns clockwise on screen; later objects hide
  earlier ones;
- the camera: an ideal low-pass of ``cutoff`` cycles per pixel (waves above it are not
  seen), then square pixels that integrate the scene over their area (a plane wave of
  frequency ``g`` (cycles per pixel) is attenuated by ``sinc(g_x) sinc(g_y)``, exactly),
  each object's edge anti-aliased by its signed distance to the pixel centre (coverage
  ``clip(0.5 + d, 0, 1)``, ``d`` in pixels); optional Gaussian noise and quantisation.

:data:`SCENE` has one object (the single rotation centre), :data:`MULTI_SCENE` three.

Pixel ``(row r, column c)`` has its centre at ``(x, y) = (c, r)`` pixels, i.e. at
``u = ((c + 0.5) / S, (r + 0.5) / S)``: a point at ``u`` is at pixel coordinates
``S u - 0.5``. A textured layer is a matrix product (waves are separable in ``x`` and
``y``), so a 2048 x 2048 frame takes well under a second.
"""

import math

import numpy as np

SCENE = {
    "objects": [                        # discs: centre and radius, rotation, mean intensity
        {"disc_centre": (0.52, 0.48), "disc_radius": 0.3,      # units of the side
         "xi": 0.43, "eta": 0.56, "omega": -0.02, "mean": 0.55},
    ],
    "background_mean": 0.45,
    "contrast": 0.12,                   # standard deviation of each texture
    "f_min": 3.0,                       # lowest texture frequency, cycles per side
    "f_max": 2048.0,                    # highest, cycles per side (before the camera's cutoff)
    "waves": 80,                        # plane waves per texture
    "cutoff": 0.3,                      # camera low-pass, cycles per pixel
    "n_frames": 3,
}

MULTI_SCENE = dict(SCENE, objects=[
    {"disc_centre": (0.27, 0.3), "disc_radius": 0.16, "xi": 0.3, "eta": 0.36,
     "omega": 0.025, "mean": 0.58},
    {"disc_centre": (0.72, 0.3), "disc_radius": 0.15, "xi": 0.68, "eta": 0.26,
     "omega": -0.03, "mean": 0.36},
    {"disc_centre": (0.5, 0.74), "disc_radius": 0.17, "xi": 0.55, "eta": 0.7,
     "omega": 0.02, "mean": 0.56},
])


def _waves(rng, scene):
    """Frequencies ``(k, 2)`` (cycles per side), amplitudes ``(k,)`` and phases ``(k,)``."""
    count = int(scene["waves"])
    radius = np.exp(rng.uniform(math.log(scene["f_min"]), math.log(scene["f_max"]), count))
    angle = rng.uniform(0.0, 2.0 * math.pi, count)
    frequency = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    amplitude = 1.0 / radius
    # a wave's share of the variance is amplitude**2 / 2 (of those the camera can see at
    # the largest size); the texture's standard deviation is set to `contrast` below
    phase = rng.uniform(0.0, 2.0 * math.pi, count)
    return frequency, amplitude, phase


def _layer(side, frequency, amplitude, phase, scene):
    """One textured layer ``(side, side)``: the waves as seen by the camera.

    ``frequency`` (cycles per side) is already expressed in image axes.
    """
    per_pixel = frequency / side                      # cycles per pixel
    seen = np.hypot(per_pixel[:, 0], per_pixel[:, 1]) <= scene["cutoff"]
    per_pixel, amplitude, phase = per_pixel[seen], amplitude[seen], phase[seen]
    gain = amplitude * np.sinc(per_pixel[:, 0]) * np.sinc(per_pixel[:, 1])
    pixel = np.arange(side, dtype=float)              # centres: u = (pixel + 0.5) / side
    # cos(2 pi (gx (x + 0.5) + gy (y + 0.5)) + phi) = Re(e^{i.} e^{i.}), separable in x, y
    ex = np.exp(2j * math.pi * per_pixel[:, 0:1] * (pixel[None, :] + 0.5))      # (k, W)
    ey = np.exp(2j * math.pi * per_pixel[:, 1:2] * (pixel[None, :] + 0.5))      # (k, H)
    weights = gain * np.exp(1j * phase)
    return np.real(ey.T @ (weights[:, None] * ex))


def _scale(amplitude, scene):
    """Factor giving a texture of standard deviation ``contrast`` (all waves counted)."""
    return scene["contrast"] / math.sqrt(0.5 * float(np.sum(amplitude ** 2)))


def _rotation(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def _object_frame(side, t, item, texture, scale, scene):
    """Object ``item``'s textured layer ``(side, side)`` and its pixel coverage in frame ``t``."""
    centre = np.array([item["xi"], item["eta"]])
    rotation = _rotation(item["omega"] * t)
    # texture seen at u in frame t: T(c + R(-omega t)(u - c)); a wave f . q becomes
    # (R(omega t) f) . u + f . (c - R(-omega t) c)
    frequency = texture[0] @ rotation.T
    shift = 2.0 * math.pi * (texture[0] @ (centre - rotation.T @ centre))
    layer = item["mean"] + scale * _layer(side, frequency, texture[1], texture[2] + shift,
                                          scene)
    moved = centre + rotation @ (np.array(item["disc_centre"]) - centre)
    pixel = (np.arange(side, dtype=float) + 0.5) / side
    distance = np.hypot(pixel[None, :] - moved[0], pixel[:, None] - moved[1])
    return layer, np.clip(0.5 + (item["disc_radius"] - distance) * side, 0.0, 1.0)


def render(side, *, seed=0, noise_sigma=0.0, bits=None, scene=None):
    """Frames of the scene at ``side x side`` pixels, the truth in pixels, the label masks.

    Parameters
    ----------
    side : int
        Frame side in pixels (at least 8).
    seed : int
        Draws the textures (the same seed gives the same scene at every size) and, from a
        separate stream, the noise.
    noise_sigma : float
        Standard deviation of additive Gaussian noise (intensity units, e.g. ``2 / 255``).
    bits : int or None
        Quantise to ``2**bits - 1`` levels after clipping to ``[0, 1]``; None keeps floats.
    scene : dict or None
        Overrides of :data:`SCENE` (e.g. :data:`MULTI_SCENE`).

    Returns
    -------
    frames : (T, side, side) ndarray of float64
    truth : dict
        ``{"objects": [{"label", "xi", "eta", "omega"}]}`` (docs/data-formats.md): centres
        in pixel coordinates (``x`` column, ``y`` row), omega in rad/frame, label ``k + 1``
        for object ``k``.
    labels : (T, side, side) ndarray of uint8
        ``k + 1`` where object ``k`` covers more than half of the pixel, else 0.
    """
    scene = dict(SCENE, **(scene or {}))
    side = int(side)
    if side < 8:
        raise ValueError(f"side={side}: expected at least 8 pixels")
    rng = np.random.default_rng([int(seed), 0])
    background = _waves(rng, scene)
    textures = [_waves(rng, scene) for _ in scene["objects"]]
    back = scene["background_mean"] + _scale(background[1], scene) * _layer(
        side, background[0], background[1], background[2], scene)
    frames = np.empty((int(scene["n_frames"]), side, side))
    labels = np.zeros(frames.shape, dtype=np.uint8)
    for t in range(frames.shape[0]):
        frames[t] = back
        for k, (item, texture) in enumerate(zip(scene["objects"], textures)):
            layer, cover = _object_frame(side, t, item, texture, _scale(texture[1], scene),
                                         scene)
            frames[t] = cover * layer + (1.0 - cover) * frames[t]
            labels[t][cover > 0.5] = k + 1
    if noise_sigma > 0:
        noise_rng = np.random.default_rng([int(seed), 1, side])
        frames = frames + noise_sigma * noise_rng.standard_normal(frames.shape)
    if bits is not None:
        levels = 2 ** int(bits) - 1
        frames = np.round(np.clip(frames, 0.0, 1.0) * levels) / levels
    truth = {"objects": [{"label": k + 1, "xi": item["xi"] * side - 0.5,
                          "eta": item["eta"] * side - 0.5, "omega": float(item["omega"])}
                         for k, item in enumerate(scene["objects"])]}
    return frames, truth, labels
