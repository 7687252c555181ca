"""The ruler's desk: plate modes, the modal bank's decays, peaks, levels and block behaviour (spec 9.5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.models.ruler.desk import (
    AIR_DENSITY_KG_M3,
    DESK_NAMES,
    DESKS,
    MAX_MODE_FRACTION,
    Desk,
    DeskModes,
    contact_restitution,
    desk_bank,
    desk_mode_list,
    desk_modes,
    process_desk,
    reset_desk,
)

SAMPLE_RATE = 48000.0


def _formula_hz(desk: Desk, m: int, n: int) -> float:
    d = desk.youngs_modulus_pa * desk.thickness_m ** 3 / (12.0 * (1.0 - desk.poisson_ratio ** 2))
    return 0.5 * math.pi * math.sqrt(d / (desk.density_kg_m3 * desk.thickness_m)) * (
        (m / desk.length_m) ** 2 + (n / desk.width_m) ** 2)


def _impulse_response(modes: DeskModes, samples: int, sample_rate: float = SAMPLE_RATE) -> np.ndarray:
    bank = desk_bank(modes, sample_rate)
    force = np.zeros(samples)
    force[0] = 1.0
    out = np.empty(samples)
    process_desk(force, out, bank)
    return out


def _one_mode(frequency_hz: float, t60_s: float, gain: float = 1.0) -> DeskModes:
    return DeskModes(np.array([frequency_hz]), np.array([t60_s]), np.array([gain]))


def _peak_hz(spectrum: np.ndarray, bin_hz: float, near_hz: float, width: float = 0.02) -> float:
    """The interpolated (parabola on dB) peak of |spectrum| within +-width of near_hz."""
    lo, hi = int(near_hz * (1 - width) / bin_hz), int(near_hz * (1 + width) / bin_hz) + 1
    k = lo + int(np.argmax(spectrum[lo:hi]))
    a, b, c = np.log(spectrum[k - 1: k + 2])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) * bin_hz


def test_presets_are_the_four_desks():
    assert DESK_NAMES == ("wood", "oak", "steel", "glass")
    assert tuple(DESKS) == DESK_NAMES
    assert all(DESKS[name].name == name and DESKS[name].source for name in DESK_NAMES)
    assert 0.02 <= DESKS["wood"].thickness_m <= 0.03 and DESKS["steel"].thickness_m == 0.001
    assert DESKS["glass"].thickness_m == 0.010


@pytest.mark.parametrize("name", DESK_NAMES)
def test_frequencies_follow_the_plate_formula(name):
    desk = DESKS[name]
    modes = desk_modes(desk, max_hz=3000.0, max_count=40)
    expected = sorted(_formula_hz(desk, m, n) for m in range(1, 60) for n in range(1, 60)
                      if _formula_hz(desk, m, n) < 3000.0)[:40]
    np.testing.assert_allclose(modes.frequency_hz, expected, rtol=1e-12)
    assert np.all(np.diff(modes.frequency_hz) >= 0.0) and np.all(modes.frequency_hz < 3000.0)


def test_max_hz_and_count_cap():
    wood = DESKS["wood"]
    all_below = desk_modes(wood, max_hz=500.0, max_count=1000)
    f11 = _formula_hz(wood, 1, 1)
    expected = sum(_formula_hz(wood, m, n) < 500.0 for m in range(1, 40) for n in range(1, 40))
    assert all_below.frequency_hz.size == expected > 5
    assert np.all(all_below.frequency_hz < 500.0)
    capped = desk_modes(wood, max_hz=500.0, max_count=5)
    assert capped.frequency_hz.size == 5
    np.testing.assert_array_equal(capped.frequency_hz, all_below.frequency_hz[:5])
    assert desk_modes(wood, max_hz=0.99 * f11).frequency_hz.size == 0
    assert desk_modes(wood, max_hz=1.01 * f11).frequency_hz.size == 1


def test_t60_is_that_of_q():
    for desk in DESKS.values():
        modes = desk_modes(desk, max_hz=5000.0)
        np.testing.assert_allclose(modes.t60_s, 2.0 * math.log(1000.0) / (desk.loss_factor * 2 * math.pi
                                                                           * modes.frequency_hz), rtol=1e-12)


@pytest.mark.parametrize("frequency_hz, t60_s", [(237.4, 0.3), (1000.0, 0.05), (80.0, 1.5)])
def test_measured_decay_of_an_isolated_mode(frequency_hz, t60_s):
    duration = min(1.2 * t60_s, 1.0)
    y = _impulse_response(_one_mode(frequency_hz, t60_s), int(duration * SAMPLE_RATE))
    period = round(4 * SAMPLE_RATE / frequency_hz)  # frames of about four periods
    frames = y[: (y.size // period) * period].reshape(-1, period)
    level_db = 10.0 * np.log10(np.mean(frames ** 2, axis=1))
    t = (np.arange(frames.shape[0]) + 0.5) * period / SAMPLE_RATE
    slope_db_s = np.polyfit(t[1:], level_db[1:], 1)[0]
    assert -60.0 / slope_db_s == pytest.approx(t60_s, rel=0.02)


@pytest.mark.parametrize("name, least", [("glass", 12), ("wood", 4)])
def test_impulse_response_peaks_at_the_modes(name, least):
    """Every mode that stands out of its neighbours' skirts peaks within 0.5 % of its frequency."""
    desk = DESKS[name]
    modes = desk_modes(desk, max_hz=2000.0, max_count=30, contact_xy=(0.37, 0.13))
    y = _impulse_response(modes, 1 << 18)
    spectrum = np.abs(np.fft.rfft(y))
    bin_hz = SAMPLE_RATE / y.size
    f, g = modes.frequency_hz, np.abs(modes.gain)
    checked = 0
    for k, fk in enumerate(f):
        others = np.arange(f.size) != k
        # the other modes' acceleration responses at fk (Pa/N) against this one's peak, |gain| Q
        skirts = np.sum(g[others] * fk ** 2 / np.abs(f[others] ** 2 - fk ** 2))
        if skirts > 0.3 * g[k] * desk.q:
            continue
        assert _peak_hz(spectrum, bin_hz, fk) == pytest.approx(fk, rel=0.005)
        checked += 1
    assert checked >= least


