"""The note analysis (barsynth.analysis.analyze_note) against notes whose truth is known.

Each note is a sum of exponentially decaying cosines built here with NumPy from its true
frequencies, levels and T60s, with what real recordings add: white noise at -40 dB re the
peak, a noise burst for the strike, hum, a short room reverb, a second decay stage, a
doublet, a loop. Real soundfont notes are checked where the files (and the SoundFont
reader) are installed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from barsynth.analysis import NoteAnalysis, analyze_note
from barsynth.analysis.onset import onset_at, strike_at
from barsynth.errors import ParameterError

LN1000 = math.log(1000.0)


def note(modes, sample_rate, duration_s=2.0, lead_s=0.0):
    """Sum of A exp(-(t - lead) ln(1000) / T60) cos(2 pi f (t - lead) + phase) from ``lead_s``
    on, for (f, A, T60, phase); T60 inf holds; T60 ("loop", T, t_loop) decays until t_loop
    and then holds."""
    t = np.arange(int(round(duration_s * sample_rate))) / sample_rate - lead_s
    x = np.zeros(t.size)
    for f, a, t60, phase in modes:
        if isinstance(t60, tuple):
            envelope = np.exp(-np.minimum(t, t60[2]) * LN1000 / t60[1])
        elif math.isfinite(t60):
            envelope = np.exp(-t * LN1000 / t60)
        else:
            envelope = np.ones(t.size)
        x += np.where(t >= 0, a * envelope * np.cos(2 * math.pi * f * t + phase), 0.0)
    return x


def with_noise(x, db=-40.0, seed=0):
    """White noise ``db`` dB re the peak added."""
    rng = np.random.default_rng(seed)
    return x + np.max(np.abs(x)) * 10.0 ** (db / 20.0) * rng.standard_normal(x.size)


def burst(sample_rate, duration_s=2.0, amplitude=0.3, seed=1, lead_s=0.0):
    """A strike's knock: white noise decaying with a 1.7 ms time constant."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration_s * sample_rate))) / sample_rate - lead_s
    return np.where(t >= 0, amplitude * np.exp(-np.maximum(t, 0.0) / 0.0017), 0.0) * rng.standard_normal(t.size)


def room(x, sample_rate, t60_s=0.3, level_db=-20.0, seed=3):
    """A short room: the direct sound plus exponentially decaying noise (T60, energy re the direct)."""
    from scipy.signal import fftconvolve

    rng = np.random.default_rng(seed)
    t = np.arange(int(1.2 * t60_s * sample_rate)) / sample_rate
    h = rng.standard_normal(t.size) * np.exp(-t * LN1000 / t60_s)
    h *= 10.0 ** (level_db / 20.0) / np.sqrt(np.sum(h**2))
    h[0] += 1.0
    return fftconvolve(x, h)[: x.size]


def cents(measured, true):
    return 1200.0 * math.log2(measured / true)


def level_db(amplitude):
    return 20.0 * math.log10(amplitude)


def everything(analysis):
    return list(analysis.below_f0) + list(analysis.partials)


def nearest(analysis, frequency_hz):
    return min(everything(analysis), key=lambda p: abs(math.log(p.frequency_hz / frequency_hz)))


def json_round_trip(analysis):
    text = json.dumps(analysis.to_json(), allow_nan=False)
    return json.loads(text)


# A bar-like note: 1 : 4 : 10, T60 from 1.5 s down to 0.5 s.
MARIMBA = [(262.3, 0.5, 1.5, 0.4), (1047.1, 0.3, 0.6, 1.3), (2618.0, 0.2, 0.5, 2.2)]


# -- precision ---------------------------------------------------------------------------
@pytest.mark.parametrize("sample_rate", [8000, 44100, 48000, 96000])
def test_noisy_decays_are_measured_to_within_half_a_cent_1_db_and_3_percent(sample_rate):
    x = with_noise(note(MARIMBA, sample_rate, lead_s=0.05), seed=7)
    analysis = analyze_note(x, sample_rate)
    assert analysis.f0_hz == pytest.approx(262.3, rel=1e-4)
    assert analysis.start_s == pytest.approx(0.05, abs=0.002)
    for f, a, t60, _ in MARIMBA:
        p = nearest(analysis, f)
        assert abs(cents(p.frequency_hz, f)) <= 0.5, (f, p)
        assert abs(p.level_db - level_db(a)) <= 1.0, (f, p)
        assert p.decay.range_db >= 20.0, (f, p.decay)  # a decay long enough for the 3 % target
        assert p.t60_s == pytest.approx(t60, rel=0.03), (f, p)
        assert p.decay.method == "line" and p.decay.knee_s is None and not p.beats
        assert p.decay.rms_db < 1.0 and p.decay.r2 > 0.98
        # the range: from where the envelope is clean to 10 dB above the noise floor
        assert p.decay.range_end_db == pytest.approx(p.decay.floor_db + 10.0, abs=3.0)
        assert 0.05 < p.decay.range_start_s < p.decay.range_end_s <= 2.0


