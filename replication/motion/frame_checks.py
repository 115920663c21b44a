"""Whole-frame checks of what the IRC equation assumes (paper 2.1), for every runner.

The IRC equation ``-omega Ix (y - eta) + omega Iy (x - xi) + It = 0`` says that a pixel's
intensity changes between frames only because the pixel moves, by a rotation: constant
brightness, no divergence (a rotation or a translation keeps areas; a zoom does not), and a
temporal change ``It`` above the sensor noise. Each check measures one of these on the whole
frame, pair by pair, and :func:`frame_checks` gives the measures and the warnings
(:func:`frame_warnings`) that ``motion_single`` and ``segment_multi`` write (one engine
for both). The thresholds were measured
on the suite's sequences (``synthetic_data/motion*``, and ``motion_accuracy``'s noisy cases,
2 and 4 /255) and on an outside user's sequences (flicker, zoom, noise 10/255); each
threshold's comment gives the measured range.
"""

from __future__ import annotations

import numpy as np

from replication.motion.derivatives import gradient_threshold, pair_derivatives, smooth
from replication.sequences import describe_repeats, repeated_frames

# the checks measure on the pixels whose |grad I| is at least this share of its 99th
# percentile (motion_single's own relative_threshold, so the noise check reads the voting
# pixels' gradients whatever the runner's setting)
GRADIENT_SHARE = 0.3

# brightness: the mean intensity changes by more than BRIGHTNESS_PCT % between two frames,
# and that uniform change is more than BRIGHTNESS_SHARE of the mean |It| (a motion moves
# intensities about, a brightness change moves them all one way). Measured (largest pair):
# suite (motion, motion_multi, accuracy noise 0/2/4) at most 0.049 % and share 0.11
# (acc10_coarse); outside user without flicker at most 0.20 % (2 %/frame zoom), share 0.37
# (a 5 px disc, where the mean changes by 0.001 %); flicker +-1 %, 2 %, 5 %: 2.0 %, 4.0 %,
# 10 %, shares 0.79, 0.95, 1.00
BRIGHTNESS_PCT, BRIGHTNESS_SHARE = 0.5, 0.3

# divergence: a similarity motion (translation, rotation and a uniform scale change) fitted
# to the normal flow of the whole frame scales it by more than DIVERGENCE_PCT % per frame,
# and its scale term explains more than DIVERGENCE_SHARE of the sum of It^2 beyond a
# translation and a rotation. Measured: suite at most 0.083 %/frame (acc02_brick), share
# 0.013 (acc08_far_outside); outside user without zoom at most 0.18 %/frame (a disc at
# 0.08 rad/frame), share 0.021 (two objects); zoom 0.5 %/frame and 2 %/frame: 0.51 and
# 2.07 %/frame, shares 0.97 and 0.97
DIVERGENCE_PCT, DIVERGENCE_SHARE = 0.3, 0.2

# noise: the sensor noise in It (after the smoothing by sigma), divided by the median
# |grad I| of the measured pixels: the noise of the normal flow, pixels/frame. Measured:
# suite at most 0.160 (acc05_mouth_outside with noise 4/255; 0.042 without added noise);
# outside user: noise 3, 5 and 10 /255 give 0.068, 0.111 and 0.217, pure noise 3.3
NOISE_FLOW = 0.19

# the similarity fit reads at most this many of the strong-gradient pixels, a regular
# stride of them (on 2048 x 2048 frames the fit on every pixel took longer than the
# pyramid method itself; every sequence of the suite has fewer, so reads them all)
MAX_FIT_PIXELS = 2 ** 17


def noise_sigma(frame):
    """The sensor noise's standard deviation in one frame (intensity units), by Immerkaer's
    estimator (Fast noise variance estimation, CVIU 64(2), 1996): the mean absolute
    response to the difference of two Laplacians, which cancels smooth texture.

    Parameters
    ----------
    frame : (H, W) ndarray
        H, W >= 3.
    """
    frame = np.asarray(frame, dtype=float)
    rows = frame[:-2] - 2.0 * frame[1:-1] + frame[2:]
    both = rows[:, :-2] - 2.0 * rows[:, 1:-1] + rows[:, 2:]  # kernel [1 -2 1]^T [1 -2 1]
    return float(np.sqrt(np.pi / 2.0) / 6.0 * np.mean(np.abs(both)))


