"""One check of a model's samples on every path (models.rendering.check_samples): non-finite or
exploding output is refused with one line naming the model and its settings, never written or served.

Each path is tested with an injected voice that blows up (so the tests keep their meaning once the
models themselves no longer blow up), and with a real case that blew up when this was written
(fd plucked at its clamp): refused, or, if the model now gives a sound, a finite one."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from fastapi.testclient import TestClient

from barsynth.cli import main
from barsynth.errors import SamplesError
from barsynth.models import get_model
from barsynth.models.base import Voice
from barsynth.models.rendering import MAX_RAW_PEAK, check_samples

RATE = 48000
FD_BLOW_UP = {"bc": "clamped-free", "excitation": "pluck", "strike_position": 1e-155}


class ExplodingVoice(Voice):
    """A banded voice whose sound is fine until ``at`` samples after a trigger, then ``bad`` (NaN,
    inf or a huge value): the whole voice contract (models.base.Voice), its own samples."""

    model = get_model("banded")

    def __init__(self, parameters, bad: float = float("nan"), at: int = 4800, sample_rate: float = RATE):
        self.bad, self.at = bad, at
        super().__init__(parameters, sample_rate=sample_rate)

    def _prepare(self) -> None:
        pass

    def _reset(self) -> None:
        self.n = -10 ** 9  # silence (far from ``at``) until the next trigger

    def _update(self, old) -> None:
        pass

    def trigger(self) -> None:
        self.n = 0

    def _render(self, out: np.ndarray) -> None:
        k = self.n + np.arange(out.size)
        out[:] = np.where(k >= self.at, self.bad, 0.1 * np.sin(2 * np.pi * 440.0 * k / self.sample_rate))
        out[k < 0] = 0.0
        self.n += out.size


@pytest.fixture(params=[float("nan"), float("inf"), 1e30])
def exploding(request, monkeypatch):
    """The banded model, its voices replaced by ones that blow up after 0.1 s."""
    model = get_model("banded")
    monkeypatch.setattr(model, "voice", lambda parameters=None, *, sample_rate=48000.0, seed=0: ExplodingVoice(
        model.table.resolve(parameters) if isinstance(parameters, dict) or parameters is None else parameters,
        request.param, sample_rate=sample_rate))
    return request.param


def assert_the_line(text: str, *needles: str) -> None:
    assert "\n" not in text.strip() and len(text) < 300, text
    for needle in needles:
        assert needle in text, (needle, text)


# -- the check itself ---------------------------------------------------------------------------
def test_finite_samples_within_the_bound_pass_unchanged():
    x = np.array([0.0, -MAX_RAW_PEAK, MAX_RAW_PEAK, 0.5])
    assert check_samples(x, None, RATE) is x


@pytest.mark.parametrize("bad, kind", [(float("nan"), "NaN"), (-float("inf"), "infinite"),
                                       (MAX_RAW_PEAK * 10, "exploding")])
def test_bad_samples_name_the_model_the_settings_and_when(bad, kind):
    parameters = get_model("fd").table.resolve(FD_BLOW_UP)
    x = np.zeros(RATE)
    x[RATE // 4:] = bad
    with pytest.raises(SamplesError) as caught:
        check_samples(x, parameters, RATE, start=RATE // 4)
    assert_the_line(str(caught.value), "model fd with bc=clamped-free, excitation=pluck, strike_position=1e-155",
                    kind, "from 0.5 s")


def test_long_values_and_many_settings_are_shortened():
    model = get_model("fd")
    changed = model.table.settings_at({p.name: 0.37 for p in model.table if p.kind != "floats"})
    parameters = model.table.resolve(changed)
    with pytest.raises(SamplesError) as caught:
        check_samples(np.array([np.nan]), parameters, RATE)
    assert_the_line(str(caught.value), "model fd with", "more gives non-finite")


# -- every path --------------------------------------------------------------------------------
def test_the_cli_refuses_to_write_a_blow_up(tmp_path, exploding):
    out, plot = tmp_path / "x.wav", tmp_path / "x.png"
    # (tuning=ratios: frequency_hz alone would also get a warning line, as it does nothing under tuning=physics)
    result = CliRunner().invoke(main, ["render", "banded", "--set", "tuning=ratios", "--set", "frequency_hz=300",
                                       "--duration", "0.5", "--raw", "--subtype", "FLOAT", "--plot", str(plot),
                                       "-o", str(out)])
    assert result.exit_code == 2
    assert_the_line(result.stderr, "barsynth: error: model banded with tuning=ratios, frequency_hz=300 gives ",
                    "from 0.1 s")
    assert not out.exists() and not plot.exists()


def test_the_cli_never_writes_the_fd_blow_up(tmp_path):
    out = tmp_path / "x.wav"
    result = CliRunner().invoke(main, ["render", "fd", *[f"--set={k}={v}" for k, v in FD_BLOW_UP.items()],
                                       "--duration", "0.2", "-o", str(out)])
    if result.exit_code == 2:
        assert_the_line(result.stderr, "model fd with", "strike_position=1e-155")
        assert not out.exists()
    else:  # the model was fixed: then its sound is finite
        import soundfile

        assert result.exit_code == 0 and np.all(np.isfinite(soundfile.read(out)[0]))


@pytest.fixture
def client():
    from barsynth.studio.server import create_app
    from barsynth.studio.work import Workers

    return TestClient(create_app(workers=Workers(processes=False)), base_url="http://127.0.0.1:8000")


@pytest.mark.parametrize("path", ["/api/render", "/api/picture"])
def test_the_studio_answers_422_with_the_line_and_keeps_serving(client, exploding, path):
    r = client.post(path, json={"model": "banded", "parameters": {"frequency_hz": 300}, "duration_s": 0.5})
    assert r.status_code == 422 and set(r.json()) == {"error"}
    assert_the_line(r.json()["error"], "model banded with frequency_hz=300 gives ")
    assert client.get("/api/health").json() == {"ok": True}
    ok = client.post("/api/render", json={"model": "twang", "duration_s": 0.1})
    assert ok.status_code == 200 and ok.headers["content-type"] == "audio/wav"


def test_the_studio_never_serves_the_fd_blow_up(client):
    import io

    import soundfile

    r = client.post("/api/render", json={"model": "fd", "parameters": FD_BLOW_UP, "duration_s": 0.2})
    if r.status_code == 422:
        assert_the_line(r.json()["error"], "model fd with", "strike_position=1e-155")
    else:
        x, _ = soundfile.read(io.BytesIO(r.content))
        assert r.status_code == 200 and np.all(np.isfinite(x))
        assert np.ptp(x) > 0.01, "a constant (DC) file is no sound"


def test_a_listening_clip_that_blows_up_is_refused_when_the_test_loads(tmp_path, exploding):
    from barsynth.listening.config import ConfigError, load_test

    config = tmp_path / "test.toml"
    config.write_text('[[clips]]\nid = "a"\nmodel = "banded"\nduration_s = 0.5\n'
                      '[[clips]]\nid = "b"\nmodel = "twang"\nduration_s = 0.5\n'
                      '[[mushra]]\nclips = ["a", "b"]\n')
    with pytest.raises(ConfigError) as caught:
        load_test(config)
    assert_the_line(str(caught.value), "[[clips]] #1 (a): model banded with its default parameters gives ")


def test_the_live_stream_refuses_a_start_that_blows_up_and_never_sends_a_later_blow_up(client, monkeypatch):
    """Through the WebSocket: a start whose probe blows up gets an error and the stream plays on
    afterwards; a voice that blows up later (after the 1 s probe) is silenced and the page told."""
    import json

    model = get_model("banded")
    at = {"sample": 4800}
    monkeypatch.setattr(model, "voice", lambda parameters=None, *, sample_rate=48000.0, seed=0: ExplodingVoice(
        model.table.resolve(parameters) if isinstance(parameters, dict) or parameters is None else parameters,
        float("nan"), at=at["sample"], sample_rate=sample_rate))
    with client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000"}) as socket:
        socket.send_json({"type": "start", "model": "banded", "sample_rate": RATE})
        reply = socket.receive_json()
        assert reply["type"] == "error"
        assert_the_line(reply["error"], "model banded with its default parameters gives non-finite")
        at["sample"] = int(1.2 * RATE)  # now past the probe: the start is taken, the blow-up comes later
        socket.send_json({"type": "start", "model": "banded", "sample_rate": RATE})
        assert socket.receive_json()["type"] == "started"
        socket.send_json({"type": "trigger"})
        samples, errors, sent = [], [], 0
        while sent < int(1.5 * RATE):
            message = socket.receive()
            if message.get("bytes"):
                samples.append(np.frombuffer(message["bytes"][8:], "<f4"))
                sent += samples[-1].size
                socket.send_json({"type": "played", "samples": sent})
            elif message.get("text"):
                errors.append(json.loads(message["text"]))
        x = np.concatenate(samples)
        assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= 1.0
        assert np.max(np.abs(x[:RATE])) > 0.1 and np.max(np.abs(x[int(1.25 * RATE):])) == 0.0
        assert len(errors) == 1 and errors[0]["type"] == "error"
        assert_the_line(errors[0]["error"], "non-finite samples (NaN from 1.2 s)")
