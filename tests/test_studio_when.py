"""The studio greys out a control whose row's ``when`` does not hold (controls.js): the rows the page
receives say it in a form the page can read, and the page's rule (``acts``, ``reads``) is the table's
own (``Parameter.acts_under``, ``Parameter.reads``), checked without a browser: the page's module runs
in Node (skipped where Node is not installed; tests/test_studio_browser.py checks the greying in
Chromium). The words the page shows are the table's (``when_text`` in each row)."""

from __future__ import annotations

import itertools
import json
import shutil
import subprocess
from importlib import resources

import pytest
from fastapi.testclient import TestClient

from barsynth.errors import ParameterError
from barsynth.models import get_model, model_names
from barsynth.parameters import BOOL, CHOICE, FLOATS, INT, Compare, Parameter, ParameterTable
from barsynth.studio.server import create_app

# A table with every kind of "when": on a choice, on one of two values, on a bool, on two parameters,
# on a number, on a list's length against another parameter, and alternatives (any one holds).
SAMPLE = ParameterTable("sample", [
    Parameter("excitation", "", None, None, "strike", "", kind=CHOICE, choices=("strike", "bow", "pluck")),
    Parameter("tuning", "", None, None, "physics", "", kind=CHOICE, choices=("physics", "ratios")),
    Parameter("vibrato", "", None, None, False, "", kind=BOOL),
    Parameter("bow_force_n", "N", 0.0, 10.0, 1.0, "bow force", when={"excitation": ("bow",)}),
    Parameter("frequency_hz", "Hz", 20.0, 2e4, 220.0, "pitch", scale="log", when={"tuning": ("ratios",)}),
    Parameter("release_time_ms", "ms", 0.1, 10.0, 0.5, "", when={"excitation": ("bow", "pluck")}),
    Parameter("vibrato_hz", "Hz", 0.1, 20.0, 5.0, "", when={"vibrato": (True,)}),
    Parameter("bow_pitch_bend", "", 0.0, 1.0, 0.0, "", when={"excitation": ("bow",), "tuning": ("ratios",)}),
    Parameter("rate_hz", "Hz", 0.0, 8.0, 0.0, "0 turns it off"),
    Parameter("depth_hz", "Hz", 0.0, 50.0, 18.0, "", when={"rate_hz": Compare(">", 0.0)}),
    Parameter("mode_count", "", 1, 6, 2, "", kind=INT),
    Parameter("ratios", "", 0.5, 20.0, (1.0, 4.0, 10.0), "", kind=FLOATS, max_items=6),
    Parameter("t60s_s", "s", 0.01, 10.0, (), "", kind=FLOATS, max_items=6),
    Parameter("q", "", 3.0, 1e4, 300.0, "", when=[{"tuning": ("physics",), "t60s_s": Compare("<", "mode_count",
                                                                                              count=True)},
                                                 {"tuning": ("ratios",), "t60s_s": Compare("<", "ratios",
                                                                                           count=True)}]),
    Parameter("spread", "", 0.0, 1.0, 0.5, "", when={"t60s_s": Compare(">=", 2, count=True),
                                                     "rate_hz": Compare("<=", 4.0)}),
])

TABLES = [SAMPLE, *(get_model(name).table for name in model_names())]


def _condition_ok(condition, controller, rows) -> bool:
    """A condition the page can read: a list of values the (choice or bool) controller takes, or a
    comparison {op, than, count} with a number or with a number or list of the same table."""
    if isinstance(condition, list):
        return (controller["kind"] in ("choice", "bool") and bool(condition)
                and all(v in (controller["choices"] or [True, False]) for v in condition))
    assert set(condition) == {"op", "than", "count"} and condition["op"] in ("<", "<=", ">", ">=")
    subject = controller["kind"] == "floats" if condition["count"] else controller["kind"] in ("float", "int")
    than = condition["than"]
    return subject and (isinstance(than, (int, float)) or rows[than]["kind"] in ("float", "int", "floats"))


def test_the_models_api_says_when_each_parameter_acts_as_the_page_reads_it():
    """Each row's "when": null, one clause or a list of clauses; a clause names parameters of the same
    table, each with a condition (what controls.js compares the current values with); "when_text"
    says it in the table's words."""
    listed = TestClient(create_app(), base_url="http://127.0.0.1:8000").get("/api/models").json()["models"]
    compared = 0
    for entry in listed:
        rows = {row["name"]: row for row in entry["parameters"]}
        table = get_model(entry["name"]).table
        for row in entry["parameters"]:
            assert "when" in row and row["when_text"] == (table[row["name"]].when_text() or None)
            if row["when"] is None:
                continue
            clauses = row["when"] if isinstance(row["when"], list) else [row["when"]]
            for clause in clauses:
                assert isinstance(clause, dict) and clause, row
                for name, condition in clause.items():
                    assert _condition_ok(condition, rows[name], rows), (row["name"], name, condition)
                    compared += isinstance(condition, dict)
    assert compared >= 8  # twang's vibrato, short cantilever and free bar, banded's q, fd's undercut
    assert SAMPLE["bow_pitch_bend"].to_json()["when"] == {"excitation": ["bow"], "tuning": ["ratios"]}
    assert SAMPLE["depth_hz"].to_json()["when"] == {"rate_hz": {"op": ">", "than": 0.0, "count": False}}
    assert SAMPLE["q"].to_json()["when"] == [
        {"tuning": ["physics"], "t60s_s": {"op": "<", "than": "mode_count", "count": True}},
        {"tuning": ["ratios"], "t60s_s": {"op": "<", "than": "ratios", "count": True}}]
    assert SAMPLE["q"].to_json()["when_text"] == ("tuning = physics and t60s_s has fewer values than mode_count, "
                                                  "or tuning = ratios and t60s_s has fewer values than ratios")
    assert SAMPLE["spread"].when_text() == "t60s_s has at least 2 values and rate_hz <= 4"
    assert SAMPLE["q"].reads == ("mode_count", "ratios", "t60s_s", "tuning")


