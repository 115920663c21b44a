"""Diagnostics of an identified answer (problem.diagnose): what the data do not determine,
the position noise and the misfit, on trajectories rolled out by the plain, independent
implementation of the contract (tests/cloth/plain_reference.py) and written by hand in the
documented format."""

import math

import numpy as np
import pytest

from replication.cloth.identify import identify, problem
from replication.cloth.io import read_trajectory
from replication.errors import InputError
from replication.sequences import repeated_frames
from tests.cloth.plain_reference import plain_run

N, SIDE, STEPS, FRAME = 7, 0.6, 60, 40
H = SIDE / (N - 1)
REST = [H, H, H * math.sqrt(2), H * math.sqrt(2), 2 * H, 2 * H]


def _write(path, frames, *, dt=0.002, pinned=((0, 0), (0, N - 1)), meta=None):
    arrays = {"positions": np.asarray(frames, dtype=float).reshape(-1, N, N, 3),
              "dt": np.float64(dt), "mass": np.float64(0.001),
              "gravity": np.array([0.0, 0.0, -9.81]),
              "pinned": np.array(pinned, dtype=np.int64).reshape(-1, 2)}
    if meta is not None:
        arrays["meta"] = np.array(meta)
    np.savez(path, **arrays)
    return read_trajectory(path)


def _diagnose(trajectory, K, tau):
    cost = problem.cost_from_config(trajectory, {"kind": "small", "frame": FRAME})
    space = problem.search_space(trajectory, {"rest": [0.8, 1.2], "K": [0.1, 10.0],
                                              "tau": [0.01, 1.0]})
    truth = np.array([H, H * math.sqrt(2), 2 * H, K, tau])
    found = problem.diagnose(cost, truth, space)
    return found, problem.diagnostic_warnings(found, truth, space.names)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("diagnostics")
    pinned = ((0, 0), (0, N - 1))
    return {tau: np.array(plain_run(STEPS, REST, [4.0] * 6, [tau] * 6, n=N, side=SIDE,
                                    pinned=pinned))
            for tau in (0.01, 0.8)} | {"folder": folder}


def test_a_tau_the_constraint_never_reaches_is_flagged_and_an_acting_one_is_not(runs):
    loose = _write(runs["folder"] / "loose.npz", runs[0.8])
    found, warnings = _diagnose(loose, 4.0, 0.8)
    assert found["undetermined"] == ["tau"]
    assert any(w.startswith("tau=0.8 is not determined by the cost") for w in warnings)
    tight = _write(runs["folder"] / "tight.npz", runs[0.01])
    found, warnings = _diagnose(tight, 4.0, 0.01)
    assert found["undetermined"] == [] and warnings == []
    assert found["misfit"] < 1.0 and found["noise_h"] < 1e-6


def test_an_answer_off_the_truth_leaves_residuals_above_the_noise(runs):
    tight = _write(runs["folder"] / "tight.npz", runs[0.01])
    found, warnings = _diagnose(tight, 4.0 * 1.01, 0.01)    # K 1% off, noise-free data
    assert found["misfit"] > 3
    assert any("the answer is off" in w for w in warnings)


def test_the_data_noise_does_not_depend_on_the_answer(runs):
    """An outside user's paper-EA answer (K 75% low, a tau that turns the constraint off)
    left residuals that looked like noise: misfit 2.35 on noise-free data, no warning.
    robust_misfit compares the typical residual with the noise the data show alone."""
    tight = _write(runs["folder"] / "tight.npz", runs[0.01])
    at_truth, _ = _diagnose(tight, 4.0, 0.01)
    assert at_truth["robust_misfit"] == 0.0 and at_truth["data_noise_h"] < 1e-4
    off, warnings = _diagnose(tight, 1.0, 0.9)
    assert off["robust_misfit"] > 100
    assert any("the answer is off" in w for w in warnings)
    rng = np.random.default_rng(5)
    noisy = runs[0.01] + 1e-4 * H * rng.standard_normal(runs[0.01].shape)
    noisy[:, [0, N - 1]] = runs[0.01][:, [0, N - 1]]
    found, _ = _diagnose(_write(runs["folder"] / "noisy5.npz", noisy), 4.0, 0.01)
    assert found["data_noise_h"] == pytest.approx(1e-4, rel=0.3)
    assert found["robust_misfit"] < 1.5


