"""Why the best peak of F(omega) overestimates |omega| (paper 2.2): a measured decomposition.

Per pixel, the vote meets the true centre at the omega ``omega_i`` that solves the pixel's
IRC equation there. Derivative errors move ``omega_i``; to leading order, for a texture
component of angular wavenumber ``k`` (rad/pixel) moving by ``d = omega A`` pixels per
frame across its crests (``A = (grad I x r) / |grad I|``, the lever arm of the pixel about
the centre, ``x = k d``):

- the suite's spatial derivative, a central difference ``(I[x+1] - I[x-1]) / 2`` of the
  smoothed frames, reads ``sin(k_x)`` for ``k_x``: ``|grad I|`` comes out low by the
  factor ``|(sin k_x, sin k_y)| / |k|``, ``omega_i`` high by its inverse, about
  ``1 + k^2 / 8`` averaged over directions, whatever the rotation speed;
- the frame difference ``I(t+1) - I(t)`` against the gradient of the two frames' average
  reads ``2 tan(x / 2) / k`` for the displacement ``d``: ``1 + x^2 / 12``; against the
  exact half-frame gradient it would read ``2 sin(x / 2) / k`` (``1 - x^2 / 24``), and a
  central difference over three frames against the middle frame's gradient ``sin(x) / k``
  (``1 - x^2 / 6``);
- the rotation itself is measured by its chord, ``2 sin(omega / 2)`` instead of
  ``omega``: ``1 - omega^2 / 24``, ``-2e-5`` at the paper's speed;
- noise spreads ``omega_i``; a pixel's line passes within ``h`` of the centre for
  ``|omega - omega_i| < h |omega| / |A|``, a window that grows with ``|omega|``, so the
  count ``F(omega)`` leans to larger ``|omega|`` by an amount set by noise / |omega|.

The study measures each term by swapping one derivative scheme at a time on frames made
from their definition (:mod:`replication.motion.wave_data`, which imports none of this
code), against the rotation speed, the texture's wavelength and the noise, and on the
paper-like sequence of ``motion_data``; the accumulator is always the suite's
(:func:`replication.motion.irc.sweep`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from scipy import ndimage

from replication.errors import check
from replication.motion import irc, single, wave_data
from replication.motion.derivatives import (
    PixelDerivatives,
    default_border,
    gradient_threshold,
    pair_derivatives,
    smooth,
    spatial_gradient,
)
from replication.motion.io import read_manifest_sequences, read_sequence
from replication.motion.synth import make_sequence
from replication.progress import bar, progress
from replication.results import read_result

# derivative schemes (readings of "calculate the local derivatives", paper 2.2)
VARIANTS = {
    "suite": "the suite's (motion_single): central differences of the average of the two "
             "smoothed frames, It their difference",
    "forward": "derivatives at frame t: central differences of smoothed frame t, "
               "It = I(t+1) - I(t)",
    "central3": "three frames: central differences of smoothed frame t, "
                "It = (I(t+1) - I(t-1)) / 2",
    "gaussian": "derivative-of-Gaussian gradient of the two frames' average (the exact "
                "gradient of the smoothed image), It = I(t+1) - I(t)",
    "gaussian_central3": "derivative-of-Gaussian gradient of frame t, "
                         "It = (I(t+1) - I(t-1)) / 2",
    "exact": "oracle: the exact derivatives of the smoothed scene at the half-frame, "
             "It instantaneous (no derivative error at all)",
    "exact_noise": "oracle plus the derivative noise of `gaussian` (noisy minus noise-free "
                   "frames): noise without derivative bias",
    "refined": "the suite's refinement (warping and robust least squares) from the suite's "
               "best peak (beyond the paper)",
}
THREE_FRAMES = ("central3", "gaussian_central3")
READINGS = ("suite", "forward", "central3", "gaussian", "gaussian_central3")


def gaussian_gradient(frame, sigma):
    """``(Ix, Iy)`` of ``frame`` smoothed by a Gaussian of ``sigma`` pixels, computed with
    the derivative of the Gaussian (no finite difference).

    Parameters
    ----------
    frame : (H, W) ndarray
    sigma : float
        Pixels, > 0.
    """
    frame = np.asarray(frame, dtype=float)
    return (ndimage.gaussian_filter(frame, sigma, order=(0, 1), mode="nearest"),
            ndimage.gaussian_filter(frame, sigma, order=(1, 0), mode="nearest"))


def derivative_fields(frames, variant, *, sigma):
    """``Ix, Iy, It`` of a reading of paper 2.2 (a key of :data:`VARIANTS` but the oracles).

    Parameters
    ----------
    frames : (T, H, W) ndarray
        Frames ``t, t + 1`` (and ``t + 2`` for the three-frame readings, which are then
        centred on frame ``t + 1``).
    variant : str
    sigma : float
        Gaussian pre-smoothing, pixels.

    Returns
    -------
    gx, gy, gt : (H, W) ndarray
    """
    if variant == "suite":
        return pair_derivatives(frames[0], frames[1], sigma=sigma)[:3]
    check(variant in READINGS, f"variant={variant!r}: expected one of {READINGS}")
    if variant in THREE_FRAMES:
        gt = 0.5 * (smooth(frames[2], sigma) - smooth(frames[0], sigma))
        at = frames[1]
    else:
        gt = smooth(frames[1], sigma) - smooth(frames[0], sigma)
        at = frames[0] if variant == "forward" else 0.5 * (frames[0] + frames[1])
    if variant.startswith("gaussian"):
        return (*gaussian_gradient(at, sigma), gt)
    return (*spatial_gradient(smooth(at, sigma)), gt)


def voting_pixels(gx, gy, gt, *, sigma, relative_threshold):
    """The pixels that vote: inside the smoothing border, ``|grad I|`` at least
    ``relative_threshold`` times its 99th percentile (as the suite selects them).

    Parameters
    ----------
    gx, gy, gt : (H, W) ndarray
    sigma : float
        Sets the border (:func:`~replication.motion.derivatives.default_border`).
    relative_threshold : float

    Returns
    -------
    PixelDerivatives
    """
    border = default_border(sigma)
    valid = np.zeros(gx.shape, dtype=bool)
    valid[border: gx.shape[0] - border, border: gx.shape[1] - border] = True
    norm = np.hypot(gx, gy)
    keep = valid & (norm >= gradient_threshold(norm, valid, relative=relative_threshold))
    keep &= norm > 0
    y, x = np.nonzero(keep)
    return PixelDerivatives(x.astype(float), y.astype(float), gx[keep], gy[keep], gt[keep],
                            np.zeros(x.size, dtype=np.int64))


def relative_omegas(omega, *, low, high, step):
    """``omega exp(u)`` for ``u`` from ``low`` to ``high`` by ``step``: a sweep whose step
    is the same fraction of ``omega`` at every speed.

    Parameters
    ----------
    omega : float
        The true rotation speed, rad/frame, non-zero.
    low, high, step : float
        Bounds and step of ``u = ln(omega' / omega)``.
    """
    count = int(round((high - low) / step)) + 1
    return omega * np.exp(low + step * np.arange(count))


def _middle(omegas):
    """The middle of a plateau of equal maxima on a geometric sweep (geometric mean)."""
    return float(np.sign(omegas[0]) * np.exp(np.mean(np.log(np.abs(omegas)))))


def best_peak(table, omega, centre):
    """The best peak of a sweep, read as a bias against the truth.

    Parameters
    ----------
    table : dict
        :func:`~replication.motion.irc.sweep` output on a :func:`relative_omegas` sweep.
    omega : float
        True speed.
    centre : (2,) sequence
        True ``(xi, eta)``.

    Returns
    -------
    dict
        ``found_omega, found_xi, found_eta`` (the peak), ``bias_pct``
        (``100 (|omega_peak| / |omega| - 1)``: positive when the peak turns too fast; on a
        plateau of equal maxima, its middle), ``normalised_pct`` (the
        same for the maximum of ``F(omega) / |omega|``), ``ties`` (omegas sharing the
        maximum), ``at_edge`` (the maximum at an end of the sweep), ``centre_px``.
    """
    omegas, peak = table["omega"], table["peak"]
    tied = np.flatnonzero(peak == peak.max())
    best = int(tied[tied.size // 2])
    scaled = peak / np.abs(omegas)
    tied_scaled = np.flatnonzero(scaled == scaled.max())
    return {"found_omega": _middle(omegas[tied]), "found_xi": float(table["xi"][best]),
            "found_eta": float(table["eta"][best]),
            "bias_pct": 100.0 * (_middle(omegas[tied]) / omega - 1.0),
            "normalised_pct": 100.0 * (_middle(omegas[tied_scaled]) / omega - 1.0),
            "ties": int(tied.size),
            "at_edge": bool(tied[0] == 0 or tied[-1] == omegas.size - 1),
            "centre_px": float(math.hypot(table["xi"][best] - centre[0],
                                          table["eta"][best] - centre[1]))}


def peak_bias(pixels, omega, centre, *, shape, grid, cell=1.0):
    """Sweep ``omega``'s relative grid with the suite's accumulation; :func:`best_peak`.

    Parameters
    ----------
    pixels : PixelDerivatives
    omega : float
    centre : (2,) sequence
    shape : (H, W) tuple
    grid : dict
        ``low, high, step`` of :func:`relative_omegas`.
    cell : float
        Accumulator cell, pixels.
    """
    table = irc.sweep(pixels, relative_omegas(omega, **grid),
                      irc.image_grid(shape, cell=cell))
    return dict(best_peak(table, omega, centre), pixels=len(pixels))


def leading_order(waves, exact_pixels, centre, omega, *, sigma):
    """The leading-order terms of the module docstring for one scene, in % of ``omega``.

    Parameters
    ----------
    waves : dict
        :func:`~replication.motion.wave_data.texture_waves`.
    exact_pixels : PixelDerivatives
        Voting pixels of the exact derivatives (for the lever arms ``A``).
    centre : (2,) sequence
    omega : float
    sigma : float
        Pre-smoothing (weights the waves by their gradient energy after it).

    Returns
    -------
    dict
        ``spatial_pct`` (exact transfer of the central difference), ``spatial_k2_pct``
        (its quadratic form ``<k^2> / 8``), ``temporal_pct`` (``<k^2> omega^2 <A^2> / 12``,
        two-frame average), ``chord_pct``, ``k2`` and ``lever_rms_px``.
    """
    k = 2.0 * math.pi * waves["frequency"]
    k2 = np.sum(k ** 2, axis=1)
    weight = waves["amplitude"] ** 2 * k2 * np.exp(-k2 * sigma ** 2)
    mean_k2 = float(np.sum(weight * k2) / np.sum(weight))
    transfer = np.sqrt(k2) / np.hypot(np.sin(k[:, 0]), np.sin(k[:, 1]))
    lever = ((exact_pixels.gy * (exact_pixels.x - centre[0])
              - exact_pixels.gx * (exact_pixels.y - centre[1])) / exact_pixels.gradient_norm)
    lever2 = float(np.mean(lever ** 2))
    return {"spatial_pct": float(100.0 * (np.sum(weight * transfer) / np.sum(weight) - 1.0)),
            "spatial_k2_pct": 100.0 * mean_k2 / 8.0,
            "temporal_pct": 100.0 * mean_k2 * omega ** 2 * lever2 / 12.0,
            "chord_pct": 100.0 * (2.0 * math.sin(omega / 2.0) / omega - 1.0),
            "k2": mean_k2, "lever_rms_px": math.sqrt(lever2)}


# ---------------------------------------------------------------------------------------
# the controlled scene (replication.motion.wave_data): one case, one axis

CONTROLLED = READINGS + ("exact", "refined")       # the speed and texture axes
NOISY = ("suite", "gaussian", "exact_noise", "refined")
AXES = ("speed", "texture", "noise", "half_speed", "cell")


class _Scene:
    """The controlled scene of a config: side, centre, textures and frames (cached)."""

    def __init__(self, config, settings):
        self.side = int(config["side"])
        self.centre = tuple(float(round(float(v) * self.side)) for v in config["centre"])
        self.texture = dict(config["texture"])
        self.texture_seed = int(config["texture_seed"])
        self.settings = settings
        self.grid = dict(config["grid"])
        self._frames = {}

    def waves(self, wavelength):
        """The texture of ``wavelength`` (the same at every speed and noise level)."""
        rng = np.random.default_rng([self.texture_seed, int(round(1000 * wavelength))])
        return wave_data.texture_waves(wavelength, rng=rng, **self.texture)

    def frames(self, omega, wavelength):
        """Frames at ``t = 0, 1, 2`` (the two-frame readings use the first two)."""
        key = (omega, wavelength)
        if key not in self._frames:
            self._frames[key] = wave_data.render(
                self.waves(wavelength), side=self.side, xi=self.centre[0],
                eta=self.centre[1], omega=omega, times=(0.0, 1.0, 2.0))
        return self._frames[key]

    def exact(self, omega, wavelength):
        """The oracle's fields at the half-frame ``t = 1/2``."""
        return wave_data.exact_derivatives(
            self.waves(wavelength), side=self.side, xi=self.centre[0], eta=self.centre[1],
            omega=omega, t=0.5, sigma=self.settings["sigma"])

    def pixels(self, fields):
        return voting_pixels(*fields, sigma=self.settings["sigma"],
                             relative_threshold=self.settings["relative_threshold"])


def _fields(scene, variant, frames, clean, omega, wavelength):
    sigma = scene.settings["sigma"]
    if variant == "exact":
        return scene.exact(omega, wavelength)
    if variant == "exact_noise":
        noise = [a - b for a, b in zip(derivative_fields(frames, "gaussian", sigma=sigma),
                                       derivative_fields(clean, "gaussian", sigma=sigma))]
        return [a + b for a, b in zip(scene.exact(omega, wavelength), noise)]
    return derivative_fields(frames, variant, sigma=sigma)


def refined_bias(frames, peak, pixels, omega, centre, settings):
    """The suite's refinement started from a best peak, read as :func:`best_peak` does.

    Parameters
    ----------
    frames : (T, H, W) ndarray
    peak : dict
        ``found_omega, found_xi, found_eta``: the best peak.
    pixels : PixelDerivatives
        The voting pixels of the suite's derivatives.
    omega : float
    centre : (2,) sequence
    settings : dict
        ``replication.motion.single.DEFAULTS`` keys.
    """
    start = {key: peak[f"found_{key}"] for key in ("xi", "eta", "omega")}
    refined = single.refined_method(frames[:2], start, pixels, settings)
    return {"found_omega": refined["omega"], "found_xi": refined["xi"],
            "found_eta": refined["eta"],
            "bias_pct": 100.0 * (refined["omega"] / omega - 1.0),
            "centre_px": math.hypot(refined["xi"] - centre[0], refined["eta"] - centre[1]),
            "pixels": int(refined["pixels"])}


def controlled_case(scene, *, omega, wavelength, variants, noise_255=0.0, rng=None,
                    cell=1.0):
    """Every variant on one controlled case: the best peak's bias per variant.

    Parameters
    ----------
    scene : _Scene
    omega, wavelength : float
    variants : sequence of str
        Keys of :data:`VARIANTS`.
    noise_255 : float
        Standard deviation of Gaussian noise added to the frames, /255.
    rng : numpy.random.Generator or None
        Draws the noise.
    cell : float

    Returns
    -------
    results : dict
        Variant name to :func:`peak_bias` (or :func:`refined_bias`) output.
    exact_pixels : PixelDerivatives or None
        The oracle's voting pixels, when ``exact`` is a variant.
    """
    clean = scene.frames(omega, wavelength)
    frames = clean if noise_255 == 0 else clean + noise_255 / 255.0 * rng.standard_normal(
        clean.shape)
    shape = clean.shape[1:]
    results, kept = {}, {}
    for variant in variants:
        if variant == "refined":
            continue
        kept[variant] = scene.pixels(_fields(scene, variant, frames, clean, omega,
                                             wavelength))
        results[variant] = peak_bias(kept[variant], omega, scene.centre, shape=shape,
                                     grid=scene.grid, cell=cell)
    if "refined" in variants:
        results["refined"] = refined_bias(frames, results["suite"], kept["suite"], omega,
                                          scene.centre, scene.settings)
    return results, kept.get("exact")


def _axis_cases(config):
    """(axis, omega, wavelength, noise_255, seed, cell, variants) of every controlled case."""
    omega_ref = float(config["reference"]["omega"])
    wavelength_ref = float(config["reference"]["wavelength"])
    half = omega_ref * float(config["collapse_factor"])
    seeds = range(int(config["noise_seeds"]))
    noises = [float(v) for v in config["noise_levels_255"]]
    cases = [("speed", float(w), wavelength_ref, 0.0, 0, 1.0, CONTROLLED)
             for w in config["speeds"]]
    cases += [("texture", omega_ref, float(wl), 0.0, 0, 1.0, CONTROLLED)
              for wl in config["wavelengths"]]
    for axis, omega, scale, variants in (("noise", omega_ref, 1.0, NOISY),
                                         ("half_speed", half, float(config["collapse_factor"]),
                                          ("exact_noise",))):
        cases += [(axis, omega, wavelength_ref, scale * n, s, 1.0, variants)
                  for n in noises for s in (seeds if n > 0 else [0])]
    cases += [("cell", half, wavelength_ref, float(config["cell_noise_255"]), s, float(c),
               ("exact_noise",)) for c in config["cells"] for s in seeds]
    return cases


def controlled_rows(config, settings):
    """Rows of every controlled case (:func:`_axis_cases`) and the leading-order terms
    of the speed and texture axes.

    Parameters
    ----------
    config : dict
        The study's resolved config.
    settings : dict
        ``replication.motion.single.DEFAULTS`` keys (smoothing, threshold, refinement).

    Returns
    -------
    rows : list of dict
        ``axis, variant, omega, wavelength, noise_255, seed, cell`` and the bias.
    predictions : list of dict
        ``axis, omega, wavelength`` and :func:`leading_order`'s terms.
    """
    scene = _Scene(config, settings)
    rows, predictions = [], []
    for index, (axis, omega, wavelength, noise, seed, cell, variants) in enumerate(
            bar(_axis_cases(config), "controlled cases")):
        rng = np.random.default_rng([int(config["seed"]), AXES.index(axis), index, seed])
        results, exact = controlled_case(scene, omega=omega, wavelength=wavelength,
                                         variants=variants, noise_255=noise, rng=rng,
                                         cell=cell)
        key = {"axis": axis, "omega": omega, "wavelength": wavelength, "noise_255": noise,
               "seed": seed, "cell": cell}
        rows += [dict(key, variant=variant, **value) for variant, value in results.items()]
        if exact is not None:
            predictions.append(dict(
                {k: key[k] for k in ("axis", "omega", "wavelength")},
                **leading_order(scene.waves(wavelength), exact, scene.centre, omega,
                                sigma=settings["sigma"])))
    return rows, predictions


# ---------------------------------------------------------------------------------------
# the paper-like sequence of motion_data, noisy (as stored) and re-rendered noise-free

def _paper_spec(sequences_dir, name):
    """The ``motion_data`` spec of sequence ``name``, its rng seed and its path."""
    manifest_path = Path(sequences_dir) / "manifest.json"
    sequences = read_manifest_sequences(manifest_path, "motion_data")
    check(name in sequences, f"{manifest_path}: no sequence '{name}'; expected one of "
          + ", ".join(sequences))
    config = json.loads(manifest_path.read_text(encoding="utf-8")).get("config") or {}
    specs = config.get("sequences") or {}
    check(name in specs and "seed" in config, f"{manifest_path}: config.sequences.{name} "
          "or config.seed missing; expected the config that made the sequences")
    spec = json.loads(json.dumps(config.get("base", {})))
    for key, value in specs[name].items():
        spec[key] = dict(spec[key], **value) if isinstance(value, dict) and isinstance(
            spec.get(key), dict) else value
    return spec, [int(config["seed"]), list(specs).index(name)], sequences[name]["path"]


def paper_like_frames(sequences_dir, name):
    """The stored (noisy) sequence and its noise-free twin, each with a third frame.

    The sequence is made again by :func:`replication.motion.synth.make_sequence` from the
    manifest's config and seed (the same textures), once as stored (checked against the
    file), once without noise and quantisation, and each with three frames.

    Returns
    -------
    frames : dict
        ``noisy`` and ``noise-free``: (3, H, W) ndarrays (the noisy frames 0, 1 are the
        file's).
    truth : dict
        ``xi, eta, omega``.
    """
    spec, seed, path = _paper_spec(sequences_dir, name)
    stored = read_sequence(path).frames
    again = make_sequence(spec, rng=np.random.default_rng(seed))[0]
    check(again.shape == stored.shape and np.allclose(again, stored, atol=1e-9),
          f"{path}: differs from the sequence its manifest's config makes; expected the "
          "files of `replicate experiment=motion_data`")
    clean = {k: v for k, v in spec.items() if k not in ("noise_sigma", "bits")}
    noisy3 = make_sequence(dict(spec, n_frames=3), rng=np.random.default_rng(seed))[0]
    clean3 = make_sequence(dict(clean, n_frames=3), rng=np.random.default_rng(seed))[0]
    noisy3[:2] = stored[:2]
    truth = {"xi": float(spec["center"][0]), "eta": float(spec["center"][1]),
             "omega": float(spec["omega"])}
    return {"noisy": noisy3, "noise-free": clean3}, truth


def paper_like_rows(frames, truth, settings, grid):
    """Every reading, and the refinement, on the paper-like frames.

    Parameters
    ----------
    frames : dict
        :func:`paper_like_frames`'s ``noisy`` and ``noise-free`` (3, H, W) frames.
    truth : dict
    settings : dict
    grid : dict
        ``low, high, step`` of :func:`relative_omegas`.

    Returns
    -------
    list of dict
        ``condition, variant`` and the bias.
    """
    omega, centre = truth["omega"], (truth["xi"], truth["eta"])
    rows = []
    for condition, stack in bar(list(frames.items()), "paper-like sequence"):
        kept = {}
        for variant in READINGS:
            fields = derivative_fields(stack, variant, sigma=settings["sigma"])
            kept[variant] = voting_pixels(
                *fields, sigma=settings["sigma"],
                relative_threshold=settings["relative_threshold"])
            rows.append(dict(peak_bias(kept[variant], omega, centre, shape=stack.shape[1:],
                                       grid=grid, cell=settings["cell"]),
                             condition=condition, variant=variant))
        suite = next(r for r in rows if r["condition"] == condition
                     and r["variant"] == "suite")
        rows.append(dict(refined_bias(stack, suite, kept["suite"], omega, centre, settings),
                         condition=condition, variant="refined"))
    return rows


# ---------------------------------------------------------------------------------------
# what the rows say: summary per case, decomposition, readings

GROUP = ("axis", "variant", "omega", "wavelength", "noise_255", "cell")


def summarise(rows):
    """Mean and standard deviation of the bias over the seeds of each case.

    Parameters
    ----------
    rows : list of dict
        :func:`controlled_rows` rows.

    Returns
    -------
    list of dict
        The keys of :data:`GROUP`, ``n``, ``bias_pct`` (mean), ``bias_sd_pct``,
        ``normalised_pct`` (mean, when the rows have it), ``centre_px`` (mean),
        ``at_edge`` (any).
    """
    groups = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in GROUP), []).append(row)
    summary = []
    for key, mine in groups.items():
        bias = np.array([r["bias_pct"] for r in mine])
        item = dict(zip(GROUP, key), n=len(mine), bias_pct=float(bias.mean()),
                    bias_sd_pct=float(bias.std()),
                    centre_px=float(np.mean([r["centre_px"] for r in mine])),
                    at_edge=any(r.get("at_edge", False) for r in mine))
        if "normalised_pct" in mine[0]:
            item["normalised_pct"] = float(np.mean([r["normalised_pct"] for r in mine]))
        summary.append(item)
    return summary


