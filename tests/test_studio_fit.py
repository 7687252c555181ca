"""The studio's fit of an uploaded recording (issue 14, item 5): POST /api/fit through FastAPI's
TestClient, with the studio's real worker processes; and the bytes reader it uses
(:func:`barsynth.audio_io.audio_from_bytes`)."""

from __future__ import annotations

import base64
import io
import json
import math
import struct

import numpy as np
import pytest
import soundfile
from fastapi.testclient import TestClient

from barsynth.audio_io import audio_from_bytes, load_audio
from barsynth.errors import AudioFileError, AudioFormatError
from barsynth.jsonout import json_ready
from barsynth.models import get_model
from barsynth.studio import server
from barsynth.studio.fitted import MAX_UPLOAD_BYTES, MAX_UPLOAD_S
from barsynth.studio.server import MAX_BODY_BYTES, create_app

RATE = 44100
PARTIALS = [(440.0, 0.5, 1.2), (440.0 * 2.76, 0.25, 0.6), (440.0 * 5.4, 0.1, 0.3)]  # Hz, amplitude, T60 s


def note(seconds: float = 1.5, rate: int = RATE, channels: int = 1) -> np.ndarray:
    """A struck note: three decaying sines after 45 ms of quiet (a little noise, as a room has)."""
    t = np.arange(int(seconds * rate)) / rate
    x = sum(a * np.exp(-t * math.log(1000.0) / t60) * np.sin(2 * np.pi * f * t) for f, a, t60 in PARTIALS)
    x = np.concatenate([np.zeros(int(0.045 * rate)), 0.8 * x])
    x = x + 1e-5 * np.random.default_rng(7).standard_normal(x.size)
    return np.column_stack([x] * channels) if channels > 1 else x


def encoded(samples: np.ndarray, rate: int = RATE, fmt: str = "WAV", subtype: str | None = "PCM_16") -> bytes:
    buffer = io.BytesIO()
    soundfile.write(buffer, samples, rate, format=fmt, subtype=subtype)
    return buffer.getvalue()


@pytest.fixture(scope="module")
def client():
    return TestClient(create_app(), base_url="http://127.0.0.1:8000")


def one_line(r, status: int, needle: str) -> str:
    assert r.status_code == status, r.text
    error = r.json()["error"]
    assert needle in error and "\n" not in error, error
    return error


def healthy(client) -> None:
    assert client.get("/api/health").json() == {"ok": True}


def spectrogram_rows(spec: dict) -> np.ndarray:
    levels = np.frombuffer(base64.b64decode(spec["levels"]), np.uint8)
    return levels.reshape(spec["bins"], len(spec["times_s"]))


def row_of(spec: dict, frequency_hz: float) -> int:
    edges = np.geomspace(spec["min_frequency_hz"], spec["max_frequency_hz"], spec["bins"] + 1)
    return int(np.searchsorted(edges, frequency_hz) - 1)


def test_a_note_is_fitted_with_its_settings_comparison_sounds_and_spectrograms(client):
    r = client.post("/api/fit?model=banded&name=note.wav&width=300", content=encoded(note()),
                    headers={"content-type": "audio/wav"})
    assert r.status_code == 200, r.text
    found = r.json()
    assert found["model"] == "banded" and found["file"] == "note.wav" and found["sample_rate"] == RATE

    # The settings: every row of banded's table, resolved as a preset's; the modes are the partials.
    values = found["parameters"]
    table = get_model("banded").table
    assert set(values) == set(table.names)
    again = json.loads(json.dumps(json_ready(table.as_dict(table.resolve(values)))))
    assert again == values  # the page sends them back as they came, and they mean the same
    assert values["frequency_hz"] == pytest.approx(440.0, rel=1e-4)
    assert values["mode_ratios"] == pytest.approx([1.0, 2.76, 5.4], rel=1e-3)
    assert values["mode_t60s_s"] == pytest.approx([1.2, 0.6, 0.3], rel=0.02)
    assert values["excitation"] == "sample" and values["attack_rate_hz"] == RATE
    assert 0.02 * RATE <= len(values["attack_samples"]) <= 0.1 * RATE  # the recorded attack, a data row

    # The fit's report: each partial within a few cents, 0.5 dB and 5 % of T60, and closer than one sine.
    report = found["fit"]
    assert report["f0_hz"] == pytest.approx(440.0, rel=1e-4)
    assert report["attack_samples"] == len(values["attack_samples"])
    assert [p["frequency_hz"] for p in report["partials"]] == pytest.approx([f for f, _, _ in PARTIALS], rel=1e-4)
    for p in report["partials"]:
        assert abs(p["cents"]) < 2 and abs(p["level_error_db"]) < 0.5 and abs(p["t60_error_percent"]) < 5
    assert report["spectral_distance_db"] < report["sine_baseline_db"]

    # Both sounds at the recording's rate, as long as each other, from the onset, the louder at -1 dBFS.
    sounds = {key: soundfile.read(io.BytesIO(base64.b64decode(found[key]["wav"]))) for key in
              ("recording", "resynthesis")}
    (recording, rate_a), (resynthesis, rate_b) = sounds["recording"], sounds["resynthesis"]
    assert rate_a == rate_b == RATE and recording.size == resynthesis.size
    assert found["duration_s"] == pytest.approx(recording.size / RATE)
    assert 0.04 <= found["onset_s"] <= 0.05
    peaks = [float(np.max(np.abs(x))) for x in (recording, resynthesis)]
    assert max(peaks) == pytest.approx(10 ** (-1 / 20), abs=2e-4) and min(peaks) > 0.8
    assert np.max(np.abs(recording[:int(0.004 * RATE)])) > 0.05  # the note starts at once: cut at the onset

    # Both spectrograms on the same axes and levels; each shows the fundamental as its loudest band
    # and the third partial well above the floor, in the same rows.
    specs = [found[key]["spectrogram"] for key in ("recording", "resynthesis")]
    for key in ("times_s", "bins", "min_frequency_hz", "max_frequency_hz", "floor_db", "ceiling_db", "scale"):
        assert specs[0][key] == specs[1][key]
    assert len(specs[0]["times_s"]) <= 300
    for spec in specs:
        rows = spectrogram_rows(spec)
        early = rows[:, :5].max(axis=1)
        assert abs(int(np.argmax(early)) - row_of(spec, 440.0)) <= 1
        assert early[row_of(spec, PARTIALS[2][0])] > 128  # above -50 dB
    healthy(client)


