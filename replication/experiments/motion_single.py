"""Runner of ``motion_single``: one rotation centre and Figs. 1-4 (paper 2.1-2.2).

Apart from the other single-rotation runners (:mod:`replication.experiments.motion`),
which import no figure: a change to Figs. 1-4 makes only this experiment stale.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from replication.experiments.motion import (
    EDGE_CELLS,
    centre_spread,
    figure_folder,
    spread_allowed,
    _check_settings,
    _load,
    _truth_of,
    check_border,
    check_grid,
    check_motion,
)
from replication.motion import baselines, coverage, irc, pyramid, single
from replication.motion.frame_checks import frame_checks
from replication.motion.derivatives import sequence_derivatives
from replication.progress import bar, progress

# a refinement on fewer pixels than this is reported with a warning
MIN_REFINE_PIXELS = 100
# a spread from fewer tiles than this is called rough
FEW_BLOCKS = 8


# the refined centre this many frame sizes away: a translation, not a rotation in view
FAR_CENTRE = 10.0
# irc and irc_refined disagree when their centres are further apart than this many pixels
# (and this many cells), or their omegas by more than this fraction plus half a sweep step:
# the best peak's own bias is about 9% in omega and a pixel in the centre, up to 33% in
# omega on the finest textures (REPORT.md, motion_omega_bias)
DISAGREE_PX, DISAGREE_CELLS, DISAGREE_OMEGA = 10.0, 3.0, 0.4


# pixels move from this normal flow, pixels/frame (segment_multi's default snake tolerance,
# SNAKE_DEFAULTS["tolerance"]; not imported: the command line would then take the
# segmentation's settings as motion_single's, since it merges the *DEFAULTS its runner reaches)
MOVING_FLOW = 0.3


def motion_outside_warnings(found):
    """A warning when moving parts of the frame lie outside the region of the rotation
    found (:func:`replication.motion.coverage.uncovered_motion`, on the voting pixels and
    the refinement's region, both on the pyramid's top level with a pyramid): the sequence
    holds another motion, which one rotation does not explain; and when no part of the
    frame moves (a still scene with sensor noise gave a confident omega, warned only by a
    refinement on 0 pixels).

    Parameters
    ----------
    found : dict
        With ``pixels`` and ``region`` (:func:`find_rotation_shown`,
        :func:`replication.motion.single.find_rotation`).
    """
    region = found["region"]
    uncovered = coverage.uncovered_motion(region.shape, found["pixels"], [region], MOVING_FLOW)
    if uncovered is None:
        return [f"no block of {coverage.BLOCK} x {coverage.BLOCK} px moves (in none do "
                f"{100 * coverage.BLOCK_MOVING:.0f}% of the selected pixels have a normal "
                f"flow of {MOVING_FLOW} "
                "px/frame or more): a still scene or noise only, about which the answer "
                "means nothing, or a rotation too slow to move any part that far"]
    if not uncovered["warned"]:
        return []
    block = coverage.BLOCK
    return [f"{100 * uncovered['share']:.0f}% of the moving blocks of {block} x {block} px "
            f"({uncovered['outside']} of {uncovered['moving']}; the largest touching patch: "
            f"{uncovered['patch']}) lie outside the region of the rotation found: the frames "
            "hold another motion (an object turning the other way or at another speed, or "
            "moving otherwise), which one rotation does not explain; segment_multi finds "
            "several rotating regions"]


def answer_warnings(paper, refined, settings, grid=None, shape=None):
    """Warnings on a rotation estimate: the best peak at the edge of the omega sweep (or
    within 1.5 steps of 0) or within ``EDGE_CELLS`` cells of the edge of the accumulator
    ``grid``, the best peak and the refinement disagreeing beyond the peak's usual bias, a
    refinement on too few pixels, a refined omega outside the sweep, a refined centre so
    far from the frames (``shape``) that the motion is a translation."""
    low, high = float(settings["omega_min"]), float(settings["omega_max"])
    step = (high - low) / max(int(settings["omega_count"]) - 1, 1)
    warnings = []
    if min(abs(paper["omega"] - low), abs(paper["omega"] - high)) <= step / 2:
        warnings.append(f"irc.omega={paper['omega']:.4g} is at the edge of the sweep "
                        f"[{low:g}, {high:g}]: the rotation may lie outside it (widen "
                        "method.omega_min/omega_max)")
    elif low < 0 < high and abs(paper["omega"]) < 1.5 * step:
        warnings.append(f"irc.omega={paper['omega']:.4g} is within 1.5 steps ({step:.3g}) "
                        "of 0, the sweep's inner edge: a slower rotation than the sweep "
                        "resolves gives a best peak of no meaning (a finer sweep, "
                        "method.omega_count, resolves it)")
    if grid is not None and grid.near_edge(paper["xi"], paper["eta"], EDGE_CELLS):
        warnings.append(f"irc centre ({paper['xi']:.4g}, {paper['eta']:.4g}) is at the "
                        "edge of the accumulator: the centre may lie outside it (widen "
                        "method.margin)")
    if refined.get("pixels", 0) >= MIN_REFINE_PIXELS and np.all(
            np.isfinite([refined["xi"], refined["eta"], refined["omega"]])):
        apart = float(np.hypot(paper["xi"] - refined["xi"], paper["eta"] - refined["eta"]))
        near = max(DISAGREE_PX, DISAGREE_CELLS * (grid.cell if grid is not None else 1.0))
        if apart > near or abs(paper["omega"] - refined["omega"]) > \
                DISAGREE_OMEGA * abs(refined["omega"]) + step / 2:
            warnings.append(f"irc and irc_refined disagree: centres {apart:.3g} px apart, "
                            f"omega {paper['omega']:.4g} against {refined['omega']:.4g}, "
                            "beyond the best peak's usual bias; irc_refined is usually the "
                            "closer, but at least one is wrong (a centre near or beyond the "
                            "accumulator's edge, a rotation the sweep does not resolve, or "
                            "noise): check the sequence and the other warnings")
    if shape is not None and np.all(np.isfinite([refined["xi"], refined["eta"]])):
        height, width = shape
        away = float(np.hypot(refined["xi"] - (width - 1) / 2, refined["eta"] - (height - 1) / 2))
        if away > FAR_CENTRE * max(height, width):
            warnings.append(f"irc_refined centre is {away:.3g} px from the frames with "
                            f"omega {refined['omega']:.3g}: the motion looks like a "
                            "translation, not a rotation about a point in or near view; "
                            "irc (the best peak) is then meaningless")
    if refined.get("pixels", 0) < MIN_REFINE_PIXELS:
        warnings.append(f"irc_refined: refinement on {refined.get('pixels', 0)} pixel(s), "
                        f"fewer than {MIN_REFINE_PIXELS}: the refined estimate is not reliable, "
                        "and nothing confirms irc either (are the frames a rotation?)")
    if not low <= refined["omega"] <= high:
        warnings.append(f"irc_refined.omega={refined['omega']:.4g} is outside the sweep "
                        f"[{low:g}, {high:g}]")
    spread = refined.get("spread")
    if spread is not None:
        centre_sd = centre_spread(refined)
        allowed = spread_allowed(shape)
        if centre_sd > allowed:
            warnings.append(f"irc_refined centre spread (block jackknife) is {centre_sd:.3g} "
                            f"px, above {allowed:.3g} px: the centre is uncertain by at "
                            "least that much, and by several times more on low-contrast "
                            "texture or a centre far from the object (the spread measures "
                            "noise, not bias)")
        elif spread["blocks"] < FEW_BLOCKS:
            warnings.append(f"irc_refined spread from {spread['blocks']} tiles only: a rough "
                            "estimate (a small object)")
    elif "spread" in refined and refined.get("pixels", 0) >= MIN_REFINE_PIXELS:
        warnings.append("irc_refined has no spread: its pixels fall in fewer than 4 tiles "
                        "of 16 px (a small object), so nothing measures its noise")
    return warnings


def _draw_figures(sequence, found, settings, figure_dir):
    """Figs. 1-4 for one sequence, from the arrays of :func:`single.find_rotation`."""
    from replication.figures import fig01_flow, fig02_peak_vs_omega, fig03_accumulator, fig04_pixels

    figure_dir.mkdir(parents=True, exist_ok=True)
    truth = _truth_of(sequence)
    paper, refined, table, grid = found["paper"], found["refined"], found["table"], found["grid"]
    flow = baselines.optical_flow_rotation(sequence.frames, method="tvl1")["flow"]
    paths = [fig01_flow.draw(figure_dir / "fig01_flow.png", sequence.frames[0], flow)]
    paths.append(fig02_peak_vs_omega.draw(
        figure_dir / "fig02_peak_vs_omega.png", table["omega"], table["peak"],
        best=paper["omega"], refined=refined["omega"],
        truth=None if truth is None else truth["omega"]))
    acc = irc.accumulate(found["pixels"], paper["omega"], grid)
    extent = (grid.x0 - grid.cell / 2, grid.x0 + (grid.nx - 0.5) * grid.cell,
              grid.y0 + (grid.ny - 0.5) * grid.cell, grid.y0 - grid.cell / 2)
    paths.append(fig03_accumulator.draw(
        figure_dir / "fig03_accumulator.png", acc, extent, peak=(paper["xi"], paper["eta"]),
        truth=None if truth is None else (truth["xi"], truth["eta"]), omega=paper["omega"]))
    pixels = found["pixels"]
    first = pixels.pair == 0
    distance = irc.line_distance(pixels, paper["xi"], paper["eta"], paper["omega"])[first]
    closeness = np.zeros(sequence.frames.shape[1:])
    closeness[pixels.y[first].astype(int), pixels.x[first].astype(int)] = np.clip(
        1.0 - distance / settings["region_tol"], 0.0, 1.0)
    outline = None if sequence.labels is None else sequence.labels[0] > 0
    paths.append(fig04_pixels.draw(figure_dir / "fig04_pixels.png", closeness,
                                   region=found["region"], label_outline=outline))
    return [str(p) for p in paths]


# calls of the omega sweep at most, so that its bar moves (each call a few accumulations)
SWEEP_STEPS = 100


def shown_sweep(pixels, omegas, grid):
    """:func:`irc.sweep` followed on a progress bar ("omega sweep"): the same table, computed
    in up to :data:`SWEEP_STEPS` calls (each omega's accumulator is independent).

    Parameters
    ----------
    pixels, omegas, grid
        As :func:`irc.sweep`: voting pixels, ``(m,)`` non-zero omegas, accumulator grid.
    """
    import numba

    threads = numba.get_num_threads()
    step = threads * max(1, -(-omegas.size // (SWEEP_STEPS * threads)))
    parts = []
    with bar(omegas.size, "omega sweep") as shown:
        for start in range(0, omegas.size, step):
            parts.append(irc.sweep(pixels, omegas[start:start + step], grid))
            shown.update(len(parts[-1]["omega"]))
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def find_rotation_shown(frames, settings):
    """:func:`single.find_rotation` with its omega sweep on a progress bar (same result).

    Parameters
    ----------
    frames : (T, H, W) ndarray
    settings : dict
        Keys of ``single.DEFAULTS``.
    """
    start = time.perf_counter()
    pixels = sequence_derivatives(frames, sigma=settings["sigma"],
                                  relative_threshold=settings["relative_threshold"])
    grid = irc.image_grid(frames.shape[1:], margin=settings["margin"], cell=settings["cell"])
    omegas = irc.omega_sweep(settings["omega_min"], settings["omega_max"],
                             int(settings["omega_count"]))
    progress(f"omega sweep: {omegas.size} values, {len(pixels)} voting pixels, "
             f"accumulator {grid.ny} x {grid.nx}")
    table = shown_sweep(pixels, omegas, grid)
    paper = irc.paper_estimate(table)
    middle = time.perf_counter()
    progress(f"refining from omega = {paper['omega']:.4g} ({settings['rounds']} round(s))")
    refined = single.refined_method(frames, paper, pixels, settings)
    seconds = {"paper": middle - start, "refined": time.perf_counter() - middle}
    region = refined.pop("region")
    return {"paper": paper, "refined": refined, "seconds": seconds, "table": table,
            "pixels": pixels, "grid": grid, "region": region}


def _top_level(sequence, found):
    """The sequence and the answer on the pyramid's top level (``accumulation: pyramid``),
    in that level's pixels, for Figs. 1-4: the figures show where the votes were cast."""
    top, factor = found["pyramid"]["top"], found["pyramid"]["factor"]
    shown = dict(found, paper=top["paper"], table=top["table"], grid=top["grid"],
                 refined=dict(top["refined"], omega=found["refined"]["omega"]))
    return pyramid.sequence_on_level(sequence, top["frames"], factor), shown


LARGE_EXACT_PIXELS = 512 * 512   # frames above this get the pyramid's note


def _pyramid_summary(found):
    """``pyramid`` of ``result.json``: factor, level shapes and the answer on each level."""
    info = found["pyramid"]
    return {"factor": info["factor"], "shapes": info["shapes"],
            "top": {key: info["top"]["refined"][key] for key in ("xi", "eta", "omega")},
            "levels": info["levels"]}


def single_rotation(config, out):
    """Paper 2.2 on one sequence: ``irc`` (paper estimate), ``irc_refined``, Figs. 1-4.

    ``data.path`` null means the paper-like synthetic sequence ``default_data``, and the
    figures go to ``figure_dir`` (``figures/``); for any other sequence they go to
    ``out/figures``. With ``method.accumulation: pyramid`` the result also holds
    ``pyramid`` (factor, level shapes, the answer on each level) and the figures show the
    pyramid's top level, where the votes were cast.
    """
    settings = single.settings_from(config.get("method"))
    _check_settings(settings)
    given = config.get("data", {}).get("path")
    figure_dir = figure_folder(config, out, given is None) if config.get("figures", True) \
        else None
    sequence = _load(given or config["default_data"])
    progress(f"{sequence.source}: {sequence.frames.shape[0]} frames of "
             f"{sequence.frames.shape[1]} x {sequence.frames.shape[2]}")
    check_motion(sequence)
    check_border(sequence, settings["sigma"],
                 ("method.coarse_side", settings["coarse_side"])
                 if settings["accumulation"] == "pyramid" else None)
    if settings["accumulation"] == "exact":
        check_grid(sequence.frames.shape[1:], settings)
        if np.prod(sequence.frames.shape[1:3]) > LARGE_EXACT_PIXELS:
            # the exact accumulation's cost grows with about the cube of the side
            # (REPORT.md, cost growth): minutes from about 1024 x 1024 on
            print("note: frames this large take minutes with the paper's exact "
                  "accumulation; method.accumulation=pyramid takes seconds at the same "
                  "accuracy (docs/experiments.md, motion_single)", file=sys.stderr)
    single.warm_up()
    found = (single.find_rotation(sequence.frames, settings)
             if settings["accumulation"] == "pyramid"
             else find_rotation_shown(sequence.frames, settings))
    paper, refined = found["paper"], found["refined"]
    progress(f"paper: {paper}; refined: {refined}")
    checks = frame_checks(sequence.frames, sigma=settings["sigma"])
    result = {
        "data": sequence.source,
        "irc": paper,
        "irc_refined": refined,
        # the pyramid's grid is its top level's, in input pixels (cell x factor)
        "warnings": answer_warnings(paper, refined, settings, found["grid"],
                                    sequence.frames.shape[1:])
        + motion_outside_warnings(found) + checks["warnings"]
        + [f"note on the input: {note}" for note in sequence.notes],
        "frame_checks": checks["measures"],
        "seconds": found["seconds"],
        "pixels_used": int(len(found["pixels"])),
        "region_pixels": int(np.count_nonzero(found["region"])),
        "sweep": {key: found["table"][key].tolist() for key in ("omega", "xi", "eta", "peak")},
    }
    if "pyramid" in found:
        result["pyramid"] = _pyramid_summary(found)
    truth = _truth_of(sequence)
    if truth is not None:
        result["truth"] = {k: truth[k] for k in ("xi", "eta", "omega")}
        result["errors"] = {"paper": single.errors(paper, truth),
                            "refined": single.errors(refined, truth)}
    if figure_dir is not None:
        shown = (sequence, found) if "pyramid" not in found else _top_level(sequence, found)
        result["figures"] = _draw_figures(*shown, settings, figure_dir)
    return result