def find(summary, **where):
    """The first summary entry whose keys have the values ``where``; None if none has."""
    found = [s for s in summary if all(s[k] == v for k, v in where.items())]
    return found[0] if found else None


def decomposition(summary, paper_rows, reference):
    """The suite's bias split into its terms, on the reference case and the paper-like one.

    Controlled reference (``omega``, ``wavelength`` of ``reference``): spatial filter =
    ``suite - gaussian``, temporal scheme = ``gaussian - exact`` (noise-free), accumulator
    = ``exact``; the noise term at each level for ``suite``, ``gaussian`` and the oracle
    (``exact_noise``), noisy minus noise-free. Paper-like: noise = stored minus noise-free
    (``suite``), spatial filter = ``suite - gaussian`` (noise-free), the rest =
    ``gaussian`` noise-free (temporal scheme, object edges, static background).

    ``temporal_from_ratio_pct`` checks the temporal term without the oracle: the leading
    orders of ``gaussian`` (``+x^2/12``) and ``gaussian_central3`` (``-x^2/6``) stand as
    1 to -2, so the temporal term of ``gaussian`` is a third of their difference.

    Returns
    -------
    dict
        ``controlled`` and ``paper_like`` terms, in % of |omega|.
    """
    ref = {"axis": "texture", "omega": reference["omega"],
           "wavelength": reference["wavelength"], "noise_255": 0.0}
    bias = {v: find(summary, variant=v, **ref)["bias_pct"]
            for v in ("suite", "gaussian", "gaussian_central3", "exact")}
    clean = {v: find(summary, axis="noise", variant=v, noise_255=0.0)["bias_pct"]
             for v in ("suite", "gaussian", "exact_noise")}
    noise = {v: {f"{s['noise_255']:g}": s["bias_pct"] - clean[v] for s in summary
                 if s["axis"] == "noise" and s["variant"] == v and s["noise_255"] > 0}
             for v in clean}
    controlled = {"total_noise_free_pct": bias["suite"],
                  "spatial_filter_pct": bias["suite"] - bias["gaussian"],
                  "temporal_scheme_pct": bias["gaussian"] - bias["exact"],
                  "temporal_from_ratio_pct": (bias["gaussian"] - bias["gaussian_central3"]) / 3,
                  "accumulator_pct": bias["exact"],
                  "noise_pct": noise["suite"], "noise_gaussian_pct": noise["gaussian"],
                  "noise_oracle_pct": noise["exact_noise"]}
    paper = {(r["condition"], r["variant"]): r["bias_pct"] for r in paper_rows}
    temporal = (paper[("noise-free", "gaussian")]
                - paper[("noise-free", "gaussian_central3")]) / 3
    paper_like = {"total_pct": paper[("noisy", "suite")],
                  "noise_pct": paper[("noisy", "suite")] - paper[("noise-free", "suite")],
                  "spatial_filter_pct": paper[("noise-free", "suite")]
                  - paper[("noise-free", "gaussian")],
                  "rest_pct": paper[("noise-free", "gaussian")],
                  "temporal_from_ratio_pct": temporal,
                  "rest_but_temporal_pct": paper[("noise-free", "gaussian")] - temporal}
    return {"controlled": controlled, "paper_like": paper_like}


