"""Bad input and faults at every boundary (docs/results.md, "Refusals, warnings,
interruptions"): each case asserts the exit status, the one ``error:`` line and that
nothing was written.

Runs are in-process (``replication.cli.main`` with ``sys.argv`` set) except the Ctrl-C
case, which needs a real process.
"""

import errno
import json
import shutil
import os
import signal
import subprocess
import sys
import time
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from replication import cli, regenerate, sweep
from replication.cloth.io import write_npz_deterministic
from replication.motion.io import write_sequence_folder, write_sequence_npz
from replication.report.build import build_report, experiment_entries

ROOT = Path(__file__).resolve().parent.parent
CLOTH_REFERENCE = ROOT / "synthetic_data" / "cloth" / "reference_tau0.5.npz"
MOTION_REFERENCE = ROOT / "synthetic_data" / "motion" / "acc12_three_frames.npz"


# ---------------------------------------------------------------- bad files
def _cloth_files(folder):
    ref = dict(np.load(CLOTH_REFERENCE))

    def cloth(name, **change):
        arrays = dict(ref)
        arrays.update(change)
        write_npz_deterministic(folder / name, arrays)

    with open(folder / "npy_named_npz.npz", "wb") as handle:
        np.save(handle, ref["positions"])
    (folder / "truncated.npz").write_bytes(CLOTH_REFERENCE.read_bytes()[:5000])
    (folder / "empty.npz").write_bytes(b"")
    cloth("huge.npz", positions=ref["positions"] * 1e300)
    cloth("tiny.npz", positions=ref["positions"] * 1e-200)  # squared lengths underflow
    cloth("dt_huge.npz", dt=np.float64(1e300))
    cloth("gravity_huge.npz", gravity=np.array([0.0, 0.0, 1e300]))
    cloth("damping_huge.npz", damping=np.float64(1e300))
    cloth("bool.npz", positions=ref["positions"] > 0)
    cloth("zero.npz", positions=np.zeros_like(ref["positions"]))
    cloth("frozen.npz", positions=np.repeat(ref["positions"][:1], len(ref["positions"]), 0))
    cloth("dt_bool.npz", dt=np.bool_(True))
    moving = ref["positions"].copy()
    moving[:, 0, 0, 2] += np.linspace(0.0, 1.0, len(moving))
    cloth("pinned_moves.npz", positions=moving)
    nan = ref["positions"].copy()
    nan[3, 2, 2, 0] = np.nan
    cloth("nan.npz", positions=nan)
    without = {k: v for k, v in ref.items() if k != "dt"}
    write_npz_deterministic(folder / "no_dt.npz", without)
    write_npz_deterministic(folder / "no_truth.npz",
                            {k: v for k, v in ref.items() if k != "meta"})
    os.mkfifo(folder / "fifo.npz")


CLOTH_CASES = {
    "npy_named_npz.npz": "not an .npz archive",
    "truncated.npz": "cannot be read as .npz",
    "empty.npz": "cannot be read as .npz",
    "huge.npz": "coordinates within",
    "tiny.npz": "found a mesh spanning 1.",
    "dt_huge.npz": "'dt': found 1e+300; expected a time step between",
    "gravity_huge.npz": "'gravity': found 1e+300",
    "damping_huge.npz": "'damping': found 1e+300",
    "bool.npz": "found dtype bool",
    "zero.npz": "at the same place",
    "frozen.npz": "no motion",
    "dt_bool.npz": "'dt': found dtype bool",
    "pinned_moves.npz": "pinned particle (0, 0) moving by",
    "nan.npz": "NaN or inf",
    "no_dt.npz": "'dt': found no such key",
    "fifo.npz": "not a regular file",
    "missing.npz": "no such file or folder",
}


