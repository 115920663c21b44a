"""The discrepancy workflow (issue 6): clean data, a planted effect, refusals, determinism,
and the real command line."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from replication.cloth.io import write_trajectory
from replication.discrepancy import generate as gen
from replication.discrepancy.workflow import analyse
from replication.errors import InputError
from replication.experiments.discrepancy import discrepancy

ROOT = Path(__file__).resolve().parents[2]
N_FRAMES = 100


def _spec(effect, truth, noise=1e-4, seed=11):
    return {"effect": effect, "truth": truth, "noise_h": noise, "K": 4.0, "tau": 0.3,
            "seed": seed}


@pytest.fixture(scope="module")
def clean_trajectory():
    return gen.make_trajectory(_spec("none", {}), N_FRAMES)


@pytest.fixture(scope="module")
def clean_result(clean_trajectory):
    return analyse(clean_trajectory, {"n_subsamples": 10}, rng=0)


def test_clean_data_gets_no_name(clean_result):
    assert clean_result["named_effects"] == []
    assert clean_result["unexplained"] is None
    assert clean_result["gap_after"] == clean_result["gap_before"]
    # the noise floor is estimated from the data alone
    assert 0.7e-4 < clean_result["where"]["noise_sigma_h"] < 1.3e-4


def test_clean_data_get_the_detection_limit_and_the_held_out_warning(clean_result):
    """Nothing is missing, but 100 frames leave tau (0.3) undetermined: the fit takes the
    training frames' largest stretch (0.17) and mispredicts the held-out block, which
    stretches further (the warning came with the held-out check; before, only the limit)."""
    limit = clean_result["detection_limit"]
    held, caveat = clean_result["warnings"]
    assert "does not predict the held-out frames" in held and "only a lower bound" in held
    assert clean_result["gap"]["generalisation"]["tau"] < 0.2
    assert caveat.split(";")[0] == "nothing is named"
    assert f"about {100 * limit['share_of_weight']:.2g}% of the weight" in caveat


def test_an_implausible_base_fit_a_small_gap_shrink_and_a_huge_body_force_are_warned(
        clean_trajectory):
    from types import SimpleNamespace

    from replication.cloth import regression
    from replication.discrepancy.workflow import _warnings

    data = regression.prepare(clean_trajectory)
    fit = regression.fit(data, np.arange(5, 90, 5))
    located = {"mask_dropped": False}
    assert _warnings(data, fit, located, [], 1.0, 1.0) == []

    broken = SimpleNamespace(base=fit.base._replace(rest=fit.base.rest * 5))
    ratio = broken.base.rest[0] / regression.typical_lengths(data)[0]   # about 5
    assert _warnings(data, broken, located, [], 1.0, 1.0)[0].startswith(
        "the base model does not fit these data plausibly (rest length of type 0 is "
        f"{ratio:.3g} x its median observed length")
    weight = 0.001 * 9.81
    force = {"name": "body_force", "parameters": {"coefficients": {
        "f_x": 0.0, "f_y": 0.0, "f_z": 0.9 * weight}}}
    found = _warnings(data, fit, {"mask_dropped": True}, [force], 1.0, 0.9)
    assert [w.split(" ")[:3] for w in found] == [
        ["no", "particle", "stays"], ["the", "named", "effect(s)"], ["the", "named", "body"]]
    def anisotropy(dk_j, dk_i, se, correlation=0.0):
        covariance = se ** 2 * np.array([[1.0, correlation], [correlation, 1.0]])
        return {"name": "anisotropic_stiffness", "parameters": {
            "coefficients": {"dk_j": dk_j, "dk_i": dk_i}, "ratio_j_over_i": 1.0,
            "covariance": covariance.tolist()}}

    # equal within their errors (shear springs stiffer than the rest): warned
    assert _warnings(data, fit, located, [anisotropy(-2.0385, -2.0386, 1e-4)], 2.0, 1.0)[
        0].startswith("anisotropic_stiffness is named with equal stiffness along j and i")
    # a 1% anisotropy measured to 1e-4: a real one, no warning
    assert _warnings(data, fit, located, [anisotropy(-0.04, 0.0, 1e-4)], 2.0, 1.0) == []
    # errors of 1e-3 that the shared springs correlate (0.9999) leave the difference
    # known to 1.4e-5, so a 1e-4 difference is real: no warning (independent ones would)
    assert _warnings(data, fit, located, [anisotropy(-2.0385, -2.0386, 1e-3)], 2.0, 1.0)
    assert _warnings(data, fit, located, [anisotropy(-2.0385, -2.0386, 1e-3, 0.9999)],
                     2.0, 1.0) == []


def test_a_mass_profile_with_no_positive_mass_somewhere_is_warned(clean_trajectory):
    """An outside user's noisy effect-free cloth got nonuniform_mass, 'strong', with an
    inverse mass 1 + row(i) + col(j) below 0 at 77 particles, and only a 'tentative'
    warning. The count is part of the effect's parameters, and a non-zero one is warned."""
    from replication.cloth import regression
    from replication.discrepancy import effects
    from replication.discrepancy.workflow import _warnings

    n = clean_trajectory.n
    theta = np.zeros(2 * (n - 1))
    assert effects.LIBRARY["nonuniform_mass"].physical(theta, {})[
        "nonpositive_inverse_mass"] == 0
    theta[0] = -1.5   # row 0: inverse mass 1 - 1.5 (1 - 1/n) < 0; other rows 1 + 1.5 / n
    physical = effects.LIBRARY["nonuniform_mass"].physical(theta, {})
    assert physical["nonpositive_inverse_mass"] == n
    data = regression.prepare(clean_trajectory)
    fit = regression.fit(data, np.arange(5, 90, 5))
    named = {"name": "nonuniform_mass", "parameters": physical}
    assert _warnings(data, fit, {"mask_dropped": False}, [named], 2.0, 1.0) == [
        f"nonuniform_mass is named with an inverse mass 1 + row(i) + col(j) of 0 or less at "
        f"{n} of {n * n} particles: no mass profile gives that, so the name describes the "
        "residuals, not the cloth (noise, a base fit in a wrong valley, or an effect outside "
        "the library)"]
    named["parameters"] = effects.LIBRARY["nonuniform_mass"].physical(theta / 3, {})
    assert _warnings(data, fit, {"mask_dropped": False}, [named], 2.0, 1.0) == []


