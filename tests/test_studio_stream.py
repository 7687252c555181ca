"""The studio's live stream (studio.stream) without a network: pacing, changes, level, stop, sleep."""

from __future__ import annotations

import json

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.studio.stream import BLOCK, HEADER, LIMIT, Stream, StreamError, parse_message

RATE = 48000


def started(model_name: str = "banded", parameters: dict | None = None, **options) -> Stream:
    stream = Stream(**options)
    model, resolved, rate = stream.prepare_start({"model": model_name, "parameters": parameters or {},
                                                  "sample_rate": RATE})
    stream.start(model, *Stream.build_voice(model, resolved, rate), rate)
    return stream


def decode(data: bytes) -> tuple[int, int, np.ndarray]:
    number, change = HEADER.unpack(data[:HEADER.size])
    return number, change, np.frombuffer(data[HEADER.size:], "<f4")


def play(stream: Stream, seconds: float, *, played_too: bool = True) -> tuple[np.ndarray, list[int]]:
    """Take blocks for ``seconds``, reporting each as played at once (a page keeping up)."""
    samples, ids = [], []
    for _ in range(int(seconds * RATE) // BLOCK):
        if not stream.wants_block():
            break
        _, change, x = decode(stream.next_block())
        samples.append(x)
        ids.append(change)
        if played_too:
            stream.handle({"type": "played", "samples": stream.samples_sent})
    return (np.concatenate(samples) if samples else np.zeros(0, np.float32)), ids


def test_the_stream_is_the_models_sound_times_one_gain():
    """Block for block, the stream is the voice's own samples times the gain set at the start
    (here the limiter has nothing to do): the offline render, scaled."""
    stream = started("banded", {"tuning": "ratios", "frequency_hz": 440.0})
    stream.handle({"type": "trigger"})
    x, _ = play(stream, 1.0)
    offline = get_model("banded").render({"tuning": "ratios", "frequency_hz": 440.0}, duration_s=x.size / RATE,
                                         sample_rate=RATE, normalize=False, dtype=np.float64)
    gain = 10 ** (-6 / 20) / np.max(np.abs(offline))  # the probe's peak: the first second
    np.testing.assert_allclose(x, (offline * gain).astype(np.float32), rtol=0, atol=2e-7)
    assert np.max(np.abs(x)) == pytest.approx(10 ** (-6 / 20), rel=1e-4)


def test_the_physical_twang_streams_its_own_sound():
    """The ruler (a finite-difference bar with contacts solved each sample) streams block for
    block the samples of its offline render, times the gain set at the start."""
    stream = started("ruler", {})
    stream.handle({"type": "trigger"})
    x, _ = play(stream, 1.0)
    offline = get_model("ruler").render({}, duration_s=x.size / RATE, sample_rate=RATE, normalize=False,
                                        dtype=np.float64)
    gain = np.max(np.abs(x)) / np.max(np.abs(offline[:x.size]))
    np.testing.assert_allclose(x, (offline * gain).astype(np.float32), rtol=0, atol=2e-6)


def test_the_server_never_runs_more_than_the_lead_ahead():
    stream = started()
    stream.handle({"type": "trigger"})
    sent = 0
    while stream.wants_block():
        stream.next_block()
        sent += 1
    assert sent * BLOCK == stream.lead and stream.lead == 1536  # 32 ms at 48 kHz
    stream.handle({"type": "played", "samples": 512})
    assert sum(1 for _ in iter(lambda: stream.wants_block() and stream.next_block(), False)) == 2
    stream.handle({"type": "played", "samples": 10 ** 9})  # more than was sent: counted as all of it
    assert stream.samples_played == stream.samples_sent


def test_a_change_is_in_the_next_block_and_carries_its_id():
    """The page's in-flight audio is at most the lead, so a change is heard after at most that."""
    stream = started("banded", {"tuning": "ratios", "frequency_hz": 440.0})
    stream.handle({"type": "trigger"})
    play(stream, 0.3)
    stream.handle({"type": "set", "id": 7, "parameters": {"frequency_hz": 660.0}})
    in_flight = stream.samples_sent - stream.samples_played
    assert in_flight <= stream.lead
    x, ids = play(stream, 0.6)
    assert ids[0] == 7 and set(ids) == {7}
    spectrum = np.abs(np.fft.rfft(x[4800:] * np.hanning(x.size - 4800)))
    assert np.fft.rfftfreq(x.size - 4800, 1 / RATE)[np.argmax(spectrum)] == pytest.approx(660.0, abs=2.0)


def largest_step(x: np.ndarray) -> float:
    return float(np.max(np.abs(np.diff(x))))


def test_a_new_model_fades_the_old_one_out_without_a_click():
    stream = started("banded", {"tuning": "ratios", "frequency_hz": 440.0})
    stream.handle({"type": "trigger"})
    before, _ = play(stream, 0.2)
    model, resolved, rate = stream.prepare_start({"model": "twang", "sample_rate": RATE})
    stream.start(model, *Stream.build_voice(model, resolved, rate), rate)
    after, _ = play(stream, 0.1)
    assert stream.model_name == "twang"
    assert largest_step(np.concatenate([before[-480:], after[:960]])) <= 1.05 * largest_step(before[-960:])
    assert np.max(np.abs(after[960:])) < 1e-6  # the old voice is gone, the twang not yet triggered


def test_a_change_that_makes_it_much_louder_is_limited_smoothly():
    stream = started("banded")
    stream.handle({"type": "trigger"})
    before, _ = play(stream, 0.1)
    stream.handle({"type": "set", "id": 1, "parameters": {"level_db": 40.0}})
    after, _ = play(stream, 1.0)
    x = np.concatenate([before, after])
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= LIMIT + 1e-6  # no sample clipped


def test_stop_fades_out_in_10_ms_then_stops_sending_and_a_trigger_starts_afresh():
    stream = started()
    stream.handle({"type": "trigger"})
    play(stream, 0.2)
    stream.handle({"type": "stop"})
    x, _ = play(stream, 0.2)
    assert not stream.running and x.size <= 768  # 10 ms, in whole blocks
    assert abs(x[-1]) < 1e-3 and largest_step(x) < 0.05
    stream.handle({"type": "trigger"})
    again, _ = play(stream, 0.05)
    assert stream.running and np.max(np.abs(again)) > 0.1


def test_a_silent_stream_sleeps_and_a_change_wakes_it():
    stream = started("banded", {"tuning": "ratios", "frequency_hz": 2000.0, "mode_t60s_s": (0.05,)})
    stream.handle({"type": "trigger"})
    x, _ = play(stream, 10.0)
    assert not stream.running
    assert 3.0 <= x.size / RATE <= 3.1  # three seconds after the trigger, silent for one
    stream.handle({"type": "set", "id": 2, "parameters": {"level_db": -3.0}})
    assert stream.running


def test_bad_messages_are_refused_and_change_nothing():
    stream = started("twang")
    for text, words in [("not json", "not valid JSON"), ("[1]", "not a stream message"),
                        ('{"type": "dance"}', "'dance' is not a stream message"),
                        ('{"type": "set"}', "needs parameters"),
                        ('{"type": "set", "parameters": {}, "colour": 1}', "unknown field 'colour'"),
                        ('{"type": "played", "samples": NaN}', "not valid JSON"),
                        ('{"type": "trigger", "x": 1}', "allowed: none")]:
        with pytest.raises(StreamError, match=words):
            parse_message(text)
    with pytest.raises(ParameterError, match="q = 5000"):
        stream.handle(parse_message(json.dumps({"type": "set", "id": 1, "parameters": {"q": 5000}})))
    with pytest.raises(StreamError, match="id = -1"):
        stream.handle({"type": "set", "id": -1, "parameters": {"q": 200}})
    with pytest.raises(StreamError, match="samples = 1.5"):
        stream.handle({"type": "played", "samples": 1.5})
    assert stream.applied_id == 0 and stream._playing.voice.parameters.q == 100.0
    with pytest.raises(StreamError, match="differs from this stream's 48000 Hz"):
        stream.prepare_start({"model": "twang", "sample_rate": 44100})
    with pytest.raises(StreamError, match="sample_rate = 200000"):
        Stream().prepare_start({"model": "twang", "sample_rate": 200000})
    with pytest.raises(StreamError, match="needs a started stream"):
        Stream().handle({"type": "trigger"})


def test_a_jump_from_very_quiet_to_very_loud_never_reaches_full_scale():
    """The gain probe of a quiet voice gives a large gain; the limiter's ramp must not let the
    first samples of a +100 dB jump through."""
    for model_name in ("banded", "allpass"):
        stream = started(model_name, {"level_db": -60.0})
        stream.handle({"type": "trigger"})
        before, _ = play(stream, 0.1)
        stream.handle({"type": "set", "id": 1, "parameters": {"level_db": 40.0}})
        after, _ = play(stream, 0.3)
        assert np.max(np.abs(after)) <= LIMIT + 1e-6, model_name
        assert np.all(np.isfinite(after))


def test_voices_fading_out_are_bounded_however_often_a_page_starts():
    stream = started("twang")
    stream.handle({"type": "trigger"})
    model, resolved, rate = stream.prepare_start({"model": "twang", "sample_rate": RATE})
    for _ in range(50):
        stream.start(model, *Stream.build_voice(model, resolved, rate), rate)
    assert len(stream._leaving) <= 4
    x, _ = play(stream, 0.05)
    assert np.all(np.isfinite(x)) and not stream._leaving


def test_a_trigger_during_the_stop_fade_lets_the_fade_finish_beside_the_new_strike():
    for model_name in ("twang", "banded"):
        stream = started(model_name)
        stream.handle({"type": "trigger"})
        ringing, _ = play(stream, 0.3)
        stream.handle({"type": "stop"})
        fading, _ = play(stream, 0.003)  # one block of the 10 ms fade
        stream.handle({"type": "trigger"})
        after, _ = play(stream, 0.02)
        x = np.concatenate([ringing[-480:], fading, after])
        steady = largest_step(ringing[-960:])
        fresh = started(model_name)
        fresh.handle({"type": "trigger"})
        attack = largest_step(np.concatenate([[0.0], play(fresh, 0.02)[0]]))  # from silence: its onset too
        assert largest_step(x) <= 1.2 * (steady + attack), model_name


def test_huge_numbers_in_messages_are_refused_not_crashed_on():
    stream = started("twang")
    for message in ({"type": "played", "samples": float("inf")}, {"type": "set", "id": 1e400, "parameters": {}}):
        with pytest.raises(StreamError, match="out of range"):
            stream.handle(message)


# -- samples that blow up, and the limiter's release -----------------------------------------------
class ScriptedVoice:
    """A stand-in voice: a 0.5-amplitude 440 Hz sine from each trigger, with ``bad`` (a value)
    written at sample ``at`` of the sound (counted from the trigger); what the stream needs."""

    def __init__(self, bad: float | None = None, at: int = 3 * BLOCK + 17):
        self.bad, self.at, self.n, self.silent = bad, at, 0, False
        self.refused: list[str] = []
        self.fading = False
        self.sample_rate = float(RATE)
        self.parameters = get_model("banded").table.resolve({"frequency_hz": 123.0})

    def warm_up(self) -> None:
        """Nothing to compile ahead (the stream warms every voice it builds)."""

    def process(self, n: int, dtype=np.float64) -> np.ndarray:
        k = self.n + np.arange(n)
        x = 0.0 * k if self.silent else 0.5 * np.sin(2 * np.pi * 440.0 * k / RATE)
        if self.bad is not None and not self.silent and self.n <= self.at < self.n + n:
            x[self.at - self.n] = self.bad
        self.n += n
        return x.astype(dtype)

    def trigger(self) -> None:
        self.n, self.silent = 0, False

    def reset(self) -> None:  # silence until the next trigger
        self.n, self.silent = 0, True

    def release(self) -> None:
        pass


def scripted(voice: ScriptedVoice) -> Stream:
    stream = Stream()
    stream.start(get_model("banded"), voice, 1.0, RATE)  # gain 1: the stream is the voice itself
    stream.handle({"type": "trigger"})
    return stream


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), 1e30])
def test_a_voice_that_blows_up_is_silenced_and_the_page_told_never_sent(bad):
    stream = scripted(ScriptedVoice(bad))
    x, _ = play(stream, 0.1)
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= LIMIT + 1e-6
    assert np.max(np.abs(x[:3 * BLOCK])) > 0.4  # it sounded before the blow-up ...
    assert np.max(np.abs(x[3 * BLOCK:])) == 0.0  # ... and from the bad block on, silence
    errors = stream.refused()
    assert len(errors) == 1 and "\n" not in errors[0] and len(errors[0]) < 300
    assert errors[0].startswith("model banded with frequency_hz=123 gives ")
    assert ("non-finite" if not np.isfinite(bad) else "exploding") in errors[0]
    assert stream.refused() == []  # told once
    stream.handle({"type": "trigger"})  # the stream stays usable: a new trigger sounds again
    again, _ = play(stream, 3 * BLOCK / RATE)
    assert np.max(np.abs(again)) > 0.4


