"""The studio greys out a control whose row's ``when`` does not hold (controls.js): the rows the page
receives say it in a form the page can read, and the page's rule (``acts``, ``whenText``) is the
table's own (``Parameter.acts_under``, ``Parameter.when_text``), checked without a browser: the page's
module runs in Node (skipped where Node is not installed; tests/test_studio_browser.py checks the
greying in Chromium)."""

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
from barsynth.parameters import BOOL, CHOICE, Parameter, ParameterTable
from barsynth.studio.server import create_app

# A table with every kind of "when": on a choice, on one of two values, on a bool, on two parameters.
SAMPLE = ParameterTable("sample", [
    Parameter("excitation", "", None, None, "strike", "", kind=CHOICE, choices=("strike", "bow", "pluck")),
    Parameter("tuning", "", None, None, "physics", "", kind=CHOICE, choices=("physics", "ratios")),
    Parameter("vibrato", "", None, None, False, "", kind=BOOL),
    Parameter("bow_force_n", "N", 0.0, 10.0, 1.0, "bow force", when={"excitation": ("bow",)}),
    Parameter("frequency_hz", "Hz", 20.0, 2e4, 220.0, "pitch", scale="log", when={"tuning": ("ratios",)}),
    Parameter("release_time_ms", "ms", 0.1, 10.0, 0.5, "", when={"excitation": ("bow", "pluck")}),
    Parameter("vibrato_hz", "Hz", 0.1, 20.0, 5.0, "", when={"vibrato": (True,)}),
    Parameter("bow_pitch_bend", "", 0.0, 1.0, 0.0, "", when={"excitation": ("bow",), "tuning": ("ratios",)}),
])

TABLES = [SAMPLE, *(get_model(name).table for name in model_names())]


def test_the_models_api_says_when_each_parameter_acts_as_the_page_reads_it():
    """Each row's "when": null, or the names of choice or bool parameters of the same table, each
    with a list of values that parameter takes (what controls.js compares the current values with)."""
    listed = TestClient(create_app(), base_url="http://127.0.0.1:8000").get("/api/models").json()["models"]
    for entry in listed:
        rows = {row["name"]: row for row in entry["parameters"]}
        for row in entry["parameters"]:
            assert "when" in row
            if row["when"] is None:
                continue
            assert isinstance(row["when"], dict) and row["when"], row
            for name, values in row["when"].items():
                controller = rows[name]
                assert controller["kind"] in ("choice", "bool") and isinstance(values, list) and values
                assert all(v in (controller["choices"] or [True, False]) for v in values), (row["name"], name)
    assert SAMPLE["bow_pitch_bend"].to_json()["when"] == {"excitation": ["bow"], "tuning": ["ratios"]}


def _settings(table: ParameterTable) -> list[dict]:
    """Every combination of the values of the parameters some row's "when" names."""
    names = sorted({name for p in table for name, _ in p.when})
    takes = [table[name].choices or (False, True) for name in names]
    return [dict(zip(names, combo)) for combo in itertools.product(*takes)]


PAGE_RULE = """
globalThis.window = {};
const controls = await import(process.argv[1]);
let input = "";
for await (const chunk of process.stdin) input += chunk;
const out = [];
for (const { rows, settings } of JSON.parse(input)) {
  out.push({
    inactive: settings.map((values) => rows.filter((row) => !controls.acts(row, values)).map((row) => row.name)),
    texts: rows.filter((row) => row.when).map((row) => [row.name, controls.whenText(row.when)]),
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
        expected.append({"inactive": inactive,
                         "texts": [[p.name, p.when_text().replace("True", "true").replace("False", "false")]
                                   for p in table if p.when]})
    run = subprocess.run([node, "--input-type=module", "-e", PAGE_RULE, f"file://{module}"],
                         input=json.dumps(cases), capture_output=True, text=True, timeout=60, check=False)
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout)
    assert found == expected
    sample = found[0]
    assert len(sample["inactive"]) == 12 and ["bow_force_n", "frequency_hz", "release_time_ms", "vibrato_hz",
                                              "bow_pitch_bend"] in sample["inactive"]
    assert ["bow_pitch_bend", "excitation = bow and tuning = ratios"] in sample["texts"]