def test_a_when_that_cannot_hold_is_refused_when_the_table_is_made():
    rate = Parameter("rate_hz", "Hz", 0.0, 8.0, 0.0, "")
    kind = Parameter("kind", "", None, None, "a", "", kind=CHOICE, choices=("a", "b"))
    for when in ({"rate_hz": ("fast",)},  # values of a number
                 {"kind": Compare(">", 0.0)},  # a choice compared
                 {"rate_hz": Compare(">", 0.0, count=True)},  # a number counted
                 {"rate_hz": Compare("<", "nothing")},  # with no such parameter
                 {"rate_hz": Compare("<", "kind")}):  # with a choice
        with pytest.raises(ValueError, match="not a value it takes"):
            ParameterTable("t", [rate, kind, Parameter("depth_hz", "Hz", 0.0, 1.0, 0.5, "", when=when)])
    with pytest.raises(ValueError, match="unknown comparison"):
        Compare("=", 0.0)
    with pytest.raises(ValueError, match="finite number"):
        Compare(">", float("nan"))


def _samples(p: Parameter) -> list:
    """Values of a parameter some "when" reads, to try: every value of a choice or bool; a number's
    ends, default and middle and every number compared with; lists of 0 to 4 values."""
    if p.kind in (CHOICE, BOOL):
        return list(p.choices or (False, True))
    if p.kind == FLOATS:
        return [(p.minimum,) * n for n in range(min(p.max_items, 4) + 1)]
    values = {p.minimum, p.maximum, p.default, p.from_unit_interval(0.5)}
    return sorted(int(v) if p.kind == INT else float(v) for v in values)


def _settings(table: ParameterTable) -> list[dict]:
    """For each row, every combination of the sampled values of the parameters its "when" reads,
    and of those these read in turn (the others at their first sample): whether a row acts depends
    on no other (the whole product of every name any row reads had grown to 1.5 million banded
    settings, more than Node.js could take in as one string)."""
    names = sorted({name for p in table for name in p.reads})
    base = {name: _samples(table[name])[0] for name in names}
    combos, seen = [], set()
    for p in table:
        group, todo = set(), list(p.reads)
        while todo:  # the reads' closure
            name = todo.pop()
            if name not in group:
                group.add(name)
                todo.extend(table[name].reads)
        group = sorted(group)
        for combo in itertools.product(*(_samples(table[n]) for n in group)):
            chosen = {**base, **dict(zip(group, combo))}
            key = json.dumps(chosen, sort_keys=True, default=str)
            if key not in seen:
                seen.add(key)
                combos.append(chosen)
    for p in table:  # each number a comparison names, and either side of it
        for name, c in (pair for clause in p.when for pair in clause):
            if isinstance(c, Compare) and not isinstance(c.than, str) and not c.count:
                row = table[name]
                near = [v for v in (c.than, c.than + 1e-9 * (row.maximum - row.minimum) + 1e-300)
                        if row.minimum <= v <= row.maximum]
                combos += [{**combos[0], name: v} for v in near]
    return combos


PAGE_RULE = """
globalThis.window = {};
const controls = await import(process.argv[1]);
let input = "";
for await (const chunk of process.stdin) input += chunk;
const out = [];
for (const { rows, settings } of JSON.parse(input)) {
  out.push({
    inactive: settings.map((values) => rows.filter((row) => !controls.acts(row, values)).map((row) => row.name)),
    reads: rows.map((row) => [row.name, controls.reads(row)]),
  });
}
console.log(JSON.stringify(out));
"""


def test_the_page_greys_out_exactly_what_the_table_says_has_no_effect():
    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.skip("Node.js is not installed (apt-get install nodejs); the browser tests check the greying")
    module = resources.files("barsynth.studio") / "web" / "controls.js"
    cases, expected = [], []
    for table in TABLES:
        settings, inactive = [], []
        for chosen in _settings(table):
            try:
                resolved = table.resolve(chosen)
            except ParameterError:
                continue
            settings.append(json.loads(json.dumps(table.as_dict(resolved))))
            inactive.append([name for name, _ in table.inactive(resolved)])
        cases.append({"rows": table.to_json(), "settings": settings})
        expected.append({"inactive": inactive, "reads": [[p.name, list(p.reads)] for p in table]})
    run = subprocess.run([node, "--input-type=module", "-e", PAGE_RULE, f"file://{module}"],
                         input=json.dumps(cases), capture_output=True, text=True, timeout=120, check=False)
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout)
    assert found == expected
    sample = found[0]
    assert ["bow_force_n", "frequency_hz", "release_time_ms", "vibrato_hz", "bow_pitch_bend", "depth_hz"] \
        in sample["inactive"]
    # each comparison both holds and fails somewhere, in the page as in the table
    for name in ("depth_hz", "q", "spread"):
        assert any(name in names for names in sample["inactive"]) and any(
            name not in names for names in sample["inactive"]), name