def _smoothing_gain(sigma):
    """How much :func:`derivatives.smooth` by ``sigma`` shrinks white noise's sd."""
    half = int(np.ceil(4 * sigma)) + 1
    delta = np.zeros((2 * half + 1, 2 * half + 1))
    delta[half, half] = 1.0
    return float(np.sqrt(np.sum(smooth(delta, sigma) ** 2)))


def _similarity_fit(gx, gy, gt, x, y, shape):
    """Scale change per frame of the similarity motion best explaining ``Ix u + Iy v + It =
    0`` (about the frame's middle), and the share of ``sum It^2`` its scale term explains
    beyond a translation and a rotation."""
    height, width = shape
    radius = 0.5 * max(height, width)
    px, py = (x - (width - 1) / 2) / radius, (y - (height - 1) / 2) / radius
    # u = a + d px - w py, v = b + w px + d py (pixels/frame at the frame's half side)
    design = np.stack([gx, gy, gy * px - gx * py, gx * px + gy * py], axis=1)
    full, *_ = np.linalg.lstsq(design, -gt, rcond=None)
    rigid, *_ = np.linalg.lstsq(design[:, :3], -gt, rcond=None)
    left = np.sum((design @ full + gt) ** 2)
    left_rigid = np.sum((design[:, :3] @ rigid + gt) ** 2)
    total = np.sum(gt ** 2)
    return float(full[3] / radius), float((left_rigid - left) / total) if total > 0 else 0.0


