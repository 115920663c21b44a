"""The pyramid method (method.accumulation=pyramid) against ground truth, and the exact
method's answer held to the committed one."""

import ast
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from replication.errors import InputError
from replication.motion import irc, pyramid, scale_data, single
from replication.motion.derivatives import default_border, smooth
from replication.motion.io import read_sequence

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def pair_512():
    """Two noisy 8-bit frames of 512 x 512 from the independent generator, and the truth."""
    frames, truth, _ = scale_data.render(512, seed=1, noise_sigma=2 / 255, bits=8,
                                         scene={"n_frames": 2})
    return frames, truth["objects"][0]


def test_pyramid_finds_the_centre_on_512(pair_512):
    frames, truth = pair_512
    settings = single.settings_from({"accumulation": "pyramid", "coarse_side": 128,
                                     "omega_count": 40})
    found = single.find_rotation(frames, settings)
    assert found["pyramid"]["factor"] == 4
    assert found["pyramid"]["shapes"] == [[512, 512], [256, 256], [128, 128]]
    error = single.errors(found["refined"], truth)
    assert error["centre_px"] <= 1.0 and abs(error["omega_pct"]) <= 3.0
    # the best peak is found on 1/4 of the resolution: within a few input pixels
    assert single.errors(found["paper"], truth)["centre_px"] <= 4 * 2.0


def test_exact_method_keeps_the_committed_answer():
    # results/motion_single/result.json (paper-like sequence, the paper's settings)
    frames = read_sequence(ROOT / "synthetic_data" / "motion" / "paper_like").frames
    found = single.find_rotation(frames, single.settings_from({}))
    assert found["paper"] == {"xi": 69.0, "eta": 141.0, "omega": -0.025, "peak": 523}
    refined = found["refined"]
    np.testing.assert_allclose(
        [refined["xi"], refined["eta"], refined["omega"]],
        [69.1051062612792, 140.01728967720365, -0.022901793875021316], rtol=0, atol=1e-9)
    assert (refined["iterations"], refined["pixels"]) == (7, 3821)
    assert "pyramid" not in found


def test_pyramid_on_small_frames_is_the_exact_method(small_sequence, fast_settings):
    frames = small_sequence[0]
    exact = single.find_rotation(frames, fast_settings)
    small = single.find_rotation(frames, dict(fast_settings, accumulation="pyramid"))
    assert small["pyramid"]["factor"] == 1
    assert small["paper"] == exact["paper"] and small["refined"] == exact["refined"]


def test_reduce_keeps_coordinates():
    # a ramp I = 0.3 x + 0.7 y, reduced: pixel (row i, col j) of the level holds the ramp at
    # the input point (2 j + 0.5, 2 i + 0.5)
    rows, cols = np.mgrid[0:40, 0:40].astype(float)
    reduced = pyramid.reduce((0.3 * cols + 0.7 * rows)[None])[0]
    r, c = np.mgrid[0:20, 0:20].astype(float)
    expected = 0.3 * pyramid.to_input(c, 2) + 0.7 * pyramid.to_input(r, 2)
    np.testing.assert_allclose(reduced[1:-1, 1:-1], expected[1:-1, 1:-1], atol=1e-12)
    assert pyramid.to_level(pyramid.to_input(13.25, 8), 8) == 13.25


def test_sampled_equations_match_the_dense_ones(small_sequence):
    frames = small_sequence[0]
    sigma, matrix = 1.5, irc.rigid_matrix(31.0, 47.0, -0.028)
    centre = np.array(irc.matrix_to_irc(matrix)[:2])
    border = default_border(sigma)
    s0, s1 = smooth(frames[0], sigma), smooth(frames[1], sigma)
    a, b, static, mask = irc._warped_equations(s0, s1, matrix, centre, border=border,
                                               relative_threshold=0.15)
    # the same pixels as the dense rows, sampled
    rows, cols = np.nonzero(mask)
    gy, gx = np.gradient(s0)
    sample = pyramid.PairSample(x=cols.astype(float), y=rows.astype(float), s0=s0[mask],
                                gx0=gx[mask], gy0=gy[mask], s1=s1[mask],
                                coefficients=pyramid.spline_coefficients(s1))
    a_s, b_s, static_s, _ = pyramid.sampled_equations(sample, matrix, centre, border=border)
    np.testing.assert_allclose(a_s, a, atol=1e-9)
    np.testing.assert_allclose(b_s, b, atol=1e-9)
    np.testing.assert_allclose(static_s, static, atol=1e-9)


def test_sample_pairs_keeps_strong_gradients_in_the_region(small_sequence):
    frames = small_sequence[0]
    region = np.zeros((48, 48), dtype=bool)
    region[10:30, 5:20] = True              # a level twice as coarse
    level = pyramid.prepare_level(frames, sigma=1.5, relative_threshold=0.15)
    sample = pyramid.sample_pairs(level, [region], 2, max_pixels=200)[0]
    assert 0 < sample.x.size <= 200
    inside = pyramid.upsample_mask(region, 2, (96, 96))
    assert np.all(inside[sample.y.astype(int), sample.x.astype(int)])
    assert inside[20:60, 10:40].all() and not inside[:19].any() and not inside[:, 41:].any()


