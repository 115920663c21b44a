"""Paper 3.4, Tables 1-2 and the success rate of the paper's EA over many seeds.

Runs the paper's EA (population 100, 49 generations) ``n_seeds`` times on each reference
run. Tables 1 and 2 are the final 5 best individuals of two runs on the table's reference:
the run with the lowest final cost ("good situation") and the one with the highest
("bad situation"), a rule fixed before looking at the results.
"""

from __future__ import annotations

import numpy as np

from replication.errors import check
from replication.experiments.identify_common import (
    check_common,
    load_cases,
    paper_ea_run,
    population_rows,
    run_rng,
    score,
)
from replication.figures import cloth_paper_ea_convergence
from replication.progress import bar, progress


def _run_record(index, ea, objective, case, rtol):
    best = ea.X[0]
    record = {"seed_index": index, "cost": float(ea.F[0]), "n_evals": objective.n_evals,
              "generations": ea.generation,
              "best": dict(zip(case.space.names, best.tolist())),
              "history": [h["best"] for h in ea.history]}
    record.update(score(best, case, rtol))
    return record


def _table(ea, case, top):
    """The paper's listing: reference line, then the ``top`` best individuals."""
    rows = population_rows(ea.X[:top], ea.F[:top], case.space.names)
    reference = None
    if case.truth is not None:
        reference = dict(zip(case.space.names, case.truth.tolist()))
        reference["cost"] = 0.0
    return {"reference": reference, "candidates": rows}


def _summary(records):
    n = len(records)
    out = {"n_runs": n, "median_cost": float(np.median([r["cost"] for r in records])),
           "median_evals": float(np.median([r["n_evals"] for r in records]))}
    if records and "success" in records[0]:
        outcomes = [r["outcome"] for r in records]
        out.update({"n_success": int(sum(r["success"] for r in records)),
                    "n_inactive_valley": outcomes.count("inactive-constraint valley"),
                    "n_elsewhere": outcomes.count("elsewhere")})
        out["success_rate"] = out["n_success"] / n
        for name in records[0]["relative_errors"]:
            out[f"median_abs_error_{name}"] = float(np.median(
                [abs(r["relative_errors"][name]) for r in records]))
    return out


def paper_ea_study(config, out):
    """Runner of ``table1_2``: the paper's EA over ``n_seeds`` seeds per reference.

    Parameters
    ----------
    config, out
        The resolved ``table1_2`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    settings = check_common(config)
    cases = load_cases(config)
    table_label = str(config["table_reference"])
    labels = [case.label for case in cases]
    if table_label not in labels:
        table_label = labels[-1]
    top = int(config["table_rows"])
    check(1 <= top <= settings.pop_size,
          f"table_rows={top}: expected 1..{settings.pop_size} (the population size)")
    rtol = float(config["success_rtol"])
    runs, summary, tables, chosen = {}, {}, {}, {}
    for case_index, case in enumerate(cases):
        records, eas = [], []
        for i in bar(range(int(config["n_seeds"])), f"paper EA seeds on {case.label}"):
            rng = run_rng(config["seed"], case_index, i)
            ea, objective = paper_ea_run(case, settings, rng,
                                         rest_spread=config["init"]["rest_spread"])
            records.append(_run_record(i, ea, objective, case, rtol))
            eas.append(ea)
        progress(f"paper EA on {case.label}: {len(records)} runs")
        runs[case.label], summary[case.label] = records, _summary(records)
        if case.label == table_label:
            costs = [r["cost"] for r in records]
            good, bad = int(np.argmin(costs)), int(np.argmax(costs))
            tables = {"good": _table(eas[good], case, top), "bad": _table(eas[bad], case, top)}
            chosen = {"good": good, "bad": bad, "ea": eas[good]}
    figure = cloth_paper_ea_convergence.plot(runs, out_name=config["figure"],
                                              figure_dir=config["figure_dir"])
    best_ea = chosen["ea"]
    case = next(c for c in cases if c.label == table_label)
    return {
        "best": population_rows(best_ea.X[:1], best_ea.F[:1], case.space.names)[0],
        "population": population_rows(best_ea.X, best_ea.F, case.space.names),
        "table_reference": table_label,
        "table_runs": {"good": chosen["good"], "bad": chosen["bad"]},
        "tables": tables,
        "success": summary,
        "runs": runs,
        "figures": [figure],
        "cost_used": config["cost"],
    }
