"""Whole-frame checks of the IRC equation's assumptions: each warning fires on the sequence
that breaks its assumption and not on the same rotation without the fault."""

import numpy as np
import pytest
from scipy import ndimage

from replication.motion.frame_checks import (
    BRIGHTNESS_PCT,
    DIVERGENCE_PCT,
    NOISE_FLOW,
    frame_checks,
    frame_statistics,
    noise_sigma,
)

SIDE, T, OMEGA_DEG = 96, 3, 1.2   # a disc turning 1.2 degrees (0.021 rad) per frame


def _texture(rng, side):
    """Smooth random texture in about [0.2, 0.8]."""
    texture = ndimage.gaussian_filter(rng.standard_normal((side, side)), 2.0)
    return 0.5 + 0.3 * texture / np.abs(texture).max()


def _disc_sequence(*, flicker=0.0, zoom=1.0, noise=0.0, seed=0):
    """(T, SIDE, SIDE) frames: a textured disc (radius 30) turning about the frame's middle
    on a still textured background; optionally each frame's brightness scaled by
    1 -+ ``flicker`` in turn, the whole frame scaled by ``zoom`` per frame about its
    middle, and Gaussian noise of sd ``noise`` added."""
    rng = np.random.default_rng(seed)
    disc, background = _texture(rng, SIDE), _texture(rng, SIDE)
    y, x = np.mgrid[:SIDE, :SIDE] - (SIDE - 1) / 2
    inside = np.hypot(x, y) < 30
    middle = np.array([(SIDE - 1) / 2] * 2)
    frames = []
    for t in range(T):
        turned = ndimage.rotate(disc, OMEGA_DEG * t, reshape=False, order=3, mode="reflect")
        frame = np.where(inside, turned, background)
        if zoom != 1.0:
            scale = zoom ** -t   # output pixel p shows input middle + (p - middle) / zoom^t
            frame = ndimage.affine_transform(frame, np.eye(2) * scale,
                                             offset=middle - scale * middle, order=3,
                                             mode="reflect")
        frame = frame * (1 + flicker * (1 if t % 2 else -1))
        frames.append(frame + noise * rng.standard_normal(frame.shape))
    return np.array(frames)


def _kinds(warnings):
    return sorted(w.split(":")[0].split(" ")[0] for w in warnings)


def test_a_plain_rotation_raises_no_frame_warning():
    frames = _disc_sequence()
    worst = frame_statistics(frames)["worst"]
    assert worst["brightness_pct"] < BRIGHTNESS_PCT / 5
    assert abs(worst["scale_pct"]) < DIVERGENCE_PCT / 3
    assert worst["noise_flow"] < NOISE_FLOW / 5
    assert frame_checks(frames)["warnings"] == []


def test_flicker_of_one_percent_is_a_brightness_change():
    """+-1 % flicker: the mean changes by 2 % from frame to frame, all one way."""
    frames = _disc_sequence(flicker=0.01)
    worst = frame_statistics(frames)["worst"]
    assert worst["brightness_pct"] == pytest.approx(2.0, rel=0.05)
    warned = frame_checks(frames)["warnings"]
    assert len(warned) == 1 and warned[0].startswith("brightness changes between frames")
    assert "assumes constant brightness" in warned[0]


def test_a_zoom_is_a_divergence_and_a_rotation_is_not():
    frames = _disc_sequence(zoom=1.01)
    worst = frame_statistics(frames)["worst"]
    assert worst["scale_pct"] == pytest.approx(1.0, rel=0.15)
    warned = frame_checks(frames)["warnings"]
    assert len(warned) == 1 and warned[0].startswith("the whole frame grows by")
    shrinking = frame_checks(_disc_sequence(zoom=1 / 1.01))["warnings"]
    assert len(shrinking) == 1 and shrinking[0].startswith("the whole frame shrinks by")


def test_noise_dominates_at_12_but_not_at_2_per_255():
    assert noise_sigma(_disc_sequence(noise=12 / 255)[0]) == pytest.approx(12 / 255, rel=0.1)
    assert frame_checks(_disc_sequence(noise=2 / 255))["warnings"] == []
    warned = frame_checks(_disc_sequence(noise=12 / 255))["warnings"]
    assert _kinds(warned) == ["noise"] and "px/frame" in warned[0]


