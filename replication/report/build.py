"""REPORT.md, written from results (never by hand).

Every experiment config may carry a ``report`` block: ``part`` (one of :data:`PARTS`),
``order``, ``title`` and ``section`` (``module:function``). The section function receives
the experiment's ``result.json`` as a dict and returns a :class:`Section`: markdown, and
rows for the summary table at the top.
"""

from __future__ import annotations

import argparse
import importlib
import re
from dataclasses import dataclass, field
from pathlib import Path

from omegaconf import OmegaConf

from replication.provenance import PROJECT_ROOT
from replication.results import read_result_or_none

CONFIG_DIR = PROJECT_ROOT / "configs" / "experiment"
# what part of the report an experiment belongs to (its report.part), in report order
PARTS = {"paper": "the paper's figures and tables",
         "baselines": "the baselines on the paper's problems",
         "validation": "validation beyond the paper (outside data, sensitivity, noise, CI)",
         "bench": "benchmarks"}


@dataclass
class SummaryRow:
    """One claim of the paper against this suite's measurement."""

    claim: str
    paper: str
    suite: str
    tolerance: str
    verdict: str  # "replicated", "partly", "not replicated", "beyond the paper"


@dataclass
class Section:
    markdown: str
    summary: list[SummaryRow] = field(default_factory=list)


def experiment_entries(config_dir=CONFIG_DIR):
    """(order, name, report block) for every experiment config with a ``report`` block."""
    entries = []
    for path in sorted(Path(config_dir).glob("*.yaml")):
        config = OmegaConf.to_container(OmegaConf.load(path))
        block = config.get("report")
        if block:
            entries.append((block.get("order", 1000), config.get("name", path.stem), block))
    return sorted(entries, key=lambda entry: (entry[0], entry[1]))


def _call_section(spec, result):
    module_name, _, function_name = spec.partition(":")
    return getattr(importlib.import_module(module_name), function_name)(result)


def command_line(result):
    """The command that made a result (experiment name; overrides are in its config;
    ``force=true`` lets it write into ``results/``)."""
    return f"replicate experiment={result['experiment']} force=true"


def anchor(title):
    """The link target of a REPORT.md heading (GitHub's rule: lower case, punctuation
    dropped, spaces to hyphens)."""
    return "#" + re.sub(r"[^a-z0-9 _-]", "", title.lower()).replace(" ", "-")


def fmt(value, digits=4):
    """Numbers for tables: general format with ``digits`` significant digits.

    Parameters
    ----------
    value : number, str or None
        A string is returned unchanged, ``None`` as ``n/a``.
    digits : int
    """
    if isinstance(value, str):
        return value
    if value is None:
        return "n/a"
    return f"{value:.{digits}g}"


def build_report(results_dir):
    """The text of REPORT.md from the results under ``results_dir``."""
    results_dir = Path(results_dir)
    # the project's own results are named as the repository's readers see them
    shown = ("results" if results_dir.resolve() == (PROJECT_ROOT / "results").resolve()
             else str(results_dir))
    sections, summary, missing, failed = [], [], [], []

    def rerun(name):
        """What makes the result again where this report reads it."""
        return "force=true" if shown == "results" else f"out={shown}/{name} force=true"

    for _, name, block in experiment_entries():
        result = read_result_or_none(results_dir / name)
        heading = f"## {block['title']}\n"
        if result is None:
            missing.append(name)
            sections.append(f"{heading}\nNot run yet: "
                            f"`replicate experiment={name} {rerun(name)}`.\n")
            continue
        try:
            section = _call_section(block["section"], result)
        except Exception as error:  # one broken section must not hide the others
            failed.append(name)
            sections.append(f"{heading}\n**This section could not be written** "
                            f"(`{block['section']}`: {type(error).__name__}: {error}).\n")
            continue
        footer = (f"\n_Made by `{command_line(result)}` in {result['wall_seconds']:.1f} s; "
                  f"config in `{shown}/{name}/result.json`._\n")
        sections.append(heading + "\n" + section.markdown.strip() + "\n" + footer)
        for row in section.summary:
            summary.append((row, name))
    lines = [
        "# Replication report: Louchet, Boccara, Crochemore and Provot (EA'95)",
        "",
        f"Written by `replicate-all` from the results in `{shown}/`; do not edit by hand.",
        "Every number below comes from a run whose resolved config is stored beside it.",
        "",
        "## Summary",
        "",
        "| claim | paper | this suite | tolerance | verdict | command |",
        "|---|---|---|---|---|---|",
    ]
    for row, name in summary:
        lines.append(f"| {row.claim} | {row.paper} | {row.suite} | {row.tolerance} | "
                     f"{row.verdict} | `replicate experiment={name} {rerun(name)}` |")
    if missing:
        lines += ["", "Not run yet: " + ", ".join(f"`{name}`" for name in missing) + "."]
    if failed:
        lines += ["", "Sections that failed: " + ", ".join(f"`{name}`" for name in failed) + "."]
    return "\n".join(lines) + "\n\n" + "\n".join(sections)


