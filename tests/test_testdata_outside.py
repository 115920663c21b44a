"""The independent cloth test-data generator (replication/testdata/cloth_outside.py)."""

import ast
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from replication.testdata import cloth_outside as co

H = 1.5 / 16
SOURCE = Path(co.__file__)
ALLOWED_IMPORTS = {"numpy", "json", "math"}
OUTSIDE = sorted(kind for kind, info in co.KINDS.items() if info["expected"] == "unexplained")


def _one_effect_spec(kind, *, noise_h=1e-3, n_frames=120, seed=7):
    rng = np.random.default_rng(seed)
    return co.draw_spec(rng, kinds=[kind], n_effects=1, noise_h=noise_h,
                        frames_range=(n_frames, n_frames))


def test_generator_imports_only_numpy_json_math():
    tree = ast.parse(SOURCE.read_text(), filename=str(SOURCE))
    seen = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            seen.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"relative import at line {node.lineno}"
            seen.add(node.module.split(".")[0])
        elif isinstance(node, ast.Name):
            assert node.id not in {"__import__", "importlib"}, f"dynamic import, line {node.lineno}"
    assert seen <= ALLOWED_IMPORTS, f"imports {sorted(seen - ALLOWED_IMPORTS)}"
    assert "numpy" in seen


def test_generator_runs_standalone_without_the_project():
    # loaded from its file alone, outside the package: it must run and pull in no project module
    script = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('standalone_outside', {str(SOURCE)!r})\n"
        "module = importlib.util.module_from_spec(spec)\n"
        "spec.loader.exec_module(module)\n"
        "run = module.make(module.draw_spec(1, frames_range=(5, 5)))\n"
        "assert run['positions'].shape == (5, 17, 17, 3)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'replication'))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         cwd="/", check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("tau", [0.1, 0.5])
def test_no_effect_matches_the_project_simulator(tau):
    from replication.cloth.model import (
        make_scene, params_from_vectors, reference_vector, simulate,
    )
    n_frames = 200
    spec = {"n_frames": n_frames, "K": 4.0, "tau": tau, "noise_h": 0.0, "seed": 0,
            "effects": []}
    ours = co.make(spec)["positions"].reshape(n_frames, 17 * 17, 3)
    theirs, _ = simulate(params_from_vectors(reference_vector(tau, K=4.0)), make_scene(),
                         n_frames - 1)
    assert np.abs(ours - theirs[0]).max() < 1e-9 * H
    # the run must move and engage the constraint, or the comparison proves little
    assert np.abs(ours[-1] - ours[0]).max() > 5 * H
    assert co.simulate(spec)["constrained"].any()


@pytest.mark.parametrize("kind", sorted(co.KINDS))
def test_every_kind(kind, tmp_path):
    spec = _one_effect_spec(kind)
    assert json.loads(json.dumps(spec)) == spec
    run = co.simulate(spec)
    T = spec["n_frames"]
    assert run["positions"].shape == (T, 17, 17, 3)
    assert run["constrained"].shape == (T - 1, 17 * 17)
    assert run["effect_accel"].shape == (T - 1, 17 * 17, 3)
    assert np.isfinite(run["positions"]).all()
    assert np.abs(run["effect_accel"]).max() > 0
    np.testing.assert_array_equal(run["effect_accel_each"][0], run["effect_accel"])
    pinned = np.array(co.PINNED)
    assert not np.abs(run["effect_accel"][:, pinned[:, 0] * 17 + pinned[:, 1]]).any()

    made = co.make(spec)
    again = co.make(spec)
    assert made["positions"].tobytes() == again["positions"].tobytes()
    assert made["truth"] == again["truth"]
    # pinned particles are exact: never moved, never noisy
    corners = made["positions"][:, pinned[:, 0], pinned[:, 1]]
    np.testing.assert_array_equal(corners, np.broadcast_to(corners[0], corners.shape))
    np.testing.assert_array_equal(corners[0], [[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]])
    noise = (made["positions"] - run["positions"]) / H
    assert 0.5e-3 < noise.std() < 2e-3
    quiet = co.make({**spec, "noise_h": 0.0})
    np.testing.assert_array_equal(quiet["positions"], run["positions"])
    assert quiet["truth"]["snr"] == math.inf

    truth = made["truth"]
    expected = co.KINDS[kind]["expected"]
    assert truth["expected_names"] == ([] if expected == "unexplained" else [expected])
    assert truth["expected_unexplained"] == (expected == "unexplained")
    assert truth["effect_rms_h"] > 0 and 0 < truth["snr"] < math.inf
    assert truth["per_effect"] == [{"kind": kind, "expected": expected,
                                    "effect_rms_h": truth["effect_rms_h"],
                                    "snr": truth["snr"]}]
    assert truth["spec"] == spec
    assert truth["constraint_share"] == float(np.mean(run["constrained"][:, co.FREE]))
    assert 0.0 <= truth["constraint_share"] <= 1.0

    # the file: nominal scalar mass, no truth anywhere
    assert made["mass"] == 0.001 and made["dt"] == 0.002 and made["damping"] == 0.0
    assert json.loads(made["meta"]) == {}
    co.write_npz(tmp_path / "run.npz", made)
    with np.load(tmp_path / "run.npz", allow_pickle=False) as data:
        assert set(data.files) == set(co.FILE_KEYS)
        np.testing.assert_array_equal(data["positions"], made["positions"])
        assert data["mass"].shape == ()
        assert str(data["meta"]) == "{}"


