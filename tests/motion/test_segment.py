"""Rigid-motion segmentation (paper 2.3): EA with sharing, radial snakes, the pipeline."""

import json

import numpy as np
import pytest

from replication.errors import InputError
from replication.experiments.segment import score_objects
from replication.motion.multi_synth import make_multi_sequence
from replication.motion.segment import assignment, disc_ea, snakes
from replication.motion.segment import pipeline as segmentation
from tests.test_cli import assert_regenerated_identically, run_cli

TWO_OBJECTS = {
    "shape": [128, 128], "n_frames": 2, "supersample": 2, "noise_sigma": 1 / 255,
    "background_texture": {"kind": "procedural", "scale": 1.5},
    "objects": [
        {"center": [38, 40], "omega": 0.04, "texture": {"kind": "procedural", "scale": 1.5},
         "shape": {"center": [38, 40], "r_inner": 0, "r_outer": 24, "gap_deg": 0}},
        {"center": [92, 86], "omega": -0.045, "texture": {"kind": "procedural", "scale": 1.5},
         "shape": {"center": [90, 88], "r_inner": 0, "r_outer": 24, "gap_deg": 0}}],
}
SMALL = {"ea": {"pop_size": 100, "generations": 40, "r_max": 24.0, "margin": 20.0,
                "beta": 20.0, "R": 20.0, "sharing": 20.0, "motion_ratio": 1.0,
                "project_fresh": True},
         "snake": {"deflate": True, "rounds": 2, "rho_max": 60},
         "accumulation": {"window": 20.0}}


@pytest.fixture(scope="module")
def two_objects():
    return make_multi_sequence(TWO_OBJECTS, rng=1)


def test_two_rotating_objects_are_segmented(two_objects):
    frames, labels, truth = two_objects
    found = segmentation.segment(frames, segmentation.settings_from(SMALL), 3)
    score = score_objects(found["objects"], labels[0], truth)
    for row in score["per_object"]:
        assert row["centre_px"] <= 2.0, row
        assert row["iou"] >= 0.6, row
        assert abs(row["omega_pct"]) <= 15.0, row
    assert score["false_regions"] == 0


def test_zero_motion_gives_no_rotating_region(two_objects):
    _, _, truth = two_objects
    static = json.loads(json.dumps(TWO_OBJECTS))
    for item in static["objects"]:
        item["omega"] = 0.0
    frames, _, _ = make_multi_sequence(static, rng=1)
    found = segmentation.segment(frames, segmentation.settings_from(SMALL), 3)
    assert found["objects"] == []
    assert not found["rotating"].any()


def test_sharing_penalises_only_the_higher_cost_of_an_overlapping_pair():
    x, y, r = np.array([10.0, 15.0, 80.0]), np.array([10.0, 10.0, 80.0]), np.full(3, 8.0)
    cost = np.array([5.0, 3.0, 4.0])
    shared = disc_ea.shared_costs(cost, x, y, r, coefficient=2.0, area_unit=10.0)
    overlap = disc_ea.overlap_areas(x, y, r)[0, 1]
    assert overlap > 0
    assert shared[1] == cost[1] and shared[2] == cost[2]
    assert shared[0] == pytest.approx(cost[0] + 2.0 * overlap / 10.0)


def test_overlap_area_matches_pixel_count():
    x, y, r = np.array([0.0, 9.0]), np.array([0.0, 4.0]), np.array([10.0, 7.0])
    grid = np.mgrid[-30:30:0.05, -30:30:0.05]
    inside = ((grid[1] - x[0]) ** 2 + (grid[0] - y[0]) ** 2 < r[0] ** 2) & \
        ((grid[1] - x[1]) ** 2 + (grid[0] - y[1]) ** 2 < r[1] ** 2)
    assert disc_ea.overlap_areas(x, y, r)[0, 1] == pytest.approx(inside.sum() * 0.0025,
                                                                 rel=0.01)