def readings(summary, paper_rows, *, tolerance_pct, max_speed):
    """Does a reading of 2.2 (or the refinement) remove the bias?

    A reading removes it when its best peak is within ``tolerance_pct`` of the true
    ``|omega|`` on every noise-free controlled case (speed axis up to ``max_speed``,
    texture axis) and on the paper-like sequence, noisy and noise-free.

    Returns
    -------
    list of dict
        Per variant: ``variant``, ``worst_pct`` (the bias of largest size), ``where``,
        ``paper_like_pct`` (noisy), ``removes`` (bool).
    """
    out = []
    for variant in (*READINGS, "refined"):
        cases = [(s["bias_pct"], f"{s['axis']} omega={s['omega']:g} "
                  f"wavelength={s['wavelength']:g}") for s in summary
                 if s["variant"] == variant and s["noise_255"] == 0
                 and s["axis"] in ("speed", "texture") and abs(s["omega"]) <= max_speed]
        cases += [(r["bias_pct"], f"paper-like, {r['condition']}") for r in paper_rows
                  if r["variant"] == variant]
        worst = max(cases, key=lambda c: abs(c[0]))
        noisy = next(r["bias_pct"] for r in paper_rows
                     if r["variant"] == variant and r["condition"] == "noisy")
        out.append({"variant": variant, "worst_pct": worst[0], "where": worst[1],
                    "paper_like_pct": noisy, "removes": abs(worst[0]) <= tolerance_pct})
    return out