def test_no_effect_truth():
    spec = {"n_frames": 50, "K": 4.0, "tau": 0.3, "noise_h": 1e-3, "seed": 3, "effects": []}
    truth = co.make(spec)["truth"]
    assert truth["expected_names"] == [] and truth["expected_unexplained"] is False
    assert truth["effect_rms_h"] == 0.0 and truth["snr"] == 0.0 and truth["per_effect"] == []


def _state_velocity(positions):
    """v_t = (x_t - x_{t-1}) / dt with v_0 = 0, (T, P, 3)."""
    x = positions.reshape(len(positions), -1, 3)
    v = np.zeros_like(x)
    v[1:] = (x[1:] - x[:-1]) / co.DT
    return v


def test_effect_accelerations_follow_their_definitions():
    free = co.FREE
    # a constant force per unit mass is the same acceleration everywhere
    spec = _one_effect_spec("constant_force")
    effect = spec["effects"][0]
    accel = co.simulate(spec)["effect_accel"]
    target = effect["a"] * np.array(effect["direction"])
    np.testing.assert_allclose(accel[:, free], np.broadcast_to(target, accel[:, free].shape),
                               rtol=0, atol=1e-12)
    # linear damping: -c v / m with v the state velocity
    spec = _one_effect_spec("air_damping")
    run = co.simulate(spec)
    v = _state_velocity(run["positions"])[:-1]
    np.testing.assert_allclose(run["effect_accel"][:, free], -spec["effects"][0]["c"]
                               * v[:, free] / 0.001, rtol=0, atol=1e-9)
    # swirl is horizontal
    accel = co.simulate(_one_effect_spec("swirl"))["effect_accel"]
    assert not accel[..., 2].any() and np.abs(accel[..., :2]).max() > 0
    # a mass band changes nothing outside the band
    spec = _one_effect_spec("mass_step")
    effect = spec["effects"][0]
    lo, hi = effect["band"]
    line = np.arange(17 * 17) // 17 if effect["axis"] == "i" else np.arange(17 * 17) % 17
    accel = co.simulate(spec)["effect_accel"]
    assert not accel[:, (line < lo) | (line > hi)].any()
    assert np.abs(accel[:, (line >= lo) & (line <= hi)]).max() > 0


def test_wind_on_the_flat_sheet_uses_lumped_areas():
    # at rest and flat, every normal is +-z: F = C A_p u_z z with A_p = h^2 inside the sheet,
    # h^2/3 at corner (16, 16) (two triangles) and h^2/6 at corner (16, 0) (one triangle)
    spec = {"n_frames": 2, "K": 4.0, "tau": 0.3, "noise_h": 0.0, "seed": 0,
            "effects": [{"kind": "wind", "C": 0.1, "velocity": [1.0, -0.5, 0.8]}]}
    accel = co.simulate(spec)["effect_accel"][0].reshape(17, 17, 3)
    unit = 0.1 * 0.8 / 0.001 * H**2
    np.testing.assert_allclose(accel[5, 7], [0.0, 0.0, unit], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(accel[16, 16, 2], unit / 3, rtol=1e-12)
    np.testing.assert_allclose(accel[16, 0, 2], unit / 6, rtol=1e-12)


def test_two_effects_truth():
    rng = np.random.default_rng(11)
    spec = co.draw_spec(rng, kinds=["gust", "mass_gradient"], n_effects=2, noise_h=1e-3,
                        frames_range=(80, 80))
    run = co.simulate(spec)
    assert run["effect_accel_each"].shape == (2, 79, 17 * 17, 3)
    truth = co.make(spec)["truth"]
    assert truth["expected_names"] == ["nonuniform_mass"]
    assert truth["expected_unexplained"] is True
    assert sorted(e["kind"] for e in truth["per_effect"]) == ["gust", "mass_gradient"]
    with pytest.raises(ValueError):
        co.simulate({**spec, "effects": [spec["effects"][0]] * 2})


def test_draw_spec_covers_its_ranges():
    rng = np.random.default_rng(2024)
    specs = [co.draw_spec(rng) for _ in range(300)]
    noises = np.array([s["noise_h"] for s in specs])
    assert (noises == 0).any() and 0.1 < (noises == 0).mean() < 0.3
    assert ((noises[noises > 0] >= 1e-4) & (noises[noises > 0] <= 5e-3)).all()
    counts = np.bincount([len(s["effects"]) for s in specs], minlength=3)
    assert counts.size == 3 and (counts > 0).all()
    for s in specs:
        kinds = [e["kind"] for e in s["effects"]]
        assert len(set(kinds)) == len(kinds) and set(kinds) <= set(co.KINDS)
        assert 100 <= s["n_frames"] <= 500
        assert 2.5 <= s["K"] <= 5.5 and 0.1 <= s["tau"] <= 0.6
        assert json.loads(json.dumps(s)) == s
    seen = {e["kind"] for s in specs for e in s["effects"]}
    assert len(seen & set(OUTSIDE)) >= 2
    assert seen == set(co.KINDS)
    # directions have a horizontal part
    for s in specs:
        for e in s["effects"]:
            for key in ("direction", "velocity"):
                if key in e:
                    vec = np.array(e[key])
                    assert np.hypot(vec[0], vec[1]) >= 0.5 * np.linalg.norm(vec) - 1e-12