def test_snake_keeps_only_energy_lowering_inflations():
    rng = np.random.default_rng(0)
    # sector energies: inside radius 20 pixels follow (-1 each), beyond they contradict
    profile = np.where(np.arange(61) < 20, -1.0, 1.0) * rng.uniform(0.5, 1.5, (32, 61))
    cumulative = np.cumsum(profile, axis=1)
    rho, history = snakes.inflate(cumulative, 5, kappa=0.05, iterations=200)
    assert len(history) < 201, "did not converge"
    assert np.all(np.diff(history) <= 0) and history[-1] < history[0]
    assert np.all(rho >= 5) and np.all(rho <= 28)
    index = np.arange(32)
    final = cumulative[index, rho].sum() + snakes.stiffness_energy(rho, 0.05)
    assert final == pytest.approx(history[-1])
    for k in range(32):
        for step in (1, 2, 4, 8):
            trial = rho.copy()
            trial[k] = min(trial[k] + step, 60)
            assert (cumulative[index, trial].sum() + snakes.stiffness_energy(trial, 0.05)
                    >= history[-1] - 1e-12)


def test_ea_is_deterministic_for_a_seed(two_objects):
    data = disc_ea.disc_data(two_objects[0])
    settings = {**SMALL["ea"], "generations": 5}
    a = disc_ea.DiscEA(data, settings, rng=7).run()
    b = disc_ea.DiscEA(data, settings, rng=7).run()
    c = disc_ea.DiscEA(data, settings, rng=8).run()
    assert np.array_equal(a["population"], b["population"])
    assert not np.array_equal(a["population"], c["population"])


def test_ea_keeps_a_quarter_at_most_whatever_the_rounding(two_objects):
    # keep = 0.25 of 150 rounds to 38 kept, and 4 x 38 > 150: the kept and their three
    # mutated copies must still fit (this ended in a numpy error before)
    data = disc_ea.disc_data(two_objects[0])
    ea = disc_ea.DiscEA(data, {**SMALL["ea"], "pop_size": 150, "keep": 0.25,
                               "generations": 2}, rng=0)
    assert ea.n_keep == 37
    assert ea.run()["population"].shape == (150, 6)


@pytest.mark.parametrize("method, message", [
    ({"ea": {"pop_size": 3}}, "pop_size=3: expected at least 10"),
    ({"ea": {"r_min": 10, "r_max": 5}}, "expected 0 < r_min < r_max"),
    ({"ea": {"keep": 0.5}}, "keep=0.5"),
    ({"snake": {"stiffness": 1}}, "method.snake: unknown setting(s) ['stiffness']"),
    ({"search": "cmaes"}, "method.search: 'cmaes'; expected paper or nichega"),
    ({"colour": {}}, "method: unknown group(s) ['colour']"),
    ({"assign": {"sigma": 0}}, "method.assign.sigma=0: expected a value > 0"),
    ({"assign": {"share": 1.5}}, "expected shares of at most 1"),
])
def test_bad_settings_are_refused_with_the_setting_named(method, message):
    with pytest.raises(InputError) as error:
        segmentation.settings_from(method)
    assert message in str(error.value)


def test_real_command_line_writes_objects_and_masks(tmp_path, two_objects):
    from replication.motion.io import write_sequence_npz

    frames, labels, truth = two_objects
    data = tmp_path / "two.npz"
    write_sequence_npz(data, frames, labels=labels, truth=truth)
    tiny = ["method.ea.pop_size=60", "method.ea.generations=10", "method.ea.r_max=24",
            "method.ea.margin=20", "method.snake.rho_max=60"]
    results = []
    for name in ("a", "b"):
        done = run_cli("experiment=segment_multi", f"data.path={data}",
                       f"out={tmp_path / name}", *tiny)
        assert done.returncode == 0, done.stderr
        results.append(json.loads((tmp_path / name / "result.json").read_text()))
    for item in results[0]["objects"]:
        assert set(item) >= {"xi", "eta", "omega", "area", "mask_file"}
        assert (tmp_path / "a" / item["mask_file"]).exists()
    assert results[0]["objects"] == results[1]["objects"]
    assert (tmp_path / "a" / "figures" / "fig05_discs.png").exists()


def test_study_refuses_an_unknown_method(tmp_path):
    done = run_cli("experiment=segment_study", f"out={tmp_path / 'out'}", "+seeds.cmaes=1")
    assert done.returncode == 2
    assert "seeds: unknown method(s) ['cmaes']" in done.stderr
    assert not (tmp_path / "out" / "result.json").exists()