def main(argv=None):
    """``python -m replication.report.build [--results DIR] [--output REPORT.md]``."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--results", default="results")
    parser.add_argument("--output", default=str(PROJECT_ROOT / "REPORT.md"))
    args = parser.parse_args(argv)
    text = build_report(args.results)
    Path(args.output).write_text(text)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()


def _meets(value, goal):
    comparison, target = goal
    return value <= target if comparison == "<=" else value >= target


def speed_section(result):
    """The speed summary: every metric gathered by ``replicate experiment=bench``."""
    goals = result.get("goals", {})
    lines = ["| metric | value | goal | met |", "|---|---|---|---|"]
    rows = []
    for name, value in result["metrics"].items():
        goal = goals.get(name)
        if isinstance(value, (int, float)) and goal is not None:
            met = "yes" if _meets(value, goal) else "**no**"
            lines.append(f"| `{name}` | {fmt(value)} | {goal[0]} {fmt(goal[1])} | {met} |")
        else:
            lines.append(f"| `{name}` | {fmt(value)} | | |")
    for name, goal in goals.items():
        value = result["metrics"].get(name)
        if isinstance(value, (int, float)):
            rows.append(SummaryRow(f"speed: `{name}`", "n/a (suite goal)", fmt(value),
                                   f"{goal[0]} {fmt(goal[1])}",
                                   "met" if _meets(value, goal) else "not met"))
    lines += ["", "Figures measured on this project's 2-core machine; the test-suite and "
              "regeneration times come from the last full runs recorded in `results/`."]
    sources = result.get("sources", {})
    lines += _reference_lines(result["metrics"].get("machine_reference_seconds"), sources)
    lines += _regeneration_lines(sources.get("last_full_regeneration"))
    lines += _bound_lines(sources.get("last_full_regeneration"), sources.get("time_split"))
    lines += _part_lines(sources.get("last_full_regeneration"), sources)
    return Section("\n".join(lines), rows)


def _bound_lines(record, split):
    """The regeneration's lower bound if the baselines' optimisers' own code took no time."""
    if not record or not split or not record.get("cpu_count"):
        return []
    cpu = record.get("cpu_seconds", {})
    name = split["experiment"]
    if name not in cpu or not split.get("run_cpu_seconds"):
        return []
    share = split["objective_cpu_seconds"] / split["run_cpu_seconds"]
    rest = sum(cpu.values()) - cpu[name] * (1.0 - share)
    return ["", f"Of `{name}`'s runs' CPU time, {share:.0%} is spent inside the cost (the "
            f"compiled kernel; {split['objective_cpu_seconds']:.0f} of "
            f"{split['run_cpu_seconds']:.0f} s in its last run, its report section has the "
            "split per optimiser); the rest is "
            "the optimisers' own code (pymoo, cma, scipy, the paper EA's operators). Were "
            f"that code to take no time at all, its {cpu[name]:.0f} s of CPU would "
            f"shrink to about {cpu[name] * share:.0f} s, and the regeneration would still use "
            f"{rest:.0f} s of CPU: at least {rest / record['cpu_count']:.0f} s on "
            f"{record['cpu_count']} CPUs."]