def noise_collapse(summary, factor):
    """The noise term of the oracle at two speeds, paired at equal noise / |omega|.

    Returns
    -------
    list of dict
        ``noise_over_omega`` (/255 per rad/frame), ``reference_pct`` and
        ``half_speed_pct`` (mean biases of ``exact_noise``), ``reference_noise_255``,
        ``difference_se_pct`` (standard error of their difference over the seeds) and
        ``agree`` (the difference within two standard errors).
    """
    pairs = []
    for slow in (s for s in summary if s["axis"] == "half_speed" and s["noise_255"] > 0):
        fast = find(summary, axis="noise", variant="exact_noise",
                     noise_255=slow["noise_255"] / factor)
        if fast is not None:
            error = math.hypot(fast["bias_sd_pct"] / math.sqrt(fast["n"]),
                               slow["bias_sd_pct"] / math.sqrt(slow["n"]))
            pairs.append({"noise_over_omega": slow["noise_255"] / abs(slow["omega"]),
                          "reference_noise_255": fast["noise_255"],
                          "reference_pct": fast["bias_pct"],
                          "half_speed_pct": slow["bias_pct"],
                          "difference_se_pct": error,
                          "agree": abs(fast["bias_pct"] - slow["bias_pct"]) <= 2.0 * error})
    return pairs