@pytest.mark.parametrize("overrides, message", [
    (["data.path=/nonexistent/seq.npz"], "no such file or folder"),
    (["method.ea.generations=0"], "generations=0: expected at least 1"),
])
def test_bad_input_on_the_command_line_gives_one_line(tmp_path, overrides, message):
    done = run_cli("experiment=segment_multi", f"out={tmp_path / 'out'}", *overrides)
    assert done.returncode == 2
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0]
    assert not (tmp_path / "out" / "result.json").exists()


def test_generator_refuses_too_many_objects_with_the_count_named():
    spec = json.loads(json.dumps(TWO_OBJECTS))
    spec["objects"] = spec["objects"] * 5
    with pytest.raises(InputError, match="objects: 10 object"):
        make_multi_sequence(spec, rng=0)


def test_generator_is_deterministic_and_labels_follow_the_objects(two_objects):
    frames, labels, truth = make_multi_sequence(TWO_OBJECTS, rng=1)
    assert np.array_equal(frames, two_objects[0]) and np.array_equal(labels, two_objects[1])
    assert [o["label"] for o in truth["objects"]] == [1, 2]
    area = np.count_nonzero(labels[0] == 1)
    assert area == pytest.approx(np.pi * 24 ** 2, rel=0.05)


@pytest.mark.slow
def test_committed_multi_object_data_is_regenerated_identically(tmp_path):
    assert_regenerated_identically("motion_multi_data", "synthetic_data/motion_multi",
                                   tmp_path)


def test_study_runs_on_one_sequence_with_tiny_settings(tmp_path, monkeypatch):
    monkeypatch.setenv("REPLICATION_PROGRESS", "plain")
    done = run_cli("experiment=segment_study", f"out={tmp_path / 'out'}", "max_sequences=1",
                   "seeds={pipeline: 1, faithful: 0, refined: 0, nichega: 0, flow: 1, "
                   "no_fresh_projection: 0, inflate_only: 0, one_round: 0, no_extra_seeds: 1, "
                   "no_assign: 0, no_rescue: 0}",
                   "method.ea.pop_size=60",
                   "method.ea.generations=10")
    assert done.returncode == 0, done.stderr
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    assert {s["method"] for s in result["summary"]} == {"pipeline", "flow", "no_extra_seeds"}
    assert {r["role"] for r in result["rows"]} == {"study", "static"}
    # progress lines only for the methods that ran (0 seeds: not "found 0.00 of objects")
    lines = [line for line in done.stderr.splitlines() if " of objects," in line]
    assert lines and all(line.split(":")[0].split()[-1] in
                         {"pipeline", "flow", "no_extra_seeds"} for line in lines), lines
    for row in result["rows"]:
        for item in row["per_object"]:
            assert 0.0 <= item["iou"] <= 1.0


# a C-shape whose rotation centre (60, 64) lies in its own hole (the shape's centre is
# (64, 64), its hole 22 px in radius): a radial snake is star-shaped around the centre
C_IN_HOLE = {
    "shape": [128, 128], "n_frames": 2, "supersample": 2, "noise_sigma": 1 / 255,
    "background_texture": {"kind": "procedural", "scale": 1.5},
    "objects": [
        {"center": [60, 64], "omega": 0.03, "texture": {"kind": "procedural", "scale": 2.0},
         "shape": {"center": [64, 64], "r_inner": 22, "r_outer": 46, "gap_deg": 120,
                   "gap_dir_deg": 0}}],
}
ASSIGN = {"enabled": True, "weight_power": 2.0, "keep_share": 0.3, "rescue": 2}


@pytest.fixture(scope="module")
def c_in_hole():
    return make_multi_sequence(C_IN_HOLE, rng=2)


def _iou(a, b):
    return np.count_nonzero(a & b) / np.count_nonzero(a | b)


def test_assignment_follows_a_c_shape_whose_centre_is_in_its_hole(c_in_hole):
    frames, labels, truth = c_in_hole
    true_mask = labels[0] == 1
    data = disc_ea.disc_data(frames)
    motion = {"xi": 60.0, "eta": 64.0, "omega": 0.03}
    # a radial snake from a disc on the object's left side, as the EA would give it
    snake = snakes.radial_snake(data, [30.0, 64.0, 8.0, 60.0, 64.0, 0.03], rho_max=60,
                                deflate=True)
    settings = {**assignment.DEFAULTS, **ASSIGN}
    mask, = assignment.assign(data, [{**motion, "mask": snake["mask"]}], settings)
    assert _iou(mask, true_mask) >= 0.7
    assert _iou(mask, true_mask) > _iou(snake["mask"], true_mask) + 0.05
    hole = np.hypot(*np.mgrid[0:128, 0:128][::-1] - np.array([64, 64])[:, None, None]) < 12
    assert np.count_nonzero(mask & hole) < 0.2 * np.count_nonzero(hole)


