"""Naming the missing effect: score candidates, confirm by refitting, decide.

Scores: for each library effect, the base model plus that effect is solved by the
instrumental-variable regression (one set of cluster sums serves every candidate) and its
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

from replication.discrepancy import effects as fx
from replication.discrepancy.fit import cluster_sums, design, iv_solve, n_base, usable_frames


def candidate_names(model):
    """Library effects that are not already part of the base model."""
    return tuple(name for name in fx.EFFECT_NAMES
                 if not (model == "18" and name == "anisotropic_stiffness"))


def wald(theta, cov, nonnegative):
    """Wald statistic of ``theta = 0``; 0 when a must-be-nonnegative coefficient is < 0."""
    if any(theta[i] < 0 for i in nonnegative):
        return 0.0
    try:
        return float(theta @ np.linalg.solve(cov, theta))
    except np.linalg.LinAlgError:
        return 0.0


def score_candidates(data, base_fit, frames, *, model="5", alpha=1e-3, n_subsamples=40,
                     rng=None, block=5):
    """Wald statistics, thresholds and stability of every candidate effect.

    Returns
    -------
    dict name -> {wald, df, threshold, significant, log10_p, stability, theta}
    """
    rng = np.random.default_rng(rng)
    names = candidate_names(model)
    frames = usable_frames(frames, data.n_frames)
    columns, slices = design(data, base_fit.base, names, model)
    G, hz, labels = cluster_sums(columns, data.target, frames, base_fit.mask, block=block)
    nb = n_base(model)

    def solve(name, clusters=None):
        cols = np.r_[np.arange(nb), np.arange(slices[name].start, slices[name].stop)]
        theta, cov = iv_solve(G, hz, cols, clusters, labels)
        effect = fx.get_effect(name)
        return theta[nb:], cov[nb:, nb:], wald(theta[nb:], cov[nb:, nb:], effect.nonnegative)

    out = {}
    for name in names:
        theta, _, w = solve(name)
        df = slices[name].stop - slices[name].start
        threshold = float(stats.chi2.isf(alpha / len(names), df))
        out[name] = {"wald": w, "df": df, "threshold": threshold,
                     "significant": bool(w > threshold),
                     "log10_p": float(stats.chi2.logsf(w, df) / np.log(10)),
                     "theta": theta.tolist(), "stability": 0.0}
    n_clusters = G.shape[0]
    for _ in range(n_subsamples):
        half = np.sort(rng.choice(n_clusters, size=max(n_clusters // 2, 1), replace=False))
        for name in names:
            _, _, w = solve(name, half)
            if w > out[name]["threshold"]:
                out[name]["stability"] += 1.0 / n_subsamples
    for name in names:
        theta, _, _ = solve(name)
        full = iv_solve(G, hz, np.r_[np.arange(nb), np.arange(slices[name].start,
                                                              slices[name].stop)])[0]
        out[name]["base_theta"] = full[:nb].tolist()
    return out
