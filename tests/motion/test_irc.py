"""The IRC equation, the accumulation and the refinement against ground truth."""

import math

import numpy as np

from replication.motion import baselines, irc, single
from replication.motion.derivatives import PixelDerivatives, pair_derivatives


def exact_pixels(xi, eta, omega, n=400, seed=0):
    """Pixels whose derivatives verify the IRC equation exactly for (xi, eta, omega)."""
    rng = np.random.default_rng(seed)
    x = rng.integers(5, 60, n).astype(float)
    y = rng.integers(5, 60, n).astype(float)
    angle = rng.uniform(0, 2 * np.pi, n)
    gx, gy = np.cos(angle), np.sin(angle)
    u, v = -omega * (y - eta), omega * (x - xi)
    gt = -(gx * u + gy * v)
    return PixelDerivatives(x, y, gx, gy, gt, np.zeros(n, dtype=np.int64))


def test_exact_lines_meet_at_the_centre():
    pixels = exact_pixels(31.0, 22.0, 0.02)
    grid = irc.image_grid((64, 64))
    acc = irc.accumulate(pixels, 0.02, grid)
    j, i = np.unravel_index(np.argmax(acc), acc.shape)
    assert grid.centre(j, i) == (31.0, 22.0)
    assert acc[j, i] == len(pixels)          # every line passes through the centre's cell
    np.testing.assert_allclose(irc.line_distance(pixels, 31.0, 22.0, 0.02), 0, atol=1e-9)


def test_sweep_peaks_at_the_true_omega_for_exact_lines():
    pixels = exact_pixels(40.0, 18.0, -0.03)
    table = irc.sweep(pixels, irc.omega_sweep(-0.05, 0.05, 100), irc.image_grid((64, 64)))
    best = irc.paper_estimate(table)
    assert (best["xi"], best["eta"]) == (40.0, 18.0)
    assert abs(best["omega"] + 0.03) < 1e-12
    assert best["peak"] == len(pixels)


def test_sweep_excludes_zero():
    omegas = irc.omega_sweep(-0.05, 0.05, 100)
    assert omegas.size == 100 and np.all(omegas != 0)
    np.testing.assert_allclose(np.diff(omegas)[[0, -1]], 0.001)


def test_rigid_matrix_round_trip():
    matrix = irc.rigid_matrix(69.0, 140.0, -0.023)
    np.testing.assert_allclose(irc.matrix_to_irc(matrix), (69.0, 140.0, -0.023), atol=1e-9)
    np.testing.assert_allclose(matrix @ [69.0, 140.0, 1.0], [69.0, 140.0, 1.0], atol=1e-12)


def test_derivative_conventions():
    rows, cols = np.mgrid[0:32, 0:32].astype(float)
    frame0 = 0.5 * cols + 0.25 * rows
    frame1 = frame0 - 0.5 * 2.0       # the ramp moved 2 px to the right
    gx, gy, gt, valid = pair_derivatives(frame0, frame1, sigma=0.0)
    np.testing.assert_allclose(gx[valid], 0.5)
    np.testing.assert_allclose(gy[valid], 0.25)
    np.testing.assert_allclose(gt[valid], -1.0)
    # optical flow equation: Ix u + It = 0 gives u = 2 px/frame
    np.testing.assert_allclose(-gt[valid] / gx[valid], 2.0)


def test_small_sequence_paper_and_refined(small_sequence, fast_settings):
    frames, _, truth = small_sequence
    truth = truth["objects"][0]
    found = single.find_rotation(frames, fast_settings)
    paper = single.errors(found["paper"], truth)
    refined = single.errors(found["refined"], truth)
    assert paper["centre_px"] <= 2.0 and abs(paper["omega_pct"]) <= 15.0
    assert refined["centre_px"] <= 1.0 and abs(refined["omega_pct"]) <= 3.0


def test_zero_motion_gives_no_rotation(small_sequence, fast_settings):
    frames = np.stack([small_sequence[0][0], small_sequence[0][0]])
    _, table, _, _ = single.paper_method(frames, fast_settings)
    assert np.ptp(table["peak"]) == 0            # F(omega) is flat: no omega is preferred
    assert baselines.direct_least_squares(frames)["omega"] == 0.0
    flow = baselines.rigid_fit(np.zeros((32, 32)), np.zeros((32, 32)),
                               np.ones((32, 32), dtype=bool))
    assert flow["omega"] == 0.0


