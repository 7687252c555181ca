"""Randomize and Mutate in the studio (issue 18): ``POST /api/draw`` over HTTP (FastAPI's
TestClient, the draw in a worker process) and :func:`barsynth.studio.variations.draw` in this
process. The same request gives the same settings (in another process too); the settings are
within the table, render finite sound, and a mutation stays within its spread of each range;
bad input gets one line and a 4xx, never a 500."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from barsynth.batch.sampler import drawable
from barsynth.models import get_model, model_names
from barsynth.parameters import BOOL, CHOICE
from barsynth.studio.server import create_app
from barsynth.studio.variations import MAX_SEED, draw

RATE = 48000


@pytest.fixture(scope="module")
def client():
    return TestClient(create_app(), base_url="http://127.0.0.1:8000")


def drawn(client, **body) -> dict:
    r = client.post("/api/draw", json=body)
    assert r.status_code == 200, r.text
    return r.json()


def defaults(name: str) -> dict:
    model = get_model(name)
    return model.table.as_dict(model.table.resolve())


def differing(a: dict, b: dict) -> set[str]:
    return {name for name in a if a[name] != b[name]}


@pytest.mark.parametrize("name", ["twang", "banded", "fd"])
def test_the_same_seed_gives_the_same_settings_here_and_in_a_worker(client, name):
    base = defaults(name)
    first = drawn(client, model=name, mode="random", seed=1234, parameters=base)
    again = drawn(client, model=name, mode="random", seed=1234, parameters=base)
    assert first == again
    here = draw(name, base, "random", 1234, None, RATE)  # this process, not the worker's
    assert here["parameters"] == first["parameters"] and here["rejected"] == first["rejected"]
    other = drawn(client, model=name, mode="random", seed=1235, parameters=base)
    rows = {p.name for p in drawable(get_model(name).table)}
    assert len(differing(first["parameters"], other["parameters"]) & rows) >= len(rows) // 2
    # a random draw moves most of the rows away from the defaults
    assert len(differing(first["parameters"], base) & rows) >= len(rows) // 2
    mutated = drawn(client, model=name, mode="mutate", seed=99, spread=0.2, parameters=first["parameters"])
    assert mutated == drawn(client, model=name, mode="mutate", seed=99, spread=0.2, parameters=first["parameters"])
    assert mutated["spread"] == 0.2 and mutated["seed"] == 99


@pytest.mark.parametrize("name", ["twang", "banded"])
def test_drawn_settings_are_in_the_table_and_render_finite(client, name):
    model = get_model(name)
    for seed in (1, 2):
        found = drawn(client, model=name, mode="random", seed=seed)
        assert set(found["parameters"]) == set(model.table.names)
        resolved = model.table.resolve(found["parameters"])  # every value within its row
        x = np.asarray(model.render(resolved, duration_s=0.5, sample_rate=RATE))
        assert np.all(np.isfinite(x)) and np.max(np.abs(x)) > 1e-6, (seed, found["parameters"])


def test_a_mutation_stays_within_its_spread_of_each_range(client):
    model = get_model("banded")
    base = drawn(client, model="banded", mode="random", seed=7)["parameters"]
    spread = 0.05
    moved, changed_choices = 0, 0
    for seed in range(4):
        found = drawn(client, model="banded", mode="mutate", seed=seed, spread=spread, parameters=base)["parameters"]
        for p in drawable(model.table):
            if p.sets is not None or any(p.name in (q.sets.names if q.sets else ()) for q in model.table):
                continue  # a material (and the E and density it sets) may jump with it
            if p.kind in (CHOICE, BOOL):
                changed_choices += found[p.name] != base[p.name]
                continue
            step = abs(p.to_unit_interval(found[p.name]) - p.to_unit_interval(base[p.name]))
            assert step <= spread + 1e-9 + (0.5 / (p.maximum - p.minimum) if p.kind == "int" else 0), \
                (seed, p.name, base[p.name], found[p.name])
            moved += step > 0
    assert moved > 40  # they do move
    assert changed_choices < 8  # a choice changes with probability 0.05 (about 1 of 4 x ~8 choices)
    same = drawn(client, model="banded", mode="mutate", seed=3, spread=0.0, parameters=base)["parameters"]
    assert same == base  # spread 0: nothing moves


def test_refused_draws_are_counted(client):
    """Banded's seed 7 draws two sets with a tube on a mode that does not sound before one it takes."""
    found = drawn(client, model="banded", mode="random", seed=7)
    assert found["rejected"] == 2 and found["reasons"][0]["reason"].startswith("parameter tube_mode = #")
    assert found["reasons"] and sum(r["count"] for r in found["reasons"]) <= found["rejected"]
    assert all("#" in r["reason"] for r in found["reasons"])


def test_the_link_words_are_no_parameter_names():
    for name in model_names():
        assert not {"model", "preset", "random", "mutate", "spread"} & set(get_model(name).table.names), name


@pytest.mark.parametrize("body, status, words", [
    ({"model": "banded", "mode": "random", "seed": -1}, 422, "seed = -1"),
    ({"model": "banded", "mode": "random", "seed": MAX_SEED + 1}, 422, "seed = 4294967296"),
    ({"model": "banded", "mode": "random", "seed": 1.5}, 422, "seed = 1.5"),
    ({"model": "banded", "mode": "random", "seed": "12"}, 422, "seed = '12'"),
    ({"model": "banded", "mode": "random", "seed": True}, 422, "seed = True"),
    ({"model": "banded", "mode": "random", "seed": 10 ** 400}, 422, "seed = "),
    ({"model": "banded", "mode": "mutate", "seed": 1, "spread": 1.01}, 422, "spread = 1.01"),
    ({"model": "banded", "mode": "mutate", "seed": 1, "spread": -0.1}, 422, "spread = -0.1"),
    ({"model": "banded", "mode": "mutate", "seed": 1, "spread": "0.1"}, 422, "spread = '0.1'"),
    ({"model": "banded", "mode": "random", "seed": 1, "spread": 0.1}, 422, "mode mutate only"),
    ({"model": "banded", "mode": "shuffle", "seed": 1}, 422, "mode = 'shuffle'"),
    ({"model": "banded", "seed": 1}, 422, "missing mode"),
    ({"model": "banded", "mode": "random", "seed": 1, "colour": 1}, 422, "unknown field 'colour'"),
    ({"model": "nope", "mode": "random", "seed": 1}, 404, "unknown model 'nope'"),
    ({"model": 3, "mode": "random", "seed": 1}, 422, "model = 3"),
    ({"model": "banded", "mode": "random", "seed": 1, "parameters": {"frequency_hz": -3}}, 422, "frequency_hz = -3"),
    ({"model": "banded", "mode": "random", "seed": 1, "parameters": [1]}, 422, "parameters must be"),
    ({"model": "banded", "mode": "random", "seed": 1, "sample_rate": 1000}, 422, "sample_rate = 1000"),
])
def test_bad_input_gets_one_line_and_a_4xx(client, body, status, words):
    r = client.post("/api/draw", json=body)
    assert r.status_code == status, r.text
    error = r.json()["error"]
    assert words in error and "\n" not in error
    assert any(w in error for w in ("allowed", "available", "missing", "must be", "not a model name"))


def test_spread_bounds_are_allowed(client):
    for spread in (0, 1, 1.0):
        assert drawn(client, model="twang", mode="mutate", seed=MAX_SEED, spread=spread)["spread"] == spread
    assert drawn(client, model="twang", mode="mutate", seed=0)["spread"] == 0.1  # the default
