"""A batch's folder is a Hugging Face audio folder (spec 11.2): `datasets` loads it with its own
`audiofolder` builder, one row per rendered item, the metadata joined on `file_name`.

Audio stays undecoded: datasets' Audio feature imports torch and torchcodec even to record a
file's path (`Audio.encode_example`), and that stack is not a barsynth dependency. The test
replaces only that import-then-return-the-path step with the path itself, as the feature
records a path; the builder's discovery of the files, its reading of metadata.csv and its
join are datasets' own.
"""

from __future__ import annotations

import hashlib

import pytest
import soundfile

from barsynth.batch.run import run_batch
from barsynth.batch.spec import parse_spec

datasets = pytest.importorskip("datasets")  # (in the test extra: never skipped in CI)

SPEC = """model = "twang"
preset = "plastic-30cm"
count = 5
seed = 11
duration_s = 0.3
format = "flac"
[vary.length_m]
random = [0.15, 0.35]
[vary.gain_mapping]
list = ["linear", "log"]
"""


def _path_only(self, value):
    """What Audio.encode_example gives for a file's path, without importing torch first."""
    if isinstance(value, str):
        return {"bytes": None, "path": value}
    raise TypeError(f"only paths here, not {type(value).__name__}")


def test_a_batch_folder_loads_as_an_audiofolder_dataset(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setattr(datasets.Audio, "encode_example", _path_only)
    out = tmp_path / "twangs"
    rows = run_batch(parse_spec(SPEC, source="twangs.toml"), out, workers=1, spec_text=SPEC)
    ds = datasets.load_dataset("audiofolder", data_dir=str(out), split="train", cache_dir=str(tmp_path / "cache"))
    ds = ds.cast_column("audio", datasets.Audio(decode=False))
    assert ds.num_rows == 5 and "file_name" not in ds.column_names and "audio" in ds.column_names
    assert ds.features["seed"].dtype == "int64" and ds.features["f0_hz"].dtype == "float64"
    by_id = {int(r["id"]): r for r in rows}
    for record in ds:
        row = by_id[record["id"]]
        path = record["audio"]["path"]
        assert path.endswith(row["file"])  # the metadata row joined to its own file
        with open(path, "rb") as f:
            assert hashlib.sha256(f.read()).hexdigest() == record["sha256"] == row["sha256"]
        assert record["seed"] == int(row["seed"]) and record["length_m"] == float(row["length_m"])
        assert record["gain_mapping"] == ("linear", "log")[record["id"] % 2]
        samples, rate = soundfile.read(path)
        assert rate == 48000 and samples.size == int(0.3 * 48000)
        assert record["f0_hz"] == pytest.approx(float(row["f0_hz"])) and 20 < record["f0_hz"] < 2000