def test_a_start_whose_settings_blow_up_is_refused_and_the_stream_goes_on(monkeypatch):
    """An injected model that explodes (a stand-in for any model's blow-up): build_voice refuses it."""
    from barsynth.errors import SamplesError

    stream = started("banded")
    stream.handle({"type": "trigger"})
    model = get_model("banded")
    monkeypatch.setattr(model, "voice", lambda *a, **k: ScriptedVoice(float("nan"), at=100))
    model_, resolved, rate = stream.prepare_start({"model": "banded", "sample_rate": RATE})
    with pytest.raises(SamplesError, match="non-finite samples"):
        Stream.build_voice(model_, resolved, rate)
    x, _ = play(stream, 0.05)
    assert stream.model_name == "banded" and np.max(np.abs(x)) > 0.1


def test_the_fd_blow_up_case_is_never_streamed():
    """fd plucked at its clamp (a blow-up before the fd fix): refused at start, or if the model
    now gives a sound, a finite one within full scale."""
    from barsynth.errors import SamplesError

    stream = Stream()
    model, resolved, rate = stream.prepare_start({"model": "fd", "sample_rate": RATE, "parameters": {
        "bc": "clamped-free", "excitation": "pluck", "strike_position": 1e-155}})
    try:
        voice, gain = Stream.build_voice(model, resolved, rate)
    except SamplesError as exc:
        assert "model fd with" in str(exc) and "strike_position=1e-155" in str(exc)
        return
    stream.start(model, voice, gain, rate)
    stream.handle({"type": "trigger"})
    x, _ = play(stream, 0.2)
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= LIMIT + 1e-6