def test_pipeline_with_assignment_segments_the_c_shape(c_in_hole):
    frames, labels, truth = c_in_hole
    rows = {}
    for enabled in (False, True):
        method = {**SMALL, "assign": {**ASSIGN, "enabled": enabled},
                  "merge": {"extra_seeds": 3}}
        found = segmentation.segment(frames, segmentation.settings_from(method), 3)
        rows[enabled] = score_objects(found["objects"], labels[0], truth)["per_object"][0]
    assert rows[True]["iou"] >= 0.7 and rows[True]["centre_px"] <= 2.0, rows
    assert rows[True]["iou"] >= rows[False]["iou"], rows


def test_assignment_switched_off_leaves_the_pipeline_unchanged(two_objects):
    frames = two_objects[0]
    base = segmentation.segment(frames, segmentation.settings_from(SMALL), 3)
    off = {**SMALL, "assign": {**ASSIGN, "enabled": False, "sigma": 9.0, "margin": 0.5}}
    other = segmentation.segment(frames, segmentation.settings_from(off), 3)
    assert len(base["objects"]) == len(other["objects"]) > 0
    for a, b in zip(base["objects"], other["objects"]):
        assert np.array_equal(a["mask"], b["mask"]) and "snake_mask" not in b
        assert (a["xi"], a["eta"], a["omega"]) == (b["xi"], b["eta"], b["omega"])
    assert segmentation.FAITHFUL["assign"] == {"enabled": False}


def test_flat_patch_joins_the_object_that_rings_it():
    labels = np.zeros((40, 40), dtype=int)
    labels[5:25, 5:25] = 1            # object 1, with a flat (undecided) face inside
    labels[10:20, 10:20] = -1
    labels[28:36, 28:40] = -1         # a flat patch of the static background at the border
    valid = np.zeros((40, 40), dtype=bool)
    valid[2:38, 2:38] = True
    out = assignment.fill_undecided(labels, valid, 1, reach=2, share=0.6)
    assert np.all(out[10:20, 10:20] == 1)
    assert np.all(out[28:36, 28:38] == -1)


def test_flat_face_behind_an_undecided_edge_joins_when_flat_patches_go_first():
    labels = np.zeros((40, 40), dtype=int)
    labels[5:30, 5:30] = 1            # object 1
    labels[10:20, 10:20] = -1         # a flat face ...
    labels[10:20, 5:10] = -1          # ... behind an undecided edge (with a gradient) ...
    labels[10:38, 2:5] = -1           # ... that runs on into undecided background
    labels[32:38, 2:38] = -1
    flat = np.zeros((40, 40), dtype=bool)
    flat[10:20, 10:20] = True
    valid = np.zeros((40, 40), dtype=bool)
    valid[2:38, 2:38] = True
    plain = assignment.fill_undecided(labels, valid, 1, reach=2, share=0.6)
    first = assignment.fill_undecided(labels, valid, 1, reach=2, share=0.6, flat=flat)
    assert np.all(plain[10:20, 10:20] == -1)
    assert np.all(first[10:20, 10:20] == 1)


def test_rescue_finds_objects_that_the_disc_search_missed(two_objects):
    frames, labels, truth = two_objects
    data = disc_ea.disc_data(frames)
    settings = segmentation.settings_from({**SMALL, "assign": ASSIGN})
    pixels = segmentation.dense_to_pixels(data)
    found = segmentation.rescued_objects(data, pixels, [], settings)
    for item in truth["objects"]:
        error = min(np.hypot(f["xi"] - item["xi"], f["eta"] - item["eta"]) for f in found)
        assert error <= 2.0, (item, [(f["xi"], f["eta"]) for f in found])


def test_rescue_finds_nothing_on_a_static_sequence(two_objects):
    static = json.loads(json.dumps(TWO_OBJECTS))
    for item in static["objects"]:
        item["omega"] = 0.0
    frames, _, _ = make_multi_sequence(static, rng=1)
    data = disc_ea.disc_data(frames)
    settings = {**assignment.DEFAULTS, **ASSIGN}
    assert assignment.unexplained_regions(data, [], settings) == []


