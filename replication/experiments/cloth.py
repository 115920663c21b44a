"""Runners of the cloth model experiments (paper 3.2, 3.4): reference runs, Figs. 8 and 11.

Each runner takes the resolved config (plain dict) and the output folder and returns the
experiment's result keys; ``replication.cli`` writes ``result.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from replication.cloth.costs import cost_frames, make_cost
from replication.cloth.io import read_trajectory, trajectory_from_rollout, write_trajectory
from replication.cloth.model import make_scene, params_from_vectors, reference_vector, simulate
from replication.errors import InputError, check
from replication.progress import progress
from replication.provenance import file_sha256
from replication.results import write_json_atomic


def reference_file(data_dir, tau):
    """Path of the reference run for ``tau`` inside ``data_dir``.

    Parameters
    ----------
    data_dir : str or Path
    tau : float
    """
    return Path(data_dir) / f"reference_tau{tau:g}.npz"


def _scene_from_config(scene_cfg):
    try:
        return make_scene(scene_cfg["n"], dt=scene_cfg["dt"], mass=scene_cfg["mass"],
                          gravity=scene_cfg["gravity"], damping=scene_cfg["damping"],
                          pinned=scene_cfg.get("pinned"))
    except InputError as error:
        raise InputError(f"scene.{error}") from None


def reference_runs(config, out):
    """Paper 3.4: the K = 4, tau = 0.1 and 0.5 reference runs, with a manifest of sha256.

    Parameters
    ----------
    config, out
        The resolved ``cloth_reference`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    scene_cfg = config["scene"]
    n_steps = int(config["n_steps"])
    check(n_steps >= 2, f"n_steps={n_steps}: expected at least 2 steps (T >= 3 frames)")
    # checked before any simulation: a bad value otherwise fails deep inside the model or
    # as a refusal of the written file, named by its staging path
    check(int(scene_cfg["n"]) >= 3, f"scene.n={scene_cfg['n']}: expected at least 3 "
                                    "particles per side")
    for key in ("side", "dt", "mass"):
        check(float(scene_cfg[key]) > 0, f"scene.{key}={scene_cfg[key]}: expected > 0")
    check(float(config["K"]) > 0, f"K={config['K']}: expected a stiffness > 0")
    check(len(config["taus"]) > 0, "taus: expected at least one value")
    data_dir = Path(config["data_dir"])
    scene = _scene_from_config(scene_cfg)
    for kind in ("small", "full"):   # the costs at the truth need their frames in the runs
        cost_frames(kind, n_steps + 1, **config["cost"])
    files, costs = {}, {}
    for tau in config["taus"]:
        check(tau > 0, f"taus: {tau}: expected tau > 0")
        truth = reference_vector(tau, K=config["K"], n=scene.n, side=scene_cfg["side"])
        progress(f"reference run tau={tau}: {n_steps} steps")
        positions, _ = simulate(params_from_vectors(truth), scene, n_steps)
        check(np.all(np.isfinite(positions)),
              f"scene.dt={scene_cfg['dt']}: the run with tau={tau} blew up (non-finite "
              "positions): expected a stable time step for this K and mass (a smaller dt)")
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
    progress(f"wrote {len(files)} trajectories and manifest.json into data_dir")
    return {"files": files, "data_dir": str(data_dir), "costs_at_truth": costs}


def fig08_mesh(config, out):
    """Paper Fig. 8: draw the mesh and its spring families; count the springs.

    Parameters
    ----------
    config, out
        The resolved ``fig08_mesh`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    from replication.cloth.mesh import TYPE_NAMES, flat_rest_positions, springs
    from replication.figures import fig08_mesh as figure

    n = int(config["scene"]["n"])
    check(n >= 3, f"scene.n={n}: expected at least 3 particles per side")
    zoom = int(config["zoom"])
    check(2 <= zoom <= n, f"zoom={zoom}: expected 2 <= zoom <= scene.n={n}")
    a, b, kind = springs(n)
    scene = _scene_from_config(config["scene"])
    path = figure.draw(Path(config["figure_dir"]) / "fig08_mesh.png",
                       positions=flat_rest_positions(n, config["scene"]["side"]), a=a, b=b,
                       kind=kind, pinned=scene.pinned, n=n, zoom=zoom)
    counts = {f"{t}: {TYPE_NAMES[t]}": int((kind == t).sum()) for t in range(len(TYPE_NAMES))}
    return {"spring_counts": counts, "n_springs": int(kind.size), "figures": [path]}


def _rms_h(a, b, h):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))) / h)


def fig11_reconstruction(config, out):
    """Paper Fig. 11: the reference animation beside re-simulations from given parameters.

    Parameters
    ----------
    config, out
        The resolved ``fig11_reconstruction`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    from replication.cloth.costs import structural_length
    from replication.figures import fig11_reconstruction as figure

    path = config["data"]["path"] or config["default_data"]
    trajectory = read_trajectory(path)
    sets = config["reconstructions"]
    check(len(sets) > 0, "reconstructions: expected at least one parameter set")
    for entry in sets:
        check(len(entry["params"]) in (5, 18),
              f"reconstructions: '{entry['label']}' has {len(entry['params'])} parameters; "
              "expected 5 (l01, l23, l45, K, tau) or 18")
    stride = config["gif_stride"]
    check(isinstance(stride, int) and not isinstance(stride, bool) and stride >= 1,
          f"gif_stride={stride!r}: expected an integer >= 1")
    for entry in sets:
        check(all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
                  for v in entry["params"]),
              f"reconstructions: '{entry['label']}' params {entry['params']}: expected "
              "finite numbers")
    frames = [int(t) for t in config["frames"]]
    check(all(0 <= t < trajectory.n_frames for t in frames),
          f"frames={frames}: expected frame indices in 0..{trajectory.n_frames - 1}")
    scene = trajectory.scene()
    recorded = trajectory.flat_positions()
    x0 = recorded[:1]
    v0 = trajectory.flat_velocities()[:1]
    h = structural_length(trajectory)
    columns, titles, rows = [recorded], ["original"], []
    for entry in sets:
        params = params_from_vectors(entry["params"])
        progress(f"re-simulating '{entry['label']}'")
        positions, _ = simulate(params, scene, trajectory.n_frames - 1, x0, v0)
        columns.append(positions[0])
        costs = {kind: float(make_cost(trajectory, kind, **config["cost"])(params)[0])
                 for kind in ("small", "full")}
        rows.append({"label": entry["label"], "params": entry["params"], **costs,
                     "paper_cost": entry.get("paper_cost"),
                     "rms_error_h": _rms_h(positions[0], recorded, h),
                     "final_error_h": _rms_h(positions[0, -1], recorded[-1], h)})
        titles.append(f"{entry['label']}\nsmall cost {costs['small']:.3g}")
    figure_dir = Path(config["figure_dir"])
    png = figure.draw(figure_dir / "fig11_reconstruction.png", columns=columns, titles=titles,
                      frames=frames, n=trajectory.n, dt=trajectory.dt)
    gif = figure.animate(figure_dir / "fig11_reconstruction.gif", columns=columns,
                         titles=titles, frames=range(0, trajectory.n_frames,
                                                      int(config["gif_stride"])),
                         n=trajectory.n, dt=trajectory.dt)
    return {"data": str(path), "h": h, "reconstructions": rows, "figures": [png, gif]}
