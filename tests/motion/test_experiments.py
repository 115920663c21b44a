"""The data and accuracy runners: same config and seed, same numbers; bad settings refused."""

import re

import numpy as np
import pytest

from replication.errors import InputError
from replication.experiments.motion import accuracy, make_data
from replication.report.motion import accuracy_section, data_section

from .conftest import small_spec


def data_config(folder):
    base = small_spec()
    base.pop("center"), base.pop("omega")
    return {"seed": 0, "data_dir": str(folder), "base": base, "sequences": {
        "one": {"center": [30.0, 48.0], "omega": -0.03, "format": "npz"},
        "two": {"center": [50.0, 48.0], "omega": 0.02, "format": "png16"},
    }}


def accuracy_config(folder):
    return {"seed": 0, "sequences_dir": str(folder), "noise_levels_255": [2], "workers": 1,
            "methods": ["paper (best peak)", "coarse sweep + refinement",
                        "DE on IRC residual"],
            "method": {"omega_count": 20}, "de": {"max_evals": 150}}


def without_times(result):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in result["rows"]]


def test_data_then_accuracy_are_deterministic(tmp_path):
    first = make_data(data_config(tmp_path / "a"), tmp_path / "out")
    second = make_data(data_config(tmp_path / "b"), tmp_path / "out")
    assert first["files"] == second["files"]            # same sha256 for every file
    assert "| `two` | accuracy | png16 |" in data_section(first).markdown
    one = accuracy(accuracy_config(tmp_path / "a"), tmp_path / "out")
    two = accuracy(accuracy_config(tmp_path / "a"), tmp_path / "out")
    assert without_times(one) == without_times(two)
    assert len(one["rows"]) == 2 * 3
    assert "coarse sweep + refinement" in accuracy_section(one).markdown


def test_accuracy_refuses_unknown_method(tmp_path):
    make_data(data_config(tmp_path), tmp_path / "out")
    config = dict(accuracy_config(tmp_path), methods=["magic"])
    with pytest.raises(InputError, match=r"methods: unknown \['magic'\]"):
        accuracy(config, tmp_path / "out")


def test_accuracy_refuses_missing_manifest(tmp_path):
    with pytest.raises(InputError, match="manifest.json: no such file"):
        accuracy(accuracy_config(tmp_path), tmp_path / "out")


def test_data_refuses_zero_omega(tmp_path):
    config = data_config(tmp_path)
    config["sequences"]["one"]["omega"] = 0
    with pytest.raises(InputError, match="sequences.one.omega: 0; expected a non-zero"):
        make_data(config, tmp_path / "out")
    assert not (tmp_path / "manifest.json").exists()


