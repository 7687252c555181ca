"""A recorded attack as the banded model's excitation (``excitation = sample``, commuted
synthesis): the loops struck by an ideal impulse, the attack heard directly from the trigger,
resampled to the voice's rate, scaled by the level and the mallet velocity; blocks of any size;
refused lengths; a preset file with an attack read back by the command line."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from barsynth.cli import main
from barsynth.dsp.resample import resample
from barsynth.errors import ParameterError
from barsynth.exciters import Sample
from barsynth.exciters.sample import DEFAULT_ATTACK, MAX_ATTACK_SAMPLES
from barsynth.models import get_model
from barsynth.studio.presets_file import preset_toml

MODEL = get_model("banded")
SILENT_MODES = (-120.0,) * 4
"""Every mode of the default bar 120 dB down: what is heard is the attack alone."""


def burst(seconds: float, rate: int, frequency_hz: float = 3000.0) -> tuple[float, ...]:
    """A Hann-windowed tone burst, peak about 1."""
    n = int(round(seconds * rate))
    t = np.arange(n) / rate
    return tuple(float(v) for v in np.hanning(n) * np.sin(2 * np.pi * frequency_hz * t))


def raw(parameters, seconds, rate=48000):
    return MODEL.render(parameters, duration_s=seconds, sample_rate=rate, normalize=False, dtype=np.float64)


def test_the_first_samples_are_the_attack_until_the_loops_speak():
    """Before the shortest loop has gone round once the output is the resampled attack times its
    level and the velocity, nothing else (correlation 1); after it, the loops ring too."""
    attack = burst(0.02, 44100)
    p = {"excitation": "sample", "attack_samples": attack, "attack_rate_hz": 44100, "attack_level_db": -6.0,
         "mallet_velocity_m_s": 2.0, "level_db": -3.0, "tuning": "ratios", "mode_ratios": (1.0, 2.7, 5.2)}
    x = raw(p, 0.2)
    quiet = int(MODEL.voice(p)._bank.loops["delay"].min())  # samples before any loop is heard
    expected = resample(np.array(attack), 44100, 48000) * 10 ** (-6 / 20) * 2.0 * 10 ** (-3 / 20)
    head = x[:quiet]
    assert quiet > 20
    assert np.corrcoef(head, expected[:quiet])[0, 1] > 0.9999
    assert head == pytest.approx(expected[:quiet], rel=1e-12, abs=1e-15)
    alone = raw({**p, "mode_gains_db": SILENT_MODES[:3]}, 0.2)
    assert np.abs(x[quiet:] - alone[quiet:]).max() > 0.1 * np.abs(alone).max()  # the loops, struck


def test_the_loops_are_struck_by_an_ideal_impulse_and_velocity_scales_everything():
    """Twice the mallet velocity, twice the sound (loops and attack alike); the loops alone are
    the sound of a unit impulse scaled by 2 m v (the attack 120 dB down)."""
    p = {"excitation": "sample", "attack_samples": burst(0.01, 48000)}
    one, two = raw(p, 0.3), raw({**p, "mallet_velocity_m_s": 2.0}, 0.3)
    assert two == pytest.approx(2.0 * one, rel=1e-9, abs=1e-15)
    loops = raw({**p, "attack_level_db": -120.0, "mallet_mass_kg": 0.05}, 0.3)
    heavier = raw({**p, "attack_level_db": -120.0, "mallet_mass_kg": 0.1}, 0.3)
    assert np.abs(heavier - 2.0 * loops).max() < 1e-5 * np.abs(loops).max()  # (but the attack, 120 dB down)


@pytest.mark.parametrize("block", [1, 7, 64, 1000])
def test_blocks_of_any_size_equal_the_offline_render(block):
    """A 30 ms attack at 44.1 kHz heard at 48 kHz, split across blocks (the contract suite checks the
    default click the same way), with a level glide during it."""
    p = {"excitation": "sample", "attack_samples": burst(0.03, 44100), "attack_rate_hz": 44100}
    whole_voice = MODEL.voice(p, sample_rate=48000)
    whole_voice.trigger()
    head = whole_voice.process(500, dtype=np.float64)
    whole_voice.set_parameters(level_db=-10.0)
    whole = np.concatenate([head, whole_voice.process(4300, dtype=np.float64)])
    voice = MODEL.voice(p, sample_rate=48000)
    voice.trigger()
    parts = [voice.process(n, dtype=np.float64) for n in [block] * (500 // block) + [500 % block]]
    voice.set_parameters(level_db=-10.0)
    rest = 4300
    while rest:
        n = min(block, rest)
        parts.append(voice.process(n, dtype=np.float64))
        rest -= n
    assert np.array_equal(np.concatenate(parts), whole)


@pytest.mark.parametrize("recorded,heard", [(44100, 48000), (48000, 44100), (96000, 22050)])
def test_resampling_keeps_the_attacks_duration(recorded, heard):
    """A 50 ms burst recorded at one rate lasts 50 ms at the other (its envelope above -40 dB of
    its peak measured in the sound, the modes 120 dB down)."""
    p = {"excitation": "sample", "attack_samples": burst(0.05, recorded, 1000.0), "attack_rate_hz": recorded,
         "attack_level_db": 0.0, "mode_gains_db": SILENT_MODES}
    x = raw(p, 0.1, heard)
    loud = np.flatnonzero(np.abs(x) > 0.01 * np.abs(x).max())
    reference = np.flatnonzero(np.abs(np.array(p["attack_samples"])) > 0.01)
    assert (loud[-1] - loud[0]) / heard == pytest.approx((reference[-1] - reference[0]) / recorded, abs=1.5e-3)
    assert np.abs(x).max() == pytest.approx(1.0, abs=0.02)


@pytest.mark.parametrize("values,rate,needle", [
    ((0.1,) * 4801, 48000, "attack_samples has 4801 values at attack_rate_hz = 48000"),
    ((0.1,) * 801, 8000, "(800 at 8000 Hz)"),
    ((0.1,) * (MAX_ATTACK_SAMPLES + 1), 192000, f"attack_samples has {MAX_ATTACK_SAMPLES + 1} values; allowed"),
    ((0.5, 1.5), 48000, "attack_samples: value 2 = 1.5 is out of range"),
])
def test_refused_attacks_give_one_line_naming_the_row(values, rate, needle):
    with pytest.raises(ParameterError) as info:
        raw({"excitation": "sample", "attack_samples": values, "attack_rate_hz": rate}, 0.05)
    assert needle in str(info.value) and "attack_samples" in str(info.value) and "\n" not in str(info.value)
    voice = MODEL.voice({"excitation": "sample"})  # a change to one is refused and changes nothing
    voice.trigger()
    twin = MODEL.voice({"excitation": "sample"})
    twin.trigger()
    with pytest.raises(ParameterError):
        voice.set_parameters(attack_samples=values, attack_rate_hz=rate)
    assert voice.parameters == twin.parameters
    assert np.array_equal(voice.process(2000, dtype=np.float64), twin.process(2000, dtype=np.float64))


def test_the_longest_attack_is_taken_at_every_rate():
    longest = tuple(np.linspace(-1.0, 1.0, MAX_ATTACK_SAMPLES).tolist())
    x = raw({"excitation": "sample", "attack_samples": longest, "attack_rate_hz": 192000}, 0.15, 44100)
    assert np.all(np.isfinite(x))


def test_a_preset_file_with_an_attack_reads_back_through_the_command_line(tmp_path):
    p = {"excitation": "sample", "attack_samples": burst(0.01, 44100), "attack_rate_hz": 44100,
         "attack_level_db": -10.0, "tuning": "ratios", "mode_ratios": (1.0, 3.9, 9.7), "mode_gains_db": (0.0, -6.0, -9.0)}
    resolved = MODEL.table.as_dict(MODEL.resolve(p))
    preset = tmp_path / "mine.toml"
    preset.write_text(preset_toml(resolved, description="an attack"), encoding="utf-8")
    out = tmp_path / "mine.wav"
    result = CliRunner().invoke(main, ["render", "banded", "--preset", str(preset), "--duration", "0.2", "--raw",
                                       "--subtype", "FLOAT", "-o", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    import soundfile

    heard, rate = soundfile.read(out, dtype="float64")
    assert rate == 48000
    assert heard == pytest.approx(raw(p, 0.2).astype(np.float32), abs=1e-7)
    described = CliRunner().invoke(main, ["describe", "banded", "--preset", str(preset)], catch_exceptions=False)
    assert "attack_samples           (441 values)" in described.output


def test_the_table_says_where_the_attack_acts_and_keeps_its_samples_out_of_sliders():
    table = MODEL.table
    assert table["attack_samples"].data and table["attack_rate_hz"].data and not table["attack_level_db"].data
    assert table["attack_samples"].default == DEFAULT_ATTACK and len(DEFAULT_ATTACK) == 48
    assert abs(sum(DEFAULT_ATTACK)) < 1e-12 and max(map(abs, DEFAULT_ATTACK)) == pytest.approx(1.0, abs=1e-5)
    resolved = MODEL.resolve({})
    assert {name for name, _ in table.inactive(resolved)} >= {"attack_samples", "attack_rate_hz", "attack_level_db"}
    assert not table.inactive(MODEL.resolve({"excitation": "sample"}), ("attack_samples", "mallet_velocity_m_s",
                                                                       "mallet_mass_kg", "strike_position"))
    assert table.inactive(MODEL.resolve({"excitation": "sample"}), ("mallet_hardness",))
    assert "| `attack_samples` | - | up to 19200 values, each -1 to 1 | (48 values) |" in table.to_markdown()
    assert Sample in MODEL.exciters and Sample.direct and Sample.in_advance