def recovery_samples(spike: float) -> int:
    """Samples of sound after a one-sample ``spike`` (at 1 s) until a block is back within 1 dB
    of the voice's own level (0.5 at gain 1)."""
    stream = scripted(ScriptedVoice(spike, at=RATE))
    x, _ = play(stream, 3.0)
    after = x[RATE + 1:]
    blocks = np.abs(after[: after.size // BLOCK * BLOCK]).reshape(-1, BLOCK).max(axis=1)
    back = np.flatnonzero(blocks >= 0.5 * 10 ** (-1 / 20))
    assert back.size, "the level never came back"
    return int(back[0] + 1) * BLOCK


def test_the_limiter_lets_the_level_back_within_half_a_second_after_a_huge_spike():
    """One spike 180 dB above the sound (still below the blow-up bound) cuts the gain by as much;
    the release brings it back within RELEASE_S of sound (at 6 dB/s it took 30 s)."""
    from barsynth.studio import stream as module

    assert recovery_samples(1e9) <= (module.RELEASE_S + 0.05) * RATE
    assert recovery_samples(10.0) <= (module.RELEASE_S + 0.05) * RATE  # a shallow cut too


def test_a_voice_built_for_the_stream_is_warmed_up():
    """The stream builds its voices warmed up (Voice.warm_up): the twang's first slider change
    then never compiles its full kernel in the middle of the stream."""
    model = get_model("twang")
    voice, _ = Stream.build_voice(model, model.table.resolve(), 48000)
    assert voice.voice._run_dynamic is not None and not voice.voice._static