def test_the_detection_limit_follows_the_noise_and_is_mentioned_when_nothing_is_named(
        clean_trajectory):
    from replication.cloth import regression
    from replication.discrepancy.workflow import DETECTION_SNR, _warnings, detection_limit

    data = regression.prepare(clean_trajectory)
    fit = regression.fit(data, np.arange(5, 90, 5))
    mask = np.zeros((data.n_frames, data.x.shape[1]), dtype=bool)
    mask[:24] = True   # 24 frames; the pinned particles in it do not count (the fit's
    mask[40] = True    # masks never hold them), nor do frames outside the fit's frames
    free = int(data.free.sum())
    limit = detection_limit(data, mask, 1e-3, np.arange(30))
    # a fit through the constraint has no mask: the free particles of the frames count
    empty = detection_limit(data, np.zeros_like(mask), 1e-3, np.arange(30))
    assert empty["particle_frames"] == 30 * free
    assert limit["particle_frames"] == 24 * free
    assert limit["displacement_h"] == pytest.approx(
        DETECTION_SNR * np.sqrt(6) * 1e-3 / np.sqrt(24 * free))
    weight_step = data.scene.dt ** 2 * 9.81 / data.h    # one step of free fall, in h
    assert limit["share_of_weight"] == pytest.approx(limit["displacement_h"] / weight_step)
    located = {"mask_dropped": False, "noise_sigma_h": 1e-3}
    assert _warnings(data, fit, located, [], 1.0, 1.0, limit)[0].startswith(
        "nothing is named; at this noise (0.001 h) the detection limit")
    assert _warnings(data, fit, located, [], 1.0, 1.0,
                     detection_limit(data, mask, 1e-7, np.arange(30))) == []


def test_planted_drag_is_named_with_its_coefficient():
    spec = _spec("quadratic_drag", {"per_mass": [2.0]})
    result = analyse(gen.make_trajectory(spec, N_FRAMES), {"n_subsamples": 10}, rng=0)
    assert [e["name"] for e in result["named_effects"]] == ["quadratic_drag"]
    fitted = result["named_effects"][0]["parameters"]["c_q"]
    assert abs(fitted - 2.0 * 0.001) < 0.05 * 2.0 * 0.001
    assert result["gap_after"] < result["gap_before"]


def test_same_seed_same_numbers(clean_trajectory, clean_result):
    again = analyse(clean_trajectory, {"n_subsamples": 10}, rng=0)
    assert again["gap_before"] == clean_result["gap_before"]
    assert again["where"]["Q"] == clean_result["where"]["Q"]
    assert again["candidates"] == clean_result["candidates"]


