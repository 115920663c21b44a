"""Blind test data: cloth trajectories with a hidden effect, magnitude, noise and seed.

The generator simulates the contract's cloth with one effect added the physical way
(non-uniform mass through the masses, anisotropy through per-type stiffness, forces through
the step's external-force argument), adds Gaussian position noise and writes positions only.
The label stays in the returned spec; the workflow only ever sees the trajectory.
``gust`` (a uniform force oscillating in time) is deliberately not in the library.
"""

from __future__ import annotations

import numpy as np

from replication.cloth.io import trajectory_from_rollout
from replication.cloth.model import (
    ClothParams, initial_state, make_scene, params_from_vectors, reference_vector, step,
)
from replication.cloth import geometry

OUTSIDE_EFFECTS = ("gust",)
# log-uniform ranges of each effect's magnitude (per unit nominal mass where a force)
MAGNITUDES = {
    "linear_damping": (1.0, 6.0),        # c/m, 1/s
    "quadratic_drag": (0.5, 3.0),        # c_q/m, 1/m
    "normal_fluid": (100.0, 700.0),      # C/m, 1/(m^2 s): times the area ~h^2 (wind 0.5..2 m/s)
    "body_force": (0.3, 2.0),            # |f|/m, m/s^2
    "anisotropic_stiffness": (0.05, 0.3),  # |a|
    "nonuniform_mass": (0.05, 0.3),      # |beta|
    "spring_damping": (2.0, 12.0),       # c_s/m, 1/s
    "gust": (0.5, 3.0),                  # amplitude/m, m/s^2 (5..10 Hz)
}


def _unit(rng, dim=3):
    vector = rng.normal(size=dim)
    return vector / np.linalg.norm(vector)


def draw_spec(rng, *, effects, noise_range, K_range=(3.0, 5.0), tau_range=(0.1, 0.5),
              magnitude_scale=1.0):
    """Draw one hidden setting: effect (or ``"none"``), its parameters, noise, base model.

    Parameters
    ----------
    rng : np.random.Generator
    effects : sequence of str
        Names to draw from with equal probability (``"none"`` for effect-free data).
    noise_range : (2,) float
        Log-uniform range of the position noise standard deviation, in units of ``h``.

    Returns
    -------
    dict with ``effect``, ``truth`` (the effect's coefficients as the library defines
    them, per unit nominal mass where relevant), ``noise_h``, ``K``, ``tau``, ``seed``.
    """
    effect = str(effects[rng.integers(len(effects))])
    spec = {"effect": effect,
            "noise_h": float(np.exp(rng.uniform(*np.log(noise_range)))),
            "K": float(rng.uniform(*K_range)),
            "tau": float(np.exp(rng.uniform(*np.log(tau_range)))),
            "seed": int(rng.integers(2**31))}
    if effect == "none":
        spec["truth"] = {}
        return spec
    lo, hi = MAGNITUDES[effect]
    size = float(np.exp(rng.uniform(np.log(lo), np.log(hi)))) * magnitude_scale
    if effect in ("linear_damping", "quadratic_drag", "spring_damping"):
        truth = {"per_mass": [size]}
    elif effect == "normal_fluid":
        wind = _unit(rng) * rng.uniform(0.5, 2.0)
        truth = {"per_mass": [size], "wind": wind.tolist()}
    elif effect == "body_force":
        truth = {"per_mass": (_unit(rng) * size).tolist()}
    elif effect == "anisotropic_stiffness":
        truth = {"a": size * (1.0 if rng.random() < 0.5 else -1.0)}
    elif effect == "nonuniform_mass":
        truth = {"beta": (_unit(rng, 2) * size).tolist()}
    elif effect == "gust":
        truth = {"per_mass": (_unit(rng) * size).tolist(),
                 "frequency": float(rng.uniform(5.0, 10.0)),
                 "phase": float(rng.uniform(0, 2 * np.pi))}
    else:
        raise ValueError(f"effect {effect!r}: the generator does not know it")
    spec["truth"] = truth
    return spec