def test_rigid_fit_recovers_a_rotation():
    rows, cols = np.mgrid[0:64, 0:64].astype(float)
    matrix = irc.rigid_matrix(20.0, 30.0, 0.05)
    u = matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2] - cols
    v = matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2] - rows
    fit = baselines.rigid_fit(u, v, np.ones_like(u, dtype=bool))
    np.testing.assert_allclose([fit["xi"], fit["eta"], fit["omega"]], [20, 30, 0.05], atol=1e-9)


def test_find_rotation_is_deterministic(small_sequence, fast_settings):
    first = single.find_rotation(small_sequence[0], fast_settings)
    second = single.find_rotation(small_sequence[0], fast_settings)
    assert first["paper"] == second["paper"]
    assert first["refined"] == second["refined"]


def test_de_same_seed_same_result(small_sequence):
    a = baselines.de_rotation(small_sequence[0], seed=4, max_evals=300)
    b = baselines.de_rotation(small_sequence[0], seed=4, max_evals=300)
    c = baselines.de_rotation(small_sequence[0], seed=5, max_evals=300)
    assert a == b and a != c
    assert a["evaluations"] == 300   # counted by the Objective: the budget, not overshot


def test_line_walk_matches_a_plain_loop():
    rng = np.random.default_rng(2)
    for _ in range(300):
        start, slope = rng.uniform(-40, 60), rng.uniform(-1, 1)
        flat = np.zeros(32 * 20, dtype=np.int32)
        votes = irc._walk(flat, start, slope, 32, 20)
        expected = np.zeros((20, 32), dtype=np.int32)   # (cells, steps)
        for step in range(32):
            cell = int(np.floor(start + step * slope))
            if 0 <= cell < 20:
                expected[cell, step] += 1
        # fixed point may move a vote by one cell when a line grazes a cell border
        assert abs(votes - expected.sum()) <= 1
        assert np.abs(flat.reshape(20, 32) - expected).sum() <= 2


def test_int16_and_int32_counters_agree():
    pixels = exact_pixels(31.0, 22.0, 0.02, n=300)
    grid = irc.image_grid((64, 64))
    omegas = irc.omega_sweep(-0.05, 0.05, 20)
    results = [irc._sweep(*irc._as_arrays(pixels), omegas, grid.x0, grid.y0, grid.cell,
                          grid.ny, grid.nx, np.zeros(1, dtype=dtype))
               for dtype in (np.int16, np.int32)]
    for a, b in zip(*results):
        assert np.array_equal(a, b)