@pytest.mark.parametrize("method, message", [
    ({"omega_min": 0.05, "omega_max": -0.05}, "expected omega_min < omega_max"),
    ({"omega_count": 1}, "omega_count=1: expected an integer from 2 to"),
    ({"sigma": -1}, "sigma=-1: expected >= 0 pixels"),
    ({"relative_threshold": 1.5}, "relative_threshold=1.5: expected a fraction in (0, 1)"),
    ({"cell": 0}, "cell=0: expected > 0 pixels"),
])
def test_single_rotation_refuses_bad_settings(tmp_path, method, message):
    from replication.experiments.motion_single import single_rotation

    config = {"seed": 0, "data": {"path": str(tmp_path / "never_read.npz")}, "method": method}
    with pytest.raises(InputError, match=re.escape(message)):
        single_rotation(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_answer_warnings_flag_a_translation_and_a_centre_at_the_accumulator_edge():
    from replication.experiments.motion_single import answer_warnings
    from replication.motion import irc, single

    settings = single.settings_from(None)
    grid = irc.image_grid((64, 64))
    inside = {"xi": 30.0, "eta": 20.0, "omega": 0.02, "pixels": 500}
    assert answer_warnings(inside, inside, settings, grid, (64, 64)) == []
    edge = dict(inside, eta=63.0)
    assert any("edge of the accumulator" in w
               for w in answer_warnings(edge, inside, settings, grid, (64, 64)))
    # a refined centre spread above 1 px (and 0.2% of the larger side) is warned
    steady = dict(inside, spread={"xi_sd": 0.3, "eta_sd": 0.4, "omega_sd": 1e-4, "blocks": 30})
    assert answer_warnings(inside, steady, settings, grid, (64, 64)) == []
    rough = dict(steady, spread=dict(steady["spread"], blocks=5))
    assert [w[:36] for w in answer_warnings(inside, rough, settings, grid, (64, 64))] == [
        "irc_refined spread from 5 tiles only"]
    # an outside user's small object: no spread and, before, no warning at all
    none = dict(inside, spread=None)
    assert any("has no spread" in w for w in answer_warnings(inside, none, settings, grid,
                                                            (64, 64)))
    noisy = dict(inside, spread={"xi_sd": 0.9, "eta_sd": 0.9, "omega_sd": 1e-3, "blocks": 30})
    assert any("centre spread (block jackknife) is 1.27 px" in w
               for w in answer_warnings(inside, noisy, settings, grid, (64, 64)))
    assert answer_warnings(inside, noisy, settings, grid, (1024, 640)) == []  # 2.05 px allowed
    far = dict(inside, xi=32.0, eta=-1e7, omega=1e-7)
    assert any("looks like a translation" in w
               for w in answer_warnings(inside, far, settings, grid, (64, 64)))
    # the pyramid's top-level grid in input pixels (factor 4): its last row is at
    # eta = to_input(63, 4), and a centre there is on its edge
    from replication.motion import pyramid

    top = pyramid.grid_in_input(grid, 4)
    last = float(pyramid.to_input(63.0, 4))
    low = dict(inside, eta=last - 1.0)
    assert any("edge of the accumulator" in w for w in answer_warnings(
        low, low, settings, top, (256, 256)))
    middle = dict(inside, eta=120.0)
    assert answer_warnings(middle, middle, settings, top, (256, 256)) == []


def test_answer_warnings_flag_a_best_peak_the_refinement_does_not_confirm():
    """An outside user's sequences: a centre beyond the accumulator whose best peak sat 2 px
    inside its edge (62 px from the truth, which the refinement found), and a rotation of
    3e-4 rad/frame, slower than the sweep resolves (best peak 19 px off); both went
    without a warning."""
    from replication.experiments.motion_single import answer_warnings
    from replication.motion import irc, single

    settings = single.settings_from(None)      # sweep -0.05..0.05, 100 values
    grid = irc.image_grid((129, 257), margin=settings["margin"])
    refined = {"xi": -60.0, "eta": 64.0, "omega": -0.015, "pixels": 5000}
    peak = {"xi": grid.x0 + 2.0, "eta": 66.0, "omega": -0.028}
    warned = answer_warnings(peak, refined, settings, grid, (129, 257))
    assert any("edge of the accumulator" in w for w in warned)
    assert any(w.startswith("irc and irc_refined disagree: centres 62") for w in warned)
    slow = {"xi": 122.0, "eta": 67.0, "omega": 0.001}
    warned = answer_warnings(slow, dict(slow, omega=0.0003, pixels=5000), settings, grid,
                             (129, 257))
    assert any("of 0, the sweep's inner edge" in w for w in warned)
    # the best peak's usual bias (omega 9% fast, a pixel off) is not a disagreement
    good = {"xi": 140.0, "eta": 62.0, "omega": 0.0327}
    assert answer_warnings(good, dict(good, xi=141.0, omega=0.030, pixels=5000), settings,
                           grid, (129, 257)) == []
    # nor is its 33% on the finest textures (motion_omega_bias)
    assert answer_warnings(dict(good, omega=0.04), dict(good, omega=0.030, pixels=5000),
                           settings, grid, (129, 257)) == []


def test_accumulator_settings_that_cannot_work_are_refused():
    from replication.errors import InputError
    from replication.experiments.motion import _check_settings, check_grid
    from replication.motion import irc, single

    with pytest.raises(InputError, match="method.margin=-10.0: expected >= 0"):
        _check_settings(single.settings_from({"margin": -10.0}))
    fine = single.settings_from({"cell": 0.5})
    _check_settings(fine)
    check_grid((64, 64), fine)
    tiny = single.settings_from({"cell": 0.01})
    grid = irc.image_grid((64, 64), margin=tiny["margin"], cell=tiny["cell"])
    with pytest.raises(InputError, match=f"accumulator of {grid.ny} x {grid.nx} cells"):
        check_grid((64, 64), tiny)


def test_segment_multi_refuses_still_frames_and_truth_labels_absent_from_the_labels(tmp_path):
    """An outside user's identical frames gave 'objects: []' (motion_single refuses them),
    and truth labels 5 and 6 over masks of 1 and 2 scored both objects as not found."""
    from replication.experiments.segment_multi import segment_sequence
    from replication.motion.io import write_sequence_npz

    still = np.repeat(np.random.default_rng(0).random((1, 64, 64)), 3, axis=0)
    write_sequence_npz(tmp_path / "still.npz", still)
    with pytest.raises(InputError, match="no motion found: all 3 frames are identical"):
        segment_sequence({"seed": 0, "data": {"path": str(tmp_path / "still.npz")}},
                         tmp_path / "out")
    moving = np.random.default_rng(1).random((3, 64, 64))
    labels = np.zeros((3, 64, 64), dtype=np.uint8)
    labels[:, 10:20, 10:20] = 1
    write_sequence_npz(tmp_path / "labelled.npz", moving, labels=labels, truth={
        "objects": [{"label": 5, "xi": 15.0, "eta": 15.0, "omega": 0.02}]})
    with pytest.raises(InputError, match=r"truth label 5: no pixel of the first label image "
                                         r"has it \(values: 0, 1\)"):
        segment_sequence({"seed": 0, "data": {"path": str(tmp_path / "labelled.npz")}},
                         tmp_path / "out")
    tiny = np.random.default_rng(2).random((3, 10, 10))
    write_sequence_npz(tmp_path / "tiny.npz", tiny)
    with pytest.raises(InputError, match=r"tiny.npz: frames of 10 x 10 pixels: fewer than 4 "
                                         r"inside"):
        segment_sequence({"seed": 0, "data": {"path": str(tmp_path / "tiny.npz")}},
                         tmp_path / "out")


def test_segment_multi_warns_of_an_object_centre_at_its_accumulator_edge():
    from replication.experiments.segment_multi import edge_warnings
    from replication.motion import irc
    from replication.motion.segment import pipeline

    settings = pipeline.settings_from(None)
    grid = irc.Grid(x0=-34.0, y0=-34.0, cell=1.0, nx=325, ny=197)
    edge = {"xi": -34.0, "eta": 68.0, "grid": grid}
    inside = {"xi": 100.0, "eta": 68.0, "grid": grid}
    warned = edge_warnings({"objects": [inside, edge]}, settings)
    assert len(warned) == 1 and warned[0].startswith("object 1: centre (-34, 68) is at the edge")


@pytest.mark.parametrize("name", ["motion_data", "motion_multi_data"])
def test_data_makers_refuse_frames_their_readers_refuse(name, tmp_path):
    """motion_multi_data with base.shape=[4,4] wrote sequences its own reader refused."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from replication.cli import CONFIG_DIR, run_experiment

    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        config = OmegaConf.to_container(compose(config_name="config", overrides=[
            f"experiment={name}", f"+smoke={name}", f"data_dir={tmp_path / 'data'}",
            "base.shape=[4,4]"]), resolve=True)
    with pytest.raises(InputError, match=r"\.shape: \[4, 4\]; expected \[H, W\] of at least 8"):
        run_experiment(config, tmp_path / "out")
    assert not (tmp_path / "data").exists()


def test_speed_verdicts_call_close_medians_as_fast():
    """0.337 s against 0.336 s read 'slower', and the verdict flipped between runs of the
    same code (wall times on a shared machine)."""
    from replication.report.motion import _speed_word

    assert _speed_word(0.337, 0.336) == "as fast (within 15 %)"
    assert _speed_word(0.2, 0.5) == "faster" and _speed_word(0.5, 0.2) == "slower"
    assert _speed_word(0.1, 0.12) == "faster" and _speed_word(0.1, 0.115).startswith("as fast")
