"""The discrepancy workflow on one trajectory: fit, localise, name, add, measure the gap."""

from __future__ import annotations

import numpy as np

from replication.discrepancy import effects as fx
from replication.discrepancy.fit import Fit, base_from_theta, fit_model, usable_frames
from replication.discrepancy.gap import STARTS, one_step_error, rollout_error, split_frames
from replication.discrepancy.naming import score_candidates
from replication.discrepancy.residuals import residuals, structure, where
from replication.errors import InputError

DEFAULTS = {
    "model": "5", "holdout_block": 25, "holdout_every": 4, "window": 10, "patch": 4,
    "alpha": 1e-3, "n_subsamples": 40, "stability_min": 0.5, "q_threshold": 3.0,
    "explained_min": 0.5, "max_candidates": 2,
}
MIN_FRAMES = 60


def settings_from(config):
    """Workflow settings: :data:`DEFAULTS` updated by ``config`` (validated)."""
    settings = dict(DEFAULTS)
    settings.update({k: v for k, v in (config or {}).items() if k in DEFAULTS})
    if str(settings["model"]) not in ("5", "18"):
        raise InputError(f"discrepancy.model={settings['model']!r}: expected '5' or '18'")
    settings["model"] = str(settings["model"])
    for key in ("holdout_block", "holdout_every", "window", "patch"):
        if int(settings[key]) < 2:
            raise InputError(f"discrepancy.{key}={settings[key]}: expected an integer >= 2")
    if not 0 < float(settings["alpha"]) < 1:
        raise InputError(f"discrepancy.alpha={settings['alpha']}: expected 0 < alpha < 1")
    return settings


def _structure_of(data, fit, frames, settings):
    r = residuals(data, fit, frames)
    return structure(r, frames, data.free, data.ops.n, window=settings["window"],
                     patch=settings["patch"]), r


def _bic_delta(r0, r1, extra_params):
    """Change of BIC (Gaussian one-step residuals) from adding ``extra_params``."""
    n = r0.size
    return float(n * np.log(np.sum(r1 ** 2) / np.sum(r0 ** 2)) + extra_params * np.log(n))