def test_flac_and_ogg_in_stereo_are_fitted_to_the_other_models(client):
    r = client.post("/api/fit?model=twang&max_modes=6", content=encoded(note(channels=2), fmt="FLAC"))
    assert r.status_code == 200, r.text
    twang = r.json()
    assert twang["model"] == "twang" and set(twang["parameters"]) == set(get_model("twang").table.names)
    assert "attack_samples" not in twang["parameters"] and len(twang["fit"]["partials"]) == 3
    r = client.post("/api/fit?model=fd&nominal_hz=440", content=encoded(note(), fmt="OGG", subtype="VORBIS"))
    assert r.status_code == 200, r.text
    fd = r.json()
    assert fd["model"] == "fd" and fd["fit"]["f0_hz"] == pytest.approx(440.0, rel=1e-3)
    healthy(client)


def test_the_fitted_settings_play_on_the_live_stream(client):
    """The page starts the stream with every fitted value, the recorded attack too: it fits a
    stream message, and the stream plays the note (at another pitch as well)."""
    values = client.post("/api/fit", content=encoded(note())).json()["parameters"]
    message = json.dumps({"type": "start", "model": "banded", "parameters": values, "sample_rate": 48000})
    assert len(message) < server.MAX_MESSAGE_BYTES
    with client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000"}) as socket:
        socket.send_text(message)
        assert socket.receive_json()["type"] == "started"
        socket.send_json({"type": "trigger"})
        samples, played = [], 0
        while len(samples) < 40:
            frame = socket.receive()
            assert frame.get("bytes"), frame
            samples.append(np.frombuffer(frame["bytes"][8:], "<f4"))
            played += 1
            socket.send_json({"type": "played", "samples": played * 256})
        sound = np.concatenate(samples)
        assert np.all(np.isfinite(sound)) and np.max(np.abs(sound)) > 0.05
        socket.send_json({"type": "set", "id": 1, "parameters": {"frequency_hz": 330.0}})
        seen = 0
        while seen != 1 and played < 400:
            frame = socket.receive()
            if frame.get("bytes"):
                seen = struct.unpack("<II", frame["bytes"][:8])[1]
                played += 1
                socket.send_json({"type": "played", "samples": played * 256})
            else:
                raise AssertionError(frame)
        assert seen == 1


@pytest.mark.parametrize("body,status,needle", [
    (b"this is not a sound file, only words" * 10, 415, "audio file upload: cannot be read as WAV, FLAC or OGG"),
    (b"RIFF\x00\x00\x00\x00WAVEfmt ", 415, "cannot be read as WAV, FLAC or OGG"),
    (b"", 422, "the upload is empty (0 bytes)"),
    (None, 422, "the recording has no note to fit (silent"),  # silence
    (b"noise", 422, "the recording has no note to fit"),
    (b"short", 422, "allowed: 8000 to 192000 Hz"),
])
def test_bad_files_get_one_line_and_the_server_keeps_serving(client, body, status, needle):
    if body is None:
        body = encoded(np.zeros(RATE))
    elif body == b"noise":
        body = encoded(0.3 * np.random.default_rng(3).standard_normal(RATE))
    elif body == b"short":
        body = encoded(note(rate=4000), rate=4000)
    one_line(client.post("/api/fit?name=x.wav" if body == b"" else "/api/fit", content=body), status, needle)
    healthy(client)