def _motion_files(folder):
    rng = np.random.default_rng(1)
    frames = np.load(MOTION_REFERENCE)["frames"][:2].astype(float)
    write_sequence_npz(folder / "frames_8x8.npz", rng.random((2, 8, 8)))
    write_sequence_npz(folder / "strip_8x4000.npz", rng.random((2, 8, 4000)))
    # 13 x 13 passed the size check and failed in the refinement without naming the file
    write_sequence_npz(folder / "frames_14x14.npz", rng.random((2, 14, 14)))
    np.savez(folder / "truth_array.npz", frames=rng.random((2, 32, 32)),
             truth=np.frombuffer(b'{"objects": []}', dtype=np.uint8))
    write_sequence_npz(folder / "identical.npz", np.stack([frames[0], frames[0]]))
    write_sequence_npz(folder / "one_frame.npz", frames[:1])
    np.savez(folder / "huge_4000.npz",
             frames=np.broadcast_to(np.arange(4000, dtype=np.uint8), (2, 4000, 4000)))
    with open(folder / "npy_named_npz.npz", "wb") as handle:
        np.save(handle, frames)
    constant = frames.copy()
    constant[1] = 0.5
    write_sequence_npz(folder / "constant.npz", constant)

    def sequence(name, labels=None, truth=None):
        write_sequence_folder(folder / name, frames, labels=labels, truth=truth)
        return folder / name

    labelled = sequence("label_sizes", labels=np.zeros(frames.shape, np.uint8))
    from PIL import Image

    Image.fromarray(np.zeros((10, 10), np.uint8)).save(labelled / "labels_001.png")
    latin = sequence("truth_latin1")
    (latin / "truth.json").write_bytes('{"objects": [], "note": "caf\xe9"}'.encode("latin-1"))
    sequence("truth_abc", truth={"objects": [{"label": 1, "xi": "abc", "eta": 1,
                                              "omega": 0.01}]})
    sequence("truth_null", truth={"objects": [{"label": 1, "xi": None, "eta": 1,
                                               "omega": 0.01}]})
    sequence("truth_zero_omega", truth={"objects": [{"label": 1, "xi": 1.0, "eta": 1.0,
                                                     "omega": 0}]})
    sequence("truth_label_zero", labels=np.zeros(frames.shape, np.uint8),
             truth={"objects": [{"label": 0, "xi": 1.0, "eta": 1.0, "omega": 0.01}]})
    sequence("truth_huge_int", truth={"objects": [{"label": 1, "xi": 10 ** 400, "eta": 1,
                                                   "omega": 0.01}]})
    sequence("truth_no_label", labels=np.zeros(frames.shape, np.uint8),
             truth={"objects": [{"xi": 1.0, "eta": 1.0, "omega": 0.01}]})
    broken = sequence("png_broken")
    (broken / "frame_001.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    os.mkfifo(folder / "fifo")


MOTION_CASES = {
    "frames_8x8.npz": "border that smoothing",
    "strip_8x4000.npz": "border that smoothing",
    "frames_14x14.npz": "expected frames of at least 16 x 16 pixels",
    "truth_array.npz": "truth: found an array of shape (15,) and dtype uint8; expected one",
    "truth_huge_int": "truth xi: found 100",
    "one_frame.npz": "T >= 2 frames",
    "huge_4000.npz": "limits.max_frame_pixels",
    "npy_named_npz.npz": "not an .npz archive",
    "constant.npz": "a constant image",
    "label_sizes": "labels_001.png: shape",
    "truth_latin1": "not UTF-8",
    "truth_abc": 'truth xi: found "abc"',
    "truth_null": "truth xi: found null",
    "png_broken": "cannot be read as an image",
    "fifo": "not a regular file",
}


@pytest.fixture(scope="module")
def bad(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad")
    _cloth_files(folder)
    _motion_files(folder)
    return folder


# ---------------------------------------------------------------- running replicate
@lru_cache(maxsize=None)
def _output_keys(name):
    defaults = cli.experiment_defaults(name)
    return tuple(key for key in cli.OUTPUT_KEYS if key in defaults)


def replicate(capsys, *args):
    """``replicate ARGS`` in this process: ``(exit status, stderr)``."""
    argv = sys.argv
    sys.argv = ["replicate", *args]
    try:
        cli.main()
        status = 0
    except SystemExit as done:
        status = done.code if isinstance(done.code, int) else (0 if done.code is None else 1)
    finally:
        sys.argv = argv
    return status, capsys.readouterr().err


def redirected(name, work):
    """``out`` and every output folder of experiment ``name`` inside ``work``."""
    return [f"experiment={name}", f"out={work / 'out'}",
            *(f"{key}={work / key}" for key in _output_keys(name))]


def assert_refused(status, err, message, work, status_expected=2):
    assert "Traceback" not in err, err
    assert status == status_expected, err
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and message in errors[0], err
    leftovers = sorted(os.listdir(work)) if work.exists() else []
    assert leftovers == [], f"written despite the refusal: {leftovers}"


# every bad file on one experiment: the checks are the trajectory reader's
# (replication/cloth/io.py) and the path guard's, which every experiment goes through; on
# each other experiment that reads a trajectory, one file of each kind of check (the
# archive, the content, the motion, the path) shows that it does
CLOTH_READER = "cloth_identify"
CLOTH_OTHERS = ["fig11_reconstruction", "table1_2", "bench_cloth", "cloth_identify_18",
                "cloth_ci", "cloth_baselines", "fig09_10", "cloth_identify_noise"]
CLOTH_MATRIX = ([(CLOTH_READER, f) for f in CLOTH_CASES]
                + [(e, f) for e in CLOTH_OTHERS
                   for f in ("npy_named_npz.npz", "nan.npz", "frozen.npz", "pinned_moves.npz",
                             "fifo.npz")]
                + [("discrepancy", f) for f in ("dt_huge.npz", "tiny.npz")])


@pytest.mark.parametrize("experiment, filename", CLOTH_MATRIX)
def test_bad_trajectory_is_refused(bad, tmp_path, capsys, experiment, filename):
    work = tmp_path / "work"
    status, err = replicate(capsys, *redirected(experiment, work),
                            f"data.path={bad / filename}")
    assert_refused(status, err, CLOTH_CASES[filename], tmp_path)


@pytest.mark.parametrize("experiment", ["cloth_ci", "cloth_identify_noise"])
def test_data_without_truth_is_refused_with_the_file_named(bad, tmp_path, capsys,
                                                           experiment):
    """The two experiments that score against ``meta.true_params`` name the file that
    lacks it (docs/data-formats.md, "Ground truth")."""
    work = tmp_path / "work"
    status, err = replicate(capsys, *redirected(experiment, work),
                            f"data.path={bad / 'no_truth.npz'}")
    assert_refused(status, err, f"{bad / 'no_truth.npz'}: no meta.true_params", tmp_path)


MOTION_READERS = ["motion_single", "segment_multi"]
MOTION_MATRIX = ([(e, f) for e in MOTION_READERS for f in MOTION_CASES]
                 + [(e, f) for e in ("bench_motion", "bench_segment")
                    for f in ("frames_8x8.npz", "huge_4000.npz", "truth_abc")]
                 + [("motion_single", "identical.npz"),
                    ("segment_multi", "truth_no_label"),
                    ("motion_single", "truth_zero_omega"),
                    ("segment_multi", "truth_label_zero")])
ONE_READER_CASES = {"identical.npz": "no motion found", "truth_no_label": "has no 'label'",
                    "truth_zero_omega": "truth omega: found 0 (an object that does not turn)",
                    "truth_label_zero": "truth label 0: found a value of 0 or less"}


@pytest.mark.parametrize("experiment, filename", MOTION_MATRIX)
def test_bad_sequence_is_refused(bad, tmp_path, capsys, experiment, filename):
    message = MOTION_CASES.get(filename) or ONE_READER_CASES[filename]
    status, err = replicate(capsys, *redirected(experiment, tmp_path / "work"),
                            f"data.path={bad / filename}", "method.omega_count=20"
                            if experiment == "motion_single" else "seed=0")
    assert_refused(status, err, message, tmp_path)


MANIFEST_CASES = {
    "truncated": ('{"sequences": ', "cannot be read as JSON"),
    "list": ("[]", "found no 'sequences' key"),
    "sequences_list": ('{"sequences": ["a"]}', "found 'sequences' of JSON type list"),
    # role "study" for segment_study, "accuracy" for motion_accuracy
    "missing_path": ('{"sequences": {"a": {"path": "nowhere", "role": "study"}, '
                     '"b": {"path": "nowhere", "role": "accuracy"}}}',
                     ".path: found 'nowhere', no such file or folder"),
    "not_utf8": (b'{"sequences": {"\xff": 1}}', "cannot be read as JSON"),
    "no_path": ('{"sequences": {"a": {"role": "study"}}}', "sequences.a: found"),
}


@pytest.mark.parametrize("experiment", ["motion_accuracy", "segment_study"])
@pytest.mark.parametrize("case", sorted(MANIFEST_CASES))
def test_bad_manifest_is_refused(tmp_path, capsys, experiment, case):
    content, message = MANIFEST_CASES[case]
    folder = tmp_path / "sequences"
    folder.mkdir()
    (folder / "manifest.json").write_bytes(content if isinstance(content, bytes)
                                           else content.encode())
    status, err = replicate(capsys, *redirected(experiment, tmp_path / "work"),
                            f"sequences_dir={folder}")
    assert_refused(status, err, message, tmp_path / "work")
    assert sorted(os.listdir(tmp_path)) == ["sequences"]


def test_a_sequences_dir_that_is_a_file_is_refused(bad, tmp_path, capsys):
    status, err = replicate(capsys, *redirected("segment_study", tmp_path / "work"),
                            f"sequences_dir={bad / 'constant.npz'}")
    assert_refused(status, err, "constant.npz: a file, not a folder", tmp_path / "work")


CONFIG_CASES = [
    ("fig08_mesh", ["seed=abc"], "seed='abc': expected an integer >= 0"),
    ("fig08_mesh", ["seed=-1"], "seed=-1: expected an integer >= 0"),
    ("fig08_mesh", ["seed=null"], "seed=null: expected an integer >= 0"),
    ("fig08_mesh", ["seed=1.5"], "seed=1.5: expected an integer >= 0"),
    ("fig08_mesh", ["seed=true"], "seed=true: expected an integer >= 0"),
    ("fig08_mesh", ["resume=maybe"], "resume='maybe': expected true or false"),
    ("fig08_mesh", ["strict=1"], "strict=1: expected true or false"),
    ("fig08_mesh", ["force=yes"], "force='yes': expected true or false"),
    ("fig08_mesh", ["zoom=abc"], "zoom='abc': expected an integer"),
    ("fig08_mesh", ["foo=1"], "Could not override 'foo'"),
    ("cloth_identify", ["data.pth=x.npz"],
     "Could not override 'data.pth': no such key; did you mean data.path?"),
    # a typo gets "did you mean", not the advice to add it with + (a setting's name
    # elsewhere: method.sigma, hydra's launcher keys); an optional setting gets both
    ("motion_single", ["mehtod.sigma=2.0"],
     "Could not override 'mehtod.sigma': no such key; did you mean method.sigma?"),
    ("motion_single", ["methods.sigma=2"], "no such key; did you mean method.sigma?"),
    # a misspelt block: spelt right, with the leaf's close key there, else the block
    ("motion_single", ["mehtod.sigmaa=2"], "no such key; did you mean method.sigma?"),
    ("motion_single", ["mehtod.x=2"], "Could not override 'mehtod.x': no such key; did you "
     "mean method?"),
    ("motion_single", ["hydra.run.dirr=x"],
     "Could not override 'hydra.run.dirr': no such Hydra setting; did you mean hydra.run.dir"),
    ("cloth_identify", ["cost.frames=20"], "did you mean cost.frame? (if cost.frames is a "
     "setting the code reads when given, add it with +cost.frames=VALUE)"),
    ("cloth_identify", ["n_seeds=3"], "the code reads a setting of that name when given, "
     "maybe for another experiment (docs/experiments.md lists this one's): if it is this "
     "one's, add it with +n_seeds=VALUE"),
    ("cloth_identify", ["init.seed=1"], "no such key in this experiment's config, nor a "
     "setting its code reads"),
    ("motion_single", ["method.pyramid.refine_pixels=9"],
     "no such key; did you mean method.refine_pixels?"),
    ("motion_single", ["method.sigma.x=2"], "method.sigma is a value (1.5), not a block"),
    ("segment_multi", ["method.pyramid.levels=3"],
     "no such key; did you mean method.pyramid.level_iterations?"),
    ("segment_multi", ["method.nichega.norm_niche_size=0.1"],
     "but a setting the code reads (docs/experiments.md): add it with "
     "+method.nichega.norm_niche_size=VALUE"),
    ("motion_single", ["~mehtod.sigma"], "~mehtod.sigma: no such key to delete; did you mean"),
    ("cloth_identify", ["bounds.k=[1,2]"], "no such key; did you mean bounds.K?"),
    ("segment_multi", ["ea.sigma=4"], "Could not override 'ea.sigma': no such key in this "
     "experiment's config, nor a setting its code reads"),
    ("segment_multi", ["method.sigma=4"], "did you mean method.assign.sigma or method.ea.sigma?"),
    ("motion_accuracy", ["flow.tvl1.attachment=5"], "in a block the code takes whole"),
    ("fig08_mesh", ["zoomm=3"], "did you mean zoom?"),
    ("fig08_mesh", ["limits.max_seconds=-1"], "limits.max_seconds=-1: expected a number > 0"),
    ("fig08_mesh", ["+limits.foo=1"], "limits.foo: unknown limit"),
    ("fig08_mesh", ["data.path=''"], "data.path='': expected a file or folder path"),
    ("cloth_identify", ["budget=abc"], "budget='abc': expected an integer"),
    ("cloth_identify", ["budget=1.5"], "budget=1.5: expected an integer"),
    ("cloth_identify", ["cost.kind=frames"], "cost.kind=frames needs a list"),
    ("cloth_identify", ["bounds.K=[0.1,nan]"], "bounds.K[1]=nan: expected a finite number"),
    ("cloth_identify", ["bounds.K=[0.1,.nan]"], "bounds.K[1]='.nan': expected a number"),
    ("motion_single", ["method.relative_threshold=abc"],
     "method.relative_threshold='abc': expected a number"),
    ("motion_single", ["method.omega_count=1e8"], "method.omega_count=100000000.0"),
    ("motion_single", ["method.omega_count=100000000"], "limits.max_sweep_values"),
    ("motion_single", ["method.sigma=inf"], "method.sigma=inf: expected a finite number"),
    ("motion_single", ["figures=maybe"], "figures='maybe': expected a boolean"),
    ("fig11_reconstruction", ["gif_stride=0"], "gif_stride=0: expected an integer >= 1"),
    ("fig11_reconstruction", ["reconstructions=[{label:a,params:[.nan,1,1,1,1]}]"],
     "reconstructions[0].params[0]"),
    ("fig11_reconstruction", ["visible_error_h=nan"], "expected a finite number"),
    ("fig11_reconstruction", ["frames=[0,5000]"], "expected frame indices"),
    ("segment_multi", ["method.snake.iterations=-1"],
     "method.snake.iterations=-1: expected an integer >= 1"),
    ("segment_multi", ["method.accumulation.cell=-2.0"], "expected a finite number >= 0"),
    ("nope", [], "experiment=nope: unknown experiment"),
    # figure_dir=null drew the default data's figures into the committed figures/
    ("motion_single", ["figure_dir=null"], "figure_dir=null: expected a folder"),
    ("segment_multi", ["figure_dir=null"], "figure_dir=null: expected a folder"),
    ("motion_single", ["data.path=/x/a,b"], "data.path=/x/a,b: a comma makes the value a "
     "list or, with -m, a sweep; for one value with a comma, quote it for Hydra inside the "
     "shell's quotes: \"data.path='/x/a,b'\""),
]


@pytest.mark.parametrize("experiment, overrides, message", CONFIG_CASES,
                         ids=[f"{e}-{'-'.join(o)}" for e, o, _ in CONFIG_CASES])
def test_bad_config_is_refused_before_any_work(tmp_path, capsys, experiment, overrides,
                                               message):
    keys = _output_keys(experiment) if experiment != "nope" else ()
    args = [f"experiment={experiment}", f"out={tmp_path / 'work' / 'out'}",
            *(f"{key}={tmp_path / 'work' / key}" for key in keys), *overrides]
    status, err = replicate(capsys, *args)
    assert_refused(status, err, message, tmp_path)


@pytest.mark.parametrize("out, message", [
    ("out=", "out=: empty"),
    ("out=''", "out=: empty"),
    ("out=results/fig08_mesh", "inside results/"),
    (f"out={ROOT / 'results' / 'x'}", "inside results/"),
    (None, "out=results/fig08_mesh: inside results/"),
    ("out=/proc/forbidden/x", "cannot write there"),
])
def test_out_empty_or_inside_results_is_refused(tmp_path, capsys, monkeypatch, out, message):
    monkeypatch.chdir(tmp_path)
    before = sorted(os.listdir(ROOT / "results"))
    args = ["experiment=fig08_mesh", f"figure_dir={tmp_path / 'fig'}"]
    status, err = replicate(capsys, *args, *([out] if out else []))
    assert_refused(status, err, message, tmp_path)
    assert sorted(os.listdir(ROOT / "results")) == before


@pytest.mark.parametrize("args, message", [
    (["experiment=fig08_mesh", "foo=1,2"], "Could not override 'foo'"),
    (["experiment=cloth_identify", "budgett=1,2"], "did you mean budget?"),
    (["experiment=nope", "seed=0,1"], "experiment=nope: unknown experiment"),
    (["experiment=fig08_mesh", "seed=0,1", "zoom=abc"], "zoom='abc': expected an integer"),
    (["experiment=fig08_mesh", "seed=0,abc"], "seed='abc': expected an integer >= 0"),
])
def test_sweep_refusals_are_one_line(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "-m", *args, f"figure_dir={tmp_path / 'fig'}")
    assert_refused(status, err, message, tmp_path)


def test_no_experiment_is_refused(tmp_path, capsys):
    status, err = replicate(capsys, f"out={tmp_path / 'work'}")
    assert_refused(status, err, "no experiment chosen", tmp_path)


def test_quoted_out_makes_no_stray_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "experiment=fig08_mesh", f"out='{tmp_path / 'q'}'",
                            f"figure_dir={tmp_path / 'fig'}")
    assert status == 0, err
    assert sorted(os.listdir(tmp_path)) == ["fig", "q"]


def test_full_disk_is_one_line_and_nothing_written(tmp_path, capsys, monkeypatch):
    def full(path, payload):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(cli, "write_json_atomic", full)
    status, err = replicate(capsys, *redirected("fig08_mesh", tmp_path / "work"))
    assert_refused(status, err, "no space left on device", tmp_path)


def test_time_limit_is_one_line_and_nothing_written(tmp_path, capsys):
    status, err = replicate(capsys, *redirected("motion_single", tmp_path / "work"),
                            "method.omega_count=4000", "limits.max_seconds=0.3")
    assert_refused(status, err, "limits.max_seconds=0.3: the run took longer", tmp_path)


# ---------------------------------------------------------------- answers' own sanity
def test_meaningless_sequence_gives_warnings_and_strict_refuses(bad, tmp_path, capsys):
    noise = bad / "noise.npz"
    write_sequence_npz(noise, np.random.default_rng(2).random((2, 64, 64)))
    args = [*redirected("motion_single", tmp_path / "work"), f"data.path={noise}",
            "method.omega_count=20"]
    status, err = replicate(capsys, *args, "--strict")
    assert_refused(status, err, "strict=true: ", tmp_path)
    status, err = replicate(capsys, *args)
    assert status == 0, err
    result = json.loads((tmp_path / "work" / "out" / "result.json").read_text())
    assert result["warnings"] and all(f"warning: {w}" in err for w in result["warnings"])
    assert any("pixel(s), fewer than" in w or "edge of the sweep" in w
               for w in result["warnings"])


def test_parameter_at_its_bound_is_a_warning(tmp_path, capsys):
    args = [*redirected("cloth_identify", tmp_path / "work"), "budget=300",
            "bounds.K=[4.5,10.0]"]  # the reference's K is 4
    status, err = replicate(capsys, *args)
    assert status == 0, err
    result = json.loads((tmp_path / "work" / "out" / "result.json").read_text())
    assert any(w.startswith("best.K=") and "lower bound" in w for w in result["warnings"])
    status, err = replicate(capsys, *args, "strict=true", f"out={tmp_path / 'strict'}")
    assert status == 2 and "error: strict=true: best.K=" in err
    assert "warning:" not in err    # the refusal names the warning once
    assert not (tmp_path / "strict").exists()
    # a kept result is refused as a new run would be (resume=true skipped the check)
    status, err = replicate(capsys, *args, "resume=true", "strict=true")
    assert status == 2 and "error: strict=true: best.K=" in err and "up to date" not in err
    status, err = replicate(capsys, *args, "resume=true")
    assert status == 0 and "up to date" in err and "warning: best.K=" in err


# ---------------------------------------------------------------- resume and provenance
def test_resume_reruns_when_the_input_file_changes(tmp_path, capsys):
    data = tmp_path / "traj.npz"
    data.write_bytes(CLOTH_REFERENCE.read_bytes())
    out = tmp_path / "work" / "out"
    out.mkdir(parents=True)
    (out / "result.json").write_text('{"truncated": ')  # unreadable: treated as missing
    args = [*redirected("fig11_reconstruction", tmp_path / "work"), f"data.path={data}",
            "gif_stride=250", "frames=[0,100]", "resume=true"]
    status, err = replicate(capsys, *args)
    assert status == 0 and "treated as missing" in err and "wrote" in err, err
    first = json.loads((out / "result.json").read_text())
    assert first["provenance"]["inputs_sha256"][str(data)]
    status, err = replicate(capsys, *args)
    assert status == 0 and "up to date" in err, err
    data.write_bytes((CLOTH_REFERENCE.parent / "reference_tau0.1.npz").read_bytes())
    status, err = replicate(capsys, *args)
    assert status == 0 and "up to date" not in err and "wrote" in err, err
    second = json.loads((out / "result.json").read_text())
    assert second["provenance"]["inputs_sha256"] != first["provenance"]["inputs_sha256"]


# ---------------------------------------------------------------- replicate-gather
def _result(experiment, value):
    return {"experiment": experiment, "seed": 0, "config": {}, "metric": value}


@pytest.mark.parametrize("content, message", [
    ('{"experiment": "a", "seed": ', "cannot be read as JSON"),
    ("", "cannot be read as JSON"),
    ("[1, 2]", "a JSON list; expected a result.json object"),
    ("null", "a JSON NoneType"),
    (b"\xff\xfe{}", "cannot be read as JSON"),
    (json.dumps(_result("other", 2.0)), "results of 2 experiments"),
])
def test_gather_refuses_bad_or_mixed_results(tmp_path, capsys, content, message):
    sweep_dir = tmp_path / "sweep"
    (sweep_dir / "seed=0").mkdir(parents=True)
    (sweep_dir / "seed=0" / "result.json").write_text(json.dumps(_result("one", 1.0)))
    (sweep_dir / "seed=1").mkdir()
    target = sweep_dir / "seed=1" / "result.json"
    target.write_bytes(content if isinstance(content, bytes) else content.encode())
    before = sorted(p.name for p in sweep_dir.rglob("*"))
    status = sweep.main([str(sweep_dir), "--metric", "metric"])
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and message in errors[0], err
    assert sorted(p.name for p in sweep_dir.rglob("*")) == before


def test_gather_refuses_an_unwritable_output(tmp_path, capsys):
    sweep_dir = tmp_path / "sweep"
    (sweep_dir / "seed=0").mkdir(parents=True)
    (sweep_dir / "seed=0" / "result.json").write_text(json.dumps(_result("one", 1.0)))
    status = sweep.main([str(sweep_dir), "--output", str(tmp_path / "no" / "such" / "x.csv")])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("error: ") and len(err.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["result.json", "seed=0", "sweep"]


# ---------------------------------------------------------------- replicate-all
def test_replicate_all_refuses_a_results_path_that_is_a_file(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert regenerate.main(["--results", str(target), "--only", "fig08_mesh"]) == 2
    assert "error: --results=" in capsys.readouterr().err



@pytest.mark.parametrize("content", ['{"provenance": ', "", "[]", b"\xff\xfe"])
def test_replicate_all_treats_an_unreadable_result_as_missing(tmp_path, capsys, content):
    entries = [entry for entry in experiment_entries() if entry[1] == "fig08_mesh"]
    (tmp_path / "fig08_mesh").mkdir()
    target = tmp_path / "fig08_mesh" / "result.json"
    target.write_bytes(content if isinstance(content, bytes) else content.encode())
    provenance = {"fig08_mesh": {"config_sha256": "c", "code_sha256": "c"}}
    stale = regenerate.stale_experiments(entries, tmp_path, provenance,
                                         {"fig08_mesh": "k"}, {})
    assert stale == {"fig08_mesh"}
    # the command that makes it again where this report reads it (a folder of its own)
    assert (f"Not run yet: `replicate experiment=fig08_mesh out={tmp_path}/fig08_mesh "
            "force=true`") in build_report(tmp_path)
    (tmp_path / regenerate.CACHE_FILE).write_bytes(
        content if isinstance(content, bytes) else content.encode())
    assert regenerate._read_json_object(tmp_path / regenerate.CACHE_FILE) == {}
    assert "treated as missing" in capsys.readouterr().err


def test_replicate_all_passes_force_and_hashes_inputs():
    command = regenerate.replicate_command(Path("results"))("fig11_reconstruction")
    assert "force=true" in command
    configs = regenerate.resolved_configs(["fig11_reconstruction"])
    entries = [e for e in experiment_entries() if e[1] == "fig11_reconstruction"]
    provenance, _ = regenerate.experiment_keys(entries, configs)
    inputs = provenance["fig11_reconstruction"]["inputs_sha256"]
    assert inputs == {"synthetic_data/cloth/reference_tau0.5.npz": json.loads(
        (ROOT / "synthetic_data/cloth/manifest.json").read_text())["files"][
            "reference_tau0.5.npz"]}


# ---------------------------------------------------------------- Ctrl-C (a real process)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_or_sigterm_during_the_sweep_exits_130_and_writes_nothing(tmp_path, signum):
    from scipy import ndimage

    rng = np.random.default_rng(0)
    first = ndimage.gaussian_filter(rng.random((384, 384)), 2)
    second = ndimage.rotate(first, 1.0, reshape=False, mode="nearest")
    data = tmp_path / "seq.npz"
    write_sequence_npz(data, np.stack([first, second]))
    work = tmp_path / "work"
    command = [sys.executable, "-m", "replication.cli", "experiment=motion_single",
               f"data.path={data}", f"out={work / 'out'}", "method.omega_count=20000"]
    # SIGINT as in a terminal: a shell starts background jobs (`pytest ... &`, nohup) with
    # SIGINT ignored, their children inherit that, and Python then installs no handler
    process = subprocess.Popen(command, cwd=ROOT, stderr=subprocess.PIPE, text=True,
                               env=dict(os.environ, PYTHONPATH=str(ROOT)),
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60
        while not (work / "out").exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        # inside the sweep (20000 omegas: minutes); 2 s after the folder appeared, a slow
        # machine was still importing, where a signal's exception can be lost (CI, stop 38)
        time.sleep(5.0)
        process.send_signal(signum)
        _, err = process.communicate(timeout=60)
    finally:  # a run that ignored the signal must not go on using a CPU after the test
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 130, err
    assert "Traceback" not in err and "error: interrupted" in err
    assert sorted(os.listdir(tmp_path)) == ["seq.npz"]


def test_interrupt_after_a_figure_leaves_no_figure_and_no_result(tmp_path, monkeypatch):
    """Ctrl-C in fig11_reconstruction after its PNG is drawn, before the GIF: the staged PNG
    is removed with the rest (run_experiment itself; ``main`` would then exit 130)."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from replication.figures import fig11_reconstruction as figure

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(figure, "animate", interrupted)
    work = tmp_path / "work"
    with initialize_config_dir(config_dir=cli.CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[
            "experiment=fig11_reconstruction", f"out={work / 'out'}",
            f"figure_dir={work / 'fig'}", "gif_stride=250", "frames=[0,100]"])
        config = OmegaConf.to_container(cfg, resolve=True)
        with pytest.raises(KeyboardInterrupt):
            cli.run_experiment(config, config["out"])
    assert sorted(os.listdir(tmp_path)) == []


def test_replicate_all_refuses_an_empty_or_outside_only(capsys):
    """`--only ''` ran every experiment; `--only cloth_baselines` called a real experiment
    unknown."""
    assert regenerate.main(["--only", ""]) == 2
    assert "no experiment named" in capsys.readouterr().err
    assert regenerate.main(["--only", "cloth_baselines"]) == 2
    assert "not part of replicate-all (no report block" in capsys.readouterr().err


def test_empty_output_folder_is_refused(tmp_path, capsys, monkeypatch):
    """``figure_dir=`` (empty) would write the figures into the working directory."""
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "experiment=fig08_mesh", "figure_dir=",
                            f"out={tmp_path / 'out'}")
    assert_refused(status, err, "figure_dir=: empty", tmp_path)


def test_hydra_run_dir_is_the_output_folder_without_out(tmp_path, capsys):
    run_dir = tmp_path / "run"
    status, err = replicate(capsys, "experiment=fig08_mesh", f"hydra.run.dir={run_dir}",
                            "--quiet")
    assert status == 0, err
    assert (run_dir / "result.json").is_file()


@pytest.mark.parametrize("value", ["bogus", "BAR", " plain"])
def test_a_misspelt_progress_environment_variable_is_refused(tmp_path, capsys, monkeypatch,
                                                             value):
    monkeypatch.setenv("REPLICATION_PROGRESS", value)
    status, err = replicate(capsys, "experiment=fig08_mesh", f"out={tmp_path / 'out'}")
    assert_refused(status, err, "REPLICATION_PROGRESS=", tmp_path)


@pytest.mark.parametrize("args, message", [
    (["hydra.sweep.dir="], "hydra.sweep.dir=: empty"),
    (["hydra/launcher=joblib", "hydra.launcher.n_jobs=0"], "hydra.launcher.n_jobs=0"),
    (["out=o/x"], "out=o/x in a sweep"),
])
def test_sweep_settings_that_cannot_work_are_refused_before_any_job(tmp_path, capsys,
                                                                    monkeypatch, args,
                                                                    message):
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "-m", "experiment=fig08_mesh", "zoom=3,4",
                            f"figure_dir={tmp_path / 'fig'}", *args)
    assert_refused(status, err, message, tmp_path)


def test_a_job_folder_name_too_long_is_refused_before_any_job(tmp_path, capsys, monkeypatch):
    """Each ``/`` of a swept path is ``%2F`` in the job folder's name, which file systems
    limit to 255 bytes (``OSError: File name too long`` after the jobs before it ran)."""
    long = tmp_path / ("a" * 120) / ("b" * 120)
    long.mkdir(parents=True)
    shutil.copy(ROOT / "synthetic_data" / "cloth" / "reference_tau0.5.npz", long / "r.npz")
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    status, err = replicate(capsys, "-m", "experiment=cloth_identify",
                            f"data.path={long / 'r.npz'},{long / 'r.npz'}x")
    assert_refused(status, err, "more than file systems take (255)", work)


def test_a_shared_figure_folder_in_a_sweep_is_noted(tmp_path, capsys):
    compose = cli.compose_first_job
    compose(["experiment=fig08_mesh", "zoom=3,4", f"figure_dir={tmp_path / 'f'}"])
    assert "note: figure_dir=" in capsys.readouterr().err
    compose(["experiment=fig08_mesh", "zoom=3", f"figure_dir={tmp_path / 'f'}"])
    compose(["experiment=fig08_mesh", "zoom=3,4", f"figure_dir={tmp_path}/" + "${zoom}"])
    assert "note:" not in capsys.readouterr().err


def test_refusals_noted_by_workers_are_read_once(tmp_path):
    folder = tmp_path / ".refused-abc"
    folder.mkdir()
    for job in (1, 0):
        (folder / f"{job}.json").write_text(json.dumps({"job": job, "overrides": f"seed={job}",
                                                        "message": f"m{job}"}))
    assert [item["message"] for item in cli._refused_jobs(folder)] == ["m0", "m1"]
    assert not folder.exists()
    assert cli._refused_jobs(folder) == []


def test_an_interrupted_sweep_loses_only_what_its_stopped_jobs_left(tmp_path, monkeypatch):
    """Only this sweep's staging folders (named with its id) and the job folders they
    leave empty go; finished jobs and another sweep's running job stay."""
    monkeypatch.setenv(cli.SWEEP_ENVIRONMENT, json.dumps({"id": "abc12345", "refused": "x"}))
    (tmp_path / "seed=0").mkdir()
    (tmp_path / "seed=0" / "result.json").write_text("{}")
    (tmp_path / "seed=1").mkdir()
    (tmp_path / ".seed=1.partial-abc12345q7" / "out").mkdir(parents=True)
    (tmp_path / "seed=2").mkdir()
    (tmp_path / ".seed=2.partial-other123zz" / "out").mkdir(parents=True)
    cli._drop_partial_jobs(tmp_path)
    assert sorted(os.listdir(tmp_path)) == [".seed=2.partial-other123zz", "seed=0", "seed=2"]


def test_a_deleted_output_key_in_a_sweep_is_no_traceback(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "-m", "experiment=fig08_mesh", "zoom=3,4", "~out")
    assert "Traceback" not in err and status == 2 and err.startswith("error: "), err


def test_a_value_hydra_cannot_read_unquoted_gets_the_quoted_spelling(tmp_path, capsys,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "experiment=fig08_mesh", f"out={tmp_path}/\u00e9")
    assert_refused(status, err, f"quote it: out='{tmp_path}/\u00e9'", tmp_path)


def test_the_quoted_spelling_of_a_sweep_quotes_each_value(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, err = replicate(capsys, "-m", "experiment=fig08_mesh", "zoom=3,4",
                            "out=a\u00e9,b")
    assert_refused(status, err, "quote it: out='a\u00e9','b' (each value", tmp_path)
