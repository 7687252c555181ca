"""The all-pass waveguide bar (spec 3.2), measured: its resonances against physics and
against its own report, decays, levels, positions, streaming and refusals.

Tolerances (48 kHz, the default aluminium bar, q = 100 to 300):
* the model's resonances in the fitted band: within 0.5 cent of Euler-Bernoulli at
  order 24 (every mode below 20 kHz fitted) and at order 8 (the first four fitted);
  the sound itself within 0.05 cent of ``describe`` and 0.6 cent of physics;
* T60: within 3 % of ``describe`` and 12 % of ``q ln(1000) / (pi f)``;
* mode levels after a strike: within 5 % of ``describe``'s gain times the mallet's
  impulse spectrum over the mass;
* a pick-up at a node: 60 dB down where the loop is symmetric about it (exact by
  construction), 20 dB down elsewhere (the filters' phase there is fitted, not exact).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from barsynth.analysis import measure_partial
from barsynth.dsp.smoothing import LEVEL_GLIDE_S
from barsynth.dsp.mallet import hertz_stiffness, mallet_pulse
from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.models.allpass import AllpassVoice
from barsynth.exciters import mallet_contact_s
from barsynth.physics import bar_frequencies

MODEL = get_model("allpass")
RATE = 48000
BAR = {"youngs_modulus_pa": 69e9, "density_kg_m3": 2700.0, "length_m": 0.3, "thickness_m": 0.01}
MASS_KG = 2700.0 * 0.3 * 0.01 * 0.04


def raw(parameters, seconds, rate=RATE):
    return MODEL.render(parameters, duration_s=seconds, sample_rate=rate, normalize=False, dtype=np.float64)


def physics(bc, count):
    return bar_frequencies(**BAR, bc=bc, count=count)


def cents(f, reference):
    return 1200.0 * math.log2(f / reference)


def resonances(parameters, rate=RATE):
    """describe's modes (no spurious ones), in order: mode n is item n - 1."""
    return [m for m in MODEL.describe(parameters, sample_rate=rate) if m.group != "spurious"]


@pytest.mark.parametrize("bc", ["free-free", "clamped-free", "pinned-pinned", "clamped-pinned"])
def test_resonances_land_on_physics_and_more_order_fits_more_of_them(bc):
    high, low = resonances({"bc": bc, "allpass_order": 24}), resonances({"bc": bc, "allpass_order": 8})
    below_20k = int(np.sum(physics(bc, 30) < 20000.0))
    expected = physics(bc, len(high))
    assert [m.group for m in high[:below_20k]] == ["fitted"] * below_20k
    for modes in (high, low):
        for m, f in zip(modes, expected):
            if m.group == "fitted":
                assert abs(cents(m.frequency_hz, f)) < 0.5, (m, f)
    fitted_low = sum(m.group == "fitted" for m in low)
    assert 3 <= fitted_low < below_20k
    error = [max(abs(cents(m.frequency_hz, f)) for m, f in zip(modes[:below_20k], expected)) for modes in (low, high)]
    assert error[1] < 0.5 < 10.0 < error[0]  # order 8 leaves the top modes tens of cents out


@pytest.mark.parametrize("parameters", [
    {"allpass_order": 24, "q": 100.0},
    {"bc": "clamped-free", "allpass_order": 16, "strike_position": 0.3, "pickup_position": 0.62, "q": 100.0},
])
def test_the_sound_rings_where_describe_and_physics_say_with_their_decays(parameters):
    x = raw(parameters, 1.0)
    modes = resonances(parameters)
    expected = physics(parameters.get("bc", "free-free"), len(modes))
    skip = int(0.03 * RATE)
    measured = 0
    for n, (mode, f) in enumerate(zip(modes, expected), start=1):
        if mode.group != "fitted" or mode.frequency_hz > 6000.0 or abs(mode.gain) < 0.05:
            continue
        partial = measure_partial(x[skip:], RATE, mode.frequency_hz)
        assert abs(cents(partial.frequency_hz, mode.frequency_hz)) < 0.05, (n, mode, partial)
        assert abs(cents(partial.frequency_hz, f)) < 0.6, (n, partial, f)
        assert partial.t60_s == pytest.approx(mode.t60_s, rel=0.03), (n, mode, partial)
        assert partial.t60_s == pytest.approx(parameters["q"] * math.log(1000) / (math.pi * f), rel=0.12), n
        measured += 1
    assert measured >= 3


def test_a_strike_rings_each_mode_as_describe_and_the_mallet_say():
    p = {"strike_position": 0.3, "pickup_position": 0.62, "mallet_hardness": 0.6, "mallet_velocity_m_s": 1.5,
         "mallet_mass_kg": 0.02, "q": 500.0}
    x = raw(p, 0.8)
    contact = mallet_contact_s(0.6)
    pulse = mallet_pulse(mass_kg=0.02, velocity_m_s=1.5, stiffness=hertz_stiffness(contact, 0.02), sample_rate=RATE)
    n = np.arange(pulse.size)
    skip = int(0.03 * RATE)
    for mode in resonances(p)[:3]:
        partial = measure_partial(x[skip:], RATE, mode.frequency_hz)
        at_strike = 10 ** (partial.level_db / 20) * 10 ** (3 * skip / RATE / mode.t60_s)  # back to t = 0
        impulse = abs(np.sum(pulse / RATE * np.exp(-2j * np.pi * mode.frequency_hz * n / RATE)))  # N s
        assert at_strike == pytest.approx(impulse * abs(mode.gain) / MASS_KG, rel=0.05), mode


