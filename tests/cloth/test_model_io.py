"""Trajectory files: reading data made elsewhere, refusing bad files, writing."""

import json

import numpy as np
import pytest

from replication.cloth.costs import make_cost
from replication.cloth.io import read_trajectory, write_trajectory
from replication.cloth.model import params_from_vectors, reference_vector, simulate
from replication.errors import InputError
from tests.cloth.plain_reference import plain_run

H = 1.5 / 16


def _valid_arrays(n_frames=5, n=17):
    rng = np.random.default_rng(0)
    positions = rng.normal(size=(n_frames, n, n, 3))
    positions[:, 0, 0] = positions[0, 0, 0]  # pinned particles stay in place
    positions[:, 0, n - 1] = positions[0, 0, n - 1]
    return {
        "positions": positions,
        "dt": np.float64(0.002),
        "mass": np.float64(0.001),
        "gravity": np.array([0.0, 0.0, -9.81]),
        "pinned": np.array([[0, 0], [0, n - 1]]),
    }


def _save(tmp_path, arrays, name="traj.npz"):
    path = tmp_path / name
    np.savez(path, **arrays)
    return path


@pytest.fixture(scope="module")
def external_file(tmp_path_factory):
    """A trajectory 'made elsewhere': the plain loop implementation, saved with np.savez."""
    truth = reference_vector(0.5)
    rest = [truth[0]] * 2 + [truth[1]] * 2 + [truth[2]] * 2
    frames = np.array(plain_run(200, rest, [4.0] * 6, [0.5] * 6)).reshape(201, 17, 17, 3)
    path = tmp_path_factory.mktemp("external") / "external.npz"
    np.savez(path, positions=frames, dt=0.002, mass=0.001, gravity=[0.0, 0.0, -9.81],
             pinned=np.array([[0, 0], [0, 16]]),
             meta=json.dumps({"source": "plain loop in the tests"}))
    return path, truth


def test_external_trajectory_is_reproduced_to_round_off(external_file):
    path, truth = external_file
    trajectory = read_trajectory(path)
    positions, _ = simulate(params_from_vectors(truth), trajectory.scene(),
                            trajectory.n_frames - 1)
    error = np.abs(positions[0] - trajectory.flat_positions()).max() / H
    assert error < 1e-9
    for kind, options in (("small", {}), ("full", {"start": 100})):
        cost = make_cost(trajectory, kind, **options)
        assert cost(params_from_vectors(truth))[0] < 1e-20
        assert cost(params_from_vectors(truth * [1, 1, 1, 1.05, 1]))[0] > 1e-12


def test_write_read_roundtrip_is_byte_deterministic(tmp_path, external_file):
    trajectory = read_trajectory(external_file[0])
    write_trajectory(tmp_path / "a.npz", trajectory)
    write_trajectory(tmp_path / "b.npz", trajectory)
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()
    again = read_trajectory(tmp_path / "a.npz")
    np.testing.assert_array_equal(again.positions, trajectory.positions)
    assert again.meta == {"source": "plain loop in the tests"}


def test_velocities_derived_when_absent_and_used_when_present(tmp_path):
    arrays = _valid_arrays()
    derived = read_trajectory(_save(tmp_path, arrays)).flat_velocities()
    x = arrays["positions"].reshape(5, -1, 3)
    np.testing.assert_allclose(derived[1:], (x[1:] - x[:-1]) / 0.002)
    assert np.all(derived[0] == 0)
    arrays["velocities"] = np.ones_like(arrays["positions"])
    assert np.all(read_trajectory(_save(tmp_path, arrays)).flat_velocities() == 1.0)


BAD_CASES = {
    "missing key": (lambda a: a.pop("gravity"), "'gravity': found no such key"),
    "wrong shape": (lambda a: a.update(positions=np.zeros((5, 17, 16, 3))),
                    "'positions': found shape (5, 17, 16, 3); expected (T, n, n, 3)"),
    "NaN": (lambda a: a["positions"].__setitem__((1, 2, 3, 0), np.nan),
            "'positions': found 1 NaN or inf"),
    "inf velocity": (lambda a: a.update(velocities=np.full((5, 17, 17, 3), np.inf)),
                     "'velocities': found 4335 NaN or inf"),
    "T < 3": (lambda a: a.update(positions=np.zeros((2, 17, 17, 3))),
              "'positions': found T = 2 frames; expected T >= 3"),
    "dt <= 0": (lambda a: a.update(dt=np.float64(0.0)),
                "'dt': found 0.0; expected a time step > 0"),
    "pinned outside": (lambda a: a.update(pinned=np.array([[0, 0], [0, 17]])),
                       "'pinned': found index (0, 17); expected indices inside the 17x17"),
    "mass not positive": (lambda a: a.update(mass=np.float64(-1.0)),
                          "'mass': found minimum -1.0; expected masses > 0"),
    "mass wrong shape": (lambda a: a.update(mass=np.ones(3)), "'mass': found shape (3,)"),
    "gravity wrong shape": (lambda a: a.update(gravity=np.zeros(2)),
                            "'gravity': found shape (2,); expected (3,)"),
    "negative damping": (lambda a: a.update(damping=np.float64(-0.1)),
                         "'damping': found -0.1; expected a damping coefficient >= 0"),
    "meta not JSON": (lambda a: a.update(meta=np.array("{oops")), "'meta': found invalid JSON"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_reader_refuses_bad_file_with_one_line(tmp_path, case):
    arrays = _valid_arrays()
    mutate, expected = BAD_CASES[case]
    mutate(arrays)
    path = _save(tmp_path, arrays)
    with pytest.raises(InputError) as info:
        read_trajectory(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(str(path))
    assert expected in message


def test_reader_refuses_truncated_and_missing_files(tmp_path):
    path = _save(tmp_path, _valid_arrays())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cannot be read as .npz"):
        read_trajectory(path)
    with pytest.raises(InputError, match="no such file"):
        read_trajectory(tmp_path / "absent.npz")


def test_cost_frame_outside_data_is_refused(tmp_path):
    trajectory = read_trajectory(_save(tmp_path, _valid_arrays(n_frames=20)))
    with pytest.raises(InputError, match="outside the data"):
        make_cost(trajectory, "small", frame=150)
    with pytest.raises(InputError, match="outside the data"):
        make_cost(trajectory, "full", start=0, window=50)


@pytest.mark.parametrize("empty", [[], np.zeros((0, 2)), np.zeros((0, 2), int)],
                         ids=["list", "float (0, 2)", "int (0, 2)"])
def test_empty_pin_list_means_nothing_pinned(tmp_path, empty):
    arrays = _valid_arrays()
    arrays["pinned"] = np.asarray(empty)
    trajectory = read_trajectory(_save(tmp_path, arrays))
    assert trajectory.pinned.shape == (0, 2) and trajectory.pinned.dtype == np.int64
    assert trajectory.scene().pinned.shape == (0, 2)


def test_non_integer_pins_are_still_refused(tmp_path):
    arrays = _valid_arrays()
    arrays["pinned"] = np.array([[0.0, 0.0]])
    with pytest.raises(InputError, match="'pinned': found dtype float64"):
        read_trajectory(_save(tmp_path, arrays))
