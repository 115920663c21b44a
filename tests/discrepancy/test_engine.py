"""One identification engine: cloth_identify and the discrepancy workflow share it, and
both recover K and tau on noise-free references."""

import numpy as np
import pytest

from replication.cloth import geometry, mesh, regression
from replication.cloth.identify import identify
from replication.cloth.identify import structured as identify_structured
from replication.cloth.io import read_trajectory
from replication.discrepancy import effects, workflow
from replication.errors import InputError

SETTINGS = {"regression": {"first": 1, "stride": 5},
            "tau_scan": {"n_grid": 40, "refine_evals": 20},
            "refine": {"box": 0.02, "ea": {"pop_size": 8, "generations": 0}}}


def test_both_workflows_call_the_same_engine():
    assert identify_structured.regression.fit is regression.fit
    assert workflow.regression.fit is regression.fit


@pytest.mark.slow
@pytest.mark.parametrize("tau", [0.1, 0.5])
def test_both_recover_K_and_tau_within_1_percent(tau):
    trajectory = read_trajectory(f"synthetic_data/cloth/reference_tau{tau}.npz")
    blind = type(trajectory)(**{**trajectory.__dict__, "meta": {}})
    best, _, _ = identify(blind, rng=0, budget=400, settings=SETTINGS)
    assert abs(best[3] / 4.0 - 1) < 0.01 and abs(best[4] / tau - 1) < 0.01
    result = workflow.analyse(blind, {"n_subsamples": 4}, rng=0)
    assert abs(result["base"]["k"][0] / 4.0 - 1) < 0.01
    assert abs(result["base"]["tau"][0] / tau - 1) < 0.01
    assert result["named_effects"] == [] and result["unexplained"] is None


def test_engine_is_exact_on_noise_free_data_and_holds_under_noise():
    trajectory = read_trajectory("synthetic_data/cloth/reference_tau0.1.npz")
    data = regression.prepare(trajectory)
    exact = regression.fit(data, np.arange(data.n_frames - 1))
    assert exact.how == "regression"
    assert abs(exact.base.k[0] - 4.0) < 1e-8 and abs(exact.base.tau[0] - 0.1) < 1e-8
    rng = np.random.default_rng(0)
    noisy = trajectory.positions + rng.normal(scale=5e-3 * data.h,
                                              size=trajectory.positions.shape)
    noisy[:, 0, [0, -1]] = trajectory.positions[:, 0, [0, -1]]
    fitted = regression.fit(regression.prepare(type(trajectory)(
        **{**trajectory.__dict__, "positions": noisy, "velocities": None})),
        np.arange(data.n_frames - 1))
    assert abs(fitted.base.k[0] / 4.0 - 1) < 0.03 and abs(fitted.base.tau[0] / 0.1 - 1) < 0.03


def test_engine_refuses_positions_that_are_not_a_cloth():
    trajectory = read_trajectory("synthetic_data/cloth/reference_tau0.1.npz")
    rng = np.random.default_rng(1)
    junk = type(trajectory)(**{**trajectory.__dict__, "velocities": None,
                               "positions": rng.normal(size=trajectory.positions.shape)})
    with pytest.raises(InputError, match="expected a cloth trajectory"):
        regression.fit(regression.prepare(junk), np.arange(100))


def _outside_trajectory(tmp_path, spec):
    from replication.testdata import cloth_outside

    made = cloth_outside.make(spec)
    made.pop("truth")
    path = tmp_path / "outside.npz"
    cloth_outside.write_npz(path, made)
    return read_trajectory(path)


def test_engine_leaves_the_wrong_valley_on_noisy_constrained_data(tmp_path, monkeypatch):
    # soft, strongly constrained and noisy: the start's stiffness comes out low and the
    # rounds from it end in the valley (K about half, rest lengths -22 %, tau 0.38)
    spec = {"n_frames": 185, "K": 2.5422, "tau": 0.1635, "noise_h": 3.79e-3,
            "seed": 1938327239, "effects": []}
    data = regression.prepare(_outside_trajectory(tmp_path, spec))
    frames = np.arange(1, data.n_frames - 1)
    fitted = regression.fit(data, frames)
    assert abs(fitted.base.k[0] / spec["K"] - 1) < 0.12     # the valley: -53 %
    assert abs(fitted.base.tau[0] / spec["tau"] - 1) < 0.05
    assert abs(fitted.base.rest[0] / (1.5 / 16) - 1) < 0.02
    monkeypatch.setattr(regression, "VALLEY_REST", 0.0)      # the guard off: the valley
    trapped = regression.fit(data, frames)
    assert trapped.base.rest[0] < 0.9 * fitted.base.rest[0]


