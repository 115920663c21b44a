"""Runners of the single-rotation experiments (paper 2.1-2.2, Figs. 1-4).

Each runner takes the resolved config (plain dict) and the output folder, validates its
settings before writing anything, and returns the experiment's result keys.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from replication.errors import check
from replication.motion import baselines, irc, pyramid, single
from replication.motion.derivatives import default_border, sequence_derivatives
from replication.motion.io import (
    check_shape,
    read_listed,
    read_manifest_sequences,
    read_sequence,
    write_sequence_folder,
    write_sequence_npz,
)
from replication.motion.synth import make_sequence
from replication.progress import bar, progress
from replication.provenance import file_sha256
from replication.results import write_json_atomic


def _sequence_spec(base, override):
    spec = json.loads(json.dumps(base))
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(spec.get(key), dict):
            spec[key].update(value)
        else:
            spec[key] = value
    return spec


def _check_spec(name, spec):
    where = f"sequences.{name}"
    for key in ("center", "omega", "c_shape"):
        check(key in spec, f"{where}: no '{key}'; expected it in the sequence or in 'base'")
    check(len(spec["center"]) == 2, f"{where}.center: {spec['center']}; expected [xi, eta]")
    check(spec["omega"] != 0, f"{where}.omega: 0; expected a non-zero rotation (rad/frame)")
    if "shape" in spec:
        check_shape(f"{where}.shape", spec["shape"])
    check(int(spec.get("n_frames", 2)) >= 2,
          f"{where}.n_frames: {spec.get('n_frames')}; expected at least 2")
    check(spec.get("format", "npz") in ("npz", "png8", "png16"),
          f"{where}.format: {spec.get('format')}; expected npz, png8 or png16")


def make_data(config, out):
    """Write every configured sequence with truth, labels and a manifest (sha256 per file).

    Sequence ``k`` (in config order) draws its textures and noise from
    ``default_rng([seed, k])``, so the files depend only on the config and the seed.
    """
    base = config.get("base", {})
    items = list(config["sequences"].items())
    check(len(items) > 0, "sequences: empty; expected at least one sequence")
    specs = {name: _sequence_spec(base, override) for name, override in items}
    for name, spec in specs.items():
        _check_spec(name, spec)
    data_dir = Path(config["data_dir"])
    files, summary = {}, {}
    for index, (name, spec) in enumerate(specs.items()):
        progress(f"sequence {name}")
        frames, labels, truth = make_sequence(spec, rng=np.random.default_rng([config["seed"],
                                                                               index]))
        fmt = spec.get("format", "npz")
        if fmt == "npz":
            written = [data_dir / f"{name}.npz"]
            write_sequence_npz(written[0], frames, labels=labels, truth=truth)
        else:
            written = write_sequence_folder(data_dir / name, frames, labels=labels, truth=truth,
                                            bits=8 if fmt == "png8" else 16)
        for path in written:
            files[str(path.relative_to(data_dir))] = file_sha256(path)
        summary[name] = {"path": str(written[0] if fmt == "npz" else data_dir / name),
                         "role": spec.get("role", "accuracy"), "format": fmt,
                         "xi": spec["center"][0], "eta": spec["center"][1],
                         "omega": spec["omega"], "n_frames": int(spec.get("n_frames", 2)),
                         "object_texture": spec.get("object_texture", {}).get("kind"),
                         "background_texture": spec.get("background_texture", {}).get("kind"),
                         "noise_sigma": spec.get("noise_sigma", 0.0), "bits": spec.get("bits")}
    manifest = {"config": {k: v for k, v in config.items() if k != "out"},
                "sequences": summary, "files": files}
    write_json_atomic(data_dir / "manifest.json", manifest)
    progress(f"wrote {len(files)} files and manifest.json into data_dir")
    return {"data_dir": str(data_dir), "sequences": summary, "files": files}


def _load(path):
    check(path is not None, "data.path: not set; expected a folder of frames or an .npz")
    return read_sequence(path)


def _check_settings(settings):
    check(settings["omega_min"] < settings["omega_max"],
          f"omega_min={settings['omega_min']}, omega_max={settings['omega_max']}: expected "
          "omega_min < omega_max")
    from replication.guard import LIMITS

    count, limit = settings["omega_count"], LIMITS["max_sweep_values"]
    check(isinstance(count, int) and not isinstance(count, bool) and 2 <= count <= limit,
          f"method.omega_count={count!r}: expected an integer from 2 to "
          f"limits.max_sweep_values={limit:g}")
    check(settings["sigma"] >= 0, f"sigma={settings['sigma']}: expected >= 0 pixels")
    for key in ("relative_threshold", "refine_threshold"):
        check(0 < settings[key] < 1, f"{key}={settings[key]}: expected a fraction in (0, 1)")
    check(settings["cell"] > 0, f"cell={settings['cell']}: expected > 0 pixels")
    check(settings["margin"] >= 0, f"method.margin={settings['margin']}: expected >= 0 "
                                   "pixels (the accumulator covers the image and more)")


# the best peak this many cells from the accumulator's border is "at the edge" (the peak
# of a centre outside it shows as a slope cut off a few cells inside)
EDGE_CELLS = 3.0
# a refined centre whose spread (irc.rigid_spread, the x and y spreads combined) is above
# this many pixels, and this fraction of the frame's larger side, is warned; the accuracy
# study measures how often such spreads cover the errors
SPREAD_PX, SPREAD_OF_SIDE = 1.0, 0.002


def spread_allowed(shape=None):
    """The largest refined-centre spread (pixels) answered without a warning, for frames of
    ``shape`` (H, W)."""
    return max(SPREAD_PX, SPREAD_OF_SIDE * max(shape)) if shape else SPREAD_PX


def centre_spread(estimate):
    """The refined centre's spread (pixels): ``hypot(xi_sd, eta_sd)`` of ``estimate``'s
    ``spread``, or ``None``."""
    spread = estimate.get("spread")
    return None if spread is None else float(np.hypot(spread["xi_sd"], spread["eta_sd"]))


def figure_folder(config, out, default):
    """Where a one-sequence experiment draws its figures: ``figure_dir`` for its own
    default data, else ``out/figures``, so that a user's sequence never overwrites the
    committed figures (``replicate`` notes a ``figure_dir`` that got no figure)."""
    if not default:
        return Path(out) / "figures"
    figure_dir = config.get("figure_dir")
    check(isinstance(figure_dir, str) and figure_dir.strip() != "",
          f"figure_dir={'null' if figure_dir is None else repr(figure_dir)}: expected a "
          "folder (figures/ is the default data's)")
    return Path(figure_dir)


def check_motion(sequence):
    """Refuse a sequence whose frames are all identical: there is no motion to find."""
    frames = sequence.frames
    change = np.abs(np.diff(frames, axis=0)).reshape(frames.shape[0] - 1, -1).max(axis=1)
    check(np.any(change > 0), f"{sequence.source}: no motion found: all {frames.shape[0]} "
                              "frames are identical; expected a sequence in which something "
                              "turns")


# pixels inside the invalid border a frame needs: the refinement keeps a pixel only when
# its warped position is inside the border too (frames of 13 and 14 px at sigma 1.5, one
# and two pixels inside, kept none)
MIN_INSIDE = 4


def check_border(sequence, sigma, coarse_side=None):
    """Refuse frames too small to keep :data:`MIN_INSIDE` pixels inside the border that
    smoothing by ``sigma`` leaves invalid (named by the sequence's source); with a pyramid
    (``coarse_side``, the setting named in the message), its top level's frames.

    Parameters
    ----------
    sequence : Sequence
    sigma : float
    coarse_side : tuple of (str, int), optional
        ``(setting name, value)`` of the pyramid's top level side.
    """
    border = default_border(sigma)
    side = 2 * border + MIN_INSIDE
    shape = sequence.frames.shape[1:]
    check(min(shape) >= side,
          f"{sequence.source}: frames of {shape[0]} x {shape[1]} pixels: fewer than "
          f"{MIN_INSIDE} inside the {border}-pixel border that smoothing (sigma={sigma:g}) "
          f"leaves invalid; expected frames of at least {side} x {side} pixels")
    if coarse_side is not None:
        name, value = coarse_side
        top = pyramid.top_shape(shape, int(value))
        check(min(top) >= side,
              f"{name}={value}: the pyramid's top level of {shape[0]} x {shape[1]} frames "
              f"would have {top[0]} x {top[1]} pixels; expected at least {side} x {side} "
              f"at sigma={sigma:g} (a larger {name}, or no pyramid for frames this small)")


def check_grid(shape, settings):
    """Refuse an accumulator (frame ``shape``, ``method.cell``, ``method.margin``) with more
    cells than ``limits.max_frame_pixels``: every omega fills one such array per thread."""
    from replication.guard import LIMITS

    grid = irc.image_grid(shape, margin=settings["margin"], cell=settings["cell"])
    limit = LIMITS["max_frame_pixels"]
    check(grid.nx * grid.ny <= limit,
          f"method.cell={settings['cell']:g}, method.margin={settings['margin']:g}: an "
          f"accumulator of {grid.ny} x {grid.nx} cells for {shape[0]} x {shape[1]} frames; "
          f"expected at most limits.max_frame_pixels={limit:g} cells (a larger cell)")


def _truth_of(sequence):
    """The first truth object of ``sequence`` (one rotation: motion_single, the accuracy
    study), or None; refused when it does not turn (its errors are relative to |omega|)."""
    if not (sequence.truth and sequence.truth.get("objects")):
        return None
    truth = sequence.truth["objects"][0]
    check(truth["omega"] != 0, f"{sequence.source}: truth omega: found 0 (an object that does "
          "not turn); expected the rotation's omega, which the errors are relative to "
          "(segment_multi accepts still objects)")
    return truth


def _methods(config, settings):
    """name -> function(frames, seed) -> {xi, eta, omega} for the accuracy table's baselines."""
    flow = config.get("flow", {})
    de = config.get("de", {})
    motion_min, erode = flow.get("motion_min", 0.25), int(flow.get("erode", 5))
    return {
        "TV-L1 flow + rigid fit": lambda frames, seed: baselines.optical_flow_rotation(
            frames, method="tvl1", motion_min=motion_min, erode=erode,
            flow_options=flow.get("tvl1"), cache_dir=flow.get("cache_dir")),
        "iLK flow + rigid fit": lambda frames, seed: baselines.optical_flow_rotation(
            frames, method="ilk", motion_min=motion_min, erode=erode,
            flow_options=flow.get("ilk"), cache_dir=flow.get("cache_dir")),
        "direct least squares": lambda frames, seed: baselines.direct_least_squares(
            frames, sigma=settings["sigma"], relative_threshold=settings["relative_threshold"]),
        "DE on IRC residual": lambda frames, seed: baselines.de_rotation(
            frames, seed=seed, sigma=settings["sigma"],
            relative_threshold=settings["relative_threshold"],
            max_evals=int(de.get("max_evals", 2000)), pop_size=int(de.get("pop_size", 30)),
            tau=float(de.get("tau", 2.0))),
    }


PAPER, REFINED = "paper (best peak)", "paper + refinement"
FAST = "coarse sweep + refinement"
TVL1, ORACLE = "TV-L1 flow + rigid fit", "TV-L1 flow + fit on the true mask (oracle)"


def _row(name, noise, method, estimate, seconds, truth, shape=None):
    row = {"sequence": name, "noise_255": noise, "method": method, "xi": estimate["xi"],
           "eta": estimate["eta"], "omega": estimate["omega"], "seconds": seconds}
    row.update(single.errors(estimate, truth))
    if "spread" in estimate:
        spread = centre_spread(estimate)
        row["centre_spread_px"] = spread
        row["spread_warned"] = spread is not None and spread > spread_allowed(shape)
    return row


def spread_coverage(rows):
    """How the refined centres' spreads describe their errors, over the ``rows`` that have
    one: the fraction with an error within 2 and 3 spreads, and how often the spread
    warning fires on errors above 2 px and on errors of at most 1 px."""
    mine = [r for r in rows if r.get("centre_spread_px") is not None
            and np.isfinite(r["centre_px"])]
    error = np.array([r["centre_px"] for r in mine], dtype=float)
    spread = np.array([r["centre_spread_px"] for r in mine], dtype=float)
    warned = np.array([r["spread_warned"] for r in mine], dtype=bool)

    def share(mask):
        return float(np.mean(mask)) if mask.size else None

    large, small = error > 2.0, error <= 1.0
    return {"rows": len(mine), "without_spread": sum(
                1 for r in rows if "centre_spread_px" in r and r["centre_spread_px"] is None),
            "within_2_spreads": share(error <= 2 * spread),
            "within_3_spreads": share(error <= 3 * spread),
            "errors_over_2px": {"n": int(large.sum()), "warned": share(warned[large])},
            "errors_at_most_1px": {"n": int(small.sum()), "warned": share(warned[small])}}


def _oracle_row(name, noise, estimate, seconds, truth, labels, erode):
    """TV-L1's flow fitted on the true object mask (eroded like the others): how much of
    the flow method's error is the flow's own, not the segmentation's."""
    start = time.perf_counter()
    mask = single.erode(labels[0] > 0, erode)
    fit = baselines.rigid_fit(estimate["flow"][0], estimate["flow"][1], mask)
    return _row(name, noise, ORACLE, fit, seconds + time.perf_counter() - start, truth)


def _one_case(name, noise, frames, truth, labels, methods, chosen, settings, config):
    """Rows of every chosen method on one noisy sequence."""
    seed = config["seed"]
    rows = []
    if PAPER in chosen or REFINED in chosen:
        found = single.find_rotation(frames, settings)
        if PAPER in chosen:
            rows.append(_row(name, noise, PAPER, found["paper"], found["seconds"]["paper"],
                             truth))
        if REFINED in chosen:
            rows.append(_row(name, noise, REFINED, found["refined"],
                             found["seconds"]["paper"] + found["seconds"]["refined"], truth,
                             frames.shape[1:]))
    if FAST in chosen:
        fast = single.coarse_then_refined(frames, settings)
        rows.append(_row(name, noise, FAST, fast["refined"], sum(fast["seconds"].values()),
                         truth, frames.shape[1:]))
    for method in chosen:
        if method in methods:
            start = time.perf_counter()
            estimate = methods[method](frames, seed)
            seconds = time.perf_counter() - start
            rows.append(_row(name, noise, method, estimate, seconds, truth))
            if method == TVL1 and ORACLE in chosen and labels is not None:
                rows.append(_oracle_row(name, noise, estimate, seconds, truth, labels,
                                        int(config.get("flow", {}).get("erode", 5))))
    return rows


def _accuracy_sequences(config):
    data_dir = Path(config["sequences_dir"])
    manifest_path = data_dir / "manifest.json"
    sequences = read_manifest_sequences(manifest_path, "motion_data")
    chosen = {name: item for name, item in sequences.items() if item["role"] == "accuracy"}
    limit = config.get("max_sequences")
    if limit is not None:
        chosen = dict(list(chosen.items())[: int(limit)])
    check(len(chosen) > 0, f"{manifest_path}: no sequence with role 'accuracy'; expected at "
          "least one")
    return chosen


def _summarise(rows, methods, noise_levels):
    summary = []
    for method in methods:
        for noise in noise_levels:
            mine = [r for r in rows if r["method"] == method and r["noise_255"] == noise]
            if not mine:
                continue
            centre = np.array([r["centre_px"] for r in mine], dtype=float)
            omega = np.abs(np.array([r["omega_pct"] for r in mine], dtype=float))
            seconds = np.array([r["seconds"] for r in mine], dtype=float)
            centre = np.where(np.isfinite(centre), centre, np.inf)
            omega = np.where(np.isfinite(omega), omega, np.inf)
            goal_px, goal_pct = (1.0, 3.0) if noise == 0 else (2.0, 5.0)
            summary.append({
                "method": method, "noise_255": noise, "n": len(mine),
                "centre_px_median": float(np.median(centre)),
                "centre_px_max": float(np.max(centre)),
                "omega_pct_median": float(np.median(omega)),
                "omega_magnitude_pct_median": float(np.median(
                    [r["omega_magnitude_pct"] for r in mine])),
                "omega_pct_max": float(np.max(omega)),
                "seconds_median": float(np.median(seconds)),
                "goal_px": goal_px, "goal_pct": goal_pct,
                "within_goal": float(np.mean((centre <= goal_px) & (omega <= goal_pct))),
            })
    return summary


def _start_worker():
    """Worker set-up: one numba thread (every method then runs on one core), warm kernels."""
    import numba

    numba.set_num_threads(1)
    single.warm_up()


def _case(args):
    """All methods on one (sequence, noise level); runs in a worker process."""
    from replication.motion.synth import degrade

    config, settings, chosen, name, path, i, j, noise = args
    sequence = read_sequence(path)
    frames = degrade(sequence.frames, noise_sigma=noise / 255.0,
                     rng=np.random.default_rng([config["seed"], i, j]))
    return _one_case(name, noise, frames, _truth_of(sequence), sequence.labels,
                     _methods(config, settings), chosen, settings, config)


def _run_cases(cases, workers):
    """Results of :func:`_case` for every case, in order, on ``workers`` processes."""
    from replication.workers import process_pool, usable_workers

    if usable_workers(workers, "sequences x noise levels") == 1:
        import numba

        threads = numba.get_num_threads()
        _start_worker()
        try:
            yield from map(_case, cases)
        finally:
            numba.set_num_threads(threads)
        return
    with process_pool(workers, initializer=_start_worker) as pool:
        yield from pool.map(_case, cases)


def accuracy(config, out):
    """The accuracy table: every method on every accuracy sequence at every noise level.

    Noise ``sigma = noise_255 / 255`` is added at run time from
    ``default_rng([seed, sequence index, noise index])``. Cases run on ``workers``
    processes; each method of a case runs in the same process, one after another, on one
    core (numba limited to one thread), and its wall-clock seconds are recorded.
    """
    settings = single.settings_from(config.get("method"))
    _check_settings(settings)
    noise_levels = [float(v) for v in config["noise_levels_255"]]
    check(len(noise_levels) > 0 and min(noise_levels) >= 0,
          f"noise_levels_255: {noise_levels}; expected a non-empty list of values >= 0")
    known = [PAPER, REFINED, FAST, *_methods(config, settings), ORACLE]
    chosen = config.get("methods") or known
    unknown = [name for name in chosen if name not in known]
    check(not unknown, f"methods: unknown {unknown}; expected some of {known}")
    workers = int(config.get("workers", 1))
    check(workers >= 1, f"workers={workers}: expected at least 1 process")
    sequences = _accuracy_sequences(config)
    loaded = read_listed(sequences, Path(config["sequences_dir"]) / "manifest.json")
    for sequence in loaded.values():
        check(_truth_of(sequence) is not None,
              f"{sequence.source}: truth: missing; expected ground truth for the accuracy table")
    cases = [(config, settings, chosen, name, sequences[name]["path"], i, j, noise)
             for i, name in enumerate(loaded) for j, noise in enumerate(noise_levels)]
    rows, load_before = [], os.getloadavg()[0]
    for case in bar(_run_cases(cases, workers), "sequences x noise levels", total=len(cases)):
        rows.extend(case)
        progress(f"{case[0]['sequence']} noise {case[0]['noise_255']:g}/255: " + ", ".join(
            f"{r['method']} {r['centre_px']:.2f}px {r['omega_pct']:+.1f}%" for r in case))
    truths = {name: _truth_of(s) for name, s in loaded.items()}
    return {"sequences": {name: {k: truths[name][k] for k in ("xi", "eta", "omega")}
                          for name in loaded},
            "noise_levels_255": noise_levels, "methods": chosen, "workers": workers,
            "wall_load_average_1min": {"start": load_before, "end": os.getloadavg()[0]},
            "rows": rows, "summary": _summarise(rows, chosen, noise_levels),
            "spread_coverage": {method: spread_coverage(
                [r for r in rows if r["method"] == method]) for method in (REFINED, FAST)
                if method in chosen}}


def _best_time(function, repeats):
    """Shortest wall-clock time of ``repeats`` calls (the least disturbed run, as
    ``timeit`` recommends on a shared machine)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return float(np.min(times))


def benchmark(config, out):
    """Voting throughput against ``skimage.transform.hough_line``, and the sweep time.

    Both vote with the same pixels (those above the gradient threshold in the first frame
    pair); Hough casts one vote per pixel and angle (``n_angles`` angles), the accumulation
    one per accumulator column or row per pixel and omega. Best of ``repeats`` runs after a
    warm-up, for both.
    """
    import numba
    from skimage.transform import hough_line

    settings = single.settings_from(config.get("method"))
    _check_settings(settings)
    repeats = int(config.get("repeats", 5))
    check(repeats >= 1, f"repeats={repeats}: expected at least 1")
    sequence = _load(config.get("data", {}).get("path") or config["default_data"])
    frames = sequence.frames[:2]
    check_grid(frames.shape[1:], settings)     # the benchmark votes into an exact accumulator
    derive = lambda: sequence_derivatives(frames, sigma=settings["sigma"],  # noqa: E731
                                          relative_threshold=settings["relative_threshold"])
    pixels = derive()
    grid = irc.image_grid(frames.shape[1:], margin=settings["margin"], cell=settings["cell"])
    omegas = irc.omega_sweep(settings["omega_min"], settings["omega_max"],
                             int(settings["omega_count"]))
    irc.sweep(pixels, omegas, grid)
    threads = numba.get_num_threads()
    sweep_s = _best_time(lambda: irc.sweep(pixels, omegas, grid), repeats)
    votes = int(irc.sweep(pixels, omegas, grid)["votes"].sum())
    numba.set_num_threads(1)
    try:
        sweep_1thread_s = _best_time(lambda: irc.sweep(pixels, omegas, grid), repeats)
    finally:
        numba.set_num_threads(threads)
    edges = np.zeros(frames.shape[1:], dtype=bool)
    edges[pixels.y.astype(int), pixels.x.astype(int)] = True
    angles = np.linspace(-np.pi / 2, np.pi / 2, int(config.get("n_angles", 180)),
                         endpoint=False)
    hough_line(edges, angles)
    hough_s = _best_time(lambda: hough_line(edges, angles), repeats)
    hough_votes = int(np.count_nonzero(edges)) * angles.size
    derivatives_s = _best_time(derive, repeats)
    found = single.find_rotation(sequence.frames, settings)
    voting = votes / sweep_s
    hough = hough_votes / hough_s
    progress(f"voting {voting:.3g} cells/s ({threads} threads), hough_line {hough:.3g} votes/s")
    metrics = {
        "frame_height_px": frames.shape[1], "frame_width_px": frames.shape[2],
        "omega_values": int(omegas.size), "voting_pixels": int(len(pixels)),
        "numba_threads": threads,
        "sweep_s": sweep_s,
        "voting_cells_per_s": voting,
        "voting_cells_per_s_1thread": votes / sweep_1thread_s,
        "hough_line_votes_per_s": hough,
        "voting_over_hough_ratio": voting / hough,
        "voting_over_hough_ratio_1thread": votes / sweep_1thread_s / hough,
        "derivatives_s": derivatives_s,
        "paper_method_s": found["seconds"]["paper"],
        "refinement_s": found["seconds"]["refined"],
        "load_average_1min": os.getloadavg()[0],
    }
    return {"data": sequence.source, "metrics": metrics,
            "goals": {"ratio_at_least": 1.0, "sweep_s_below": 1.5}}