def analyse(trajectory, config=None, *, rng=None):
    """Run the whole workflow on a validated trajectory.

    Parameters
    ----------
    trajectory : replication.cloth.io.Trajectory
        Positions (noise expected); ``meta`` is never read.
    config : dict, optional
        Settings (see :data:`DEFAULTS`).
    rng : np.random.Generator | int | None
        For stability selection.

    Returns
    -------
    dict with ``named_effects``, ``unexplained``, ``gap_before``, ``gap_after`` (held-out
    rollout RMS in ``h``), ``gap`` (one-step and rollout details), ``where``, ``base``,
    ``candidates``.
    """
    from replication.discrepancy.fit import prepare

    settings = settings_from(config)
    if trajectory.n_frames < MIN_FRAMES:
        raise InputError(f"{trajectory.source}: field 'positions': found {trajectory.n_frames} "
                         f"frames; expected at least {MIN_FRAMES} for fitting and held-out "
                         "checks")
    rng = np.random.default_rng(rng)
    data = prepare(trajectory)
    train, held = split_frames(data.n_frames, block=settings["holdout_block"],
                               every=settings["holdout_every"])
    if not held:
        needed = settings["holdout_block"] * settings["holdout_every"]
        raise InputError(f"{trajectory.source}: field 'positions': found {data.n_frames} "
                         f"frames; expected at least {needed} for one held-out block")
    model = settings["model"]
    base_fit = fit_model(data, train, model=model)
    frames = usable_frames(train, data.n_frames)
    located = where(data, base_fit, frames, window=settings["window"], patch=settings["patch"])
    q_before = located["Q"]
    scores = score_candidates(data, base_fit, train, model=model, alpha=settings["alpha"],
                              n_subsamples=settings["n_subsamples"], rng=rng)
    before = {how: rollout_error(data, base_fit, held, start=how) for how in STARTS}
    start = min(STARTS, key=lambda how: before[how])
    gap_before = {"rollout": before[start], "one_step": one_step_error(data, base_fit, held),
                  "rollout_start": start}
    _, r0 = _structure_of(data, base_fit, frames, settings)
    quick_q = {}
    for name, s in scores.items():
        if s["significant"] and s["stability"] >= settings["stability_min"]:
            quick = base_from_theta(s["base_theta"], model, base_fit.base.tau)
            trial = Fit(quick, [(name, np.asarray(s["theta"]))], None, None, base_fit.mask)
            quick_q[name] = _structure_of(data, trial, frames, settings)[0]["Q"]
            s["Q_quick"] = quick_q[name]
    ranked = sorted(quick_q, key=lambda name: quick_q[name])[:settings["max_candidates"]]
    strongest = sorted(quick_q, key=lambda name: scores[name]["log10_p"])[:1]
    ranked += [name for name in strongest if name not in ranked]
    named, final_fit, tried = [], base_fit, []
    for name in ranked:
        trial = fit_model(data, train, [name], model=model)
        after, r1 = _structure_of(data, trial, frames, settings)
        gap_trial = {"rollout": rollout_error(data, trial, held, start=start),
                     "one_step": one_step_error(data, trial, held)}
        excess = max(q_before - 1.0, 1e-12)
        explained = (q_before - after["Q"]) / excess
        evidence = {
            "wald": scores[name]["wald"], "threshold": scores[name]["threshold"],
            "log10_p": scores[name]["log10_p"], "stability": scores[name]["stability"],
            "Q_before": q_before, "Q_after": after["Q"], "explained_fraction": explained,
            "heldout_rollout_before": gap_before["rollout"],
            "heldout_rollout_after": gap_trial["rollout"],
            "heldout_one_step_before": gap_before["one_step"],
            "heldout_one_step_after": gap_trial["one_step"],
            "delta_bic": _bic_delta(r0[:, data.free], r1[:, data.free],
                                    scores[name]["df"]),
        }
        confirmed = (gap_trial["rollout"] < gap_before["rollout"]
                     and evidence["delta_bic"] < 0
                     and (after["Q"] <= settings["q_threshold"]
                          or explained >= settings["explained_min"]))
        tried.append({"name": name, "confirmed": bool(confirmed), "evidence": evidence})
        if confirmed and (not named or after["Q"] < named[0]["evidence"]["Q_after"]):
            theta = trial.terms[0][1]
            base_dict = {"k": trial.base.k.tolist()}
            effect = fx.get_effect(name)
            named = [{"name": name,
                      "parameters": {"coefficients": dict(zip(effect.coefficients,
                                                              np.asarray(theta).tolist())),
                                     **effect.physical(theta, base_dict)},
                      "evidence": evidence}]
            final_fit = trial
    gap_after = gap_before if final_fit is base_fit else {
        "rollout": rollout_error(data, final_fit, held, start=start),
        "one_step": one_step_error(data, final_fit, held)}
    q_final = (_structure_of(data, final_fit, frames, settings)[0]["Q"]
               if final_fit is not base_fit else q_before)
    unexplained = None
    if q_final > settings["q_threshold"]:
        unexplained = {"Q": q_final, "q_threshold": settings["q_threshold"],
                       "note": ("structured residual above the noise floor that no library "
                                "candidate explains" if not named else
                                "structure remains after the named effect")}
    noise_floor = located["noise_sigma_h"]
    return {
        "named_effects": named,
        "n_frames": int(data.n_frames),
        "unexplained": unexplained,
        "gap_before": gap_before["rollout"],
        "gap_after": gap_after["rollout"],
        "gap": {"before": gap_before, "after": gap_after,
                "rollout_steps": int(min(len(chunk) for chunk in held)),
                "one_step_noise_floor_h": float(np.sqrt(6.0) * noise_floor),
                "held_out_frames": [[int(c[0]), int(c[-1])] for c in held]},
        "where": located,
        "base": {"model": model, "rest": base_fit.base.rest.tolist(),
                 "k": base_fit.base.k.tolist(), "tau": base_fit.base.tau.tolist()},
        "final_base": {"rest": final_fit.base.rest.tolist(), "k": final_fit.base.k.tolist(),
                       "tau": final_fit.base.tau.tolist()},
        "candidates": scores,
        "tried": tried,
        "settings": settings,
    }
