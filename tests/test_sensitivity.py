"""The verdict-sensitivity runner: readings, de-duplication, overrides and verdicts."""

import pytest

from replication.errors import InputError
from replication.experiments.sensitivity import get_dotted, run_study, set_dotted, verdict


def _config(**block):
    return {"name": "toy", "a": {"b": 1}, "c": 0.5, "figure": "x.png",
            "sensitivity": {"goal_rate": 0.5, "axes": [
                {"key": "a.b", "values": [0, 1, 2], "label": "b"},
                {"key": "c", "values": [0.5, 0.9], "label": "c"},
                {"key": "d.e", "values": [3], "label": "beyond", "beyond": True}], **block}}


def _runner(calls):
    def run(config, out):
        calls.append(config)
        return {"value": config["a"]["b"] + config["c"] + get_dotted(config, "d.e", 0)}
    return run


def _score(result):
    return {"rate": min(result["value"] / 3.0, 1.0), "points": [result["value"]]}


def test_each_reading_runs_once_with_its_override(tmp_path):
    calls = []
    study = run_study(_config(), tmp_path, _runner(calls), _score)
    # 3 + 2 + 1 readings, the base values (b=1, c=0.5) the same reading: 5 runs
    assert len(study["readings"]) == 6 and len(calls) == 5
    assert [r["is_base"] for r in study["readings"]] == [False, True, False, True, False,
                                                          False]
    assert all("sensitivity" not in c and "figure" not in c for c in calls)
    assert sorted(c["a"]["b"] for c in calls) == [0, 1, 1, 1, 2]
    assert calls[-1]["d"] == {"e": 3}
    by_value = {(r["key"], repr(r["value"])): r["rate"] for r in study["readings"]}
    assert by_value[("a.b", "2")] == pytest.approx(2.5 / 3)
    assert by_value[("c", "0.9")] == pytest.approx(1.9 / 3)


def test_verdict_counts_distinct_readings_of_the_paper(tmp_path):
    study = run_study(_config(), tmp_path, _runner([]), _score)
    meeting, total = verdict(study, meets=lambda r: r["rate"] >= 0.5)
    assert total == 4    # b=0, base, b=2, c=0.9 (the beyond-the-paper axis left out)
    assert sorted((r["key"], r["value"]) for r in meeting) == [("a.b", 1), ("a.b", 2),
                                                               ("c", 0.9)]


def test_smoke_limits_and_bad_axes(tmp_path):
    calls = []
    study = run_study(_config(max_axes=1, max_values=2), tmp_path, _runner(calls), _score)
    assert [r["value"] for r in study["readings"]] == [0, 1]
    with pytest.raises(InputError, match="expected at least one axis"):
        run_study({"sensitivity": {"axes": []}}, tmp_path, _runner([]), _score)
    with pytest.raises(InputError, match="is not a group"):
        set_dotted({"c": 0.5}, "c.d", 1)


def test_table1_bar_paragraph_names_readings_within_the_papers_own_spread():
    """The paragraph is computed: a reading between the 2% bar and the paper's own K spread
    (2.35%) is named, one beyond it and one within 2% are not, and table1_2's own run is
    placed against the spread from its errors."""
    from replication.report.table1_sensitivity import _bar_paragraph

    def row(name, worst, beyond=False):
        return {"name": name, "beyond": beyond, "tau0.5": {"good_max_abs_error": worst}}

    result = {"table1_2": {"table_reference": "tau0.5",
                           "good_relative_errors": {"K": 0.022, "tau": 0.001}},
              "rows": [row("inside_bar", 0.01), row("between", 0.022),
                       row("beyond_spread", 0.03), row("restarts", 0.022, beyond=True)]}
    text = _bar_paragraph(result)
    assert "would also pass under `between`;" in text
    assert "inside_bar" not in text and "beyond_spread" not in text and "restarts" not in text
    assert "2.2% off, is within it" in text
    result["table1_2"]["good_relative_errors"] = {"K": -0.164}
    assert "16.4% off, is outside it" in _bar_paragraph(result)