def test_a_camera_pan_is_warned_about_and_a_rotation_is_not():
    """Frames made here with scipy.ndimage from a smooth random texture: one translated by
    (1, 0) px/frame, one rotated about its centre."""
    import yaml
    from scipy import ndimage

    from replication.experiments.segment_multi import translation_warnings
    from replication.motion.segment import pipeline as segmentation

    settings = segmentation.settings_from(yaml.safe_load(open(
        "configs/segment_method/paper.yaml")))
    texture = ndimage.gaussian_filter(np.random.default_rng(0).random((140, 140)), 2.0)
    pan = np.stack([ndimage.shift(texture, (0, t), order=3, mode="nearest")[10:-10, 10:-10]
                    for t in range(3)])
    turn = np.stack([ndimage.rotate(texture, 1.5 * t, reshape=False, order=3,
                                    mode="nearest")[10:-10, 10:-10] for t in range(3)])
    warned = translation_warnings(pan, settings)
    assert len(warned) == 1 and "one translation (1" in warned[0]
    assert translation_warnings(turn, settings) == []


def _turning_disc(omega, *, side=128, radius=30, frames=3, noise=0.0, seed=0):
    """A smooth random texture whose disc about the centre turns by ``omega`` rad/frame
    (scipy's rotation, nothing of the suite) over a still background."""
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    texture = ndimage.gaussian_filter(rng.random((side, side)), 2.0) * 255
    yy, xx = np.mgrid[:side, :side]
    disc = (xx - side / 2) ** 2 + (yy - side / 2) ** 2 <= radius ** 2
    out = []
    for t in range(frames):
        turned = ndimage.rotate(texture, np.degrees(omega * t), reshape=False, order=3)
        frame = np.where(disc, turned, texture) + noise * rng.standard_normal((side, side))
        out.append(frame)
    return np.array(out), disc


def test_a_small_missed_object_beside_a_large_found_one_is_warned():
    """A small disc turning at -0.15 rad/frame (beyond the omega bounds) beside a large one
    found was 14% of the moving blocks, under the 20% share: it was missed without a word.
    Its 10 touching blocks are warned now; with both found, nothing is."""
    from scipy import ndimage

    from replication.experiments.segment_multi import motion_outside_warnings

    settings = segmentation.settings_from(None)
    side = 256
    texture = ndimage.gaussian_filter(np.random.default_rng(0).random((side, side)), 2.0)
    yy, xx = np.mgrid[:side, :side]

    def turned(cx, cy, omega, t):   # the texture turned about (cx, cy), with scipy alone
        centred = ndimage.shift(texture, (side / 2 - cy, side / 2 - cx), order=3,
                                mode="nearest")
        centred = ndimage.rotate(centred, np.degrees(omega * t), reshape=False, order=3,
                                 mode="nearest")
        return ndimage.shift(centred, (cy - side / 2, cx - side / 2), order=3, mode="nearest")

    large = (xx - 100) ** 2 + (yy - 120) ** 2 <= 75 ** 2
    small = (xx - 210) ** 2 + (yy - 210) ** 2 <= 26 ** 2
    frames = np.array([np.where(small, turned(210, 210, -0.15, t),
                                np.where(large, turned(100, 120, 0.02, t), texture))
                       for t in range(3)])
    missed = motion_outside_warnings(frames, {"objects": [{"mask": large}]}, settings)
    assert len(missed) == 1 and "(10 of 71; the largest touching patch: 10)" in missed[0]
    assert motion_outside_warnings(frames, {"objects": [{"mask": large}, {"mask": small}]},
                                   settings) == []


def test_moving_blocks_outside_every_object_are_warned():
    """An outside user's disc turning at 0.15 rad/frame, beyond the omega bounds, was
    missed without a word; a still scene got an empty object list without one."""
    from replication.experiments.segment_multi import motion_outside_warnings

    settings = segmentation.settings_from(None)
    frames, disc = _turning_disc(0.15)
    missed = motion_outside_warnings(frames, {"objects": []}, settings)
    assert len(missed) == 1 and missed[0].startswith("no rotating object found, yet")
    assert motion_outside_warnings(frames, {"objects": [{"mask": disc}]}, settings) == []
    other = np.zeros_like(disc)
    other[:20, :20] = True
    partly = motion_outside_warnings(frames, {"objects": [{"mask": other}]}, settings)
    assert len(partly) == 1 and "lie outside every object found" in partly[0]
    still, _ = _turning_disc(0.0, noise=1.0)
    assert motion_outside_warnings(still, {"objects": []}, settings) == [
        "no rotating object found, and no part of the frame moves beyond single pixels (a "
        "still scene, or noise only)"]