@pytest.mark.parametrize("override, message", [
    ({"accumulation": "magic"}, "method.accumulation='magic': expected one of exact, pyramid"),
    ({"coarse_side": 8}, "method.coarse_side=8: expected an integer >= 32"),
    ({"refine_pixels": 2.5}, "method.refine_pixels=2.5: expected an integer >= 100"),
])
def test_bad_pyramid_settings_are_refused(override, message):
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        single.settings_from(override)


def test_generator_imports_only_numpy_and_math():
    source = Path(scale_data.__file__)
    seen = set()
    for node in ast.walk(ast.parse(source.read_text())):
        if isinstance(node, ast.Import):
            seen.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            seen.add((node.module or "").split(".")[0])
    assert seen == {"numpy", "math"}


def test_generator_turns_the_objects_about_the_truth():
    # a smooth scene (low-pass at 0.08 cycles/pixel), so that interpolation is accurate:
    # frame 1 read at the true rotation of each pixel is frame 0, inside each disc
    scene = dict(scale_data.MULTI_SCENE, cutoff=0.08, n_frames=2)
    frames, truth, labels = scale_data.render(128, scene=scene)
    rows, cols = np.mgrid[0:128, 0:128].astype(float)
    for item, disc in zip(truth["objects"], scene["objects"]):
        matrix = irc.rigid_matrix(item["xi"], item["eta"], item["omega"])
        xw = matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2]
        yw = matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2]
        back = ndimage.map_coordinates(frames[1], [yw, xw], order=3, mode="nearest")
        centre = np.array(disc["disc_centre"]) * 128 - 0.5
        inside = np.hypot(cols - centre[0], rows - centre[1]) < disc["disc_radius"] * 128 - 4
        assert np.all(labels[0][inside] == item["label"])
        warped = np.sqrt(np.mean((back - frames[0])[inside] ** 2))
        still = np.sqrt(np.mean((frames[1] - frames[0])[inside] ** 2))
        assert warped < 0.002 and still > 10 * warped
    assert truth["objects"][0] == {"label": 1, "xi": 0.3 * 128 - 0.5,
                                   "eta": 0.36 * 128 - 0.5, "omega": 0.025}


def test_segmentation_with_the_pyramid_on_512():
    from replication.experiments.segment import score_objects
    from replication.motion.segment import pipeline as segmentation

    frames, truth, labels = scale_data.render(512, seed=0, scene=dict(
        scale_data.MULTI_SCENE, n_frames=2))
    settings = segmentation.settings_from({
        "ea": {"generations": 40, "project_fresh": True}, "snake": {"deflate": True},
        "assign": {"enabled": True},
        "pyramid": {"enabled": True, "coarse_side": 256, "refine_pixels": 20000}})
    found = segmentation.segment(frames, settings, 0)
    assert found["pyramid"]["factor"] == 2 and found["objects"][0]["mask"].shape == (512, 512)
    score = score_objects(found["objects"], labels[0], truth)
    assert score["false_regions"] == 0
    for row in score["per_object"]:
        assert row["found"] and row["iou"] >= 0.8, row
        assert row["centre_px"] <= 1.0 and abs(row["omega_pct"]) <= 3.0, row


def test_segmentation_refuses_bad_pyramid_settings():
    from replication.motion.segment import pipeline as segmentation

    with pytest.raises(InputError, match=r"method.pyramid.coarse_side=4: expected an integer"):
        segmentation.settings_from({"pyramid": {"coarse_side": 4}})


def test_top_shape_is_the_shape_of_the_top_level_and_a_small_one_is_refused():
    """A coarse_side leaving a top level too small for the border was refused naming the
    reduced frames (8 x 20), which the user never gave."""
    from replication.experiments.motion import check_border
    from replication.motion.io import Sequence

    for shape, coarse in (((64, 160), 32), ((300, 301), 256), ((33, 70), 16), ((20, 20), 64)):
        frames = np.zeros((2, *shape))
        assert pyramid.levels(frames, coarse)[-1].shape[1:] == pyramid.top_shape(shape, coarse)
    sequence = Sequence(frames=np.random.default_rng(0).random((2, 64, 160)), labels=None,
                        truth=None, source="seq")
    check_border(sequence, 1.5, ("method.coarse_side", 32))
    with pytest.raises(InputError, match=r"method.coarse_side=16: the pyramid's top level of "
                                         r"64 x 160 frames would have 8 x 20 pixels"):
        check_border(sequence, 1.5, ("method.coarse_side", 16))


def test_wide_short_frames_keep_half_of_coarse_side_on_the_top_level():
    """An outside user's 88 x 954 and 166 x 817 frames were halved until the longer side
    fitted 256 (22 x 238, 41 x 204): the pyramid's centre was 813 and 132 px off where the
    exact accumulation was within 0.4 px. Halving now stops before the shorter side falls
    under coarse_side // 2; square frames are reduced as before."""
    assert pyramid.top_shape((88, 954), 256) == (88, 954)
    assert pyramid.top_shape((166, 817), 256) == (166, 817)
    assert pyramid.top_shape((339, 584), 256) == (169, 292)
    assert pyramid.top_shape((768, 1024), 256) == (192, 256)
    for side in (100, 255, 256, 257, 300, 511, 512, 513, 1024, 2048, 3000):
        halvings = 0
        while (side >> halvings) > 256:
            halvings += 1
        assert pyramid.top_shape((side, side), 256) == (side >> halvings,) * 2
    for shape in ((88, 954), (339, 584), (954, 88)):
        top = pyramid.top_shape(shape, 256)
        assert min(top) >= 128 or top == shape