def test_clean_decays_are_measured_exactly():
    x = note(MARIMBA, 48000)
    analysis = analyze_note(x, 48000)
    for f, a, t60, phase in MARIMBA:
        p = nearest(analysis, f)
        assert abs(cents(p.frequency_hz, f)) < 0.01
        assert p.level_db == pytest.approx(level_db(a), abs=0.05)
        assert p.t60_s == pytest.approx(t60, rel=0.002)
        assert math.cos(p.phase_rad - phase) > 0.999
        (only,) = p.components
        assert (only.frequency_hz, only.level_db, only.t60_s, only.phase_rad) == (
            p.frequency_hz, p.level_db, pytest.approx(p.t60_s), p.phase_rad)
    assert [round(p.ratio, 3) for p in analysis.partials] == [1.0, 3.992, 9.981]


def resynthesis(analysis, size):
    """The partials' components summed from the start (a knee found in dB not followed)."""
    t = np.arange(size) / analysis.sample_rate - analysis.start_s
    x = np.zeros(size)
    for p in everything(analysis):
        for c in p.components:
            decay = np.exp(-t * LN1000 / c.t60_s) if c.t60_s else 1.0
            x += np.where(t >= 0, 10.0 ** (c.level_db / 20.0) * decay * np.cos(2 * math.pi * c.frequency_hz * t + c.phase_rad), 0.0)
    return x


@pytest.mark.parametrize("modes", [MARIMBA, [(500.0, 0.4, 0.15, 0.0), (500.0, 0.04, 3.0, 0.0)],
                                   [(440.0, 0.3, 1.5, 0.0), (443.0, 0.25, 1.2, 1.0)]],
                         ids=["marimba", "two-stage", "doublet"])
def test_the_components_resynthesise_the_note(modes):
    clean = note(modes, 44100, lead_s=0.03)
    analysis = analyze_note(with_noise(clean), 44100)
    error = resynthesis(analysis, clean.size) - clean
    assert 10.0 * math.log10(np.sum(error**2) / np.sum(clean**2)) < -30.0


def test_a_room_moves_levels_by_less_than_1_db_and_frequencies_by_less_than_a_cent():
    x = with_noise(room(note(MARIMBA, 44100), 44100))
    analysis = analyze_note(x, 44100)
    for f, a, t60, _ in MARIMBA:
        p = nearest(analysis, f)
        assert abs(cents(p.frequency_hz, f)) <= 1.0, (f, p)
        assert abs(p.level_db - level_db(a)) <= 1.0, (f, p)
    # the room (T60 0.3 s) barely touches a decay five times longer
    assert nearest(analysis, 262.3).t60_s == pytest.approx(1.5, rel=0.05)


# -- f0 ----------------------------------------------------------------------------------
def test_hum_under_a_marimba_is_reported_below_f0_and_not_used_for_ratios():
    hum = [(60.0, 0.05, math.inf, 0.0), (120.0, 0.01, math.inf, 1.0)]
    x = with_noise(note(MARIMBA + hum, 44100))
    analysis = analyze_note(x, 44100)
    assert analysis.f0_hz == pytest.approx(262.3, rel=1e-4)
    assert analysis.f0_family == "tuned bar 1:4:10"
    assert analysis.partials[0].ratio == 1.0
    assert [p.ratio for p in analysis.partials] == pytest.approx([1.0, 1047.1 / 262.3, 2618.0 / 262.3], rel=1e-4)
    below = {round(p.frequency_hz): p for p in analysis.below_f0}
    assert set(below) == {60, 120}
    for p in below.values():
        assert p.ratio < 1.0
        assert p.t60_s is None and p.decay.sustains  # hum does not decay
    assert below[60].level_db == pytest.approx(level_db(0.05), abs=1.0)
    assert not analysis.looped  # the note decays; only the hum holds