def _force(spec, x, v, t, scene, ops):
    """External force of the hidden effect on one state (1, P, 3), or None."""
    effect, truth = spec["effect"], spec["truth"]
    m = scene.mass[None, :, None]
    if effect == "linear_damping":
        return -truth["per_mass"][0] * m * v
    if effect == "quadratic_drag":
        return -truth["per_mass"][0] * m * np.linalg.norm(v, axis=2, keepdims=True) * v
    if effect == "normal_fluid":
        # Provot's fluid force on the particle's share of the surface: C A (n.(u - v)) n
        area_normal = geometry.area_normals(x, scene.n)
        unit = area_normal / np.linalg.norm(area_normal, axis=2, keepdims=True)
        relative = np.asarray(truth["wind"])[None, None, :] - v
        return (truth["per_mass"][0] * m
                * np.sum(area_normal * relative, axis=2, keepdims=True) * unit)
    if effect == "body_force":
        return m * np.asarray(truth["per_mass"])[None, None, :]
    if effect == "spring_damping":
        return truth["per_mass"][0] * m * geometry.dashpot_sums(ops, x, v)
    if effect == "gust":
        phase = 2 * np.pi * truth["frequency"] * t * scene.dt + truth["phase"]
        return m * np.sin(phase) * np.asarray(truth["per_mass"])[None, None, :]
    return None


def simulate_spec(spec, n_frames):
    """Noise-free positions (n_frames, P, 3) of the hidden setting, and the nominal scene."""
    nominal = make_scene()
    truth = spec["truth"]
    scene = nominal
    params = params_from_vectors(reference_vector(spec["tau"], K=spec["K"]))
    if spec["effect"] == "nonuniform_mass":
        ops = geometry.MeshOperators(nominal.n)
        inverse = 1.0 + truth["beta"][0] * ops.s_i + truth["beta"][1] * ops.s_j
        scene = make_scene(nominal.n, mass=(nominal.mass / inverse).reshape(nominal.n, -1))
    if spec["effect"] == "anisotropic_stiffness":
        a = truth["a"]
        k = params.k.copy()
        k[:, [0, 4]] *= 1.0 + a
        k[:, [1, 5]] *= 1.0 - a
        params = ClothParams(params.rest, k, params.tau)
    ops = geometry.MeshOperators(nominal.n)
    x, v = initial_state(scene)
    frames = [x[0]]
    for t in range(n_frames - 1):
        x, v = step(x, v, params, scene, _force(spec, x, v, t, scene, ops))
        frames.append(x[0])
    return np.stack(frames), nominal


def make_trajectory(spec, n_frames):
    """The blind trajectory of ``spec``: noisy positions only, nominal scene, no label."""
    positions, scene = simulate_spec(spec, n_frames)
    rng = np.random.default_rng(spec["seed"])
    h = 1.5 / (scene.n - 1)
    noisy = positions + rng.normal(scale=spec["noise_h"] * h, size=positions.shape)
    return trajectory_from_rollout(noisy, scene, meta={})


def truth_coefficients(spec, mass):
    """The hidden effect's coefficients in the library's parametrisation (or None)."""
    effect, truth = spec["effect"], spec["truth"]
    if effect in ("linear_damping", "quadratic_drag", "spring_damping"):
        return np.array([truth["per_mass"][0] * mass])
    if effect == "normal_fluid":
        C = truth["per_mass"][0] * mass
        return np.concatenate([[C], C * np.asarray(truth["wind"])])
    if effect == "body_force":
        return np.asarray(truth["per_mass"]) * mass
    if effect == "anisotropic_stiffness":
        # k = K (1 + a) along j and K (1 - a) along i: extra stiffness K a and -K a
        return np.array([truth["a"] * spec["K"], -truth["a"] * spec["K"]])
    if effect == "nonuniform_mass":
        # inverse mass 1 + beta_i s_i + beta_j s_j in the library's centred row and column
        # indicators (last row and column as reference): coefficient beta (s(r) - 1)
        n = 17
        s = 2.0 * np.arange(n - 1) / (n - 1) - 1.0
        return np.concatenate([truth["beta"][0] * (s - 1.0), truth["beta"][1] * (s - 1.0)])
    return None
