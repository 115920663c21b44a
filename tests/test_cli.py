"""The real command line, configs and result.json (docs/results.md)."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from replication.cli import CONFIG_DIR, available_experiments
from replication.errors import InputError
from replication.report.build import build_report, experiment_entries

ROOT = Path(__file__).resolve().parent.parent


def run_cli(*overrides, cwd=ROOT):
    command = [sys.executable, "-m", "replication.cli", *overrides]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=env,
                          timeout=300)


@pytest.mark.parametrize("name", available_experiments())
def test_every_experiment_config_composes(name):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"experiment={name}"])
    assert cfg.name == name, "experiment configs must set name to their file name"
    module, _, function = cfg.runner.partition(":")
    assert callable(getattr(__import__(module, fromlist=[function]), function))


def test_reference_run_through_real_command_line(tmp_path):
    out = tmp_path / "out"
    done = run_cli("experiment=cloth_reference", f"out={out}", f"data_dir={tmp_path / 'data'}",
                   "n_steps=160")
    assert done.returncode == 0, done.stderr
    result = json.loads((out / "result.json").read_text())
    for key in ("experiment", "config", "seed", "versions", "wall_seconds", "provenance"):
        assert key in result
    assert result["experiment"] == "cloth_reference"
    assert result["config"]["n_steps"] == 160
    manifest = json.loads((tmp_path / "data" / "manifest.json").read_text())
    assert set(manifest["files"]) == {"reference_tau0.1.npz", "reference_tau0.5.npz"}
    # same config, same numbers and same bytes
    again = run_cli("experiment=cloth_reference", f"out={tmp_path / 'again'}",
                    f"data_dir={tmp_path / 'data2'}", "n_steps=160")
    assert again.returncode == 0, again.stderr
    second = json.loads((tmp_path / "data2" / "manifest.json").read_text())
    assert second["files"] == manifest["files"]
    assert json.loads((tmp_path / "again" / "result.json").read_text())["costs_at_truth"] \
        == result["costs_at_truth"]


def assert_regenerated_identically(experiment, data_dir, tmp_path):
    """``experiment`` writes into a fresh ``data_dir`` the files (by sha256) that its
    committed ``data_dir/manifest.json`` lists."""
    committed = json.loads((ROOT / data_dir / "manifest.json").read_text())
    done = run_cli(f"experiment={experiment}", f"out={tmp_path / 'out'}",
                   f"data_dir={tmp_path / 'data'}")
    assert done.returncode == 0, done.stderr
    fresh = json.loads((tmp_path / "data" / "manifest.json").read_text())
    assert fresh["files"] == committed["files"]


def test_committed_reference_data_is_regenerated_identically(tmp_path):
    assert_regenerated_identically("cloth_reference", "synthetic_data/cloth", tmp_path)


@pytest.mark.parametrize("overrides, message", [
    (["taus=[]"], "taus: expected at least one value"),
    (["n_steps=1"], "n_steps=1: expected at least 2 steps"),
    (["scene.n=2"], "scene.n=2: expected at least 3 particles per side"),
    (["K=-1.0"], "K=-1.0: expected a stiffness > 0"),
    (["scene.mass=-1.0"], "scene.mass=-1.0: expected > 0"),
    (["scene.dt=1.0", "n_steps=200"], "scene.dt=1.0: the run with tau=0.1 blew up"),
    (["out=/proc/forbidden/x"], "cannot write there"),
    ([], "no experiment chosen"),
])
def test_bad_config_gives_one_line_and_no_result(tmp_path, overrides, message):
    args = list(overrides)
    if args != []:
        args = ["experiment=cloth_reference", f"data_dir={tmp_path / 'data'}", *args]
    if not any(a.startswith("out=") for a in args):
        args.append(f"out={tmp_path / 'out'}")
    done = run_cli(*args)
    assert done.returncode == 2
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert lines == [lines[0]] and lines[0].startswith("error: ") and message in lines[0]
    assert not (tmp_path / "out" / "result.json").exists()
    assert not (tmp_path / "data").exists()


def test_bad_data_file_gives_one_line(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    done = run_cli("experiment=fig11_reconstruction", f"data.path={bad}",
                   f"out={tmp_path / 'out'}")
    assert done.returncode == 2
    assert done.stderr.strip().startswith(f"error: {bad}: cannot be read as .npz")
    assert not (tmp_path / "out" / "result.json").exists()


def test_report_lists_every_reported_experiment(tmp_path):
    text = build_report(tmp_path)  # no results: every section says how to make it
    assert f"from the results in `{tmp_path}/`" in text   # the folder it was built from
    assert f"`replicate experiment=fig08_mesh out={tmp_path}/fig08_mesh force=true`" in text
    for _, name, _ in experiment_entries():
        assert f"replicate experiment={name}" in text


def _settings(name):
    from replication.cli import _experiment_config, code_settings

    config = _experiment_config([f"experiment={name}"])
    return config, code_settings(config["runner"])


def test_an_added_key_the_experiment_does_not_hold_is_noted_and_a_known_one_is_not():
    from replication.cli import CodeSettings, unread_added_keys

    defaults = {"budget": 2000, "cost": {"kind": "small", "frame": 150}, "data": {"path": None}}
    overrides = ["+budgett=300", "+cost.frame=10", "+cost.start=5", "+smoke=cloth_ci",
                 "+hydra.launcher.x=1", "budget=10", "+data.path=x", "++hydrate=1",
                 "+cost.framez=3"]
    nothing = CodeSettings()
    assert unread_added_keys(overrides, defaults, nothing) == [
        "+budgett", "+cost.start", "++hydrate", "+cost.framez"]
    # settings the code reads from the block when given (cost_from_config's cost_cfg.get)
    config, settings = _settings("cloth_identify")
    assert unread_added_keys(overrides, defaults, settings) == [
        "+budgett", "++hydrate", "+cost.framez"]
    # by the block the code reads a name from: seed is read, but not from init or cost
    assert unread_added_keys(["+cost.frames=[1]", "+cost.window=3", "+init.seed=1",
                              "+cost.seed=1", "+data.seed=1"], config, settings) == [
        "+init.seed", "+cost.seed", "+data.seed"]


def test_added_settings_merged_from_the_codes_defaults_go_by_block():
    from replication.cli import unread_added_keys

    # motion_single's method block is merged over motion.single.DEFAULTS
    config, settings = _settings("motion_single")
    assert unread_added_keys(["+method.tukey_c=0.2", "+method.pyramid.refine_pixels=9",
                              "+methods.sigma=2", "+report.sigma=1", "+budget=5"],
                             config, settings) == [
        "+method.pyramid.refine_pixels", "+methods.sigma", "+report.sigma", "+budget"]
    # the segmentation's method block holds groups (pipeline.GROUPS), each over its own
    # defaults; nichega is read with method.pop and merged over NICHEGA_DEFAULTS
    config, settings = _settings("segment_multi")
    assert unread_added_keys(["+method.pyramid.refine_pixels=9", "+method.pyramid.bogus=1",
                              "+method.nichega.norm_niche_size=0.1", "+method.tukey_c=1"],
                             config, settings) == ["+method.pyramid.bogus",
                                                   "+method.tukey_c"]
    # groups only inside their block, not at the top level
    assert unread_added_keys(["+pyramid.enabled=true", "+ea.sigma=4"], config, settings) == [
        "+pyramid.enabled", "+ea.sigma"]


@pytest.mark.parametrize("name, keys", [
    ("table1_2", ["+references.copy=x.npz"]),           # iterated: config["references"].items()
    ("motion_data", ["+sequences.new.role=accuracy"]),
    ("motion_accuracy", ["+flow.tvl1.attachment=5"]),   # passed on as flow_options, unpacked
    ("motion_accuracy", ["+flow.cache_dir=x"]),         # read in the runner's own module
    ("discrepancy", ["+figures_dir=x"]),
])
def test_added_keys_of_blocks_the_code_takes_whole_get_no_note(name, keys):
    from replication.cli import unread_added_keys

    config, settings = _settings(name)
    assert unread_added_keys(keys, config, settings) == []


def test_a_setting_the_config_leaves_out_is_refused_with_the_plus_spelling(tmp_path):
    done = run_cli("experiment=segment_multi", "method.pyramid.refine_pixels=20000",
                   f"out={tmp_path / 'out'}")
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "a setting the code reads" in done.stderr
    assert "+method.pyramid.refine_pixels=VALUE" in done.stderr


def test_an_unknown_config_group_option_lists_the_options():
    done = run_cli("experiment=fig08_mesh", "+smoke=nope")
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "available options in 'smoke': bench_cloth, " in done.stderr
    assert "fig08_mesh" in done.stderr


def test_a_run_with_out_leaves_the_committed_figures_and_data_alone(tmp_path):
    """An audit's first commands (`+smoke=NAME out=DIR`) replaced the committed figures and
    reference runs, and replicate-all then called them up to date."""
    committed = ROOT / "figures" / "fig08_mesh.png"
    before = committed.read_bytes()
    out = tmp_path / "out"
    done = run_cli("experiment=fig08_mesh", "+smoke=fig08_mesh", f"out={out}")
    assert done.returncode == 0, done.stderr
    assert committed.read_bytes() == before
    assert (out / "figures" / "fig08_mesh.png").is_file()
    assert "note: figure_dir=figures is in the committed figures/" in done.stderr
    result = json.loads((out / "result.json").read_text())
    assert result["config"]["figure_dir"] == str(out / "figures")
    assert all(str(out) in path for path in result["figures"])
    # a file key with a folder (discrepancy_blind's figure and manifest) moves as well
    config = {"figure": "figures/x.png", "manifest": "synthetic_data/y/m.json",
              "figure_dir": str(tmp_path / "mine"), "data_dir": None}
    from replication.cli import keep_committed
    kept, notes = keep_committed(config, out)
    assert kept["figure"] == str(out / "x.png") and kept["manifest"] == str(out / "m.json")
    assert kept["figure_dir"] == str(tmp_path / "mine")
    assert [moved for moved, _ in notes] == [out / "x.png", out / "m.json"]
    assert keep_committed(dict(config, force=True), out) == (dict(config, force=True), [])


@pytest.mark.parametrize("args, message", [
    (["experiment=cloth_identify", "seed=0,1", "out=o/same"],
     "out=o/same in a sweep: every job would write that folder"),
    (["hydra/launcher=lokal", "experiment=fig08_mesh"],
     "available options in 'hydra/launcher': basic, dask"),
    (["hydra/launcher=dask", "hydra.launcher.n_worker=3", "experiment=fig08_mesh"],
     "Could not override 'hydra.launcher.n_worker'"),
    (["experiment=fig08_mesh,cloth_identify", "figure_dir=o/f"],
     "figure_dir: a sweep over experiments can set only the keys every experiment shares"),
])
def test_sweep_refusals_come_before_any_job(args, message):
    """Outside users' sweeps: a fixed out kept only the last job; a misspelt launcher or
    launcher key, and an experiment-specific key in a sweep over experiments, gave Hydra's
    multi-line message with status 1."""
    from replication.cli import compose_first_job

    with pytest.raises(InputError, match=re.escape(message)):
        compose_first_job(args)


def test_sweeps_hydra_runs_pass_the_sweep_checks():
    """The other side of the refusals above: sweeps Hydra runs (a reviewer's list): an out
    per job or none, one job, a swept key in a sweep over experiments, a list index."""
    from replication.cli import compose_first_job

    for legit in (["experiment=cloth_identify", "seed=0,1", "out=o/a,o/b"],
                  ["experiment=cloth_identify", "seed=0,1", "out=null"],
                  ["experiment=cloth_identify", "seed=0,1", "out=o/${seed}"],
                  ["experiment=fig08_mesh", "out=o/d"],
                  ["experiment=fig08_mesh,cloth_identify", "seed=3"],
                  ["experiment=cloth_identify,cloth_identify_18", "budget=300,600"],
                  ["experiment=cloth_reference", "taus.0=0.3,0.4"]):
        compose_first_job(legit)


def test_a_sweep_over_experiments_into_one_folder_is_refused(tmp_path):
    """An outside user's experiment=cloth_identify,cloth_ci seed=0,1 into one
    hydra.sweep.dir wrote seed=0/ twice: job folders leave the experiment out, and only
    cloth_ci's results stayed."""
    from replication.cli import compose_first_job

    with pytest.raises(InputError, match="experiment swept into one folder"):
        compose_first_job(["experiment=cloth_identify,cloth_ci", "seed=0,1",
                           f"hydra.sweep.dir={tmp_path}"])
    # the default sweep folder is one per experiment; job folders by number are distinct
    compose_first_job(["experiment=cloth_identify,cloth_ci", "seed=0,1"])
    compose_first_job(["experiment=cloth_identify,cloth_ci", "seed=0,1",
                       f"hydra.sweep.dir={tmp_path}", "++hydra.sweep.subdir=${hydra.job.num}"])
    # an out per job that does not depend on the experiment: both write one out
    with pytest.raises(InputError, match=re.escape(
            f"experiment swept into out={tmp_path}/0 for both")):
        compose_first_job(["experiment=fig08_mesh,cloth_reference", f"out={tmp_path}/${{seed}}"])
    compose_first_job(["experiment=fig08_mesh,cloth_reference", f"out={tmp_path}/${{name}}"])
    assert os.listdir(tmp_path) == []


def test_a_sweep_over_experiments_records_itself_in_each_experiments_folder(tmp_path):
    """experiment=fig08_mesh,cloth_reference wrote its multirun.yaml to multirun/None/ (the
    sweep's own config names no experiment), and replicate-gather of each experiment's
    folder could not tell a job missing. Each folder now holds it, and None/ is gone."""
    done = run_cli("-m", "experiment=fig08_mesh,cloth_reference", "seed=3,4", "--quiet",
                   f"hydra.sweep.dir={tmp_path}/" + "${name}")
    assert done.returncode == 0, done.stderr[-3000:]
    assert sorted(os.listdir(tmp_path)) == ["cloth_reference", "fig08_mesh"]
    for name in ("cloth_reference", "fig08_mesh"):
        assert (tmp_path / name / "multirun.yaml").is_file()
    shutil.rmtree(tmp_path / "cloth_reference" / "seed=4")
    from replication.sweep import sweep_warnings

    assert "1 of the 2 jobs of the last sweep" in " ".join(
        sweep_warnings(tmp_path / "cloth_reference", ["seed=3"]))


def test_a_sweep_moves_only_its_own_record(tmp_path):
    """A sweep over experiments started while another runs writes multirun/None/multirun.yaml
    again: each sweep moves only the record of its own overrides."""
    from omegaconf import OmegaConf

    from replication.cli import _place_sweep_record

    record, folders = tmp_path / "None", [str(tmp_path / "a"), str(tmp_path / "b")]
    for folder in [record, *folders]:
        Path(folder).mkdir()
    OmegaConf.save({"hydra": {"overrides": {"task": ["experiment=a,b", "seed=1,2"]}}},
                   record / "multirun.yaml")
    _place_sweep_record(folders, str(record), ["experiment=a,b", "seed=3,4"])
    assert (record / "multirun.yaml").is_file() and not (tmp_path / "a" / "multirun.yaml").exists()
    _place_sweep_record(folders, str(record), ["experiment=a,b", "seed=1,2"])
    assert not record.exists()
    assert all((Path(folder) / "multirun.yaml").is_file() for folder in folders)


def test_two_experiments_without_a_sweep_are_one_line():
    done = run_cli("experiment=fig08_mesh,cloth_ci")
    assert done.returncode == 2 and done.stderr == (
        "error: experiment=fig08_mesh,cloth_ci: experiment takes one option per run; for a "
        "sweep over them: replicate -m experiment=fig08_mesh,cloth_ci\n")


def test_glob_of_files_gets_a_hint():
    from replication.cli import compose_first_job

    with pytest.raises(InputError, match="not files: list the files instead"):
        compose_first_job(["experiment=cloth_identify", "data.path=glob(x/*.npz)"])


def test_help_names_the_suites_own_options():
    done = run_cli("--help")
    assert done.returncode == 0
    for option in ("--strict", "--quiet", "--progress=MODE", "docs/experiments.md"):
        assert option in done.stdout


@pytest.mark.parametrize("args, message", [
    (["--cfg", "jobs"], "argument --cfg/-c: invalid choice: 'jobs'"),
    (["--info", "experiment=fig08_mesh"], "argument --info/-i: invalid choice"),
    (["--conf", "x"], "ambiguous option: --conf could match"),
    (["-p"], "argument --package/-p: expected one argument"),
    (["--progress"], "--progress needs a value"),
    (["-m", "seed=0,1"], "seed=0,1: overrides split by one of Hydra's options"),
    (["-m", "--cfg", "job"], "--multirun and --cfg: Hydra takes one of them at a time"),
    (["-p", "seed=1"], "--package took seed=1 as its value"),
    (["mehtod.sigma=1", "--cfg", "job"], "Could not override 'mehtod.sigma'"),
    # values Hydra would refuse with several lines or a traceback
    (["--config-name=x"], "--config-name=x: no such config in "),
    (["--config-dir=/no/such/dir"], "--config-dir=/no/such/dir: no such folder"),
    (["--config-path=/no/such/dir"], "--config-path=/no/such/dir: no such folder"),
    (["--shell-completion"], "--shell-completion needs one of install=SHELL"),
    (["--experimental-rerun", "nope.pickle"], "--experimental-rerun nope.pickle: no such file"),
])
def test_options_argparse_refuses_are_one_line(tmp_path, args, message):
    done = run_cli("experiment=fig08_mesh", *args, cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("error: " + message), done.stderr
    assert os.listdir(tmp_path) == []


def test_an_abbreviated_multirun_is_a_sweep(tmp_path):
    # argparse takes --mult for --multirun: it gets the sweep's checks (a fixed out)
    done = run_cli("--mult", "experiment=fig08_mesh", f"out={tmp_path / 'o'}", "seed=0,1",
                   cwd=tmp_path)
    assert done.returncode == 2 and "in a sweep: every job would write" in done.stderr
    assert os.listdir(tmp_path) == []


def test_an_unknown_option_is_one_line_with_the_close_one():
    done = run_cli("experiment=fig08_mesh", "--strictt")
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("error: unknown option(s) --strictt")
    assert "did you mean --strict?" in done.stderr


def test_a_figure_dir_that_got_no_figure_is_noted(tmp_path, capsys):
    """An outside user's figure_dir= with data.path was ignored silently (a user's
    sequence draws its figures in out/figures)."""
    from replication.cli import _note_unused_figure_dir

    result = {"figures": [str(tmp_path / "out" / "figures" / "fig01.png")]}
    defaults = {"figure_dir": "figures"}
    _note_unused_figure_dir({"figure_dir": str(tmp_path / "mine")}, defaults, result,
                            {tmp_path / "out" / "figures", tmp_path / "out"})
    err = capsys.readouterr().err
    assert err.startswith(f"note: figure_dir={tmp_path / 'mine'} got no figure: this run drew "
                          f"them in {tmp_path / 'out' / 'figures'}")
    # figures drawn there, or figure_dir as the experiment's own: no note
    _note_unused_figure_dir({"figure_dir": str(tmp_path / "mine")}, defaults, result,
                            {tmp_path / "mine"})
    _note_unused_figure_dir({"figure_dir": "figures"}, defaults, result, set())
    assert capsys.readouterr().err == ""