def test_a_glockenspiel_whose_first_partial_is_weaker_than_its_second():
    modes = [(784.0, 0.15, 1.0, 0.3), (784.0 * 2.71, 0.4, 0.6, 1.0), (784.0 * 5.15, 0.1, 0.3, 2.0)]
    analysis = analyze_note(with_noise(note(modes, 44100) + burst(44100, amplitude=0.2)), 44100)
    assert analysis.f0_hz == pytest.approx(784.0, rel=1e-4)
    assert analysis.f0_family == "free bar"
    assert analysis.partials[1].level_db > analysis.partials[0].level_db + 6.0


def test_a_harmonic_note():
    modes = [(220.0 * n, 0.5 / n, 2.0 / math.sqrt(n), float(n)) for n in range(1, 11)]
    analysis = analyze_note(with_noise(note(modes, 44100)), 44100)
    assert analysis.f0_hz == pytest.approx(220.0, rel=1e-5)
    assert analysis.f0_family == "harmonic"
    assert analysis.f0_explained > 0.99
    assert [p.ratio for p in analysis.partials] == pytest.approx(list(range(1, 11)), abs=1e-3)


def test_a_nominal_pitch_picks_a_weak_fundamental():
    modes = [(500.0, 0.02, 1.0, 0.0), (500.0 * 2.756, 0.5, 0.8, 1.0)]
    x = with_noise(note(modes, 44100), -60.0)
    assert analyze_note(x, 44100).f0_hz == pytest.approx(1378.0, rel=1e-4)  # 28 dB weaker: not f0
    assert analyze_note(x, 44100, nominal_hz=493.9).f0_hz == pytest.approx(500.0, rel=1e-4)


# -- decays: two stages, doublets, loops ---------------------------------------------------
def test_a_two_stage_decay_reports_its_knee_and_both_t60s():
    t60s, amplitudes = (0.15, 3.0), (0.4, 0.04)
    modes = [(500.0, a, t60, 0.0) for a, t60 in zip(amplitudes, t60s)]
    p = analyze_note(with_noise(note(modes, 44100), -60.0), 44100).partials[0]
    assert p.decay.method == "two-stage"
    assert p.t60_s == pytest.approx(0.15, rel=0.05)
    assert p.decay.second_t60_s == pytest.approx(3.0, rel=0.05)
    knee = math.log(10.0) / (LN1000 / 0.15 - LN1000 / 3.0)  # where the two are equal
    assert p.decay.knee_s == pytest.approx(knee, abs=0.01)
    assert p.level_db == pytest.approx(level_db(0.44), abs=0.5)
    assert not p.decay.sustains
    # the two exponentials themselves, to resynthesise it
    fast, slow = sorted(p.components, key=lambda c: c.t60_s)
    assert (fast.t60_s, slow.t60_s) == (pytest.approx(0.15, rel=0.05), pytest.approx(3.0, rel=0.05))
    assert (fast.level_db, slow.level_db) == (pytest.approx(level_db(0.4), abs=0.5),
                                              pytest.approx(level_db(0.04), abs=0.5))


def test_a_doublet_the_file_resolves_is_two_linked_partials():
    modes = [(440.0, 0.3, 1.5, 0.0), (443.0, 0.25, 1.2, 1.0)]
    analysis = analyze_note(with_noise(note(modes, 44100)), 44100)
    found = [p for p in everything(analysis) if 430 < p.frequency_hz < 450]
    assert len(found) == 2
    for (f, a, t60, _), p in zip(modes, sorted(found, key=lambda p: p.frequency_hz)):
        assert abs(cents(p.frequency_hz, f)) <= 0.5
        assert p.level_db == pytest.approx(level_db(a), abs=1.0)
        assert p.t60_s == pytest.approx(t60, rel=0.03)
        assert p.decay.method == "doublet"
    assert found[0].doublet_hz == found[1].frequency_hz and found[1].doublet_hz == found[0].frequency_hz


def test_a_doublet_too_close_for_the_file_is_one_partial_that_beats():
    modes = [(440.0, 0.3, 1.5, 0.0), (440.4, 0.25, 1.2, 1.0)]  # 0.4 Hz: under one beat in 2 s
    analysis = analyze_note(with_noise(note(modes, 44100)), 44100)
    found = [p for p in everything(analysis) if 430 < p.frequency_hz < 450]
    assert len(found) == 1
    assert found[0].beats and found[0].doublet_hz is None
    assert 439.9 < found[0].frequency_hz < 440.5


