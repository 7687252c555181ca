"""The on-disk design cache (barsynth.designcache): a stored design comes back bit for bit;
a different input, source or record is never mistaken for it; a corrupt file is ignored and
written anew; only the cache's own files are touched; the program uses it, the library not."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from barsynth import designcache
from barsynth.models import get_model
from barsynth.models.allpass import design as allpass_design

SOURCES = ("barsynth.numerics",)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BARSYNTH_CACHE_DIR", str(tmp_path))
    designcache.enable()
    yield tmp_path / "designs"
    designcache.enable(False)


class Counter:
    """A design that counts how often it was computed: a value and an array."""

    def __init__(self):
        self.calls = 0

    def __call__(self, value=0.1):
        self.calls += 1
        return {"value": value / 3.0, "array": np.arange(6.0).reshape(2, 3) / 7.0}


def to_record(result):
    return {"value": float.hex(result["value"]), "array": designcache.array_record(result["array"])}


def from_record(record):
    return {"value": float.fromhex(record["value"]), "array": designcache.array_from(record["array"])}


def get(counter, inputs=(1,), sources=SOURCES, kind="test"):
    return designcache.cached(kind, list(inputs), sources, counter, to_record, from_record)


def test_a_stored_design_comes_back_exactly_without_computing(cache):
    counter = Counter()
    first, second = get(counter), get(counter)
    assert counter.calls == 1
    assert second["value"] == first["value"] and np.array_equal(second["array"], first["array"])
    assert second["array"].flags.writeable and second["array"].dtype == np.float64
    assert [p.suffix for p in cache.iterdir()] == [".json"]  # no temporary file left


def test_other_inputs_or_sources_are_other_designs(cache):
    counter = Counter()
    get(counter, (1,))
    get(counter, (2,))
    get(counter, (1,), sources=("barsynth.numerics", "barsynth.errors"))
    assert counter.calls == 3 and len(list(cache.iterdir())) == 3


@pytest.mark.parametrize("damage", ["truncated", "not json", "other key", "malformed record"])
def test_a_damaged_or_foreign_file_is_ignored_and_written_anew(cache, damage):
    counter = Counter()
    get(counter)
    (path,) = cache.iterdir()
    text = path.read_text()
    stored = json.loads(text)
    if damage == "truncated":
        path.write_text(text[:len(text) // 2])
    elif damage == "not json":
        path.write_bytes(b"\x00\xff garbage")
    elif damage == "other key":
        stored["key"]["inputs"] = [2]
        path.write_text(json.dumps(stored))
    else:
        stored["record"]["array"]["f8"] = "%%%"
        path.write_text(json.dumps(stored))
    assert get(counter)["value"] == 0.1 / 3.0 and counter.calls == 2
    assert json.loads(path.read_text()) == json.loads(text)  # written anew
    get(counter)
    assert counter.calls == 2


def test_only_the_newest_designs_of_a_kind_are_kept_and_nothing_else_is_touched(cache, monkeypatch):
    monkeypatch.setattr(designcache, "MAX_FILES", 3)
    cache.mkdir(parents=True)
    others = [cache / "notes.txt", cache / "other-1.json"]
    for path in others:
        path.write_text("mine")
    counter, seen = Counter(), set()
    for i in range(5):
        get(counter, (i,))
        for path in set(cache.glob("test-*.json")) - seen:  # written in this order
            os.utime(path, (1000 + i, 1000 + i))
            seen.add(path)
    assert len(list(cache.glob("test-*.json"))) == 3
    assert all(path.read_text() == "mine" for path in others)
    get(counter, (4,))
    assert counter.calls == 5  # the newest kept
    get(counter, (0,))
    assert counter.calls == 6  # the oldest gone


def test_off_by_default_with_an_empty_folder_name_or_an_unwritable_folder(tmp_path, monkeypatch):
    counter = Counter()
    monkeypatch.setenv("BARSYNTH_CACHE_DIR", str(tmp_path))
    get(counter)  # not enabled: the library's default
    assert counter.calls == 1 and not (tmp_path / "designs").exists()
    designcache.enable()
    try:
        monkeypatch.setenv("BARSYNTH_CACHE_DIR", "")
        get(counter)
        assert not designcache.enabled() and counter.calls == 2
        blocked = tmp_path / "file"
        blocked.write_text("")  # a file where the folder would be made
        monkeypatch.setenv("BARSYNTH_CACHE_DIR", str(blocked))
        assert get(counter)["value"] == 0.1 / 3.0 and counter.calls == 3
    finally:
        designcache.enable(False)


def test_an_allpass_design_from_disk_is_the_fitted_one_bit_for_bit(cache):
    p = get_model("allpass").resolve({"strike_position": 0.3, "pickup_position": 0.8, "allpass_order": 8})
    allpass_design._design.cache_clear()
    fitted = allpass_design.design_for(p, 22050.0)
    allpass_design._design.cache_clear()
    stored = allpass_design.design_for(p, 22050.0)
    allpass_design._design.cache_clear()
    assert stored is not fitted and len(list(cache.glob("allpass-*.json"))) == 1
    assert allpass_design._record(stored) == allpass_design._record(fitted)
    assert stored.modes == fitted.modes and stored.spurious == fitted.spurious
    for a, b in zip(stored.filters, fitted.filters):
        assert (a.name, a.delay, a.sign, a.poles, a.loss) == (b.name, b.delay, b.sign, b.poles, b.loss)
        assert np.array_equal(a.sections, b.sections)


def test_the_program_stores_a_design_and_renders_the_same_samples_from_it(tmp_path):
    env = {**os.environ, "BARSYNTH_CACHE_DIR": str(tmp_path / "cache")}
    command = [sys.executable, "-m", "barsynth", "render", "allpass", "--set", "allpass_order=6", "--set",
               "q=37", "--duration", "0.1", "--raw", "-o"]
    outputs = []
    for name in ("first.wav", "second.wav"):
        subprocess.run(command + [name], cwd=tmp_path, env=env, check=True, capture_output=True, timeout=300)
        outputs.append((tmp_path / name).read_bytes())
    assert len(list((tmp_path / "cache" / "designs").glob("allpass-*.json"))) == 1
    assert outputs[0] == outputs[1]


def test_a_key_that_cannot_be_made_leaves_the_design_uncached(cache):
    counter = Counter()
    assert get(counter, sources=("barsynth.no_such_module",))["value"] == 0.1 / 3.0
    get(counter, sources=("barsynth.no_such_module",))
    assert counter.calls == 2 and not cache.exists()


def test_a_folder_others_may_write_to_is_neither_read_nor_written(cache):
    """A record is data the program trusts: in a designs folder that a group or another user may
    write to (someone could plant one), nothing is read or stored; the design is computed."""
    counter = Counter()
    get(counter)
    os.chmod(cache, 0o777)
    try:
        get(counter)
        get(counter, inputs=(2,))
        assert counter.calls == 3 and len(list(cache.glob("test-*.json"))) == 1
    finally:
        os.chmod(cache, 0o700)
    get(counter)
    assert counter.calls == 3  # ours again: read


def test_a_hit_marks_the_design_used_and_old_temporaries_are_removed(cache):
    counter = Counter()
    get(counter, inputs=(1,))
    (stored,) = cache.glob("test-*.json")
    os.utime(stored, (1.0, 1.0))
    left = cache / ".test-killed.tmp"  # what a process killed mid-write leaves
    left.write_text("{")
    os.utime(left, (1.0, 1.0))
    fresh = cache / ".test-writing.tmp"  # another process writing now
    fresh.write_text("{")
    get(counter, inputs=(1,))
    assert stored.stat().st_mtime > 1.0  # used now: pruned last
    get(counter, inputs=(2,))  # a write prunes
    assert not left.exists() and fresh.exists()


def test_a_record_that_cannot_be_written_leaves_the_design_uncached(cache):
    counter = Counter()
    result = designcache.cached("test", [1], SOURCES, counter, lambda r: {"bad": object()}, from_record)
    assert result["value"] == 0.1 / 3.0 and not list(cache.glob("test-*.json"))


def test_a_package_without_sources_is_not_cached(cache, tmp_path, monkeypatch):
    package = tmp_path / "compiledonly"
    package.mkdir()
    (package / "__init__.pyc").write_bytes(b"")
    monkeypatch.syspath_prepend(str(tmp_path))
    counter = Counter()
    get(counter, sources=("compiledonly",))
    get(counter, sources=("compiledonly",))
    assert counter.calls == 2 and not list(cache.glob("test-*.json"))


def test_the_command_line_called_in_a_process_leaves_numba_as_it_is():
    """Only the program (barsynth.entry) lightens numba's cache loads and skips its imports; a
    process that calls barsynth.cli.main itself (tests, other programs) keeps numba's own."""
    code = ("from click.testing import CliRunner\n"
            "from barsynth.cli import main\n"
            "assert CliRunner().invoke(main, ['describe', 'farnell']).exit_code == 0\n"
            "from numba.core import caching\n"
            "print(getattr(caching.Cache.load_overload, 'lightened', False))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    assert out.stdout.strip() == "False"