def test_a_recording_over_the_length_limit_is_refused_before_it_is_decoded(client):
    long = np.tile(note(1.0, rate=8000), int(MAX_UPLOAD_S) + 1)  # 31 s: a small FLAC file
    body = encoded(long, rate=8000, fmt="FLAC")
    assert len(body) < MAX_UPLOAD_BYTES
    one_line(client.post("/api/fit?name=long.flac", content=body), 422,
             f"audio file long.flac: is {long.size / 8000:.4g} s long; allowed: up to {MAX_UPLOAD_S:g} s")
    healthy(client)


def test_an_upload_over_the_size_limit_gets_413_declared_or_chunked(client):
    too_big = b"\0" * (MAX_UPLOAD_BYTES + 1)
    one_line(client.post("/api/fit", content=too_big), 413,
             f"request body too large; allowed: up to {MAX_UPLOAD_BYTES} bytes")
    healthy(client)

    def chunks():  # no Content-Length: counted as it comes
        for _ in range(MAX_UPLOAD_BYTES // (1 << 20) + 1):
            yield b"\0" * (1 << 20)
    one_line(client.post("/api/fit", content=chunks()), 413, f"allowed: up to {MAX_UPLOAD_BYTES} bytes")
    healthy(client)
    # The larger limit is the upload's only: the same body to another path gets the JSON limit.
    body = encoded(note(8.0))
    assert MAX_BODY_BYTES < len(body) < MAX_UPLOAD_BYTES
    one_line(client.post("/api/render", content=body, headers={"content-type": "application/json"}), 413,
             f"allowed: up to {MAX_BODY_BYTES} bytes")
    healthy(client)


@pytest.mark.parametrize("query,needle", [
    ("model=allpass", "parameter model = 'allpass' cannot be fitted; allowed: one of banded, twang, fd"),
    ("max_modes=many", "parameter max_modes = 'many' is not a whole number of modes"),
    ("max_modes=99", "parameter max_modes = 99 is out of range"),
    ("nominal_hz=high", "parameter nominal_hz = 'high' is not a number of Hz"),
    ("nominal_hz=30000", "parameter nominal_hz = 30000.0 is out of range"),
    ("width=3", "parameter width = 3 is out of range"),
    ("colour=red", "unknown option 'colour'; allowed: model, max_modes, nominal_hz, name, width"),
])
def test_bad_options_get_one_line(client, query, needle):
    one_line(client.post(f"/api/fit?{query}", content=encoded(note(0.5))), 422, needle)
    healthy(client)


def test_too_many_uploads_at_once_get_503(client, monkeypatch):
    monkeypatch.setattr(server, "MAX_UPLOADS", 0)
    one_line(client.post("/api/fit", content=encoded(note(0.5))), 503, "recordings at once; try again")
    healthy(client)


def test_the_page_learns_the_fit_models_and_limits(client):
    assert client.get("/api/models").json()["fit"] == {"models": ["banded", "twang", "fd"],
                                                       "max_upload_bytes": MAX_UPLOAD_BYTES,
                                                       "max_upload_s": MAX_UPLOAD_S}


# --- the bytes reader ---------------------------------------------------------------------------

@pytest.mark.parametrize("fmt,subtype", [("WAV", "PCM_24"), ("FLAC", "PCM_16"), ("OGG", "VORBIS")])
def test_bytes_read_as_the_same_file_reads(tmp_path, fmt, subtype, monkeypatch):
    import barsynth.audio_io as audio_io

    monkeypatch.setattr(audio_io, "READ_BLOCK_VALUES", 3000)  # several blocks, a channel count that does not divide
    x = np.random.default_rng(1).uniform(-0.5, 0.5, (20011, 7))
    data = encoded(x, 48000, fmt, subtype)
    path = tmp_path / f"x.{fmt.lower()}"
    path.write_bytes(data)
    mono, rate = audio_from_bytes(data, name=path.name)
    expected, expected_rate = load_audio(path)
    assert rate == expected_rate == 48000 and np.array_equal(mono, expected)


def test_bytes_that_are_no_sound_or_too_much_get_one_line():
    with pytest.raises(AudioFormatError, match=r"^audio file a\.wav: cannot be read as WAV, FLAC or OGG "
                                               r"\(Format not recognised\.\)$"):
        audio_from_bytes(b"plain text" * 10, name="a.wav")
    with pytest.raises(AudioFileError, match=r"^audio file upload: is empty \(0 bytes\)$"):
        audio_from_bytes(b"")
    with pytest.raises(AudioFileError, match=r"^audio file b\.wav: contains no samples$"):
        audio_from_bytes(encoded(np.zeros(0)), name="b.wav")
    data = encoded(note(2.0), fmt="FLAC")
    with pytest.raises(AudioFileError, match=r"is 2\.045 s long; allowed: up to 1\.5 s$"):
        audio_from_bytes(data, max_duration_s=1.5)
    with pytest.raises(AudioFileError, match=r"sample rate 44100 Hz is too high; allowed: up to 22050 Hz$"):
        audio_from_bytes(data, max_rate_hz=22050)
    assert audio_from_bytes(data, max_duration_s=2.5, max_rate_hz=48000)[0].size == note(2.0).size
