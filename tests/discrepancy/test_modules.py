"""The discrepancy workflow's building blocks, directly: residual noise floor and structure
(replication.discrepancy.residuals) and held-out frames and start states
(replication.discrepancy.gap)."""

import numpy as np
import pytest

from replication.discrepancy import gap
from replication.discrepancy import residuals as res

N = 9                 # a small mesh: 81 particles, two pinned
SIGMA = 0.01          # position noise


def _free(n=N):
    free = np.ones(n * n, dtype=bool)
    free[[0, n - 1]] = False
    return free


def _model_noise(rng, n_frames, sigma=SIGMA, n=N):
    """Residuals of a right model on white position noise: e_(t+1) - 2 e_t + e_(t-1)."""
    e = rng.normal(scale=sigma, size=(n_frames + 2, n * n, 3))
    return e[2:] - 2 * e[1:-1] + e[:-2]


def _slow(n_frames, amplitude, period=200.0, n=N):
    """A coherent slow residual: the same vertical sine at every particle, (F, P, 3)."""
    s = np.zeros((n_frames, n * n, 3))
    s[..., 2] = amplitude * np.sin(2 * np.pi * np.arange(n_frames) / period)[:, None]
    return s


def test_runs_split_sorted_frames_at_every_gap():
    """Index arrays (positions in ``frames``) of the runs of consecutive frame numbers."""
    got = res.runs([0, 1, 2, 5, 6, 9, 11, 12])
    assert [g.tolist() for g in got] == [[0, 1, 2], [3, 4], [5], [6, 7]]
    assert [g.tolist() for g in res.runs(np.arange(10, 15))] == [[0, 1, 2, 3, 4]]


def test_noise_sigma_by_hand_skips_lag_products_across_gaps_pinned_and_masked():
    """sigma^2 = (gamma_0 - gamma_1) / 10 with gamma_1 only over consecutive frames, only
    free particles and only particle-frames in the mask (values worked by hand)."""
    frames = np.array([0, 1, 5, 6])
    r = np.zeros((4, 2, 3))
    r[:, 0] = 100.0                                   # pinned: ignored
    r[:, 1] = np.array([1.0, 2.0, 3.0, -1.0])[:, None]
    free = np.array([False, True])
    # gamma_0 = (1 + 4 + 9 + 1) / 4, gamma_1 = (1*2 + 3*(-1)) / 2 (not 2*3: frames 1, 5)
    assert res.noise_sigma(r, frames, free) == pytest.approx(np.sqrt((3.75 + 0.5) / 10),
                                                             rel=1e-12)
    mask = np.ones((4, 2), dtype=bool)
    mask[1, 1] = False                                # drop the value 2
    # gamma_0 = (1 + 9 + 1) / 3, gamma_1 = 3*(-1) / 1
    assert res.noise_sigma(r, frames, free, mask) == pytest.approx(np.sqrt((11 / 3 + 3) / 10),
                                                                   rel=1e-12)


def test_noise_sigma_recovers_white_position_noise_even_with_a_slow_residual():
    """Second differences of white noise sd sigma give back sigma; adding a slow structured
    residual of twice the noise's power barely moves it; exact zeros give 0."""
    rng = np.random.default_rng(0)
    n_frames = 400
    frames = np.arange(n_frames)
    r = _model_noise(rng, n_frames)
    # ~95,000 values: over 200 seeds the estimate's relative sd is 0.36%, so 2% is > 5 sd;
    # a wrong lag-1 term or divisor (e.g. gamma_0/6 alone) is off by far more
    assert res.noise_sigma(r, frames, _free()) == pytest.approx(SIGMA, rel=0.02)
    # z only, so the mean power over x, y, z is A^2 / 6 = 12 sigma^2 = 2 x the noise's
    slow = _slow(n_frames, amplitude=np.sqrt(72) * SIGMA)
    # the sine's own (gamma_0 - gamma_1) / 10 is A^2 (1 - cos w) / 60 ~ 6e-4 sigma^2
    assert res.noise_sigma(r + slow, frames, _free()) == pytest.approx(SIGMA, rel=0.02)
    assert np.sqrt(np.mean((r + slow)[:, _free()] ** 2) / 6) > 1.5 * SIGMA   # naive: biased
    assert res.noise_sigma(np.zeros_like(r), frames, _free()) == 0.0