def _config(path, tmp_path):
    return {"seed": 0, "data": {"path": str(path)}, "plots": False,
            "discrepancy": {"n_subsamples": 5}, "out": str(tmp_path)}


def test_refuses_missing_data_path(tmp_path):
    with pytest.raises(InputError, match="data.path is not set"):
        discrepancy({"seed": 0, "data": {"path": None}}, tmp_path)


def test_refuses_file_without_positions(tmp_path):
    path = tmp_path / "bad.npz"
    np.savez(path, dt=0.002, mass=0.001, gravity=np.zeros(3), pinned=np.zeros((0, 2), int))
    with pytest.raises(InputError, match=r"bad.npz: field 'positions': found no such key"):
        discrepancy(_config(path, tmp_path), tmp_path)


def test_refuses_too_short_trajectory(tmp_path, clean_trajectory):
    path = tmp_path / "short.npz"
    short = clean_trajectory.__class__(**{**clean_trajectory.__dict__,
                                          "positions": clean_trajectory.positions[:20]})
    write_trajectory(path, short)
    with pytest.raises(InputError, match=r"field 'positions': found 20 frames; expected at least"):
        discrepancy(_config(path, tmp_path), tmp_path)


def test_command_line(tmp_path, clean_trajectory):
    data = tmp_path / "tiny.npz"
    write_trajectory(data, clean_trajectory)
    out = tmp_path / "run"
    command = [sys.executable, "-m", "replication.cli", "experiment=discrepancy",
               f"data.path={data}", f"out={out}", "discrepancy.n_subsamples=5"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    result = json.loads((out / "result.json").read_text())
    for key in ("named_effects", "gap_before", "gap_after", "where"):
        assert key in result
    assert (out / "discrepancy_where.png").exists()

    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    out_bad = tmp_path / "run_bad"
    done = subprocess.run(command[:4] + [f"data.path={bad}", f"out={out_bad}"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip().startswith("error: ") and "bad.npz" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not (out_bad / "result.json").exists()


def test_effect_outside_the_library_is_unexplained_not_named():
    spec = _spec("gust", {"per_mass": [0.0, 2.0, 0.0], "frequency": 8.0, "phase": 0.3},
                 noise=3e-5)
    result = analyse(gen.make_trajectory(spec, N_FRAMES), {"n_subsamples": 10}, rng=0)
    assert result["named_effects"] == []
    assert result["unexplained"] is not None


def test_generator_is_deterministic():
    spec = gen.draw_spec(np.random.default_rng(5), effects=["body_force"],
                         noise_range=(1e-4, 1e-4))
    first = gen.make_trajectory(spec, 30).positions
    second = gen.make_trajectory(spec, 30).positions
    assert np.array_equal(first, second)
    assert spec == gen.draw_spec(np.random.default_rng(5), effects=["body_force"],
                                 noise_range=(1e-4, 1e-4))


def test_refuses_data_that_is_not_a_cloth(tmp_path, clean_trajectory):
    rng = np.random.default_rng(0)
    noise = clean_trajectory.__class__(**{**clean_trajectory.__dict__,
                                          "positions": rng.normal(size=(N_FRAMES, 17, 17, 3))})
    path = tmp_path / "noise.npz"
    write_trajectory(path, noise)
    with pytest.raises(InputError, match=r"noise.npz: field .positions.: .*expected a cloth"):
        discrepancy(_config(path, tmp_path), tmp_path)


def test_structure_measures_two_models_on_one_noise_scale():
    from replication.discrepancy.residuals import structure

    rng = np.random.default_rng(3)
    n, frames = 17, np.arange(40)
    free = np.ones(n * n, dtype=bool)
    r = rng.normal(scale=1e-3, size=(frames.size, n * n, 3))
    own = structure(r, frames, free, n)
    halved = structure(r, frames, free, n, sigma=2.0 * own["sigma"])
    assert halved["sigma"] == 2.0 * own["sigma"]
    assert np.isclose(halved["Q"], own["Q"] / 4.0)


def test_the_warned_detection_limit_is_the_outside_study_s():
    """The workflow's caveat quotes the limit the outside study states and measures."""
    import yaml

    from replication.discrepancy.workflow import DETECTION_SNR

    study = yaml.safe_load(open("configs/experiment/discrepancy_outside.yaml"))["study"]
    assert DETECTION_SNR == study["detection_snr"]


def test_the_wide_outside_study_draws_k_and_tau_per_decade_and_the_narrow_one_as_before():
    """discrepancy_outside_wide draws K and tau log-uniformly over the identification
    bounds (as many soft and weakly damped cloths as stiff ones); without log_uniform the
    draw is the generator's own, spec for spec."""
    import yaml

    from replication.experiments.discrepancy_outside import draw_specs
    from replication.testdata import cloth_outside as og

    narrow = yaml.safe_load(open("configs/experiment/discrepancy_outside.yaml"))["study"]
    narrow = {**narrow, "n_datasets": 5}
    rng = np.random.default_rng(3)
    assert draw_specs(narrow, 3) == [
        og.draw_spec(rng, kinds=list(og.KINDS), frames_range=tuple(narrow["frames_range"]),
                     K_range=tuple(narrow["K_range"]), tau_range=tuple(narrow["tau_range"]),
                     size_decades=tuple(narrow["size_decades"])) for _ in range(5)]
    wide = {**narrow, "n_datasets": 300, "K_range": [0.1, 10.0], "tau_range": [0.01, 1.0],
            "log_uniform": True}
    specs = draw_specs(wide, 3)
    K = np.array([s["K"] for s in specs])
    tau = np.array([s["tau"] for s in specs])
    assert K.min() >= 0.1 and K.max() <= 10.0 and tau.min() >= 0.01 and tau.max() <= 1.0
    # a uniform draw puts 3% below 0.4 and below 0.04; log-uniform about 30%
    assert 0.2 < np.mean(K < 0.4) < 0.4 and 0.2 < np.mean(tau < 0.04) < 0.4


def test_a_base_misfit_without_structure_is_warned_when_nothing_is_named(clean_trajectory):
    """An outside user's reversed reference (and a noise-free 25 x 25 sheet whose base tau
    was 3e-4 off) got 'nothing missing' with no warning, their residuals 5e4 x the noise
    lying where the constraint acts or without structure."""
    from replication.cloth import regression
    from replication.discrepancy.workflow import LIMIT_CAVEAT, _warnings

    data = regression.prepare(clean_trajectory)
    fit = regression.fit(data, np.arange(5, 90, 5))
    quiet = {"mask_dropped": False, "excess_power": 5e4}
    # analyse reports such a misfit as unexplained, with its excess power (no windows)
    misfit = {"Q": 1.0, "excess_power": 5e4, "time_windows_s": [], "patches": []}
    warned = _warnings(data, fit, quiet, [], 1.0, 1.0, unexplained=misfit)
    assert warned[0].startswith("the base model's one-step residuals are 5e+04 x what the "
                                "noise explains, yet nothing is named and the structure test "
                                "finds nothing")
    assert warned[0].endswith("reported as unexplained (unexplained.excess_power)")
    assert not warned[0].startswith(LIMIT_CAVEAT)   # the outside study counts it as a warning
    # structure unexplained (no excess_power: the structure test found it): no such line
    assert not any("yet nothing is named" in w for w in
                   _warnings(data, fit, quiet, [], 1.0, 1.0, unexplained={"Q": 9.0}))


@pytest.mark.parametrize("n", [9, 12, 17, 25])
def test_a_mass_profile_names_one_coefficient_per_row_and_column_of_any_mesh(n):
    """The names were the 17 x 17 contract's on every mesh: on 12 x 12, 'row11..row15'
    were columns; on 25 x 25, 16 of 48 coefficients were dropped."""
    from replication.discrepancy.effects import coefficient_names, get_effect

    from types import SimpleNamespace

    from replication.cloth.regression import n_base
    from replication.discrepancy.workflow import _describe

    expected = tuple(f"row{i}" for i in range(n - 1)) + tuple(f"col{j}" for j in range(n - 1))
    profile = get_effect("nonuniform_mass")
    assert coefficient_names(profile, 2 * (n - 1)) == expected
    assert coefficient_names(get_effect("linear_damping"), 1) == ("c",)
    # what a result shows: every coefficient named, none dropped (a fit of n x n data)
    theta = np.linspace(-0.1, 0.1, 2 * (n - 1))
    width = n_base("5") + theta.size
    fit = SimpleNamespace(terms=[(profile, theta)], cov=np.eye(width),
                          base=SimpleNamespace(k=np.ones(6)), term=lambda name: theta)
    parameters = _describe(fit, "nonuniform_mass", {}, "5")["parameters"]
    assert tuple(parameters["coefficients"]) == expected
    assert list(parameters["coefficients"].values()) == theta.tolist()
    assert tuple(parameters["standard_errors"]) == expected