def test_robust_misfit_warns_only_when_misfit_does_not():
    names = ("l01", "l23", "l45", "K", "tau")
    base = {"undetermined": [], "noise_h": 1e-5, "misfit": 2.0, "data_noise_h": 3e-7,
            "robust_misfit": 3e4}
    warnings = problem.diagnostic_warnings(base, np.ones(5), names)
    assert len(warnings) == 1 and "the noise the data show without a model" in warnings[0]
    both = problem.diagnostic_warnings(dict(base, misfit=10.0), np.ones(5), names)
    assert len(both) == 1 and "leaves one-step residuals 10" in both[0]
    assert problem.diagnostic_warnings(dict(base, robust_misfit=1.0), np.ones(5), names) == []


def test_noise_is_estimated_and_warned_about_above_the_warning_level(runs):
    rng = np.random.default_rng(3)
    for level, warned in ((1e-5, False), (3e-3, True)):
        noisy = runs[0.01] + level * H * rng.standard_normal(runs[0.01].shape)
        noisy[:, [0, N - 1]] = runs[0.01][:, [0, N - 1]]      # pins stay put
        found, warnings = _diagnose(_write(runs["folder"] / "noisy.npz", noisy), 4.0, 0.01)
        assert found["noise_h"] == pytest.approx(level, rel=0.3)
        assert any("carry noise" in w for w in warnings) is warned
        assert found["misfit"] < 2.0


def test_frames_out_of_order_are_warned_as_meaningless(runs):
    """An outside user's shuffled frames came out as 'noise of about 2.8 h ... expect errors
    of several %', as if the answer were only biased."""
    shuffled = runs[0.01][np.random.default_rng(0).permutation(len(runs[0.01]))]
    shuffled[:, [0, N - 1]] = runs[0.01][:1, [0, N - 1]]            # pins stay put
    found, warnings = _diagnose(_write(runs["folder"] / "shuffled.npz", shuffled), 4.0, 0.01)
    assert found["noise_h"] > 0.1
    assert any("the answer means nothing" in w for w in warnings)
    assert not any("expect errors of several %" in w for w in warnings)


def test_data_in_other_units_are_reported_as_not_explained(runs):
    # the recorded time step is written 10 x too long: no parameters make the model fit
    wrong = _write(runs["folder"] / "dt.npz", runs[0.01], dt=0.02)
    found, warnings = _diagnose(wrong, 4.0, 0.01)
    assert found["misfit"] > 100
    assert any("leaves one-step residuals" in w for w in warnings)


def test_a_stiffness_without_stretched_springs_is_flagged(tmp_path):
    # no pins: the sheet falls freely, no spring leaves its rest length, K has no effect
    falling = np.array(plain_run(STEPS, REST, [4.0] * 6, [0.3] * 6, n=N, side=SIDE,
                                 pinned=()))
    found, warnings = _diagnose(_write(tmp_path / "fall.npz", falling, pinned=()), 4.0, 0.3)
    assert "K" in found["undetermined"]
    assert any(w.startswith("K=4 is not determined by the data") for w in warnings)


def test_identify_returns_the_diagnostics(runs):
    loose = _write(runs["folder"] / "loose.npz", runs[0.8])
    _, _, info = identify(loose, rng=0, cost={"kind": "small", "frame": FRAME})
    assert info["diagnostics"]["undetermined"] == ["tau"]


