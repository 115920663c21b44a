"""The data and accuracy runners: same config and seed, same numbers; bad settings refused."""

import re

import pytest

from replication.errors import InputError
from replication.experiments.motion import accuracy, make_data
from replication.report.motion import accuracy_section, data_section

from .conftest import small_spec


def data_config(folder):
    base = small_spec()
    base.pop("center"), base.pop("omega")
    return {"seed": 0, "data_dir": str(folder), "base": base, "sequences": {
        "one": {"center": [30.0, 48.0], "omega": -0.03, "format": "npz"},
        "two": {"center": [50.0, 48.0], "omega": 0.02, "format": "png16"},
    }}


def accuracy_config(folder):
    return {"seed": 0, "sequences_dir": str(folder), "noise_levels_255": [2], "workers": 1,
            "methods": ["paper (best peak)", "coarse sweep + refinement",
                        "DE on IRC residual"],
            "method": {"omega_count": 20}, "de": {"max_evals": 150}}


def without_times(result):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in result["rows"]]


def test_data_then_accuracy_are_deterministic(tmp_path):
    first = make_data(data_config(tmp_path / "a"), tmp_path / "out")
    second = make_data(data_config(tmp_path / "b"), tmp_path / "out")
    assert first["files"] == second["files"]            # same sha256 for every file
    assert "| `two` | accuracy | png16 |" in data_section(first).markdown
    one = accuracy(accuracy_config(tmp_path / "a"), tmp_path / "out")
    two = accuracy(accuracy_config(tmp_path / "a"), tmp_path / "out")
    assert without_times(one) == without_times(two)
    assert len(one["rows"]) == 2 * 3
    assert "coarse sweep + refinement" in accuracy_section(one).markdown


def test_accuracy_refuses_unknown_method(tmp_path):
    make_data(data_config(tmp_path), tmp_path / "out")
    config = dict(accuracy_config(tmp_path), methods=["magic"])
    with pytest.raises(InputError, match=r"methods: unknown \['magic'\]"):
        accuracy(config, tmp_path / "out")


def test_accuracy_refuses_missing_manifest(tmp_path):
    with pytest.raises(InputError, match="manifest.json: no such file"):
        accuracy(accuracy_config(tmp_path), tmp_path / "out")


def test_data_refuses_zero_omega(tmp_path):
    config = data_config(tmp_path)
    config["sequences"]["one"]["omega"] = 0
    with pytest.raises(InputError, match="sequences.one.omega: 0; expected a non-zero"):
        make_data(config, tmp_path / "out")
    assert not (tmp_path / "manifest.json").exists()


@pytest.mark.parametrize("method, message", [
    ({"omega_min": 0.05, "omega_max": -0.05}, "expected omega_min < omega_max"),
    ({"omega_count": 1}, "omega_count=1: expected an integer from 2 to"),
    ({"sigma": -1}, "sigma=-1: expected >= 0 pixels"),
    ({"relative_threshold": 1.5}, "relative_threshold=1.5: expected a fraction in (0, 1)"),
    ({"cell": 0}, "cell=0: expected > 0 pixels"),
])
def test_single_rotation_refuses_bad_settings(tmp_path, method, message):
    from replication.experiments.motion_single import single_rotation

    config = {"seed": 0, "data": {"path": str(tmp_path / "never_read.npz")}, "method": method}
    with pytest.raises(InputError, match=re.escape(message)):
        single_rotation(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_answer_warnings_flag_a_translation_and_a_centre_at_the_accumulator_edge():
    from replication.experiments.motion_single import answer_warnings
    from replication.motion import irc, single

    settings = single.settings_from(None)
    grid = irc.image_grid((64, 64))
    inside = {"xi": 30.0, "eta": 20.0, "omega": 0.02, "pixels": 500}
    assert answer_warnings(inside, inside, settings, grid, (64, 64)) == []
    edge = dict(inside, eta=63.0)
    assert any("edge of the accumulator" in w
               for w in answer_warnings(edge, inside, settings, grid, (64, 64)))
    far = dict(inside, xi=32.0, eta=-1e7, omega=1e-7)
    assert any("looks like a translation" in w
               for w in answer_warnings(inside, far, settings, grid, (64, 64)))
    # the pyramid's top-level grid in input pixels (factor 4): its last row is at
    # eta = to_input(63, 4), and a centre there is on its edge
    from replication.motion import pyramid

    top = pyramid.grid_in_input(grid, 4)
    last = float(pyramid.to_input(63.0, 4))
    assert any("edge of the accumulator" in w for w in answer_warnings(
        dict(inside, eta=last - 1.0), inside, settings, top, (256, 256)))
    assert answer_warnings(dict(inside, eta=120.0), inside, settings, top, (256, 256)) == []


def test_accumulator_settings_that_cannot_work_are_refused():
    from replication.errors import InputError
    from replication.experiments.motion import _check_settings, check_grid
    from replication.motion import irc, single

    with pytest.raises(InputError, match="method.margin=-10.0: expected >= 0"):
        _check_settings(single.settings_from({"margin": -10.0}))
    fine = single.settings_from({"cell": 0.5})
    _check_settings(fine)
    check_grid((64, 64), fine)
    tiny = single.settings_from({"cell": 0.01})
    grid = irc.image_grid((64, 64), margin=tiny["margin"], cell=tiny["cell"])
    with pytest.raises(InputError, match=f"accumulator of {grid.ny} x {grid.nx} cells"):
        check_grid((64, 64), tiny)