# ---------------------------------------------------------------------------------------
# the runner

def _check_config(config):
    side, band = int(config["side"]), float(config["texture"]["band"])
    check(side >= 32, f"side={side}: expected at least 32 pixels")
    check(len(config["centre"]) == 2 and all(0 < float(v) < 1 for v in config["centre"]),
          f"centre={config['centre']}: expected [x, y] as fractions of the side in (0, 1)")
    for key in ("speeds", "wavelengths", "noise_levels_255", "cells"):
        check(len(config[key]) > 0, f"{key}: empty; expected at least one value")
    check(all(float(w) != 0 for w in config["speeds"]) and config["reference"]["omega"] != 0,
          "speeds, reference.omega: expected non-zero rotation speeds (rad/frame)")
    for wavelength in (*config["wavelengths"], config["reference"]["wavelength"]):
        check(math.sqrt(band) / float(wavelength) < 0.5,
              f"wavelength {wavelength} with texture.band={band}: the texture's highest "
              "frequency reaches 0.5 cycle/pixel; expected a longer wavelength")
    grid = config["grid"]
    check(grid["low"] < 0 < grid["high"] and grid["step"] > 0,
          f"grid={grid}: expected low < 0 < high and step > 0 (ln of omega / true omega)")
    check(min(float(v) for v in config["noise_levels_255"]) >= 0,
          f"noise_levels_255={config['noise_levels_255']}: expected values >= 0")
    check(int(config["noise_seeds"]) >= 1, "noise_seeds: expected at least 1")
    check(0 < float(config["collapse_factor"]) < 1,
          f"collapse_factor={config['collapse_factor']}: expected a fraction in (0, 1)")
    check(min(float(c) for c in config["cells"]) > 0, "cells: expected sizes > 0 pixels")
    check(int(config["threads"]) >= 1, f"threads={config['threads']}: expected at least 1")