def test_flow_cache_gives_the_same_numbers_and_keys_on_images_and_options(small_sequence,
                                                                          tmp_path):
    frames = small_sequence[0]
    plain = baselines.optical_flow_rotation(frames, method="ilk")
    stored = baselines.optical_flow_rotation(frames, method="ilk", cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npy"))) == 1
    read = baselines.optical_flow_rotation(frames, method="ilk", cache_dir=tmp_path,
                                           motion_min=0.5)
    assert len(list(tmp_path.glob("*.npy"))) == 1          # moving-region settings: reused
    assert np.array_equal(plain["flow"], stored["flow"])
    assert np.array_equal(plain["flow"], read["flow"])
    assert plain["xi"] == stored["xi"] and plain["omega"] == stored["omega"]
    # any other image, method or option is another field
    baselines.optical_flow_rotation(frames, method="ilk", cache_dir=tmp_path,
                                    flow_options={"radius": 3})
    baselines.optical_flow_rotation(frames[::-1], method="ilk", cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npy"))) == 3
    assert not list(tmp_path.glob("*.partial*"))


def test_refined_spread_grows_with_noise_and_covers_the_error(small_sequence, fast_settings):
    """The block-jackknife spread: tiny without noise, larger with noise, and the noisy
    centre error within 3 spreads (the accuracy study measures the coverage at large)."""
    from replication.motion import single
    from replication.motion.synth import degrade

    frames, _, truth = small_sequence
    truth = truth["objects"][0]
    spreads, errors = [], []
    for noise in (0.0, 6.0 / 255):
        noisy = degrade(frames, noise_sigma=noise, rng=np.random.default_rng(1))
        refined = single.find_rotation(noisy, fast_settings)["refined"]
        spread = refined["spread"]
        assert spread is not None and spread["blocks"] >= 4
        spreads.append(math.hypot(spread["xi_sd"], spread["eta_sd"]))
        errors.append(math.hypot(refined["xi"] - truth["xi"], refined["eta"] - truth["eta"]))
        assert spread["omega_sd"] > 0
    assert spreads[1] > 5 * spreads[0]
    assert errors[1] <= 3 * spreads[1]


def test_rigid_spread_needs_four_tiles():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(300, 3)), rng.normal(size=300) * 1e-3
    matrix, centre = irc.rigid_matrix(10.0, 20.0, 0.02), np.array([10.0, 20.0])
    three = np.repeat(np.arange(3), 100)
    assert irc.rigid_spread(a, b, np.ones(300), three, matrix, centre) is None
    six = np.repeat(np.arange(6), 50)
    spread = irc.rigid_spread(a, b, np.ones(300), six, matrix, centre)
    assert spread["blocks"] == 6 and spread["omega_sd"] > 0
    # tiles with no weighted row are not left out in turn
    weights = (six < 4).astype(float)
    assert irc.rigid_spread(a, b, weights, six, matrix, centre)["blocks"] == 4


def test_rigid_spread_deals_many_tiles_into_groups():
    rng = np.random.default_rng(1)
    n = 40 * irc.SPREAD_GROUPS
    a, b = rng.normal(size=(n, 3)), rng.normal(size=n) * 1e-3
    tiles = np.arange(n) // 10 * 7  # 4 x SPREAD_GROUPS tiles, labels not 0..k-1
    spread = irc.rigid_spread(a, b, np.ones(n), tiles, irc.rigid_matrix(5.0, 5.0, 0.01),
                              np.array([5.0, 5.0]))
    assert spread["blocks"] == irc.SPREAD_GROUPS


def test_rigid_spread_counts_only_tiles_with_weight():
    """A small object on a large frame: the refinement writes rows for the whole frame's
    gradient mask with weight 0 outside the object; those tiles grouped the object's 36
    tiles into 6 (or none)."""
    rng = np.random.default_rng(2)
    x, y = np.meshgrid(np.arange(1024.0), np.arange(256.0))
    x, y = x.ravel()[::7], y.ravel()[::7]
    n = x.size
    a, b = rng.normal(size=(n, 3)), rng.normal(size=n) * 1e-3
    weights = ((x < 96) & (y < 96)).astype(float)        # 6 x 6 tiles of 16 px
    spread = irc.rigid_spread(a, b, weights, irc.spread_tiles(x, y),
                              irc.rigid_matrix(40.0, 40.0, 0.02), np.array([40.0, 40.0]))
    assert spread["blocks"] == 36


def test_flow_baselines_see_frames_on_one_intensity_scale(small_sequence, capsys):
    """Frames read as stored (float 0..255, 12-bit counts, 1e-90, 1e300) reach
    scikit-image's flow mapped to 0..1, one map for the pair: the same field at every
    scale, no float32 overflow, one note per range; frames already on the 0..1 scale
    (every sequence of the suite) pass unchanged."""
    import warnings

    frames = small_sequence[0]
    first, second, mapped = baselines.unit_intensities(frames[0], frames[1])
    assert mapped is None and np.array_equal(first, frames[0])
    low, high = frames[:2].min(), frames[:2].max()
    unit = (frames - low) / (high - low)
    expected = baselines.flow_field(unit[0], unit[1], method="tvl1")
    for scale in (255.0, 4095.0, 1e-90, 1e300):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            u, v = baselines.flow_field(frames[0] * scale, frames[1] * scale, method="tvl1")
        assert np.allclose(u, expected[0], atol=1e-4) and np.allclose(v, expected[1],
                                                                     atol=1e-4)
    baselines.flow_field(frames[0] * 255.0, frames[1] * 255.0, method="ilk")
    notes = [line for line in capsys.readouterr().err.splitlines() if "mapped to 0..1" in line]
    assert len(notes) == 4 and all(line.startswith("note: frame intensities span")
                                   for line in notes)
    # a pair whose span is tiny or whose values are huge, though its span is of order 1
    assert baselines.unit_intensities(frames[0] * 1e-3, frames[1] * 1e-3)[2] is not None
    assert baselines.unit_intensities(frames[0] + 1e6, frames[1] + 1e6)[2] is not None
