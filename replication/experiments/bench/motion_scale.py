"""Cost against frame size (``bench_motion_scale``, beyond the paper): time and accuracy of
one rotation centre for frame sides from 128 to 2048, the paper's exact accumulation
against the pyramid (:func:`replication.motion.single.pyramid_rotation`), and of the
multi-object segmentation with the pyramid
(:func:`replication.motion.segment.pipeline.segment_pyramid`).

The frames come from :mod:`replication.motion.scale_data`, which renders the same scene
at every size from its definition without using any of the method's code.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from replication.errors import check
from replication.growth import exponent
from replication.motion import scale_data, single
from replication.progress import progress

METHODS = ("exact", "pyramid")


def growth_exponent(sides, seconds):
    """Slope of ``log(seconds)`` against ``log(pixels)``, ``pixels = side**2``
    (:func:`replication.growth.exponent`): 1 means time proportional to the number of
    pixels, 1.5 to the cube of the side. None with fewer than two sizes."""
    return exponent(np.asarray(sides, dtype=float) ** 2, seconds)


def _check(config):
    sides = [int(side) for side in config["sides"]]
    check(len(sides) >= 2 and all(side >= 32 for side in sides),
          f"sides={sides}: expected at least two frame sides of at least 32 pixels")
    small, large = (int(side) for side in config["compare"])
    check(small in sides and large in sides and small < large,
          f"compare={list(config['compare'])}: expected two sides of 'sides', smaller first")
    for key in ("repeats", "exact_repeats"):
        check(int(config[key]) >= 1, f"{key}={config[key]}: expected at least 1")
    noise = [float(level) for level in config["noise_levels_255"]]
    check(len(noise) > 0 and min(noise) >= 0,
          f"noise_levels_255={noise}: expected a non-empty list of values >= 0")
    return sides, (small, large), noise


def _timed(frames, settings, repeats):
    """The answer of the fastest of ``repeats`` runs, its wall-clock seconds and all times."""
    times, best = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        found = single.find_rotation(frames, settings)
        times.append(time.perf_counter() - start)
        if times[-1] == min(times):
            best = found
    return best, min(times), times


def _row(method, side, noise, found, seconds, times, truth):
    refined, paper = found["refined"], found["paper"]
    error, peak = single.errors(refined, truth), single.errors(paper, truth)
    return {"method": method, "side": side, "noise_255": noise, "seconds": seconds,
            "seconds_all": times,
            "step_seconds": {key: float(value) for key, value in found["seconds"].items()},
            "xi": refined["xi"], "eta": refined["eta"], "omega": refined["omega"],
            "centre_px": error["centre_px"], "omega_pct": error["omega_pct"],
            "centre_fraction_of_side": error["centre_px"] / side,
            "peak_centre_px": peak["centre_px"], "peak_omega_pct": peak["omega_pct"],
            "voting_pixels": int(len(found["pixels"])),
            "factor": found.get("pyramid", {}).get("factor", 1)}


def _fits(rows, small):
    """Growth exponent per method and noise level, over every side and over the sides from
    ``small`` up (where the pyramid's top level no longer grows)."""
    fits = []
    for method in METHODS:
        for noise in sorted({row["noise_255"] for row in rows}):
            mine = [row for row in rows if row["method"] == method and row["noise_255"] == noise]
            if len(mine) >= 2:
                sides = [row["side"] for row in mine]
                seconds = [row["seconds"] for row in mine]
                large = [(side, s) for side, s in zip(sides, seconds) if side >= small]
                fits.append({"method": method, "noise_255": noise, "sides": sides,
                             "seconds_exponent_vs_pixels": growth_exponent(sides, seconds),
                             "seconds_exponent_vs_pixels_from_small": growth_exponent(
                                 *zip(*large)) if len(large) >= 2 else None})
    return fits


def _metrics(rows, fits, compare):
    """The headline numbers (worst over the noise levels) for ``replicate experiment=bench``."""
    small, large = compare
    pyramid = [row for row in rows if row["method"] == "pyramid"]
    exact = [row for row in rows if row["method"] == "exact"]
    at = lambda side, rows_: [row for row in rows_ if row["side"] == side]  # noqa: E731
    ratios = [big["seconds"] / little["seconds"] for big in at(large, pyramid)
              for little in at(small, pyramid) if big["noise_255"] == little["noise_255"]]
    metrics = {
        f"pyramid_seconds_{small}": max(row["seconds"] for row in at(small, pyramid)),
        f"pyramid_seconds_{large}": max(row["seconds"] for row in at(large, pyramid)),
        f"pyramid_seconds_{large}_over_{small}_ratio": max(ratios),
        f"pyramid_centre_px_{small}": max(row["centre_px"] for row in at(small, pyramid)),
        f"pyramid_centre_px_{large}": max(row["centre_px"] for row in at(large, pyramid)),
        "pyramid_omega_pct_max": max(abs(row["omega_pct"]) for row in pyramid),
    }
    if at(small, exact):
        metrics[f"exact_seconds_{small}"] = max(row["seconds"] for row in at(small, exact))
        metrics[f"exact_centre_px_{small}"] = max(row["centre_px"] for row in at(small, exact))
    for method in METHODS:
        exponents = [fit["seconds_exponent_vs_pixels"] for fit in fits
                     if fit["method"] == method]
        if exponents:
            metrics[f"{method}_seconds_exponent_vs_pixels"] = max(exponents)
    metrics["largest_exact_side"] = max((row["side"] for row in exact), default=None)
    return metrics


def _goals_met(metrics, goals, compare):
    small, large = compare
    return {
        "seconds_ratio": metrics[f"pyramid_seconds_{large}_over_{small}_ratio"]
        <= goals["seconds_ratio_at_most"],
        "centre_small": metrics[f"pyramid_centre_px_{small}"] <= goals["small_centre_px_at_most"],
        "centre_large": metrics[f"pyramid_centre_px_{large}"] <= goals["large_centre_px_at_most"],
        "omega": metrics["pyramid_omega_pct_max"] <= goals["omega_pct_at_most"],
        "seconds_linear": metrics["pyramid_seconds_exponent_vs_pixels"] <= 1.0,
    }


def _multi_row(side, noise, found, seconds, score):
    per_object = score["per_object"]
    centre = [row["centre_px"] for row in per_object if row["centre_px"] is not None]
    omega = [abs(row["omega_pct"]) for row in per_object if row["omega_pct"] is not None]
    return {"side": side, "noise_255": noise, "seconds": seconds,
            "step_seconds": {key: float(value) for key, value in found["seconds"].items()},
            "factor": found.get("pyramid", {}).get("factor", 1),
            "found_fraction": sum(row["found"] for row in per_object) / len(per_object),
            "min_iou": min(row["iou"] for row in per_object),
            "max_centre_px": max(centre) if centre else None,
            "max_omega_pct": max(omega) if omega else None,
            "false_regions": score["false_regions"],
            "n_found_objects": score["n_found_objects"], "per_object": per_object}


def multi_benchmark(multi):
    """Rows of the segmentation with the pyramid against the frame side (``multi`` block).

    The frames are :data:`replication.motion.scale_data.MULTI_SCENE` (three discs turning
    about their own centres); each run is scored like ``segment_multi``.
    """
    from replication.experiments.segment import score_objects
    from replication.motion.segment import pipeline as segmentation

    settings = segmentation.settings_from(multi.get("method"))
    rows = []
    for side in (int(v) for v in multi["sides"]):
        for noise in (float(v) for v in multi["noise_levels_255"]):
            frames, truth, labels = scale_data.render(
                side, seed=int(multi["scene_seed"]), noise_sigma=noise / 255.0,
                bits=8 if noise > 0 else None, scene=scale_data.MULTI_SCENE)
            times, found = [], None
            for _ in range(int(multi["repeats"])):
                start = time.perf_counter()
                found = segmentation.segment(frames, settings, int(multi["seed"]))
                times.append(time.perf_counter() - start)
            rows.append(_multi_row(side, noise, found, min(times),
                                   score_objects(found["objects"], labels[0], truth)))
            progress(f"segmentation {side} x {side}, noise {noise:g}/255: {min(times):.3g} s, "
                     f"{rows[-1]['found_fraction']:.0%} found, IoU >= {rows[-1]['min_iou']:.2f}")
    return rows


def _multi_summary(rows, compare):
    """Growth exponents and headline numbers of the segmentation rows."""
    fits = []
    for noise in sorted({row["noise_255"] for row in rows}):
        mine = [row for row in rows if row["noise_255"] == noise]
        if len(mine) >= 2:
            fits.append({"method": "segmentation (pyramid)", "noise_255": noise,
                         "sides": [row["side"] for row in mine],
                         "seconds_exponent_vs_pixels": growth_exponent(
                             [row["side"] for row in mine], [row["seconds"] for row in mine])})
    small, large = compare
    at = {side: [row for row in rows if row["side"] == side] for side in (small, large)}
    metrics = {}
    if at[small] and at[large]:
        metrics = {
            f"multi_seconds_{large}": max(row["seconds"] for row in at[large]),
            f"multi_seconds_{large}_over_{small}_ratio": max(
                big["seconds"] / little["seconds"] for big in at[large] for little in at[small]
                if big["noise_255"] == little["noise_255"]),
            f"multi_found_fraction_{small}": min(row["found_fraction"] for row in at[small]),
            f"multi_found_fraction_{large}": min(row["found_fraction"] for row in at[large]),
            f"multi_min_iou_{small}": min(row["min_iou"] for row in at[small]),
            f"multi_min_iou_{large}": min(row["min_iou"] for row in at[large]),
        }
    if fits:
        metrics["multi_seconds_exponent_vs_pixels"] = max(
            fit["seconds_exponent_vs_pixels"] for fit in fits)
    return fits, metrics


def benchmark(config, out):
    """Time and accuracy of the exact and the pyramid methods against the frame side.

    For every side of ``sides`` and noise level of ``noise_levels_255`` (noisy frames are
    also quantised to 8 bits), the frames of :func:`replication.motion.scale_data.render`
    (``scene_seed``) are analysed by the pyramid method (best of ``repeats`` runs) and, up
    to ``exact_max_side``, by the exact one (best of ``exact_repeats``). Times are
    wall-clock seconds of :func:`replication.motion.single.find_rotation` (frames in
    memory, kernels compiled beforehand). With a ``multi`` block, the segmentation too
    (:func:`multi_benchmark`).

    Parameters
    ----------
    config, out
        The resolved ``bench_motion_scale`` config (plain dict, docs/experiments.md) and the
        run's output folder.
    """
    from replication.figures import bench_motion_scale

    sides, compare, noise_levels = _check(config)
    base = dict(config.get("method") or {})
    settings = {method: single.settings_from(dict(base, accumulation=method))
                for method in METHODS}
    exact_max = int(config["exact_max_side"])
    single.warm_up()
    load_before, rows = os.getloadavg()[0], []
    for side in sides:
        for noise in noise_levels:
            frames, truth, _ = scale_data.render(side, seed=int(config["scene_seed"]),
                                                 noise_sigma=noise / 255.0,
                                                 bits=8 if noise > 0 else None)
            truth = truth["objects"][0]
            for method in METHODS:
                if method == "exact" and side > exact_max:
                    continue
                repeats = int(config["repeats" if method == "pyramid" else "exact_repeats"])
                found, seconds, times = _timed(frames, settings[method], repeats)
                rows.append(_row(method, side, noise, found, seconds, times, truth))
                progress(f"{method} {side} x {side}, noise {noise:g}/255: {seconds:.3g} s, "
                         f"centre {rows[-1]['centre_px']:.3g} px, "
                         f"omega {rows[-1]['omega_pct']:+.3g} %")
    fits = _fits(rows, compare[0])
    metrics = _metrics(rows, fits, compare)
    multi = config.get("multi") or {}
    multi_rows = multi_benchmark(multi) if multi.get("sides") else []
    multi_fits, multi_metrics = _multi_summary(multi_rows, compare)
    metrics.update(multi_metrics)
    import numba

    metrics["numba_threads"] = numba.get_num_threads()
    metrics["load_average_1min"] = os.getloadavg()[0]
    figure = bench_motion_scale.draw(Path(config["figure_dir"]) / "bench_motion_scale.png",
                                     rows, fits, multi_rows, multi_fits)
    goals = dict(config["goals"])
    return {"sides": sides, "compare": list(compare), "noise_levels_255": noise_levels,
            "exact_max_side": exact_max, "scene": dict(scale_data.SCENE),
            "rows": rows, "fits": fits, "multi_rows": multi_rows, "multi_fits": multi_fits,
            "multi_scene": dict(scale_data.MULTI_SCENE) if multi_rows else None,
            "metrics": metrics, "goals": goals,
            "goals_met": _goals_met(metrics, goals, compare),
            "load_average_1min_start": load_before, "figures": [figure]}