def test_gain_scales_the_resonance():
    """At its resonance a mode's acceleration response is |gain| Q (Pa/N)."""
    frequency_hz, q, gain = 300.0, 50.0, 0.004
    t60 = 2.0 * q * math.log(1000.0) / (2 * math.pi * frequency_hz)
    y = _impulse_response(_one_mode(frequency_hz, t60, gain), 1 << 17)
    at_f0 = abs(np.sum(y * np.exp(-2j * np.pi * frequency_hz * np.arange(y.size) / SAMPLE_RATE)))
    assert at_f0 == pytest.approx(gain * q, rel=0.01)


def test_gain_of_the_lowest_mode_from_first_principles():
    desk = DESKS["wood"]
    x0, y0 = 0.5, 0.15
    modes = desk_modes(desk, max_hz=2000.0, contact_xy=(x0, y0))
    a, b, h = desk.length_m, desk.width_m, desk.thickness_m
    volume = a * b * (2 / math.pi) ** 2
    mass = desk.density_kg_m3 * h * a * b / 4
    kd = 2 * math.pi * modes.frequency_hz[0] / 343.2 * (a + b) / 4
    expected = -(kd / math.sqrt(1 + kd * kd)) * AIR_DENSITY_KG_M3 * volume * math.sin(math.pi * x0) \
        * math.sin(math.pi * y0) / (4 * math.pi * mass)
    assert modes.gain[0] == pytest.approx(expected, rel=1e-12)
    assert 1e-3 < abs(modes.gain[0]) < 1e-1  # a few mPa per newton at 1 m


