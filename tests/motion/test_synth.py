"""The generator: conventions of docs/data-formats.md and determinism."""

import numpy as np
import pytest

from replication.errors import InputError
from replication.motion.synth import degrade, make_sequence, photo_texture
from tests.test_cli import assert_regenerated_identically

from .conftest import small_spec


def centroid(mask):
    rows, cols = np.nonzero(mask)
    return np.array([cols.mean(), rows.mean()])


def test_positive_omega_turns_clockwise_on_screen():
    spec = small_spec(omega=0.2, center=[48.0, 48.0],
                      c_shape={"center": [70.0, 48.0], "r_inner": 0.0, "r_outer": 8.0,
                               "gap_deg": 0.0})
    _, labels, _ = make_sequence(spec, rng=0)
    before, after = centroid(labels[0]), centroid(labels[1])
    # a point right of the centre moves down (+y) for omega > 0
    angle = np.arctan2(after[1] - 48.0, after[0] - 48.0)
    assert before[0] > 60 and after[1] > before[1] + 3
    assert abs(angle - 0.2) < 0.02


def test_same_seed_same_frames():
    a = make_sequence(small_spec(), rng=np.random.default_rng(7))[0]
    b = make_sequence(small_spec(), rng=np.random.default_rng(7))[0]
    c = make_sequence(small_spec(), rng=np.random.default_rng(8))[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_degrade_quantises_and_adds_noise():
    frames = np.full((2, 8, 8), 0.5)
    noisy = degrade(frames, noise_sigma=2 / 255, bits=8, rng=1)
    assert np.allclose(noisy * 255, np.round(noisy * 255))
    assert 0 < np.std(noisy - frames) < 4 / 255


def test_photo_texture_refuses_unknown_name():
    with pytest.raises(InputError, match="texture 'nosuch': unknown photograph"):
        photo_texture("nosuch", (8, 8))


@pytest.mark.slow
def test_committed_sequences_are_regenerated_identically(tmp_path):
    assert_regenerated_identically("motion_data", "synthetic_data/motion", tmp_path)