def test_engine_is_exact_where_the_constraint_moves_most_particles(tmp_path, monkeypatch):
    # weakly damped: the constraint moves 74 % of the free particle-steps, so every start
    # by trimming fits the constrained majority and the rounds end in the valley (rest
    # lengths -53 %, K -72 %, tau x26); the consensus start finds the unconstrained few
    spec = {"n_frames": 300, "K": 2.0, "tau": 0.02, "noise_h": 0.0, "seed": 5,
            "effects": []}
    data = regression.prepare(_outside_trajectory(tmp_path, spec))
    frames = np.arange(1, data.n_frames - 1, 5)
    started = regression.consensus_start(data, frames, (), "5")
    assert np.allclose(started[0].rest[[0, 2, 4]], [1.5 / 16, 1.5 / 16 * 2 ** 0.5, 3 / 16],
                       rtol=1e-8)
    assert abs(started[0].k[0] / spec["K"] - 1) < 1e-8
    fitted = regression.fit(data, frames)
    assert abs(fitted.base.k[0] / spec["K"] - 1) < 1e-8
    assert abs(fitted.base.tau[0] / spec["tau"] - 1) < 1e-8
    monkeypatch.setattr(regression, "CONSENSUS_WINDOWS", ())   # without it: the valley
    trapped = regression.fit(data, frames)
    assert abs(trapped.base.tau[0] / spec["tau"] - 1) > 1


def test_consensus_starts_come_before_the_fallback_through_the_constraint(tmp_path):
    # the constraint moves 85 % of the free particle-steps: neither usual start leaves a
    # round with data (the fallback through the constraint then ended 2600 % off)
    spec = {"n_frames": 520, "K": 0.7988322832956302, "tau": 0.023008340737650488,
            "noise_h": 0.0, "seed": 1219739602, "effects": []}
    data = regression.prepare(_outside_trajectory(tmp_path, spec))
    frames = regression.usable_frames(np.arange(1, data.n_frames - 1, 5), data.n_frames)
    options = {"model": "5", "rounds": 3, "block": 5, "min_rows_per_coefficient": 30}
    starts = [regression.conservative_start(data, frames, (), "5"),
              regression.trimmed_starts(data, frames, (), "5", regression.SMOOTH_WINDOWS)]
    assert all(start is None or regression._rounds(data, frames, (), start, **options) is None
               for start in starts)
    fitted = regression.fit(data, frames)
    assert fitted.how == "regression"
    assert abs(fitted.base.k[0] / spec["K"] - 1) < 1e-8
    assert abs(fitted.base.tau[0] / spec["tau"] - 1) < 1e-8


def test_spring_sums_of_all_frames_are_computed_once_and_read_only():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    first = regression.state_frames(data, base).sums
    other = regression.state_frames(data, base._replace(k=np.full(6, 2.0))).sums
    assert first[0] is other[0] and first[1] is other[1]
    fresh = geometry.spring_sums(data.ops, data.x)
    assert all(np.array_equal(a, b) for a, b in zip(first, fresh))
    with pytest.raises(ValueError):
        first[0][0, 0, 0, 0] = 1.0
    part = regression.state_frames(data, base, [5, 9]).sums   # a subset: its own sums
    assert np.array_equal(part[0], fresh[0][:, [5, 9]])
    assert np.array_equal(part[1], fresh[1][:, [5, 9]])


def test_spring_sums_of_a_frame_selection_are_kept_for_the_last_few_selections():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    first = regression.state_frames(data, base, np.array([5, 9])).sums
    again = regression.state_frames(data, base._replace(k=np.full(6, 2.0)), [5, 9]).sums
    assert again[0] is first[0]                     # the same frames, any base: shared
    mask = np.zeros(data.n_frames, bool)
    mask[[5, 9]] = True
    assert regression.state_frames(data, base, mask).sums[0] is first[0]   # same frames
    with pytest.raises(ValueError):
        first[1][0, 0, 0, 0] = 1.0
    for start in range(regression.SELECTIONS_KEPT):   # newer selections push it out
        regression.state_frames(data, base, [10 + start])
    assert len(data.cache["selections"]) == regression.SELECTIONS_KEPT
    later = regression.state_frames(data, base, [5, 9]).sums
    assert later[0] is not first[0] and np.array_equal(later[0], first[0])