@pytest.mark.parametrize("truth, found", [
    ('{"true_params": [1, 2, 3, 4, 5]}', "JSON type list"),
    ('{"true_params": {"K": "abc"}}', "true_params.l01=null"),
    ('{"true_params": {"l01": 1, "l23": 1, "l45": 1, "K": "abc", "tau": 1}}',
     'true_params.K="abc"'),
    ('{"true_params": {"l01": 1, "l23": 1, "l45": 1, "K": 0, "tau": 1}}', "true_params.K=0"),
])
def test_a_malformed_ground_truth_is_refused_with_the_field(tmp_path, runs, truth, found):
    with pytest.raises(InputError, match="field 'meta'") as error:
        _write(tmp_path / "meta.npz", runs[0.01], meta=truth)
    assert found in str(error.value)


@pytest.mark.parametrize("change, message", [
    ({"regression": {"first": 1, "stride": 0}}, r"structured.regression.stride=0"),
    ({"tau_scan": {"n_grid": 0, "refine_evals": 40}}, r"structured.tau_scan.n_grid=0"),
    ({"refine": {"box": -1, "ea": {}}}, r"structured.refine.box=-1"),
    ({"tau_scan": {"n_grid": 100.0, "refine_evals": 40}}, r"structured.tau_scan.n_grid=100.0"),
])
def test_structured_settings_it_cannot_run_with_are_refused(change, message):
    from replication.cloth.identify.api import check_solver, default_structured

    settings = {**default_structured(), **change}
    with pytest.raises(InputError, match=message):
        check_solver("structured", settings)


def test_pins_outside_the_mesh_are_refused_and_the_default_follows_the_mesh():
    from replication.cloth.model import make_scene

    with pytest.raises(InputError, match=r"pinned: \(0, 16\) is outside the 9x9 mesh"):
        make_scene(9, pinned=[[0, 0], [0, 16]])
    assert make_scene(9).pinned.tolist() == [[0, 0], [0, 8]]


def test_a_cost_frame_outside_the_data_names_the_setting_and_the_file(runs):
    short = _write(runs["folder"] / "short.npz", runs[0.01])
    with pytest.raises(InputError, match=r"short.npz: cost.frame=150 \(small cost\)"):
        problem.cost_from_config(short, {"kind": "small", "frame": 150})
    with pytest.raises(InputError, match=r"cost.kind='bogus': expected 'small', 'full' or"):
        problem.cost_from_config(short, {"kind": "bogus"})


def test_a_text_file_named_npz_is_not_called_pickled_data(tmp_path):
    path = tmp_path / "notes.npz"
    path.write_text("hello\n")
    with pytest.raises(InputError, match="not with a zip archive's") as error:
        read_trajectory(path)
    assert "pickle" not in str(error.value)


def test_too_few_frames_for_a_fourth_difference_give_no_data_noise(runs):
    """A 4-frame file (the reader takes T >= 3): the median of no fourth differences was
    NaN, written as such, and the warning could never fire."""
    short = _write(runs["folder"] / "short.npz", runs[0.01][:4])
    cost = problem.cost_from_config(short, {"kind": "small", "frame": 1})
    found = problem.residual_fit(cost, np.array([H, H * math.sqrt(2), 2 * H, 4.0, 0.01]))
    assert found["data_noise_h"] is None and found["robust_misfit"] is None
    assert np.isfinite(found["misfit"])


def test_a_cloth_at_rest_with_noise_is_warned_as_meaningless(runs):
    """An outside user's cloth at rest (its first frame held, plus noise of 1e-3 h) came out
    with K=9.87 and no warning beyond tau at its bound: the frames determine nothing."""
    rng = np.random.default_rng(7)
    still = np.repeat(runs[0.01][:1], len(runs[0.01]), axis=0)
    still = still + 1e-3 * H * rng.standard_normal(still.shape)
    still[:, [0, N - 1]] = runs[0.01][:1, [0, N - 1]]
    found, warnings = _diagnose(_write(runs["folder"] / "still.npz", still), 4.0, 0.01)
    assert found["motion_h"] == pytest.approx(1e-3, rel=0.3)
    assert found["position_noise_h"] == pytest.approx(1e-3, rel=0.3)
    assert any(w.startswith("the free particles move") and "the answer means nothing" in w
               for w in warnings)