def test_each_boundary_condition_rings_its_own_series():
    series = {}
    skip = int(0.03 * RATE)
    for bc in ("free-free", "clamped-free", "clamped-clamped", "pinned-pinned", "clamped-pinned"):
        p = {"bc": bc, "strike_position": 0.3, "pickup_position": 0.62, "q": 100.0}
        x = raw(p, 0.4)
        expected = physics(bc, 2)
        found = [measure_partial(x[skip:], RATE, f).frequency_hz for f in expected]
        for f_found, f in zip(found, expected):
            assert abs(cents(f_found, f)) < 0.6, (bc, found, expected)
        series[bc] = np.array(found[1:]) / found[0]
        assert series[bc] == pytest.approx(expected[1:] / expected[0], rel=1e-4)
    # free-free and clamped-clamped share their frequencies (the same lambda_n), as physics says;
    # the other three series are each their own
    assert series["free-free"] == pytest.approx(series["clamped-clamped"], rel=1e-5)
    distinct = [series[bc][0] for bc in ("free-free", "clamped-free", "pinned-pinned", "clamped-pinned")]
    assert min(abs(a / b - 1) for i, a in enumerate(distinct) for b in distinct[i + 1:]) > 0.1


@pytest.mark.parametrize("bc,strike,node,modes,down_db", [
    ("free-free", 0.5, 0.5, (2, 4), 60.0),  # the loop is symmetric about the centre: exact nodes
    ("pinned-pinned", 0.5, 0.5, (2, 4), 60.0),
    ("pinned-pinned", 0.2, 1.0 / 3.0, (3,), 20.0),  # fitted filters: the node is only approximate
])
def test_a_pickup_at_a_node_attenuates_that_mode(bc, strike, node, modes, down_db):
    skip = int(0.03 * RATE)
    expected = physics(bc, max(modes))
    levels = {}
    for pickup in (node, 0.4):
        x = raw({"bc": bc, "strike_position": strike, "pickup_position": pickup, "q": 100.0}, 0.5)
        levels[pickup] = [measure_partial(x[skip:], RATE, expected[k - 1], bandwidth_hz=100.0).level_db
                          for k in modes]
    for at_node, elsewhere in zip(levels[node], levels[0.4]):
        assert at_node < elsewhere - down_db, levels


def test_changes_while_ringing_carry_on_without_a_jump():
    def struck(n):
        v = AllpassVoice({"allpass_order": 16}, sample_rate=RATE)
        v.trigger()
        v.process(n, dtype=np.float64)
        return v

    voice, twin = struck(2000), struck(2000)
    voice.set_parameters(level_db=-6.0)  # same waveguide: the state carries over, the level glides there
    steps = round(LEVEL_GLIDE_S * RATE)  # in equal steps of dB, from one step below 1
    ramp = 10.0 ** (-6.0 / 20.0 * np.minimum(np.arange(1, 2 * steps + 1), steps) / steps)
    assert np.allclose(voice.process(2 * steps, dtype=np.float64), ramp * twin.process(2 * steps, dtype=np.float64),
                       rtol=1e-12, atol=0.0)
    voice, twin = struck(2000), struck(2000)
    before = voice.process(400, dtype=np.float64)
    twin.process(400, dtype=np.float64)
    for v in (voice, twin):
        v.set_parameters(pickup_position=0.35)  # a new waveguide: the old one rings on beside it
    after = voice.process(2000, dtype=np.float64)
    assert abs(after[0] - before[-1]) <= 2.0 * np.abs(np.diff(before)).max()
    assert np.abs(after[-500:]).max() > 0.3 * np.abs(before).max()
    twin.process(2000, dtype=np.float64)
    voice.trigger()  # a new strike goes to the new waveguide, on top of the old one's ringing
    fresh = AllpassVoice({"allpass_order": 16, "pickup_position": 0.35}, sample_rate=RATE)
    fresh.trigger()
    added = voice.process(3000, dtype=np.float64) - twin.process(3000, dtype=np.float64)
    assert np.max(np.abs(added - fresh.process(3000, dtype=np.float64))) < 1e-12


def test_a_pluck_rings_each_mode_as_the_release_and_describe_say():
    p = {"excitation": "pluck", "strike_position": 0.3, "pickup_position": 0.62, "q": 300.0,
         "pluck_displacement_mm": 0.5, "release_time_ms": 0.05}
    x = raw(p, 0.8)
    voice = AllpassVoice(p, sample_rate=RATE)
    force = p["pluck_displacement_mm"] * 1e-3 / voice._strike_point.compliance_m_n
    skip = int(0.03 * RATE)
    for mode in resonances(p)[:2]:
        partial = measure_partial(x[skip:], RATE, mode.frequency_hz)
        at_release = 10 ** (partial.level_db / 20) * 10 ** (3 * skip / RATE / mode.t60_s)
        expected = force * abs(mode.gain) / (MASS_KG * 2 * math.pi * mode.frequency_hz)  # a force step's response
        assert at_release == pytest.approx(expected, rel=0.05), mode