def test_patch_labels_are_square_blocks_numbered_row_by_row():
    """Particle (i, j) is in patch (i // patch) * ceil(n / patch) + j // patch."""
    n, patch = 10, 4
    labels = res.patch_labels(n, patch)
    for i in range(n):
        for j in range(n):
            assert labels[i * n + j] == (i // patch) * 3 + j // patch
    sizes = np.bincount(labels)
    assert sizes.tolist() == [16, 16, 8, 16, 16, 8, 8, 8, 4]   # edge patches are cut


def test_window_sums_cover_complete_windows_within_each_run():
    """Non-overlapping windows inside each run of consecutive frames (leftovers dropped);
    complete only where the particle is in the mask at every frame of the window."""
    rng = np.random.default_rng(1)
    frames = np.concatenate([np.arange(0, 23), np.arange(30, 42)])
    r = rng.normal(size=(frames.size, 4, 3))
    sums, starts, complete = res.window_sums(r, frames, 5)
    assert starts.tolist() == [0, 5, 10, 15, 30, 35]
    rows = [np.flatnonzero((frames >= s) & (frames < s + 5)) for s in starts]
    np.testing.assert_allclose(sums, np.stack([r[k].sum(axis=0) for k in rows]), atol=1e-12)
    assert complete.all()
    mask = np.ones((frames.size, 4), dtype=bool)
    mask[7, 2] = False                       # frame 7, particle 2: window starting at 5
    _, _, complete = res.window_sums(r, frames, 5, mask)
    want = np.ones((6, 4), dtype=bool)
    want[1, 2] = False
    assert complete.tolist() == want.tolist()
    empty, none, _ = res.window_sums(r[:3], frames[:3], 5)
    assert empty.shape == (0, 4, 3) and none.size == 0


def test_structure_is_near_one_on_the_residuals_of_a_right_model():
    """Only position noise: window sums telescope to variance 4 sigma^2, so Q_patch ~ 1."""
    rng = np.random.default_rng(2)
    n_frames = 400
    out = res.structure(_model_noise(rng, n_frames), np.arange(n_frames), _free(), N)
    # 40 windows x 9 patches x 3 components of ~chi^2(1)/1: sd sqrt(2/1080) = 0.043 (0.048
    # measured over 60 seeds); 0.2 is > 4 sd. A variance off by 2x would give 0.5 or 2.
    assert out["Q_patch"] == pytest.approx(1.0, abs=0.2)
    assert out["sigma"] == pytest.approx(SIGMA, rel=0.02)
    assert len(out["Q_by_window"]) == 40 and len(out["Q_by_patch"]) == 9


def test_structure_scores_a_coherent_slow_pattern_far_above_noise_of_the_same_power():
    """Same mean square residual: a slow sheet-wide pattern on top of weaker noise scores
    Q >> 1, pure position noise Q ~ 1; the excess is in z, the normal component."""
    rng = np.random.default_rng(3)
    n_frames = 400
    frames = np.arange(n_frames)
    noise = _model_noise(rng, n_frames)                      # power 6 sigma^2
    weaker = _model_noise(rng, n_frames, sigma=SIGMA / np.sqrt(2))
    # mean power over x, y, z: 3 sigma^2 of noise + A^2 / 6 = 3 sigma^2 of the z-only sine
    pattern = weaker + _slow(n_frames, amplitude=np.sqrt(18) * SIGMA)
    free = _free()
    power = [np.mean(x[:, free] ** 2) for x in (noise, pattern)]
    assert power[1] == pytest.approx(power[0], rel=0.05)   # 5%: sampling of ~95k squares
    up = np.broadcast_to([0.0, 0.0, 1.0], noise.shape)
    q_noise = res.structure(noise, frames, free, N, directions=up)
    q_pattern = res.structure(pattern, frames, free, N, directions=up)
    # pattern window sums ~ 10 * 4.2 sigma, over a noise sd of 2 * 0.7 sigma, averaged
    # coherently over 16-particle patches: Q in the thousands. Noise alone: Q is the larger
    # of Q_patch (sd 0.05) and Q_sheet (120 terms, sd 0.18 over 60 seeds): 2 is > 5 sd
    assert q_noise["Q"] < 2 and q_pattern["Q"] > 50 * q_noise["Q"]
    # components: 360 ~chi^2(1) terms each, sd 0.075; 1.5 is > 6 sd
    by = q_pattern["Q_by_component"]
    assert by["z"] > 100 and by["x"] < 1.5 and by["y"] < 1.5
    assert q_pattern["Q_normal"] > 100 and q_pattern["Q_tangential"] < 1.5


def test_structure_counts_window_sums_only_where_the_mask_holds_throughout():
    """Large residuals at masked particle-frames (the constraint's) leave Q ~ 1; without
    the mask they dominate it."""
    rng = np.random.default_rng(4)
    n_frames = 400
    frames = np.arange(n_frames)
    r = _model_noise(rng, n_frames)
    mask = np.ones((n_frames, N * N), dtype=bool)
    hit = rng.random(mask.shape) < 0.01
    mask[hit] = False
    r[hit] += 50 * SIGMA
    assert res.structure(r, frames, _free(), N, mask=mask)["Q_patch"] == pytest.approx(
        1.0, abs=0.25)   # fewer complete windows: sd 0.045 over 40 seeds, 0.25 > 5 sd
    assert res.structure(r, frames, _free(), N)["Q"] > 5


def test_structure_measures_everything_when_no_particle_fills_a_window_of_the_mask():
    """A patchy mask (every particle out at some frame of every window) leaves no window
    sum: Q is measured without the mask and says so, instead of reading 0."""
    rng = np.random.default_rng(5)
    n_frames = 200
    frames = np.arange(n_frames)
    r = _model_noise(rng, n_frames) + _slow(n_frames, 20 * SIGMA)
    mask = np.ones((n_frames, N * N), dtype=bool)
    mask[::5] = False     # windows of 10 frames: none complete
    patchy = res.structure(r, frames, _free(), N, mask=mask)
    plain = res.structure(r, frames, _free(), N)
    assert patchy["mask_dropped"] and not plain["mask_dropped"]
    assert patchy["Q"] == plain["Q"] > 5
    assert len(patchy["Q_by_window"]) == len(patchy["window_starts"]) > 0


def test_structure_uses_the_floor_and_a_given_sigma():
    """Exact zeros: sigma is the floor and Q is 0; a given sigma replaces the estimate."""
    n_frames = 40
    frames = np.arange(n_frames)
    out = res.structure(np.zeros((n_frames, N * N, 3)), frames, _free(), N, floor=1e-6)
    assert out["sigma"] == 1e-6 and out["Q"] == 0.0
    rng = np.random.default_rng(5)
    r = _model_noise(rng, n_frames)
    half = res.structure(r, frames, _free(), N, sigma=SIGMA / 2)
    full = res.structure(r, frames, _free(), N, sigma=SIGMA)
    assert half["sigma"] == SIGMA / 2
    # Q scales as 1 / sigma^2 (the 1e-300 guard is negligible)
    assert half["Q_patch"] == pytest.approx(4 * full["Q_patch"], rel=1e-9)


def test_structure_flags_white_residuals_which_a_right_model_cannot_produce():
    """i.i.d. residuals of variance s^2 (a random force, not position noise): the noise
    estimate is s^2 / 10, window sums have variance W s^2, so Q ~ W / 0.4."""
    rng = np.random.default_rng(6)
    n_frames = 400
    r = rng.normal(scale=SIGMA, size=(n_frames, N * N, 3))
    out = res.structure(r, np.arange(n_frames), _free(), N, window=10)
    # sd 0.9 (3.6%) over 40 seeds: 15% is > 4 sd; a noise floor of 6 sigma^2 instead of
    # 4 sigma^2 would give ~17
    assert out["Q_patch"] == pytest.approx(25.0, rel=0.15)


@pytest.mark.parametrize("n_frames, block, every, starts", [
    (501, 25, 4, [75, 175, 275, 375, 475]), (510, 25, 4, [75, 175, 275, 375, 475]),
    (203, 10, 3, [20, 50, 80, 110, 140, 170]), (101, 5, 2, list(range(5, 100, 10))),
    # block divides n_frames: the last block would end on the last frame, which has no
    # next one, so it starts a frame earlier (it used to be held out one frame short,
    # and rollout_error takes the shortest block for all; 100 frames must keep a block)
    (500, 25, 4, [75, 175, 275, 375, 474]), (100, 25, 2, [25, 74]), (100, 25, 4, [74]),
])
def test_split_frames_holds_out_blocks_and_keeps_training_three_frames_away(n_frames, block,
                                                                           every, starts):
    """Block k (frames k*block .. (k+1)*block - 1) is held out when k % every == every - 1;
    frames 0..n-2 are each exactly one of: training, held out, within 3 of a held block."""
    train, held = gap.split_frames(n_frames, block=block, every=every)
    assert [int(chunk[0]) for chunk in held] == starts
    for chunk in held:
        assert chunk.tolist() == list(range(chunk[0], chunk[0] + block))
    held_all = np.concatenate(held)
    assert np.unique(held_all).size == held_all.size           # blocks do not overlap
    assert held_all.max() <= n_frames - 2                       # every frame has a next one
    distance = np.abs(train[:, None] - held_all[None, :]).min(axis=1)
    assert distance.min() >= 4                                  # 3 frames of clearance
    guard = [t for t in range(n_frames - 1)
             if t not in set(held_all) and np.abs(held_all - t).min() <= 3]
    everything = np.sort(np.concatenate([train, held_all, guard]))
    assert everything.tolist() == list(range(n_frames - 1))     # each frame exactly once
    assert np.all(np.diff(train) > 0)


def test_start_state_recorded_is_the_frame_and_its_backward_difference():
    """how="recorded": (x_t, (x_t - x_(t-1)) / dt), a copy of the data."""
    rng = np.random.default_rng(7)
    x = rng.normal(size=(12, 5, 3))
    x0, v0 = gap.start_state(x, 6, 0.002, "recorded")
    np.testing.assert_array_equal(x0, x[6])
    np.testing.assert_allclose(v0, (x[6] - x[5]) / 0.002, rtol=1e-12)
    x0[:] = 0.0
    assert np.all(x[6] != 0.0)


def test_start_state_refuses_an_unknown_start_and_frames_outside_the_data():
    x = np.zeros((12, 5, 3))
    with pytest.raises(ValueError, match="how='smoothed': expected 'recorded' or 'centred'"):
        gap.start_state(x, 6, 0.002, "smoothed")
    gap.start_state(x, 1, 0.002, "recorded")
    gap.start_state(x, 8, 0.002, "centred")
    for t, how in ((0, "recorded"), (12, "recorded"), (2, "centred"), (9, "centred")):
        with pytest.raises(ValueError, match=f"t={t}: a '{how}' start needs frames"):
            gap.start_state(x, t, 0.002, how)


def test_window_sums_refuse_a_window_of_one_frame():
    """A single residual e_(t+1) - 2 e_t + e_(t-1) has variance 6 sigma^2: Q's noise scale
    (four telescoped terms) holds from two frames on."""
    r = np.zeros((10, 4, 3))
    with pytest.raises(ValueError, match="window=1: expected at least 2 frames"):
        res.window_sums(r, np.arange(10), 1)
    assert res.window_sums(r, np.arange(10), 2)[0].shape == (5, 4, 3)


def test_start_state_centred_is_the_seven_point_quadratic_fit():
    """how="centred": least-squares quadratic on t-3..t+3, i.e. the Savitzky-Golay weights
    (-2, 3, 6, 7, 6, 3, -2)/21 for the value and (-3..3)/(28 dt) for the slope; exact on a
    quadratic trajectory and blind to frames outside the window."""
    rng = np.random.default_rng(8)
    dt, t = 0.002, 6
    x = rng.normal(size=(14, 5, 3))
    x0, v0 = gap.start_state(x, t, dt, "centred")
    window = x[t - 3:t + 4]
    value_w = np.array([-2, 3, 6, 7, 6, 3, -2]) / 21
    slope_w = np.arange(-3, 4) / (28 * dt)
    np.testing.assert_allclose(x0, np.einsum("k,kpc->pc", value_w, window), atol=1e-12)
    # slope values are O(1/dt) = O(500): round-off ~1e-13 relative
    np.testing.assert_allclose(v0, np.einsum("k,kpc->pc", slope_w, window), rtol=1e-9,
                               atol=1e-9)
    moved = x.copy()
    moved[[t - 4, t + 4]] += 1.0
    np.testing.assert_allclose(gap.start_state(moved, t, dt, "centred")[0], x0, atol=1e-12)
    a, v, p = rng.normal(size=(3, 5, 3))
    times = np.arange(14)[:, None, None] * dt
    quad = p + v * times + 0.5 * a * times ** 2
    q0, w0 = gap.start_state(quad, t, dt, "centred")
    np.testing.assert_allclose(q0, quad[t], atol=1e-12)
    np.testing.assert_allclose(w0, v + a * t * dt, atol=1e-9)


def test_the_outside_summary_counts_wrong_and_exact_answers_that_carry_a_warning():
    from replication.experiments.discrepancy_outside import summarise

    def row(exact, warned, kinds=("air_damping",), caveat=False):
        return {"kinds": list(kinds), "min_snr": 100.0, "exact": exact, "limit_caveat": caveat,
                "expected_names": ["linear_damping"] if kinds else [],
                "named": ["linear_damping"] if exact and kinds else [], "unexplained": False,
                "expected_unexplained": False, "gap_before": 2.0, "gap_after": 1.0,
                "noise_h": 1e-4, "refused": None, "wall_seconds": 1.0, "warned": warned}

    rows = [row(False, True), row(False, False, caveat=True), row(True, True),
            row(True, False), row(True, False, kinds=(), caveat=True)]
    summary = summarise(rows, 30.0)
    assert (summary["n_wrong"], summary["wrong_warned"], summary["exact_warned"]) == (2, 1, 1)
    assert (summary["wrong_caveat"], summary["exact_caveat"]) == (1, 1)


def test_the_blind_summary_says_whether_stated_standard_errors_cover_the_truth():
    """A correct name's coefficient error and its largest |fitted - truth| / standard error:
    drag of 0.5/s per mass (truth 5e-4 at mass 0.001) fitted 6e-4 +- 2.5e-5 is 20% off and 4
    standard errors away; without standard errors the ratio is None; a wrong name has none."""
    from replication.experiments.discrepancy import _coefficient_error, summarise

    spec = {"effect": "linear_damping", "truth": {"per_mass": [0.5]}, "noise_h": 1e-3}

    def named(value, se):
        return [{"name": "linear_damping", "parameters": {
            "coefficients": {"c": value}, "standard_errors": None if se is None else {"c": se}}}]

    error, z = _coefficient_error(spec, named(6e-4, 2.5e-5), 0.001)
    assert (error, z) == (pytest.approx(0.2), [pytest.approx(4.0)])
    assert _coefficient_error(spec, named(5.1e-4, None), 0.001) == pytest.approx((0.02, None))
    assert _coefficient_error(spec, [{"name": "quadratic_drag", "parameters": {}}],
                              0.001) == (None, None)

    def row(index, error, z):
        return {"index": index, "spec": spec, "expected": "linear_damping", "call":
                "linear_damping", "correct": True, "gap_before": 2.0, "gap_after": 1.0,
                "coefficient_error": error, "coefficient_z": z, "wall_seconds": 1.0}

    summary = summarise([row(0, 0.01, [0.5]), row(1, 0.2, [1.5, 0.2]), row(2, 0.3, [4.0])],
                        {"moderate_noise_h": 1e-3})
    assert summary["coefficient_within_2se"] == pytest.approx(2 / 3)
    assert summary["coefficient_z_max"] == 4.0
    assert summary["coefficient_z_median"] == pytest.approx(1.0)   # of 0.2, 0.5, 1.5, 4
    assert summary["coefficient_z_within"] == {"1": 0.5, "2": 0.75, "n": 4}
    assert [b["index"] for b in summary["coefficient_beyond_10pct"]] == [1, 2]
    assert summary["coefficient_beyond_10pct"][1]["z_max"] == 4.0
