"""Small synthetic sequences shared by the motion tests (96 x 96, fast)."""

import numpy as np
import pytest

from replication.motion.synth import make_sequence


def small_spec(**override):
    """A 96 x 96 C-shape turning about (30, 48); keys of ``override`` replace the defaults."""
    spec = {
        "shape": [96, 96], "center": [30.0, 48.0], "omega": -0.03, "n_frames": 2,
        "c_shape": {"center": [50.0, 48.0], "r_inner": 10.0, "r_outer": 30.0,
                    "gap_deg": 90.0, "gap_dir_deg": 0.0},
        "object_texture": {"kind": "procedural", "scale": 1.5},
        "background_texture": {"kind": "procedural", "scale": 1.5},
    }
    spec.update(override)
    return spec


@pytest.fixture(scope="session")
def small_sequence():
    """(frames (2, 96, 96), labels, truth) of :func:`small_spec`, seed 3."""
    return make_sequence(small_spec(), rng=np.random.default_rng(3))


@pytest.fixture(scope="session")
def fast_settings():
    """Method settings for small images: a 40-value sweep."""
    from replication.motion.single import settings_from

    return settings_from({"omega_count": 40})