@pytest.mark.parametrize("change,needles", [
    ({"bc": "free"}, ["bc", "free-free"]),
    ({"allpass_order": 0}, ["allpass_order", "1 to 64"]),
    ({"allpass_order": 2.5}, ["allpass_order", "whole number"]),
    ({"q": 1.0}, ["q", "3 to 10000"]),
    ({"strike_position": 1.5}, ["strike_position", "0 to 1"]),
    ({"excitation": "bow"}, ["excitation", "strike"]),
    ({"length_m": 0.02, "thickness_m": 0.02}, ["length_m", "first mode", "allowed", "Hz"]),  # above the band
    ({"length_m": 3.0, "thickness_m": 0.0003}, ["length_m", "first mode", "allowed", "Hz"]),  # below 1 Hz
])
def test_bars_it_cannot_build_are_refused_with_one_line(change, needles):
    with pytest.raises(ParameterError) as info:
        raw(change, 0.05, 22050)
    text = str(info.value)
    assert "\n" not in text and all(needle in text for needle in needles), text


def test_a_retired_waveguide_fades_out_over_fade_s_and_is_then_gone():
    """After a change that rebuilds the waveguide, the old one plays on exactly as if nothing
    had changed, then its last FADE_S fall linearly to nothing: the voice's output is the
    unchanged twin's times min(1, samples left / fade samples), bit for bit."""
    from barsynth.models.allpass.voice import FADE_S, RETIRE_T60S

    rate, p = 22050, {"q": 3.0, "allpass_order": 8}
    voice, twin = AllpassVoice(p, sample_rate=rate), AllpassVoice(p, sample_rate=rate)
    for v in (voice, twin):
        v.trigger()
        v.process(100, dtype=np.float64)
    longest = max(m.model_t60_s for m in voice.design.modes if m.fitted)
    voice.set_parameters(pickup_position=0.4)
    fade = int(round(FADE_S * rate))
    left = int(round(RETIRE_T60S * longest * rate)) + fade
    x = np.concatenate([voice.process(b, dtype=np.float64) for b in (1, 17, 300, left)])
    y = twin.process(x.size, dtype=np.float64)
    gain = np.minimum(1.0, (left - np.arange(x.size)) / fade).clip(0.0)
    assert np.array_equal(x[:left], y[:left] * gain[:left])
    assert np.abs(y[left - fade:left]).max() > 0.0 and not voice._retired
    assert np.all(x[left:] == 0.0)  # the new waveguide was never struck


def test_the_compiled_entry_point_gives_the_dispatchers_samples():
    """The voice calls process() through its compiled entry point (jitstart.compiled_for),
    which checks no types: over blocks of changing sizes, a pending force and a held one, it
    gives exactly what numba's dispatcher (which types every argument) gives."""
    from barsynth.exciters import ForceQueue
    from barsynth.models.allpass import kernel as K

    voice = AllpassVoice({"allpass_order": 8}, sample_rate=22050)
    engine = voice._engine
    loop, state = engine.loop, K.empty_state(engine.loop)
    force = ForceQueue()
    force.add(np.linspace(1.0, 0.0, 300), 0.25)
    twin = ForceQueue()
    twin.add(force.pending.copy(), force.held)
    for size in (1, 17, 256, 1000):
        out, expected = np.empty(size), np.empty(size)
        engine.run(out, force)
        K.process(expected, twin.pending, twin.held, loop, state)
        twin.advance(size)
        assert np.array_equal(out, expected)
    assert np.abs(expected).max() > 0.0


def test_the_loss_fits_rows_are_each_losss_own_nepers_exactly():
    """The loss fit evaluates many points at once (_nepers_rows); each row must be, bit for
    bit, the nepers of the Loss the fit makes of that point (the golden sounds pin the fits)."""
    from barsynth.models.allpass.loss import MAX_SHELF_NEPERS, Loss, _nepers_rows, _shelf

    rng = np.random.default_rng(5)
    w = np.sort(rng.uniform(0.01, 3.0, 9))
    for count in (1, 2, 3):
        points = rng.normal(0.0, 1.5, (6, 1 + 2 * count))
        rows = _nepers_rows(points.tolist(), count, np.cos(w))
        for x, row in zip(points, rows):
            shelves = tuple(_shelf(0.999 * math.tanh(x[2 + 2 * k]), min(x[1 + 2 * k] ** 2, MAX_SHELF_NEPERS))
                            for k in range(count))
            loss = Loss(math.exp(-min(x[0] ** 2, MAX_SHELF_NEPERS)), shelves)
            assert np.array_equal(row, loss.nepers(w))
