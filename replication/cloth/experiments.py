"""Runners of the cloth experiments of issue 2: reference runs, Figs. 8 and 11.

Each runner takes the resolved config (plain dict) and the output folder and returns the
experiment's result keys; ``replication.cli`` writes ``result.json``.
"""

from __future__ import annotations

import json
from pathlib import Path

from replication.cloth.costs import make_cost
from replication.cloth.io import read_trajectory, trajectory_from_rollout, write_trajectory
from replication.cloth.model import make_scene, params_from_vectors, reference_vector, simulate
from replication.errors import check
from replication.progress import progress
from replication.provenance import file_sha256
from replication.results import write_json_atomic


def reference_file(data_dir, tau):
    """Path of the reference run for ``tau`` inside ``data_dir``."""
    return Path(data_dir) / f"reference_tau{tau:g}.npz"


def _scene_from_config(scene_cfg):
    return make_scene(scene_cfg["n"], dt=scene_cfg["dt"], mass=scene_cfg["mass"],
                      gravity=scene_cfg["gravity"], damping=scene_cfg["damping"],
                      pinned=scene_cfg["pinned"])


def reference_runs(config, out):
    """Paper 3.4: the K = 4, tau = 0.1 and 0.5 reference runs, with a manifest of sha256."""
    scene_cfg = config["scene"]
    n_steps = int(config["n_steps"])
    check(n_steps >= 2, f"n_steps={n_steps}: expected at least 2 steps (T >= 3 frames)")
    check(len(config["taus"]) > 0, "taus: expected at least one value")
    data_dir = Path(config["data_dir"])
    scene = _scene_from_config(scene_cfg)
    files, costs = {}, {}
    for tau in config["taus"]:
        check(tau > 0, f"taus: {tau}: expected tau > 0")
        truth = reference_vector(tau, K=config["K"], n=scene.n, side=scene_cfg["side"])
        progress(f"reference run tau={tau}: {n_steps} steps")
        positions, _ = simulate(params_from_vectors(truth), scene, n_steps)
        meta = {
            "description": f"contract reference run, K={config['K']}, tau={tau}",
            "true_params": dict(zip(("l01", "l23", "l45", "K", "tau"), truth.tolist())),
            "generator": "replicate experiment=cloth_reference",
        }
        path = reference_file(data_dir, tau)
        write_trajectory(path, trajectory_from_rollout(positions[0], scene, meta=meta))
        files[path.name] = file_sha256(path)
        trajectory = read_trajectory(path)
        truth_params = params_from_vectors(truth)
        costs[f"tau={tau:g}"] = {
            kind: float(make_cost(trajectory, kind, **config["cost"])(truth_params)[0])
            for kind in ("small", "full")
        }
    manifest = {"config": {k: v for k, v in config.items() if k != "out"}, "files": files}
    write_json_atomic(data_dir / "manifest.json", manifest)
    progress(f"wrote {len(files)} trajectories and manifest.json to {data_dir}")
    return {"files": files, "data_dir": str(data_dir), "costs_at_truth": costs}


def load_manifest(data_dir):
    """The manifest written by :func:`reference_runs`."""
    return json.loads((Path(data_dir) / "manifest.json").read_text())