def _single_result(path):
    """motion_single's result on the paper-like sequence: its best peak and its settings."""
    result = read_result(path)
    check(result is not None, f"single_result={path}: no such result; expected the "
          "result of `replicate experiment=motion_single force=true`")
    check(all(k in result for k in ("irc", "truth", "errors")),
          f"{path}: no irc, truth or errors; expected motion_single's result on a sequence "
          "with ground truth")
    return result


def omega_bias_study(config, out):
    """Measure why the best peak of F(omega) overestimates |omega| (see the module
    docstring): every reading of the derivatives against the rotation speed, the texture's
    wavelength, the noise and the cell size on frames made from their definition, and on
    the paper-like sequence. The settings (smoothing, threshold, cell) are those of
    ``single_result`` (motion_single's result, whose best peak the verdict is about).
    """
    import numba

    _check_config(config)
    single_result = _single_result(config["single_result"])
    settings = single.settings_from(single_result["config"]["method"])
    threads = numba.get_num_threads()
    numba.set_num_threads(min(int(config["threads"]), threads))
    try:
        rows, predictions = controlled_rows(config, settings)
        frames, truth = paper_like_frames(config["sequences_dir"], config["paper_like"])
        paper_rows = paper_like_rows(frames, truth, settings, dict(config["paper_grid"]))
    finally:
        numba.set_num_threads(threads)
    summary = summarise(rows)
    reference = {k: float(v) for k, v in config["reference"].items()}
    result = {
        "scene": {"side": int(config["side"]),
                  "xi": float(round(float(config["centre"][0]) * config["side"])),
                  "eta": float(round(float(config["centre"][1]) * config["side"])),
                  "texture": config["texture"]},
        "settings": {k: settings[k] for k in ("sigma", "relative_threshold", "cell")},
        "variants": {k: VARIANTS[k] for k in (*CONTROLLED, "exact_noise")},
        "single": {k: single_result[k] for k in ("irc", "truth", "errors", "data")},
        "paper_truth": truth,
        "rows": rows, "summary": summary, "predictions": predictions,
        "paper_like": paper_rows,
        "decomposition": decomposition(summary, paper_rows, reference),
        "readings": readings(summary, paper_rows, tolerance_pct=float(config["tolerance_pct"]),
                             max_speed=float(config["max_speed"])),
        "noise_collapse": noise_collapse(summary, float(config["collapse_factor"])),
        "warnings": [f"{r['axis']} {r['variant']} omega={r['omega']:g}: best peak at the edge "
                     "of the sweep; widen grid" for r in summary if r["at_edge"]],
    }
    from replication.figures import motion_omega_bias

    result["figures"] = [motion_omega_bias.draw(
        Path(config["figure_dir"]) / "motion_omega_bias.png", summary, predictions,
        paper_rows, reference)]
    progress("decomposition: " + json.dumps(result["decomposition"]))
    return result

