"""Runner of ``segment_multi``: paper 2.3 on one sequence, Figs. 5-7.

Apart from the other segmentation runners (:mod:`replication.experiments.segment`), which
import no figure: a change to Figs. 5-7 makes only this experiment stale.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from replication.errors import check
from replication.experiments.motion import (EDGE_CELLS, check_border, check_motion,
                                             figure_folder)
from replication.experiments.segment import _load, score_objects
from replication.motion import coverage
from replication.motion.derivatives import sequence_derivatives
from replication.motion.frame_checks import frame_checks
from replication.progress import progress


def write_mask(path, mask):
    """One object's mask as an 8-bit PNG (255 inside, 0 outside).

    Parameters
    ----------
    path : str or Path
    mask : (H, W) bool ndarray
    """
    from PIL import Image

    Image.fromarray(np.where(mask, 255, 0).astype(np.uint8)).save(path, compress_level=6)
    return path


def _objects_json(objects, out):
    rows = []
    for k, item in enumerate(objects, 1):
        name = f"object_{k:02d}.png"
        write_mask(Path(out) / name, item["mask"])
        rows.append({"xi": float(item["xi"]), "eta": float(item["eta"]),
                     "omega": float(item["omega"]), "area": int(item["area"]),
                     "mask_file": name, "peak": int(item.get("peak", 0)),
                     "spread": item.get("spread")})
    return rows


def _draw_figures(sequence, found, figure_dir):
    """Figs. 5-7 from the arrays of :func:`segmentation.segment`."""
    from replication.figures import fig05_discs, fig06_snakes, fig07_rotations
    from replication.motion import irc

    frame = sequence.frames[0]
    paths = [fig05_discs.draw(figure_dir / "fig05_discs.png", frame, found["discs"],
                              found["rotating"])]
    paths.append(fig06_snakes.draw(figure_dir / "fig06_snakes.png", frame,
                                   [(r["centre"], r["rho"]) for r in found["regions"]]))
    panels = []
    for item in found["objects"]:
        grid = item["grid"]
        inside = item["mask"][found["pixels"].y.astype(int), found["pixels"].x.astype(int)]
        chosen = type(found["pixels"])(*(getattr(found["pixels"], f)[inside]
                                         for f in ("x", "y", "gx", "gy", "gt", "pair")))
        acc = irc.accumulate(chosen, item["omega"], grid)
        extent = (grid.x0 - grid.cell / 2, grid.x0 + (grid.nx - 0.5) * grid.cell,
                  grid.y0 + (grid.ny - 0.5) * grid.cell, grid.y0 - grid.cell / 2)
        panels.append({"acc": acc, "extent": extent, "xi": item["xi"], "eta": item["eta"],
                       "omega": item["omega"], "mask": item["mask"]})
    truth = (sequence.truth or {}).get("objects", [])
    paths.append(fig07_rotations.draw(figure_dir / "fig07_rotations.png", frame, panels,
                                      truth=[(o["xi"], o["eta"]) for o in truth]))
    return [str(p) for p in paths]


# the whole frame moves by one translation when at least this share of its pixels moves
# and one translation explains at least this share of their normal flow (rotating objects
# on the suite's sequences: under 0.35; a pan: over 0.99)
MOVING_SHARE, TRANSLATION_SHARE = 0.5, 0.8


def translation_warnings(frames, settings, pixels=None):
    """A warning when one translation of the whole frame explains the motion (a camera
    pan): the rotating regions found are then pieces of it (rotations about points far
    away look like translations). ``pixels``: the full-resolution derivatives of
    ``frames`` at the settings' ``sigma`` and threshold when the caller has them (the
    segmentation without a pyramid); computed here otherwise."""
    from replication.motion import irc

    ea = settings["ea"]
    if pixels is None:
        pixels = sequence_derivatives(frames, sigma=ea["sigma"],
                                      relative_threshold=ea["relative_threshold"])
    u, v, moving, explained = irc.translation_fit(pixels, settings["snake"]["tolerance"])
    if moving >= MOVING_SHARE and explained >= TRANSLATION_SHARE:
        return [f"{100 * moving:.0f}% of the frame moves, by one translation ({u:.3g}, "
                f"{v:.3g}) px/frame that explains {100 * explained:.0f}% of its normal flow: "
                "the objects found are pieces of that motion (a camera pan?), not rotating "
                "regions"]
    return []


def motion_outside_warnings(frames, found, settings, pixels=None):
    """A warning when moving parts of the frame lie outside every object found
    (:func:`replication.motion.coverage.uncovered_motion`): an object turning faster or
    slower than the omega sweep, or moving otherwise, is missed silently (its pixels belong
    to no region), and when no object is found at all. Pixels move when their normal flow
    is at least the snake's ``tolerance``. ``pixels``: the full-resolution derivatives
    when the caller has them."""
    ea = settings["ea"]
    if pixels is None:
        pixels = sequence_derivatives(frames, sigma=ea["sigma"],
                                      relative_threshold=ea["relative_threshold"])
    uncovered = coverage.uncovered_motion(frames.shape[1:3], pixels,
                                          [item["mask"] for item in found["objects"]],
                                          settings["snake"]["tolerance"])
    if uncovered is None:
        return ([] if found["objects"] else
                ["no rotating object found, and no part of the frame moves beyond single "
                 "pixels (a still scene, or noise only)"])
    block = coverage.BLOCK
    if not found["objects"]:
        return [f"no rotating object found, yet {uncovered['moving']} block(s) of "
                f"{block} x {block} px move: an object may turn faster or slower than the "
                "omega bounds (method.ea.omega_min, method.ea.omega_max) or "
                "move otherwise (a translation, a deformation), or noise moves them"]
    if not uncovered["warned"]:
        return []
    return [f"{100 * uncovered['share']:.0f}% of the moving blocks of {block} x {block} px "
            f"({uncovered['outside']} of {uncovered['moving']}; the largest "
            f"touching patch: {uncovered['patch']}) lie outside every object found: another "
            "object may turn faster or slower than the omega bounds "
            "(method.ea.omega_min, method.ea.omega_max) or move otherwise (a translation, a "
            "deformation), and is missed (or noise moves them)"]


def translating_object_warnings(frames, found, settings, pixels=None):
    """A warning per object found whose own motion one translation explains about as well
    as a rotation (:func:`replication.motion.coverage.translating_regions`): a translating
    object is found as rotating pieces, often pairs turning opposite ways, each a
    meaningless rotation. ``pixels``: the full-resolution derivatives when the caller has them."""
    ea = settings["ea"]
    if pixels is None:
        pixels = sequence_derivatives(frames, sigma=ea["sigma"],
                                      relative_threshold=ea["relative_threshold"])
    objects = found["objects"]
    return [f"object {hit['index']}: moves like one translation ({hit['u']:.3g}, "
            f"{hit['v']:.3g}) px/frame (a rotation about any point fits its normal flow only "
            f"{100 * hit['gain']:.0f}% better): it may be a piece of a translating object "
            "(found as rotations, often pieces turning opposite ways) or of a rotation about "
            "a point far away; its rotation "
            f"({objects[hit['index']]['xi']:.4g}, {objects[hit['index']]['eta']:.4g}, "
            f"omega {objects[hit['index']]['omega']:.3g}) is then not the object's motion"
            for hit in coverage.translating_regions(pixels, [item["mask"] for item in objects],
                                                    settings["snake"]["tolerance"])]


def edge_warnings(found, settings):
    """A warning per object whose centre is at the edge of its restricted accumulation
    (the region's bounding box plus ``accumulation.window``, within the image plus
    ``ea.margin``): the centre may lie outside it, as for a whole view turning about a
    point beyond the frame. With a pyramid the check is on its top level, where the
    accumulation ran."""
    top = found["pyramid"]["top_objects"] if "pyramid" in found else found["objects"]
    warnings = []
    for k, (item, shown) in enumerate(zip(top, found["objects"])):
        grid = item.get("grid")
        if grid is not None and grid.near_edge(item["xi"], item["eta"], EDGE_CELLS):
            warnings.append(
                f"object {k}: centre ({shown['xi']:.4g}, {shown['eta']:.4g}) is at the edge "
                "of its accumulator (the region's box plus method.accumulation.window="
                f"{settings['accumulation']['window']:g} px, within the image plus "
                f"method.ea.margin={settings['ea']['margin']:g} px): the centre may lie "
                "outside it (widen both)")
    return warnings


def segment_sequence(config, out):
    """Paper 2.3 on one sequence: ``objects`` (one mask file each in ``out``), Figs. 5-7.

    ``data.path`` null means the configured ``default_data`` and the figures go to
    ``figure_dir`` (``figures/``); for any other sequence they go to ``out/figures``. With
    ``method.pyramid.enabled`` the result also holds ``pyramid`` (factor, level shapes, each
    object's rotation on the top level and after each finer level) and the figures show the
    pyramid's top level, where the segmentation ran.

    Parameters
    ----------
    config, out
        The resolved ``segment_multi`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    from replication.motion import pyramid
    from replication.motion.segment import pipeline as segmentation

    settings = segmentation.settings_from(config.get("method"))
    sequence, default = _load(config)
    figure_dir = figure_folder(config, out, default) if config.get("figures", True) else None
    progress(f"{sequence.source}: {sequence.frames.shape[0]} frames of "
             f"{sequence.frames.shape[1]} x {sequence.frames.shape[2]}")
    # scored: truth objects (a truth without 'objects' scores nothing) and labels
    scored = "objects" in (sequence.truth or {}) and sequence.labels is not None
    if scored:
        unlabelled = [i for i, item in enumerate(sequence.truth["objects"])
                      if "label" not in item]
        check(not unlabelled, f"{sequence.source}: truth object {unlabelled[:1]} has no "
                              "'label'; expected the label value of each object (scoring "
                              "against the labels needs it)")
        background = [item["label"] for item in sequence.truth["objects"]
                      if item["label"] <= 0]
        check(not background, f"{sequence.source}: truth label "
                              f"{background[0] if background else ''}: found a "
                              "value of 0 or less (0 is the static background's); expected "
                              "the label value of each object's pixels, from 1")
        present = np.unique(sequence.labels[0])
        absent = [item["label"] for item in sequence.truth["objects"]
                  if item["label"] not in present]
        check(not absent, f"{sequence.source}: truth label {absent[0] if absent else ''}: no "
                          "pixel of the first label image has it (values: "
                          f"{', '.join(str(v) for v in present[:10])}); expected the label "
                          "value of each object's pixels (scoring would count the object as "
                          "not found)")
    check_motion(sequence)
    check_border(sequence, settings["ea"]["sigma"],
                 ("method.pyramid.coarse_side", settings["pyramid"]["coarse_side"])
                 if settings["pyramid"]["enabled"] else None)
    start = time.perf_counter()
    found = segmentation.segment(sequence.frames, settings, int(config["seed"]))
    seconds = time.perf_counter() - start
    result = {"data": sequence.source, "objects": _objects_json(found["objects"], out),
              "pipeline_seconds": seconds, "seconds": found["seconds"],
              "evaluations": int(found["evaluations"]),
              "discs": found["discs"].tolist(), "rotating": found["rotating"].tolist(),
              "snake_iterations": [r["iterations"] for r in found["regions"]]}
    progress(f"{len(found['objects'])} object(s) in {seconds:.1f} s")
    # without a pyramid the segmentation's pixels are these derivatives (same settings)
    ea = settings["ea"]
    pixels = (sequence_derivatives(sequence.frames, sigma=ea["sigma"],
                                   relative_threshold=ea["relative_threshold"])
              if "pyramid" in found else found["pixels"])
    result["warnings"] = translation_warnings(sequence.frames, settings, pixels)
    result["warnings"] += edge_warnings(found, settings)
    result["warnings"] += motion_outside_warnings(sequence.frames, found, settings, pixels)
    result["warnings"] += translating_object_warnings(sequence.frames, found, settings, pixels)
    # what the IRC equation assumes of the whole frame: motion_single's checks
    checks = frame_checks(sequence.frames, sigma=settings["ea"]["sigma"])
    result["warnings"] += checks["warnings"]
    result["warnings"] += [f"note on the input: {note}" for note in sequence.notes]
    result["frame_checks"] = checks["measures"]
    if "pyramid" in found:
        result["pyramid"] = {"factor": found["pyramid"]["factor"],
                             "shapes": found["pyramid"]["shapes"],
                             "objects": [{"top": item.get("top"), "levels": item.get("levels")}
                                         for item in found["objects"]]}
    if "objects" in (sequence.truth or {}) and sequence.labels is None:
        result["warnings"].append(
            f"the truth names {len(sequence.truth['objects'])} object(s) but the sequence "
            "has no label masks (labels_*.png in a folder, a labels array in an .npz; "
            "docs/data-formats.md): nothing is scored")
    if scored:
        result["truth"] = sequence.truth["objects"]
        result["score"] = score_objects(found["objects"], sequence.labels[0], sequence.truth)
    if figure_dir is not None:
        shown = (sequence, found)
        if "pyramid" in found:
            shown = (pyramid.sequence_on_level(sequence, found["pyramid"]["frames"],
                                               found["pyramid"]["factor"]),
                     dict(found, objects=found["pyramid"]["top_objects"]))
        result["figures"] = _draw_figures(*shown, figure_dir)
    return result
