"""Naming missing effects: score candidates, confirm by refitting, decide.

Scores: for each library effect not yet named, the base model plus the effects named so
far plus that candidate is solved by the engine's instrumental-variable regression (one
set of cluster sums serves every candidate) and its
coefficients get a cluster-robust Wald statistic, one-sided (zero) when a coefficient that
must be >= 0 comes out negative (its null is then a 50:50 mixture, so the chi2 threshold is
conservative). A candidate is significant above the chi2 quantile at ``alpha`` divided by
the number of candidates; stability selection refits on random halves of the time clusters
and counts how often each candidate is significant there. Confirmation refits the
whole model with the candidate (tau and constraint mask included) and asks for a smaller
held-out rollout error and for the residual structure statistic to fall back to the noise
floor or by ``explained_min`` of its excess. A structured residual that no candidate
explains is reported as unexplained instead of being given a name.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from replication.cloth.regression import cluster_sums, design, iv_solve, n_base, usable_frames
from replication.discrepancy import effects as fx


def candidate_names(model):
    """Library effects that are not already part of the base model."""
    return tuple(name for name in fx.EFFECT_NAMES
                 if not (model == "18" and name == "anisotropic_stiffness"))


def wald(theta, cov, nonnegative, *, rcond=1e-9):
    """Wald statistic of ``theta = 0`` and its degrees of freedom.

    Directions of ``cov`` with eigenvalues below ``rcond`` times the largest are left out
    (a profile coefficient with no data outside the constraint, e.g. the pinned row, is not
    tested), and the degrees of freedom are the directions kept. The statistic is 0 when a
    must-be-nonnegative coefficient is < 0.
    """
    if any(theta[i] < 0 for i in nonnegative) or not np.all(np.isfinite(cov)):
        return 0.0, len(theta)
    values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    if values.size == 0 or values[-1] <= 0:
        return 0.0, len(theta)
    keep = values > rcond * values[-1]
    projected = vectors[:, keep].T @ theta
    return float(np.sum(projected ** 2 / values[keep])), int(keep.sum())


def score_candidates(data, fit, frames, *, selected=(), model="5", alpha=1e-3,
                     n_subsamples=40, rng=None, block=5):
    """Wald statistics, thresholds and stability of every candidate effect not in
    ``selected``, each added to the base model and the ``selected`` effects.

    Returns
    -------
    dict name -> {wald, df, threshold, significant, log10_p, stability, theta, base_theta}
    (empty when ``fit`` was not made by regression: nothing to test on).
    """
    if fit.theta is None:
        return {}
    rng = np.random.default_rng(rng)
    selected = [fx.get_effect(name) for name in selected]
    names = [name for name in candidate_names(model)
             if name not in {effect.name for effect in selected}]
    frames = usable_frames(frames, data.n_frames)
    plugins = selected + [fx.get_effect(name) for name in names]
    columns, slices = design(data, fit.base, plugins, model)
    G, hz, labels, _ = cluster_sums(columns, data.target, frames, fit.mask, block=block)
    nb = n_base(model)
    kept = np.r_[np.arange(nb)] if not selected else np.r_[
        np.arange(nb), np.concatenate([np.arange(slices[e.name].start, slices[e.name].stop)
                                       for e in selected])]
    n_kept = kept.size

    def solve(name, clusters=None):
        cols = np.r_[kept, np.arange(slices[name].start, slices[name].stop)]
        theta, cov = iv_solve(G, hz, cols, clusters, labels)
        effect = fx.get_effect(name)
        w, df = wald(theta[n_kept:], cov[n_kept:, n_kept:], effect.nonnegative)
        return theta, cov, w, df

    out = {}
    for name in names:
        theta, _, w, df = solve(name)
        threshold = float(stats.chi2.isf(alpha / len(candidate_names(model)), df))
        out[name] = {"wald": w, "df": df, "threshold": threshold,
                     "significant": bool(w > threshold),
                     "log10_p": float(stats.chi2.logsf(w, df) / np.log(10)),
                     "theta": theta[n_kept:].tolist(), "base_theta": theta[:nb].tolist(),
                     "stability": 0.0}
    n_clusters = G.shape[0]
    for _ in range(n_subsamples):
        half = np.sort(rng.choice(n_clusters, size=max(n_clusters // 2, 1), replace=False))
        for name in names:
            if out[name]["significant"] and solve(name, half)[2] > out[name]["threshold"]:
                out[name]["stability"] += 1.0 / n_subsamples
    return out