def test_a_looped_sample_holds_after_its_loop():
    modes = [(523.0, 0.4, ("loop", 0.8, 0.6), 0.0), (1046.0, 0.2, ("loop", 0.5, 0.6), 1.0)]
    analysis = analyze_note(with_noise(note(modes, 44100), -60.0), 44100)
    assert analysis.looped
    p = analysis.partials[0]
    assert p.frequency_hz == pytest.approx(523.0, rel=1e-5)
    assert p.t60_s is None and p.decay.sustains
    assert p.decay.knee_s == pytest.approx(0.6, abs=0.03)
    assert p.decay.t60_s == pytest.approx(0.8, rel=0.05)  # the decay before the loop
    assert p.decay.second_t60_s is None
    assert json_round_trip(analysis)["partials"][0]["t60_s"] is None


def test_decaying_notes_are_not_looped():
    assert not analyze_note(with_noise(note(MARIMBA, 44100)), 44100).looped


# -- the attack ------------------------------------------------------------------------------
def test_the_strike_is_the_attack_and_not_a_partial():
    x = with_noise(note(MARIMBA, 44100, lead_s=0.1) + burst(44100, lead_s=0.1))
    analysis = analyze_note(x, 44100)
    attack = analysis.attack
    assert 0.002 <= attack.duration_s <= 0.04
    assert -40.0 < attack.energy_db < -5.0
    assert attack.centroid_hz > 3000.0  # white noise: broadband
    assert {round(p.frequency_hz) for p in everything(analysis)} == {262, 1047, 2618}
    for f, a, t60, _ in MARIMBA:
        p = nearest(analysis, f)
        assert p.level_db == pytest.approx(level_db(a), abs=1.0)
        assert p.t60_s == pytest.approx(t60, rel=0.03)


def test_the_onset_follows_spec_7_1_and_the_strike_ignores_noise_before_it():
    x = with_noise(note(MARIMBA, 44100, lead_s=0.2), -70.0)
    first = int(np.argmax(np.abs(x) >= 0.01 * np.max(np.abs(x))))
    assert onset_at(x, 44100) == max(0, first - round(0.003 * 44100))
    noisy = with_noise(note(MARIMBA, 44100, lead_s=0.2), -40.0)
    assert abs(strike_at(noisy, 44100) - round(0.2 * 44100)) <= 0.001 * 44100
    assert strike_at(np.zeros(100), 44100) == 0


# -- anything else: an analysis (perhaps empty), never an exception ----------------------
@pytest.mark.parametrize("sample_rate", [8000, 11025, 22050, 44100, 96000, 192000])
@pytest.mark.parametrize("kind", ["silence", "noise", "clipped", "dc", "click", "square"])
@pytest.mark.parametrize("length_s", [1e-4, 0.02, 0.3])
def test_any_input_gives_an_analysis(sample_rate, kind, length_s):
    n = max(1, int(length_s * sample_rate))
    t = np.arange(n) / sample_rate
    rng = np.random.default_rng(5)
    x = {
        "silence": np.zeros(n),
        "noise": rng.standard_normal(n) * 0.1,
        "clipped": np.clip(5.0 * note(MARIMBA, sample_rate, length_s), -1.0, 1.0)[:n],
        "dc": np.full(n, 0.3),
        "click": np.concatenate(([1.0], np.zeros(n - 1))),
        "square": np.sign(np.sin(2 * math.pi * 440.0 * t)) * 0.5,
    }[kind]
    analysis = analyze_note(x, sample_rate)
    assert isinstance(analysis, NoteAnalysis)
    data = json_round_trip(analysis)
    assert data["sample_rate"] == sample_rate
    if kind in ("silence", "noise", "dc", "click"):
        assert analysis.f0_hz is None and not analysis.partials
    if analysis.f0_hz is None:
        assert analysis.notes  # says why


@pytest.mark.parametrize("seed", range(4))
def test_white_noise_has_no_f0(seed):
    x = np.random.default_rng(seed).standard_normal(2 * 44100) * 0.1
    analysis = analyze_note(x, 44100)
    assert analysis.f0_hz is None and not analysis.partials and not analysis.below_f0
    assert analysis.noise_floor_db == pytest.approx(-20.0, abs=1.0)