def test_recorded_positions_of_a_frame_selection_are_kept_read_only():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    first = regression.state_frames(data, base, [5, 9])
    again = regression.state_frames(data, base._replace(k=np.full(6, 2.0)), [5, 9])
    assert again.x is first.x and again.v is first.v
    assert np.array_equal(first.x, data.x[[5, 9]]) and np.array_equal(first.v, data.v[[5, 9]])
    with pytest.raises(ValueError):
        first.x[0, 0, 0] = 1.0
    assert regression.state_frames(data, base).x is data.x   # all frames: the data's own


@pytest.mark.parametrize("frames", [np.array(5), np.array([[5, 9]]), np.array([[True]])])
def test_frames_that_are_not_one_dimensional_are_refused(frames):
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    regression.state_frames(data, base, frames.ravel()[:1].astype(np.intp))   # kept: 1-D
    with pytest.raises(ValueError, match="1-D"):
        regression.state_frames(data, base, frames)


def test_plugin_columns_are_computed_once_per_frames_and_per_base_when_they_need_it():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    stiffer = base._replace(k=np.full(6, 5.0))
    calls = []

    def counted(basis):
        def call(q):
            calls.append(basis)
            return basis(q)
        return call
    free = regression.Plugin("drag", counted(effects.LIBRARY["quadratic_drag"].basis))
    based = regression.Plugin("mass", counted(effects.LIBRARY["nonuniform_mass"].basis), True)
    for plugin, bases, computed in ((free, (base, stiffer), 1), (based, (base, stiffer), 2)):
        calls.clear()
        columns = [regression.state_frames(data, b, [5, 9]).columns(plugin) for b in bases * 2]
        assert len(calls) == computed
        for b, cols in zip(bases * 2, columns):   # what the plug-in itself gives
            fresh = plugin.basis(regression.StateFrames(
                data.x[[5, 9]], data.v[[5, 9]], data.ops, data.mass, b.rest, b.k,
                data.scene.damping))
            assert np.array_equal(cols, fresh)
        with pytest.raises(ValueError):
            columns[0][0, 0, 0, 0] = 1.0
    calls.clear()
    regression.state_frames(data, base, [5, 10]).columns(free)   # other frames: computed
    assert len(calls) == 1


def test_kept_plugin_columns_stay_within_their_byte_bound(monkeypatch):
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    plugin = regression.Plugin("drag", effects.LIBRARY["quadratic_drag"].basis)
    one = plugin.basis(regression.StateFrames(data.x[[5]], data.v[[5]], data.ops, data.mass,
                                              base.rest, base.k)).nbytes
    monkeypatch.setattr(regression, "COLUMNS_BYTES_KEPT", 2 * one)
    for frame in range(5, 12):
        regression.state_frames(data, base, [frame]).columns(plugin)
    kept = data.cache["columns"]
    assert kept.nbytes <= 2 * one and len(kept) == 2
    assert [key[2] for key in kept.keys()] == [np.array([f], np.intp).tobytes() for f in (10, 11)]


def _fresh_design(data, base, plugins, model, frames=None):
    """The regressors built from scratch (on a new ``Data``, with nothing kept in its
    cache), as one array, and the column slice of each plug-in."""
    columns, slices = regression.design(regression.prepare(data.trajectory), base,
                                        tuple(plugins), model, frames)
    return np.asarray(columns), slices


def test_a_design_without_base_dependent_plugins_is_made_once_and_shared_read_only(
        monkeypatch):
    monkeypatch.setattr(regression, "DESIGNS_KEPT", 10)   # every design below stays kept
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    stiffer = base._replace(k=np.full(6, 5.0), rest=np.full(6, 1.1 * data.h))
    plugins = [regression.Plugin(name, effects.LIBRARY[name].basis)
               for name in ("quadratic_drag", "body_force")]
    first, slices = regression.design(data, base, plugins, "5")
    again, slices_again = regression.design(data, stiffer, plugins, "5")   # any base
    assert again is first and slices_again == slices
    fresh, fresh_slices = _fresh_design(data, base, plugins, "5")
    assert np.array_equal(first, fresh) and slices == fresh_slices
    q = regression.state_frames(data, base)
    for plugin in plugins:   # each plug-in's slice holds its columns, the rest the base's
        assert np.array_equal(first[..., slices[plugin.name]], q.columns(plugin))
    assert slices["quadratic_drag"].start == regression.n_base("5") and \
        slices["body_force"].stop == first.shape[-1]
    with pytest.raises(ValueError):
        first[0, 0, 0, 0] = 1.0
    slices_again["quadratic_drag"] = slice(0, 1)   # the caller's own copy
    assert regression.design(data, base, plugins, "5")[1] == fresh_slices
    # other plug-ins, model or frames: other regressors, each made from scratch
    mask = np.zeros(data.n_frames, bool)
    mask[[5, 9]] = True
    for other in ((plugins[:1], "5", None), (plugins, "18", None), (plugins, "5", [5, 9]),
                  (plugins, "5", mask)):
        columns, other_slices = regression.design(data, base, *other)
        assert columns is not first
        expected, expected_slices = _fresh_design(data, base, *other)
        assert np.array_equal(columns, expected) and other_slices == expected_slices
    assert regression.design(data, base, plugins, "5", mask)[0] is \
        regression.design(data, base, plugins, "5", [5, 9])[0]   # the same frames


