"""The documentation in docs/ against the repository: the results schema, references that
stay inside the repository, one section per experiment, links that resolve.

``jsonschema`` is not a dependency: the schema is checked with the small validator of
``tests/json_schema_subset.py``, which refuses any keyword it does not implement.
"""

import copy
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.json_schema_subset import errors, validate

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
SCHEMA = json.loads((DOCS / "result.schema.json").read_text())
RESULTS = sorted((ROOT / "results").glob("*/result.json"))
EXPERIMENTS = sorted(p.stem for p in (ROOT / "configs" / "experiment").glob("*.yaml"))


def test_there_are_committed_results():
    assert RESULTS, "no results/*/result.json found"


@pytest.mark.parametrize("path", RESULTS, ids=lambda p: p.parent.name)
def test_committed_result_matches_the_schema(path):
    validate(json.loads(path.read_text()), SCHEMA)


@pytest.mark.parametrize("experiment, key", [
    ("motion_single", "irc"), ("segment_multi", "objects"), ("cloth_identify", "best"),
    ("cloth_identify_18", "population"), ("bench_cloth", "metrics"),
    ("discrepancy_example", "gap_after"), ("fig08_mesh", "provenance"),
])
def test_schema_refuses_a_result_without_a_key_of_its_kind(experiment, key):
    result = json.loads((ROOT / "results" / experiment / "result.json").read_text())
    del result[key]
    assert any(repr(key) in message for message in errors(result, SCHEMA))


def test_schema_checks_nested_values():
    result = json.loads((ROOT / "results" / "cloth_identify_18" / "result.json").read_text())
    bad = copy.deepcopy(result)
    bad["best"]["rest"] = bad["best"]["rest"][:5]
    assert errors(bad, SCHEMA)
    bad = copy.deepcopy(result)
    bad["best"]["cost"] = "inf"   # non-finite numbers are written as strings
    assert not errors(bad, SCHEMA)
    bad["best"]["cost"] = "large"
    assert errors(bad, SCHEMA)


def test_every_kind_in_the_schema_names_existing_experiments():
    for rule in SCHEMA["allOf"]:
        for name in rule["if"]["properties"]["experiment"]["enum"]:
            assert name in EXPERIMENTS, f"{name}: no configs/experiment/{name}.yaml"


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                    reason="needs git and a git checkout")
def test_nothing_points_outside_the_repository():
    command = ["git", "grep", "-n", "shared/", "--", "*.py", "*.md", "*.yaml", ":!tests"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 1 and not done.stdout, (
        "references to a folder outside the repository (use docs/...):\n" + done.stdout)


def _documented_experiments():
    text = (DOCS / "experiments.md").read_text()
    return re.findall(r"^### `([A-Za-z0-9_]+)`", text, flags=re.MULTILINE)


def test_every_experiment_has_a_section_in_docs():
    documented = _documented_experiments()
    missing = sorted(set(EXPERIMENTS) - set(documented))
    assert not missing, f"docs/experiments.md has no '### `NAME`' section for {missing}"


def test_every_documented_experiment_exists_once():
    documented = _documented_experiments()
    assert sorted(set(documented) - set(EXPERIMENTS)) == []
    assert len(documented) == len(set(documented))


@pytest.mark.parametrize("page", ["README.md", *sorted(
    str(p.relative_to(ROOT)) for p in DOCS.glob("*.md"))])
def test_relative_links_resolve(page):
    path = ROOT / page
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", path.read_text()):
        if re.match(r"[a-z]+://", target):
            continue
        assert (path.parent / target).exists(), f"{page}: link to {target} does not resolve"