def test_flow_baseline_finds_the_same_objects_at_any_intensity_scale(two_objects):
    """The flow + RANSAC baseline reads its flow through the one flow engine
    (``motion.baselines.flow_field``), which maps frames off the 0..1 scale to it: frames
    as float 0..255 give what the same frames mapped to 0..1 give."""
    from replication.motion.segment.baselines import flow_ransac_segment

    frames = two_objects[0]
    low, high = frames[:2].min(), frames[:2].max()
    found = [flow_ransac_segment(scaled, {}, 5)
             for scaled in ((frames - low) / (high - low), frames * 255.0)]
    assert found[0] and len(found[0]) == len(found[1])
    for a, b in zip(*found):
        assert abs(a["xi"] - b["xi"]) < 0.05 and abs(a["omega"] - b["omega"]) < 1e-4
        assert np.array_equal(a["mask"], b["mask"])


def _translating_disc(side=128, radius=30, frames=3, speed=1.0):
    """A smooth random texture whose disc about the centre shifts by ``speed`` px/frame
    along x (scipy's shift, nothing of the suite) over a still background."""
    from scipy import ndimage

    texture = ndimage.gaussian_filter(np.random.default_rng(4).random((side, side)), 2.0)
    yy, xx = np.mgrid[:side, :side]
    disc = (xx - side / 2) ** 2 + (yy - side / 2) ** 2 <= radius ** 2
    out = [np.where(disc, ndimage.shift(texture, (0, speed * t), order=3, mode="nearest"),
                    texture) for t in range(frames)]
    return np.array(out), disc, xx


def test_a_translating_object_found_as_rotating_pieces_is_warned():
    """An outside user's disc shifting 1 px/frame was found as rotating pieces turning
    opposite ways (a 'rotation' each) without a word. Each half of it is warned as moving
    like one translation; a disc turning about its own centre is not."""
    from replication.experiments.segment_multi import translating_object_warnings
    from replication.motion.coverage import translating_regions

    settings = segmentation.settings_from(None)
    frames, disc, xx = _translating_disc()
    halves = [{"mask": disc & (xx < 64), "xi": 50.0, "eta": 64.0, "omega": 0.05},
              {"mask": disc & (xx >= 64), "xi": 78.0, "eta": 64.0, "omega": -0.05}]
    warned = translating_object_warnings(frames, {"objects": halves}, settings)
    assert [w.split(":")[0] for w in warned] == ["object 0", "object 1"]
    assert all("moves like one translation (1" in w for w in warned), warned
    turning, turning_disc = _turning_disc(0.03)
    from replication.motion.derivatives import sequence_derivatives
    pixels = sequence_derivatives(turning, sigma=1.5, relative_threshold=0.15)
    assert translating_regions(pixels, [turning_disc], settings["snake"]["tolerance"]) == []


def test_objects_found_in_pieces_are_scored_as_split():
    """Five objects on one true disc (one matching it, four pieces) scored 0 false regions
    and nothing else: the pieces are split regions now."""
    from replication.experiments.segment import score_objects

    labels = np.zeros((64, 64), dtype=int)
    labels[10:50, 10:50] = 1
    whole = {"mask": labels == 1, "xi": 30.0, "eta": 30.0, "omega": 0.02}
    piece = np.zeros((64, 64), dtype=bool)
    piece[12:20, 12:20] = True
    background = np.zeros((64, 64), dtype=bool)
    background[55:, 55:] = True
    found = [whole, {"mask": piece, "xi": 15.0, "eta": 15.0, "omega": -0.05},
             {"mask": background, "xi": 60.0, "eta": 60.0, "omega": 0.03}]
    score = score_objects(found, labels, {"objects": [{"label": 1, "xi": 30.0, "eta": 30.0,
                                                       "omega": 0.02}]})
    assert (score["false_regions"], score["split_regions"]) == (1, 1)
    assert score["per_object"][0]["found"] is True