def test_a_design_with_a_base_dependent_plugin_follows_the_base():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    stiffer = base._replace(k=np.full(6, 5.0), rest=np.full(6, 1.1 * data.h))
    plugins = [regression.Plugin("quadratic_drag", effects.LIBRARY["quadratic_drag"].basis),
               regression.Plugin("anisotropic_stiffness",
                                 effects.LIBRARY["anisotropic_stiffness"].basis, True)]
    at_base, _ = regression.design(data, base, plugins, "5", [5, 9])
    at_stiffer, _ = regression.design(data, stiffer, plugins, "5", [5, 9])
    assert not np.array_equal(at_base, at_stiffer)
    assert np.array_equal(at_base, _fresh_design(data, base, plugins, "5", [5, 9])[0])
    assert np.array_equal(at_stiffer, _fresh_design(data, stiffer, plugins, "5", [5, 9])[0])


def test_kept_designs_stay_within_their_bounds(monkeypatch):
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    alone = regression.prepare(data.trajectory)
    regression.design(alone, base, (), "5", [5])
    one = alone.cache["designs"].nbytes   # one kept design: its columns and their widths
    monkeypatch.setattr(regression, "DESIGNS_BYTES_KEPT", 2 * one)
    for frame in range(5, 9):
        regression.design(data, base, (), "5", [frame])
    kept = data.cache["designs"]
    assert len(kept) == 2 and kept.nbytes <= 2 * one
    monkeypatch.setattr(regression, "DESIGNS_BYTES_KEPT", 10 * one)
    for frame in range(5, 9):
        regression.design(data, base, (), "5", [frame])
    assert len(data.cache["designs"]) == regression.DESIGNS_KEPT