def test_output_is_linear_in_force():
    modes = desk_modes(DESKS["oak"], max_hz=5000.0)
    rng = np.random.default_rng(3)
    f1, f2 = rng.standard_normal(4000), rng.standard_normal(4000)
    outs = []
    for force in (f1, f2, 2.5 * f1 - 0.75 * f2):
        out = np.empty(force.size)
        process_desk(force, out, desk_bank(modes, SAMPLE_RATE))
        outs.append(out)
    np.testing.assert_allclose(outs[2], 2.5 * outs[0] - 0.75 * outs[1], rtol=0, atol=1e-12 * np.max(np.abs(outs[2])))


@pytest.mark.parametrize("block", [1, 7, 64, 1000])
def test_block_splits_give_the_same_samples(block):
    modes = desk_modes(DESKS["glass"], max_hz=20000.0)
    force = np.random.default_rng(5).standard_normal(3000)
    whole = np.empty(force.size)
    process_desk(force, whole, desk_bank(modes, SAMPLE_RATE))
    bank = desk_bank(modes, SAMPLE_RATE)
    pieces = np.empty(force.size)
    for start in range(0, force.size, block):
        process_desk(force[start:start + block], pieces[start:start + block], bank)
    np.testing.assert_array_equal(pieces, whole)


def test_steel_lowest_mode_against_wood_as_the_formula_says():
    steel, wood = DESKS["steel"], DESKS["wood"]
    f_steel = desk_modes(steel, max_hz=1000.0).frequency_hz[0]
    f_wood = desk_modes(wood, max_hz=1000.0).frequency_hz[0]

    def scale(d):
        return d.thickness_m * math.sqrt(d.youngs_modulus_pa / (d.density_kg_m3 * (1 - d.poisson_ratio ** 2))) * (
            d.length_m ** -2 + d.width_m ** -2)

    assert f_steel / f_wood == pytest.approx(scale(steel) / scale(wood), rel=1e-12)
    assert f_steel < 0.2 * f_wood  # a 1 mm sheet is far floppier than a 25 mm board


def test_softer_desks_have_softer_contacts():
    k = {name: DESKS[name].contact_stiffness_n_m2 for name in DESK_NAMES}
    assert k["wood"] < k["oak"] < k["steel"] < k["glass"]
    e = {name: contact_restitution(DESKS[name]) for name in DESK_NAMES}
    assert e["wood"] < e["oak"] < e["steel"] < e["glass"] < 1.0
    assert e["wood"] == pytest.approx(0.5, rel=1e-9)


def test_reset_silences():
    bank = desk_bank(desk_modes(DESKS["steel"], max_hz=20000.0), SAMPLE_RATE)
    force = np.ones(500)
    out = np.empty(500)
    process_desk(force, out, bank)
    assert np.max(np.abs(out)) > 0.0 and np.any(bank.state != 0.0)
    reset_desk(bank)
    process_desk(np.zeros(500), out, bank)
    assert np.all(out == 0.0)


def test_zero_force_gives_exact_zeros():
    for name in DESK_NAMES:
        out = np.full(777, np.nan)
        process_desk(np.zeros(777), out, desk_bank(desk_modes(DESKS[name], max_hz=20000.0), SAMPLE_RATE))
        assert np.all(out == 0.0)


def test_modes_near_nyquist_are_dropped():
    modes = desk_modes(DESKS["wood"], max_hz=20000.0, max_count=1000)
    for sample_rate in (8000.0, 22050.0, 48000.0):
        bank = desk_bank(modes, sample_rate)
        assert bank.coefficients.shape[0] == np.sum(modes.frequency_hz < MAX_MODE_FRACTION * sample_rate)


