"""The package's layout (issue 16): no import circles, libraries never import runners or
report sections, no folder crowded with one name prefix."""

from __future__ import annotations

import collections

from replication.provenance import PACKAGE_DIR, PROJECT_ROOT, imported_modules


def _modules():
    """``{module name: path}`` of every module of the package."""
    found = {}
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        parts = path.relative_to(PROJECT_ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


def _imports(path, name):
    """Package modules imported anywhere in ``path`` (the closure's own reading), itself
    excluded."""
    return imported_modules(path, name) - {name}


def _graph():
    modules = _modules()
    return {name: _imports(path, name) for name, path in modules.items()}


def _cycles(graph):
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_circles():
    # a package's __init__ re-exporting its modules is not a circle: a module of the
    # package importing the package's name would be, and is counted
    graph = {name: {m for m in targets if not name.startswith(m + ".")}
             for name, targets in _graph().items()}
    assert _cycles(graph) == []


def test_the_circle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_libraries_import_no_runner_and_no_report_section():
    libraries = ("replication.cloth", "replication.motion", "replication.discrepancy",
                 "replication.optim", "replication.figures", "replication.testdata")
    upward = ("replication.experiments", "replication.report")
    wrong = {name: sorted(m for m in targets if m.startswith(upward))
             for name, targets in _graph().items() if name.startswith(libraries)}
    assert {name: found for name, found in wrong.items() if found} == {}


def test_runners_do_not_import_report_sections():
    wrong = {name: sorted(m for m in targets if m.startswith("replication.report"))
             for name, targets in _graph().items()
             if name.startswith("replication.experiments")}
    assert {name: found for name, found in wrong.items() if found} == {}


def test_no_folder_crowded_with_one_prefix():
    crowded = {}
    for folder in [PACKAGE_DIR, *(p for p in PACKAGE_DIR.rglob("*") if p.is_dir())]:
        prefixes = collections.Counter(p.stem.split("_")[0] for p in folder.glob("*.py")
                                       if p.stem != "__init__")
        crowded.update({f"{folder.relative_to(PROJECT_ROOT)}/{prefix}_*": count
                        for prefix, count in prefixes.items() if count > 5})
    assert crowded == {}


def _experiment_runners():
    from hydra import compose, initialize_config_dir

    from replication.cli import CONFIG_DIR, available_experiments

    runners = {}
    for name in available_experiments():
        with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
            runners[name] = compose(config_name="config",
                                    overrides=[f"experiment={name}"]).runner
    return runners


def test_a_figure_change_makes_only_the_experiments_that_draw_it_stale():
    """A figure module is in the code hash of an experiment only when the experiment's
    runner draws it (its function reaches the figure's ``draw``), not because the runner
    imports a sibling runner module that draws it. The figures that several experiments
    draw (shared helpers, the sensitivity and growth plots, the style) are listed."""
    from replication.provenance import CORE_MODULES, module_closure, runner_parts

    shared = {"__init__.py", "style.py", "cloth_common.py", "sensitivity.py", "growth.py",
              "discrepancy_where.py", "cloth_baselines_ecdf.py",
              "discrepancy_outside.py"}   # the outside study and its wide variant
    users = {}
    for name, runner in _experiment_runners().items():
        _, roots = runner_parts(runner)
        parts = runner.partition(":")[0].split(".")
        roots += [".".join(parts[:i]) for i in range(1, len(parts))]
        for path in module_closure([*roots, *CORE_MODULES]):
            if path.parent.name == "figures" and path.name not in shared:
                users.setdefault(path.name, []).append(name)
    several = {figure: names for figure, names in users.items() if len(names) > 1}
    assert several == {}
    assert users["fig05_discs.py"] == ["segment_multi"]
    assert users["fig01_flow.py"] == ["motion_single"]