def test_a_moving_cloth_is_not_warned_as_still_even_under_noise(runs):
    rng = np.random.default_rng(8)
    noisy = runs[0.01] + 3e-3 * H * rng.standard_normal(runs[0.01].shape)
    noisy[:, [0, N - 1]] = runs[0.01][:, [0, N - 1]]
    found, warnings = _diagnose(_write(runs["folder"] / "moving.npz", noisy), 4.0, 0.01)
    assert found["motion_h"] > 20 * found["position_noise_h"]
    assert not any(w.startswith("the free particles move") for w in warnings)


@pytest.mark.parametrize("still_steps, expected", [
    ([], []),                      # a moving cloth
    ([20], [21]),                  # one frame repeated
    ([20, 21, 22], [21, 22, 23]),  # a stall of three frames
    ([5, 30], [6, 31]),
    ([0, 1, 2], [1, 2, 3]),        # held still, then released: no freely moving cloth
])
def test_repeated_frames_are_those_that_stop_the_motion_and_let_it_resume(runs, still_steps,
                                                                          expected):
    frames = runs[0.01].copy()
    for step in still_steps:                 # frame step + 1 repeats frame step
        frames[step + 1:] = np.concatenate([frames[step:step + 1], frames[step + 1:-1]])
    assert repeated_frames(frames) == expected
    frames[-3:] = frames[-4]                 # and comes to rest at the end: no repeat more
    assert repeated_frames(frames) == expected
    assert repeated_frames(np.repeat(frames[:1], 5, axis=0)) == []   # nothing moves


def test_repeated_frames_are_named_before_the_misfit_they_cause(runs):
    """An outside user's capture with repeated frames (each a copy of the frame before, as
    a capture that drops a frame writes it) got a misfit warning sending them to the
    discrepancy workflow, which found nothing: the cause was not named. It is now, first,
    wherever the repeats are (here outside the cost's frames)."""
    frames = runs[0.01].copy()
    frames[30] = frames[29]
    frames[45:47] = frames[44]
    found, warnings = _diagnose(_write(runs["folder"] / "repeated.npz", frames), 4.0, 0.01)
    assert found["repeated_frames"] == [30, 45, 46]
    assert warnings[0].startswith("3 frame(s) (30, 45, 46) repeat the frame before"), warnings
    clean, warnings = _diagnose(_write(runs["folder"] / "clean.npz", runs[0.01]), 4.0, 0.01)
    assert clean["repeated_frames"] == [] and not any("repeat the frame" in w
                                                      for w in warnings)


def test_a_pin_missing_from_the_file_is_named_first(runs):
    """An outside user's file listed one of its two pins: the still corner, read as a free
    particle, gave a misfit (and a mass effect in the discrepancy workflow) and no word of
    the cause."""
    trajectory = _write(runs["folder"] / "one_pin.npz", runs[0.01], pinned=((0, 0),))
    found, warnings = _diagnose(trajectory, 4.0, 0.01)
    assert found["unlisted_pins"] == [[0, N - 1]]
    assert warnings[0].startswith(f"1 free particle(s) ((0, {N - 1})) never move"), warnings
    clean, warnings = _diagnose(_write(runs["folder"] / "pins.npz", runs[0.01]), 4.0, 0.01)
    assert clean["unlisted_pins"] == [] and not any("never move" in w for w in warnings)


def test_rounded_positions_are_measured_and_float_resolution_is_not():
    from replication.sequences import rounding_step

    rng = np.random.default_rng(3)
    exact = rng.uniform(-1.0, 1.0, (40, 7, 7, 3))
    assert problem.rounding_step_h(np.round(exact / 1e-3) * 1e-3, 0.1) == pytest.approx(1e-2)
    assert problem.rounding_step_h(np.round(exact * 1000.0), 100.0) == pytest.approx(1e-2)
    assert problem.rounding_step_h(exact, 0.1) is None
    assert problem.rounding_step_h(exact.astype(np.float32).astype(float), 0.1) is None
    assert rounding_step([1.0, 1.0], 1e-9) is None