def _part_lines(record, sources):
    """The last full regeneration's CPU time by part of the report (``report.part``), and
    the last forced regeneration of parts alone (``replicate-all --force --part``)."""
    if not record or not record.get("cpu_count") or not record.get("cpu_seconds"):
        return []
    part_of = {name: block.get("part") for _, name, block in experiment_entries()}
    cpu, cpus = record["cpu_seconds"], record["cpu_count"]
    lines = ["", "| part of the report (`report.part`) | experiments | CPU (s) | at least, on "
             f"{cpus} CPUs (s) |", "|---|---|---|---|"]
    for part, what in [*PARTS.items(), (None, None)]:
        names = [name for name in cpu if part_of.get(name) == part]
        if names:
            total = sum(cpu[name] for name in names)
            label = f"`{part}`: {what}" if part else "no `report.part`"
            lines.append(f"| {label} | {len(names)} | {total:.0f} | {total / cpus:.0f} |")
    lines += ["", "CPU time of each part in the last full regeneration; a regeneration of "
              "parts alone (`replicate-all --force --part paper[,baselines,...]`) cannot "
              "take less than its CPU time divided by the CPUs."]
    for label, part_record in sources.items():
        if label.startswith("last_regeneration_of_") and part_record.get("total_seconds"):
            parts = label.removeprefix("last_regeneration_of_").replace("+", ", ")
            lines.append(f"The last forced regeneration of the part(s) {parts} alone took "
                         f"{part_record['total_seconds']:.0f} s on {part_record['cpu_count']}"
                         f" CPUs, {sum(part_record['cpu_seconds'].values()):.0f} s of CPU.")
    return lines


def _reference_lines(now, sources):
    """The machine's speed at each recorded time: the reference workload's seconds."""
    if now is None:
        return []
    runs = [f"{fmt(record['machine_reference_seconds'])} s {when}"
            for key, when in (("last_full_regeneration", "at the start of the last full "
                               "regeneration"),
                              ("test_suite", "at the end of the last full test run"))
            if "machine_reference_seconds" in (record := sources.get(key) or {})]
    return ["", "Machine speed: the reference workload of `replication/machine.py` (a "
            "Python loop and a numpy sort, the best of repeated timings) took " + ", ".join(
                runs + [f"{fmt(now)} s when these figures were gathered"])
            + ". The machine is shared and its speed moves between runs with the same "
            "code and results: to compare a time with another run's, compare each with "
            "its run's reference."]


def _regeneration_lines(record, slowest=6):
    """How the last full regeneration spent its time: parallelism, CPU, slowest runs."""
    if not record:
        return []
    walls = {name: s for name, s in record.get("experiments", {}).items()
             if isinstance(s, (int, float))}
    cpu = record.get("cpu_seconds", {})
    lines = ["", f"Last full regeneration: {fmt(record['total_seconds'])} s for {len(walls)} "
             f"experiments, {record.get('jobs', 1)} at a time on {record.get('cpu_count')} "
             "CPUs" + (" (benchmarks alone)" if record.get("jobs", 1) > 1 else "")
             + (f", {fmt(sum(cpu.values()))} s of CPU in all" if cpu else "") + ". Slowest:",
             "", "| experiment | wall (s) | CPU (s) |", "|---|---|---|"]
    for name in sorted(walls, key=walls.get, reverse=True)[:slowest]:
        lines.append(f"| `{name}` | {fmt(walls[name])} | {fmt(cpu.get(name, ''))} |")
    if cpu and record.get("cpu_count"):
        largest = max(cpu, key=cpu.get)
        lines += ["", f"The run used {fmt(sum(cpu.values()))} s of CPU on "
                  f"{record['cpu_count']} CPUs, so it could not take less than "
                  f"{fmt(sum(cpu.values()) / record['cpu_count'])} s however it was scheduled;"
                  f" `{largest}` alone used {fmt(cpu[largest])} s of it "
                  f"({cpu[largest] / sum(cpu.values()):.0%})."]
    return lines
