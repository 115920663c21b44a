"""Config groups (issue 16): a block several experiments share lives once, in its group;
an experiment that takes the group holds only what differs from it."""

from __future__ import annotations

import pytest
from omegaconf import OmegaConf

from replication.provenance import PROJECT_ROOT
from replication.regenerate import resolved_configs

CONFIGS = PROJECT_ROOT / "configs"
GROUPS = {"segment_method": "method", "paper_ea": "ea", "structured": "structured"}


def _leaves(node, prefix=()):
    """``{path: value}`` of the leaves of a plain dict."""
    if not isinstance(node, dict):
        return {prefix: node}
    out = {}
    for key, value in node.items():
        out.update(_leaves(value, (*prefix, key)))
    return out


def _users(group):
    """``{experiment: option}`` of the experiment configs that take ``group``."""
    found = {}
    for path in sorted((CONFIGS / "experiment").glob("*.yaml")):
        raw = OmegaConf.to_container(OmegaConf.load(path))
        for entry in raw.get("defaults") or []:
            if isinstance(entry, dict):
                for key, option in entry.items():
                    if key.lstrip("/").split("@")[0] == group:
                        found[path.stem] = option
    return found


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_experiments_taking_a_group_hold_only_what_differs(group):
    users = _users(group)
    assert users, f"no experiment takes configs/{group}/"
    for name, option in users.items():
        shared = _leaves(OmegaConf.to_container(OmegaConf.load(CONFIGS / group / f"{option}.yaml")))
        raw = OmegaConf.to_container(OmegaConf.load(CONFIGS / "experiment" / f"{name}.yaml"))
        own = _leaves(raw.get(GROUPS[group]) or {})
        repeated = sorted(".".join(p) for p, v in own.items() if shared.get(p, object()) == v)
        assert repeated == [], f"{name} repeats {group}/{option}: {repeated}"


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_the_group_reaches_the_resolved_config(group):
    users = _users(group)
    configs = resolved_configs(sorted(users))
    for name, option in users.items():
        shared = _leaves(OmegaConf.to_container(OmegaConf.load(CONFIGS / group / f"{option}.yaml")))
        raw = OmegaConf.to_container(OmegaConf.load(CONFIGS / "experiment" / f"{name}.yaml"))
        own = _leaves(raw.get(GROUPS[group]) or {})
        resolved = _leaves(configs[name][GROUPS[group]])
        for path, value in shared.items():
            assert resolved[path] == own.get(path, value), (name, path)