def pair_statistics(frame0, frame1, *, sigma=1.5):
    """The whole-frame measures of one frame pair.

    Parameters
    ----------
    frame0, frame1 : (H, W) ndarray
    sigma : float
        Gaussian pre-smoothing (pixels), as the method's derivatives.

    Returns
    -------
    dict
        ``brightness_pct`` (change of the mean intensity, % of it), ``brightness_share``
        (``|mean It| / mean |It|``), ``scale_pct`` (the similarity fit's scale change, %
        per frame), ``scale_share`` (the share of ``sum It^2`` it explains) and
        ``noise_flow`` (noise of the normal flow, pixels/frame); NaN where the pair has no
        pixel to measure on.
    """
    gx, gy, gt, valid = pair_derivatives(frame0, frame1, sigma=sigma)
    # the smoothing is linear: the pair's mean smoothed frame in one pass
    mean = np.mean(np.abs(smooth(0.5 * (np.asarray(frame0, float)
                                        + np.asarray(frame1, float)), sigma))[valid])
    change = np.mean(gt[valid])
    spread = np.mean(np.abs(gt[valid]))
    stats = {"brightness_pct": 100.0 * abs(change) / mean if mean > 0 else np.nan,
             "brightness_share": abs(change) / spread if spread > 0 else 0.0,
             "scale_pct": np.nan, "scale_share": np.nan, "noise_flow": np.nan}
    norm = np.hypot(gx, gy)
    keep = valid & (norm > 0) & (norm >= gradient_threshold(norm, valid,
                                                            relative=GRADIENT_SHARE))
    if np.count_nonzero(keep) < 4:
        return stats
    y, x = np.nonzero(keep)
    stride = -(-y.size // MAX_FIT_PIXELS)
    y, x = y[::stride], x[::stride]
    scale, share = _similarity_fit(gx[y, x], gy[y, x], gt[y, x], x, y, gx.shape)
    noise_it = np.sqrt(0.5 * (noise_sigma(frame0) ** 2 + noise_sigma(frame1) ** 2)) \
        * np.sqrt(2.0) * _smoothing_gain(sigma)
    stats.update(scale_pct=100.0 * scale, scale_share=share,
                 noise_flow=float(noise_it / np.median(norm[keep])))
    return stats


def frame_statistics(frames, *, sigma=1.5):
    """:func:`pair_statistics` of every consecutive pair, and the worst pair's.

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    sigma : float
        Gaussian pre-smoothing (pixels).

    Returns
    -------
    dict
        ``pairs``: one dict per pair; ``worst``: each measure's largest value over the
        pairs (``scale_pct`` and ``scale_share`` from the pair of largest ``|scale_pct|``).
    """
    pairs = [pair_statistics(frames[t], frames[t + 1], sigma=sigma)
             for t in range(frames.shape[0] - 1)]

    def largest(key, values=None):
        values = np.array([p[key] for p in pairs] if values is None else values, dtype=float)
        return float(np.nanmax(values)) if np.any(np.isfinite(values)) else np.nan

    scales = np.array([abs(p["scale_pct"]) for p in pairs], dtype=float)
    zoomed = pairs[int(np.nanargmax(scales))] if np.any(np.isfinite(scales)) else pairs[0]
    worst = {key: largest(key) for key in ("brightness_pct", "brightness_share",
                                           "noise_flow")}
    worst.update(scale_pct=zoomed["scale_pct"], scale_share=zoomed["scale_share"])
    return {"pairs": pairs, "worst": worst}


def frame_checks(frames, *, sigma=1.5):
    """The whole-frame measures and their warnings, as the runners write them.

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    sigma : float
        Gaussian pre-smoothing (pixels), the runner's own.

    Returns
    -------
    dict
        ``measures``: the worst pair's measures (:func:`frame_statistics`) with the
        ``thresholds`` they are held to, and ``repeated_frames``
        (:func:`replication.sequences.repeated_frames`); ``warnings``: the repeats'
        (:func:`repeated_frames_warning`), then :func:`frame_warnings` of the measures.
    """
    worst = frame_statistics(frames, sigma=sigma)["worst"]
    thresholds = {"brightness_pct": BRIGHTNESS_PCT, "brightness_share": BRIGHTNESS_SHARE,
                  "scale_pct": DIVERGENCE_PCT, "scale_share": DIVERGENCE_SHARE,
                  "noise_flow": NOISE_FLOW}
    repeated = repeated_frames(frames)
    warnings = ([repeated_frames_warning(repeated)] if repeated else []) \
        + frame_warnings(worst)
    return {"measures": {**worst, "thresholds": thresholds, "repeated_frames": repeated},
            "warnings": warnings}


def repeated_frames_warning(frames):
    """The warning for frames that repeat the frame before while the scene moves after
    them (:func:`replication.sequences.repeated_frames`): the IRC equation reads the
    frames as equally spaced in time, so a repeated pair votes for no motion at all."""
    return (f"{describe_repeats(frames)} "
            "while the scene moves after them: a capture that dropped or repeated frames, or "
            "frames from before the motion began? The method takes the frames as equally "
            "spaced in time, so a repeated pair shows no motion and omega comes out low, "
            "the centres pulled (leave the repeats out, or restore the missing frames)")


def frame_warnings(worst):
    """Warnings when the frames break an assumption of the IRC equation: a brightness
    change between frames, a zoom (divergence), or noise dominating the normal flow.

    Parameters
    ----------
    worst : dict
        The worst pair's measures, ``frame_statistics(frames, sigma=)["worst"]``.

    Returns
    -------
    list of str
    """
    warnings = []
    if worst["brightness_pct"] > BRIGHTNESS_PCT and \
            worst["brightness_share"] > BRIGHTNESS_SHARE:
        warnings.append(
            f"brightness changes between frames: the mean intensity changes by "
            f"{worst['brightness_pct']:.3g}% (above {BRIGHTNESS_PCT:g}%), uniformly enough "
            f"to be {100 * worst['brightness_share']:.0f}% of the mean |It| (above "
            f"{100 * BRIGHTNESS_SHARE:.0f}%): the IRC equation assumes constant brightness, "
            "so the change is read as motion and the centres and omegas are biased (flicker "
            "or auto-exposure? normalise the frames' brightness first)")
    if abs(worst["scale_pct"]) > DIVERGENCE_PCT and worst["scale_share"] > DIVERGENCE_SHARE:
        warnings.append(
            f"the whole frame {'grows' if worst['scale_pct'] > 0 else 'shrinks'} by "
            f"{abs(worst['scale_pct']):.3g}% per frame (above {DIVERGENCE_PCT:g}%), a scale "
            f"change that explains {100 * worst['scale_share']:.0f}% of It (above "
            f"{100 * DIVERGENCE_SHARE:.0f}%): a zoom or a motion towards the camera, which "
            "no rotation explains; the rotations found are pieces of it")
    if worst["noise_flow"] > NOISE_FLOW:
        warnings.append(
            f"noise dominates: the sensor noise makes the normal flow uncertain by "
            f"{worst['noise_flow']:.3g} px/frame at the median strong-gradient pixel (above "
            f"{NOISE_FLOW:g}): the votes and the objects found may follow the noise (more "
            "smoothing, method sigma, or less noisy frames)")
    return warnings