def test_extreme_valid_inputs_stay_finite():
    corner = desk_modes(DESKS["steel"], max_hz=1e9, max_count=1000, contact_xy=(0.0, 1.0))
    assert corner.frequency_hz.size == 1000 and np.all(np.abs(corner.gain) < 1e-12)
    thin = Desk("thin", "", 1e5, 10.0, 0.49, 1e-5, 10.0, 0.01, 1.0, 1.0, 0.0, "assumed")
    thick = Desk("thick", "", 1e12, 20000.0, 0.0, 1.0, 0.05, 5.0, 1e-9, 1e12, 1e6, "assumed")
    for desk in (DESKS["glass"], thin, thick):
        for sample_rate in (1000.0, 192000.0):
            modes = desk_modes(desk, max_hz=1e6, max_count=1000, contact_xy=(0.37, 0.01))
            assert np.all(np.isfinite(modes.frequency_hz)) and np.all(np.isfinite(modes.gain))
            bank = desk_bank(modes, sample_rate)
            force = np.zeros(4000)
            force[::97] = 1e6
            force[1::97] = -1e-300
            out = np.empty(4000)
            process_desk(force, out, bank)
            assert np.all(np.isfinite(out))
    empty = desk_bank(desk_modes(DESKS["wood"], max_hz=1.0), SAMPLE_RATE)
    out = np.full(10, np.nan)
    process_desk(np.ones(10), out, empty)
    assert np.all(out == 0.0)


def test_mode_list_reads_the_modes():
    rows = desk_mode_list(DESKS["glass"], 1000.0)
    modes = desk_modes(DESKS["glass"], max_hz=1000.0)
    assert rows[0] == (modes.frequency_hz[0], modes.gain[0], modes.t60_s[0])
    assert len(rows) == modes.frequency_hz.size


@pytest.mark.parametrize("call, name", [
    (lambda: desk_modes(DESKS["wood"], max_hz=-1.0), "max_hz"),
    (lambda: desk_modes(DESKS["wood"], max_hz=1e3, max_count=0), "max_count"),
    (lambda: desk_modes(DESKS["wood"], max_hz=1e3, contact_xy=(0.5, 1.5)), "contact_xy[1]"),
    (lambda: desk_bank(desk_modes(DESKS["wood"], max_hz=1e3), 0.0), "sample_rate"),
    (lambda: desk_bank(DeskModes(np.array([100.0]), np.array([1e-4]), np.array([1.0])), 48000.0), "modes.t60_s"),
    (lambda: Desk("x", "", 1e9, 500.0, 0.6, 0.02, 1.0, 1.0, 0.01, 1e8, 0.0, ""), "poisson_ratio"),
    (lambda: Desk("x", "", 1e9, 500.0, 0.3, 0.02, 1.0, 1.0, 0.0, 1e8, 0.0, ""), "loss_factor"),
])
def test_bad_input_names_the_parameter(call, name):
    with pytest.raises(ParameterError, match=f"parameter {name.replace('[', '.').replace(']', '.')}"):
        call()


def test_held_force_gives_the_exact_continuous_response():
    """Zero-order hold: under a constant force the summed output is the mode's velocity, exactly."""
    frequency_hz, q, gain = 440.0, 30.0, 0.01
    omega = 2 * math.pi * frequency_hz
    t60 = 2.0 * q * math.log(1000.0) / omega
    bank = desk_bank(_one_mode(frequency_hz, t60, gain), SAMPLE_RATE)
    out = np.empty(5000)
    process_desk(np.full(5000, 2.0), out, bank)
    t = np.arange(1, 5001) / SAMPLE_RATE
    sigma, omega_d = omega / (2 * q), omega * math.sqrt(1 - 0.25 / q ** 2)
    velocity = 2.0 * gain / omega_d * np.exp(-sigma * t) * np.sin(omega_d * t)
    np.testing.assert_allclose(np.cumsum(out) / SAMPLE_RATE, velocity, rtol=0, atol=1e-12 * np.max(np.abs(velocity)))
    assert bank.state[0, 1] == pytest.approx(velocity[-1], rel=1e-9)


def test_docstring_examples():
    import doctest

    import barsynth.models.ruler.desk as desk_module

    result = doctest.testmod(desk_module)
    assert result.attempted >= 5 and result.failed == 0
