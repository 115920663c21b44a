"""Synthetic sequences for paper 2.3: several textured objects rotating on a static background.

Built on :mod:`replication.motion.synth` (textures, C-shapes, rendering, camera degradation). Object
``k`` (label ``k + 1``) has a frame-0 shape (:func:`~replication.motion.synth.c_shape_mask`
keywords: a disc is ``r_inner = 0, gap_deg = 0``), its own texture, and turns about its own
centre ``(xi_k, eta_k)`` at ``omega_k`` rad/frame (coordinates of docs/data-formats.md:
``x`` column, ``y`` row, ``omega > 0`` clockwise on screen). Objects are painted in list
order, so a later object hides an earlier one where they meet.
"""

from __future__ import annotations

import numpy as np

from replication.errors import check
from replication.motion.synth import degrade, make_texture, render_objects

SHAPE_KEYS = ("center", "r_inner", "r_outer", "gap_deg", "gap_dir_deg")
MAX_OBJECTS = 8   # objects per sequence (labels 1..8)


def check_object(where, item):
    """Refuse an object spec without ``center``, ``omega`` or ``shape``, or a bad one.

    Parameters
    ----------
    where : str
        Name of the spec, for the message.
    item : dict
    """
    for key in ("center", "omega", "shape"):
        check(key in item, f"{where}: no '{key}'; expected center [xi, eta], omega "
              "(rad/frame) and shape {center, r_inner, r_outer, gap_deg}")
    check(len(item["center"]) == 2, f"{where}.center: {item['center']}; expected [xi, eta]")
    unknown = sorted(set(item["shape"]) - set(SHAPE_KEYS))
    check(not unknown, f"{where}.shape: unknown key(s) {unknown}; expected some of "
          + ", ".join(SHAPE_KEYS))
    check(0 <= item["shape"].get("r_inner", 0) < item["shape"].get("r_outer", 0),
          f"{where}.shape: r_inner={item['shape'].get('r_inner', 0)}, r_outer="
          f"{item['shape'].get('r_outer')}; expected 0 <= r_inner < r_outer")


def make_multi_sequence(spec, *, rng):
    """A multi-object sequence from one config ``spec`` (see ``motion_multi_data.yaml``).

    Parameters
    ----------
    spec : dict
        ``shape, n_frames, supersample, noise_sigma, bits, background_texture`` and
        ``objects``: a list of ``{center: [xi, eta], omega, shape: {c_shape keywords},
        texture: {texture spec}}``.
    rng : numpy.random.Generator or int or None
        Draws the procedural textures (background first, then each object's) and the noise.

    Returns
    -------
    frames : (T, H, W) ndarray of float64
    labels : (T, H, W) ndarray of uint8
    truth : dict
        ``{"objects": [{"label", "xi", "eta", "omega"}]}`` (data-formats.md), label ``k + 1``
        for object ``k``.
    """
    rng = np.random.default_rng(rng)
    shape = tuple(int(v) for v in spec.get("shape", (256, 256)))
    check(1 <= len(spec.get("objects", [])) <= MAX_OBJECTS,
          f"objects: {len(spec.get('objects', []))} object(s); expected 1 to {MAX_OBJECTS}")
    for k, item in enumerate(spec["objects"]):
        check_object(f"objects[{k}]", item)
    background = make_texture(spec.get("background_texture", {}), shape, rng=rng)
    objects, truth = [], []
    for k, item in enumerate(spec["objects"]):
        mask_kwargs = {key: float(v) for key, v in item["shape"].items() if key != "center"}
        mask_kwargs["center"] = tuple(float(v) for v in item["shape"]["center"])
        objects.append({"xi": float(item["center"][0]), "eta": float(item["center"][1]),
                        "omega": float(item["omega"]), "mask_kwargs": mask_kwargs,
                        "texture": make_texture(item.get("texture", {}), shape, rng=rng)})
        truth.append({"label": k + 1, "xi": float(item["center"][0]),
                      "eta": float(item["center"][1]), "omega": float(item["omega"])})
    frames, labels = render_objects(shape=shape, objects=objects,
                                    background_texture=background,
                                    n_frames=int(spec.get("n_frames", 2)),
                                    supersample=int(spec.get("supersample", 3)))
    frames = degrade(frames, noise_sigma=float(spec.get("noise_sigma", 0.0)),
                     bits=spec.get("bits"), rng=rng)
    return frames, labels, {"objects": truth}