def test_the_json_keeps_the_old_keys_and_adds_the_rest():
    data = json_round_trip(analyze_note(with_noise(note(MARIMBA, 44100)), 44100))
    assert {"sample_rate", "duration_s", "onset_s", "start_s", "f0_hz", "f0_index", "f0_family", "f0_explained",
            "looped", "noise_floor_db", "attack", "partials", "below_f0", "notes"} <= set(data)
    assert set(data["attack"]) == {"duration_s", "energy_db", "centroid_hz"}
    p = data["partials"][0]
    assert {"frequency_hz", "level_db", "t60_s", "ratio", "phase_rad", "beats", "doublet_hz", "decay",
            "components"} <= set(p)
    assert set(p["components"][0]) == {"frequency_hz", "level_db", "t60_s", "phase_rad"}
    assert {"method", "t60_s", "range_start_s", "range_end_s", "range_start_db", "range_end_db", "range_db",
            "floor_db", "rms_db", "r2", "points", "knee_s", "second_t60_s", "line_rms_db", "sustains"} <= set(p["decay"])
    assert data["f0_index"] == 0 and p["ratio"] == 1.0


def test_max_partials_and_min_level_keep_the_strongest():
    modes = [(220.0 * n, 0.5 / n**2, 2.0, float(n)) for n in range(1, 11)]  # -6 dB per octave squared
    x = with_noise(note(modes, 44100), -80.0)
    assert len(analyze_note(x, 44100, max_partials=3).partials) == 3
    kept = analyze_note(x, 44100, min_level_db=-20.0).partials
    assert [round(p.ratio) for p in kept] == [1, 2, 3]  # 1/9 is -19 dB, 1/16 is -24 dB


@pytest.mark.parametrize("call, name", [
    (lambda: analyze_note(np.zeros(100), 44100, nominal_hz=-1.0), "nominal_hz"),
    (lambda: analyze_note(np.zeros(100), 44100, nominal_hz=30000.0), "nominal_hz"),
    (lambda: analyze_note(np.zeros(100), 44100, max_partials=0), "max_partials"),
    (lambda: analyze_note(np.zeros(100), 44100, min_level_db=3.0), "min_level_db"),
    (lambda: analyze_note(np.zeros((2, 100)), 44100), "samples"),
    (lambda: analyze_note(np.zeros(0), 44100), "samples"),
    (lambda: analyze_note(np.zeros(100), 0.0), "sample_rate"),
    (lambda: analyze_note([0.0, math.nan], 44100), "samples"),
])
def test_bad_arguments_are_refused_by_name(call, name):
    with pytest.raises(ParameterError, match=name):
        call()


# -- real recordings (for development: skipped where the soundfonts are not installed) -----
MUSESCORE = Path("/usr/share/sounds/sf3/MuseScore_General_Lite.sf3")
# (GM program name, sample name): f0 within 25 cents of the font's root key
REAL_NOTES = [
    ("marimba", "Marimba C5"), ("marimba", "Marimba C6"), ("xylophone", "Xylophone C5"),
    ("xylophone", "Xylophone C6"), ("vibraphone", "Vibraphone D#5"), ("kalimba", "Kalimba F6"),
    ("celesta", "Celesta C4"), ("glockenspiel", "Glocken G7"),
]


@pytest.fixture(scope="module")
def musescore():
    soundfont = pytest.importorskip("barsynth.soundfont")
    if not MUSESCORE.exists():
        pytest.skip(f"{MUSESCORE} is not installed (Debian: musescore-general-soundfont-small)")
    return soundfont, soundfont.SoundFont(MUSESCORE)


@pytest.mark.parametrize("program, sample", REAL_NOTES)
def test_real_notes_find_the_root_key(musescore, program, sample):
    soundfont, font = musescore
    zone = next(z for z in font.preset(soundfont.GM_PROGRAMS[program]).zones if z.sample.name == sample)
    samples, rate = font.read(zone.sample)
    analysis = analyze_note(samples, rate, nominal_hz=zone.nominal_hz)
    assert abs(cents(analysis.f0_hz, zone.nominal_hz)) <= 25.0
    assert analysis.attack.duration_s <= 0.15
    for p in everything(analysis):
        assert math.isfinite(p.frequency_hz) and p.level_db <= 6.0
        # a doublet's beats notch its dB envelope: it is judged by its complex fit instead
        assert p.decay.rms_db <= 6.0 or p.decay.method == "doublet"
    json_round_trip(analysis)