def test_a_repeated_frame_is_warned_first_and_a_moving_sequence_is_not():
    """An outside user's 4 frames with one repeated (a dropped frame written twice): the
    refined centre moved 0.8 px and omega 2.4 % low (from 0.02 px, 0.03 %), without a
    word. Also frames before the motion began; not a scene at rest at its end."""
    frames = _disc_sequence()
    assert frame_checks(frames)["measures"]["repeated_frames"] == []
    for repeated, expected in ((frames[[0, 1, 1, 2]], [2]), (frames[[0, 0, 1, 2]], [1]),
                               (frames[[0, 1, 2, 2]], [])):
        checks = frame_checks(repeated)
        assert checks["measures"]["repeated_frames"] == expected
        named = [w for w in checks["warnings"] if "repeat the frame before" in w]
        assert len(named) == (1 if expected else 0), checks["warnings"]
        if expected:   # first, and naming the frame
            assert checks["warnings"][0] == named[0]
            assert named[0].startswith(f"1 frame(s) ({expected[0]}) repeat")


def test_both_runners_add_the_frame_warnings(tmp_path):
    """motion_single and segment_multi call the same check: a flickering sequence is warned
    by both (figures off; the segmentation shrunk to a few generations)."""
    from replication.experiments.motion_single import single_rotation
    from replication.experiments.segment_multi import segment_sequence
    from replication.motion.io import write_sequence_npz

    path = tmp_path / "flicker.npz"
    write_sequence_npz(path, np.clip(_disc_sequence(flicker=0.02), 0, 1))
    config = {"seed": 0, "data": {"path": str(path)}, "figures": False}
    single = single_rotation(dict(config, method={"omega_count": 20}), tmp_path / "single")
    method = {"ea": {"pop_size": 20, "generations": 3}, "snake": {"iterations": 2}}
    multi = segment_sequence(dict(config, method=method), tmp_path / "multi")
    for result in (single, multi):
        assert sum(w.startswith("brightness changes") for w in result["warnings"]) == 1
        # the measures behind the warning are in the result, with their thresholds
        measures = result["frame_checks"]
        assert measures["brightness_pct"] > measures["thresholds"]["brightness_pct"]
        assert measures["noise_flow"] < measures["thresholds"]["noise_flow"]


def test_two_regions_turning_opposite_ways_are_warned_by_motion_single():
    """An outside user's two discs turning at +-0.03 rad/frame: motion_single answered one
    rotation, the other disc unexplained and unwarned. Its moving blocks outside the
    region found are warned now (the check segment_multi uses); one disc is not."""
    from scipy import ndimage

    from replication.experiments.motion_single import motion_outside_warnings
    from replication.motion import single

    side = 128
    texture = ndimage.gaussian_filter(np.random.default_rng(5).random((side, 2 * side)), 2.0)
    yy, xx = np.mgrid[:side, :2 * side]

    def turned(cx, omega, t):   # the texture turned about (cx, 64), with scipy alone
        centred = ndimage.shift(texture, (0, side - cx), order=3, mode="nearest")
        centred = ndimage.rotate(centred, np.degrees(omega * t), reshape=False, order=3,
                                 mode="nearest")
        return ndimage.shift(centred, (0, cx - side), order=3, mode="nearest")

    left = (xx - 64) ** 2 + (yy - 64) ** 2 <= 40 ** 2
    right = (xx - 192) ** 2 + (yy - 64) ** 2 <= 40 ** 2
    both = np.array([np.where(left, turned(64, 0.03, t), np.where(right, turned(192, -0.03, t),
                                                                  texture)) for t in range(3)])
    one = np.array([np.where(left, turned(64, 0.03, t), texture) for t in range(3)])
    settings = single.settings_from(None)
    warned = motion_outside_warnings(single.find_rotation(both, settings))
    assert len(warned) == 1 and "lie outside the region of the rotation found" in warned[0]
    assert motion_outside_warnings(single.find_rotation(one, settings)) == []


def test_a_still_scene_with_sensor_noise_is_warned_by_motion_single():
    """An outside user's still texture with 3/255 sensor noise: motion_single answered
    omega = -0.046, warned only by a refinement on 0 pixels. That no block moves is said
    now (segment_multi said it already); a slow rotation that moves blocks is not."""
    from scipy import ndimage

    from replication.experiments.motion_single import motion_outside_warnings
    from replication.motion import single

    rng = np.random.default_rng(11)
    texture = ndimage.gaussian_filter(rng.random((128, 128)), 2.0)
    texture = (texture - texture.min()) / np.ptp(texture)
    still = np.array([texture + rng.normal(0, 3 / 255, texture.shape) for _ in range(3)])
    settings = single.settings_from(None)
    warned = motion_outside_warnings(single.find_rotation(still, settings))
    assert len(warned) == 1 and warned[0].startswith("no block of 16 x 16 px moves")
    turning = np.array([ndimage.rotate(texture, np.degrees(0.01 * t), reshape=False, order=3,
                                       mode="nearest") for t in range(3)])
    assert motion_outside_warnings(single.find_rotation(turning, settings)) == []