def test_typical_lengths_are_measured_once_and_handed_out_as_copies():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    first = regression.typical_lengths(data)
    expected = mesh.type_lengths(data.x[::max(1, data.n_frames // 50)], data.ops.n,
                                 statistic="median")
    assert np.array_equal(first, expected)
    first[:] = 0.0                                   # the caller's own copy
    assert np.array_equal(regression.typical_lengths(data), expected)


def _noisy_reference(scale_h=5e-3, seed=0):
    trajectory = read_trajectory("synthetic_data/cloth/reference_tau0.1.npz")
    h = regression.prepare(trajectory).h
    noisy = trajectory.positions + np.random.default_rng(seed).normal(
        scale=scale_h * h, size=trajectory.positions.shape)
    noisy[:, 0, [0, -1]] = trajectory.positions[:, 0, [0, -1]]
    return regression.prepare(type(trajectory)(
        **{**trajectory.__dict__, "positions": noisy, "velocities": None}))


def test_smoothed_versions_of_the_data_are_made_once_and_equal_fresh_ones():
    data = _noisy_reference()
    assert regression.version(data, 0) is data
    smooth = regression.version(data, 11)
    assert regression.version(data, 11) is smooth and regression.version(data, 7) is not smooth
    fresh = regression.prepare(regression.smoothed(data.trajectory, 11))
    for name in ("x", "v", "target", "mass", "free"):
        assert np.array_equal(getattr(smooth, name), getattr(fresh, name), equal_nan=True)
    assert regression.tau_data(data) is smooth          # noisy: the tau search smooths
    assert regression.position_noise(data) == regression.position_noise(
        regression.prepare(data.trajectory))            # kept, and as computed afresh
    clean = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    assert regression.tau_data(clean) is clean


def test_consensus_coefficients_are_shared_by_every_set_of_plugins():
    data = _noisy_reference(5e-4)
    frames = np.arange(data.n_frames - 1)
    drag = regression.Plugin("quadratic_drag", effects.LIBRARY["quadratic_drag"].basis)
    mass = regression.Plugin("nonuniform_mass", effects.LIBRARY["nonuniform_mass"].basis, True)
    alone = regression.consensus_start(data, frames, (), "5")
    assert regression.CONSENSUS_QUANTILES == (0.05, 0.1)
    assert len(data.cache["consensus"]) == 2            # both quantiles rank the same draws
    with_plugins = regression.consensus_start(data, frames, (drag, mass), "5")
    assert len(data.cache["consensus"]) == 2            # the same coefficients, kept
    fresh = regression.consensus_start(regression.prepare(data.trajectory), frames,
                                       (drag, mass), "5")
    for got in (alone, with_plugins):
        for a, b in zip(got[0], fresh[0]):
            assert np.array_equal(a, b)
    assert [(p.name, t.tolist()) for p, t in with_plugins[1]] == \
        [(p.name, t.tolist()) for p, t in fresh[1]]
    assert [p.name for p, _ in with_plugins[1]] == ["quadratic_drag", "nonuniform_mass"]
    for quantile in (0.1, 0.2):                          # kept already; another one
        other = regression.consensus_start(data, frames, (), "5", quantile=quantile)
        anew = regression.prepare(data.trajectory)
        alone_fresh = regression.consensus_start(anew, frames, (), "5", quantile=quantile)
        assert len(anew.cache["consensus"]) == 3 - (quantile == 0.1)
        for a, b in zip(other[0], alone_fresh[0]):
            assert np.array_equal(a, b)
    assert len(data.cache["consensus"]) == 3
    with_plugins[0].rest[:] = 0.0                       # a start is the caller's own
    again = regression.consensus_start(data, frames, (drag, mass), "5")
    assert np.array_equal(again[0].rest, fresh[0].rest)


def test_consensus_ranks_several_quantiles_as_each_alone():
    data = _noisy_reference(5e-4)
    frames = np.arange(data.n_frames - 1)
    together = regression._consensus_thetas(data, frames, "5", [0.05, 0.1, 0.3], 60, 1)
    for quantile, theta in zip((0.05, 0.1, 0.3), together):
        alone = regression._consensus_thetas(data, frames, "5", [quantile], 60, 1)[0]
        assert np.array_equal(theta, alone)
    assert not np.array_equal(together[0], together[2])


def test_columns_in_blocks_read_exactly_like_the_concatenated_array():
    rng = np.random.default_rng(3)
    blocks = [rng.normal(size=(7, 5, 3, w)) for w in (4, 1, 6)]
    whole = np.concatenate(blocks, axis=-1)
    columns = regression.Columns(blocks)
    assert columns.shape == whole.shape and np.array_equal(np.asarray(columns), whole)
    keep = rng.random(5) < 0.5
    rows = rng.random((7, 5)) < 0.5
    for index in ((2, keep), (2,), 2, (slice(None), keep), (slice(1, 4),), (rows,),
                  (np.array([0, 3]), keep), (Ellipsis, slice(4, 5)), (Ellipsis, slice(5, 11)),
                  (Ellipsis, slice(3, 6)), (2, keep, 1), (..., 0), (None, 1)):
        got = columns[index]
        expected = whole[index]
        assert got.shape == expected.shape and np.array_equal(got, expected), index
    assert columns[..., slice(4, 5)] is blocks[1]   # one block's columns: the block itself
    gathered = columns[2, keep]   # what cluster_sums reads: the same layout, C order
    assert gathered.flags.c_contiguous and gathered.tobytes() == whole[2, keep].tobytes()
    with pytest.raises(ValueError):   # numpy 2's copy=False: joining the blocks copies
        np.array(columns, copy=False)


def test_a_base_dependent_design_gives_the_same_normal_equations_as_the_whole_array():
    data = regression.prepare(read_trajectory("synthetic_data/cloth/reference_tau0.1.npz"))
    base = regression.BaseModel(np.full(6, data.h), np.full(6, 4.0), np.full(6, 0.1))
    plugins = [regression.Plugin("anisotropic_stiffness",
                                 effects.LIBRARY["anisotropic_stiffness"].basis, True),
               regression.Plugin("quadratic_drag", effects.LIBRARY["quadratic_drag"].basis)]
    columns, slices = regression.design(data, base, plugins, "5")
    assert isinstance(columns, regression.Columns)
    whole, whole_slices = _fresh_design(data, base, plugins, "5")
    assert slices == whole_slices
    frames = regression.usable_frames(np.arange(data.n_frames), data.n_frames)
    mask = np.random.default_rng(0).random((data.n_frames, data.x.shape[1])) < 0.8
    for got, expected in zip(regression.cluster_sums(columns, data.target, frames, mask),
                             regression.cluster_sums(whole, data.target, frames, mask)):
        assert np.array_equal(got, expected)
