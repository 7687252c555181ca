"""The finite-difference bar in Timoshenko form (spec 8.2, issue 15 item 3): a thick bar's
rendered partials against its own describe, against the converged thick bar and against the
Euler–Bernoulli bar; the scheme's discrete energy kept without losses and never gained with
them; blocks against one render; bad settings refused in one line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.models.fd import FdVoice, mode_errors_cents
from barsynth.models.fd.design import design
from barsynth.models.rows import material_shear, profile_of
from barsynth.physics import bar_frequencies
from barsynth.physics.grid import grid_modes
from barsynth.physics.timoshenko_grid import timoshenko_grid_modes
from test_fd import peak_near  # (Hz, magnitude) of the spectral peak near a frequency

MODEL = get_model("fd")
RATE = 44100
SHEAR = {"shear_modulus_pa": 1.4e9, "shear_coefficient": 5 / 6}  # rosewood across the grain (E / G = 14)
ROSEWOOD = {"youngs_modulus_pa": 20e9, "density_kg_m3": 1000.0, "length_m": 0.40, "width_m": 0.05, "thickness_m": 0.02}
THICK = {**ROSEWOOD, **SHEAR, "theory": "timoshenko", "sigma0_per_s": 0.5, "sigma1_m2_s": 0.0}
UNDERCUT = {"profile": "parabolic", "undercut_depth": 0.5, "undercut_width": 0.6, "strike_position": 0.9}


def raw(parameters, seconds, rate=RATE):
    return MODEL.render(parameters, duration_s=seconds, sample_rate=rate, normalize=False, dtype=np.float64)


def cents(a, b):
    return 1200.0 * np.log2(np.asarray(a) / np.asarray(b))


def rendered_and_described(p, count=5):
    x = raw(p, 2.0)[RATE // 10:]
    described = np.array([m.frequency_hz for m in MODEL.describe(p, sample_rate=RATE)[:count]])
    return np.array([peak_near(x, RATE, f)[0] for f in described]), described


@pytest.mark.parametrize("shape", [{}, UNDERCUT], ids=["uniform", "undercut"])
def test_a_thick_bar_rings_where_describe_says_and_shear_lowers_it(shape):
    thick = {**THICK, **shape}
    found, described = rendered_and_described(thick)
    assert np.all(np.abs(cents(found, described)) < 1.0)  # measured: within 0.15 cents
    # describe's errors against the converged Timoshenko bar are the grid's and the step's: small, flat
    errors = mode_errors_cents(thick, sample_rate=RATE)[:5]
    assert np.all(errors < 0) and np.all(np.abs(errors) < [1.5, 3.0, 5.0, 8.0, 12.0])
    # the same bar in Euler–Bernoulli form rings sharp of it by what the physics says
    thin = {**thick, "theory": "euler-bernoulli"}
    thin_found, _ = rendered_and_described(thin)
    measured = cents(thin_found, found)
    bar = {"bc": "free-free", "count": 5, **ROSEWOOD}
    shaped = profile_of(MODEL.resolve(thick))
    euler = grid_modes(profile=shaped, **bar) if shape else bar_frequencies(
        **{k: v for k, v in bar.items() if k != "width_m"})
    physics = cents(euler, timoshenko_grid_modes(profile=shaped, **bar, **SHEAR))
    assert np.all(physics[1:4] > 80.0)  # a real marimba bar's shift: tens to hundreds of cents
    # each scheme's own error (a few cents, flat) is what is left between sound and physics
    assert np.allclose(measured[1:4], physics[1:4], rtol=0.01), (measured, physics)  # measured: 0.2-0.7 %
    assert np.allclose(measured, physics, rtol=0.015, atol=0.5)


def test_blocks_are_the_offline_render_sample_for_sample():
    p = {**THICK, "points": 60}
    whole = FdVoice(p, sample_rate=RATE)
    whole.trigger()
    one = whole.process(20000, dtype=np.float64)
    voice = FdVoice(p, sample_rate=RATE)
    voice.trigger()
    sizes = np.random.default_rng(3).integers(1, 700, 200)
    blocks, done = [], 0
    for n in sizes:
        n = int(min(n, one.size - done))
        if n == 0:
            break
        blocks.append(voice.process(n, dtype=np.float64))
        done += n
    assert np.array_equal(np.concatenate(blocks), one[:done]) and done == one.size
    assert np.array_equal(raw(p, 20000 / RATE), one)


def scheme_energy(voice):
    """The theta scheme's energy between the last two steps (J): kinetic, plus the potential
    ``theta/2 u+ K u + (1 - theta)/4 (u+ K u+ + u K u)`` (Bilbao 2009, ch. 7)."""
    grid, theta = voice._design.grid, voice.parameters.theta
    rate = voice._design.scheme.step_rate
    now, before = voice._bar.u[2:-2], voice._bar.u_prev[2:-2]
    k = grid.stiffness
    return (0.5 * np.sum(grid.mass * ((now - before) * rate) ** 2) + 0.5 * theta * now @ k @ before
            + 0.25 * (1 - theta) * (now @ k @ now + before @ k @ before))


def energies(p, steps, lossless):
    voice = FdVoice({**p, "excitation": "pluck", "oversampling": 1}, sample_rate=RATE)
    if lossless:  # below the table's range, so straight into the design
        voice._allocate(design(dataclasses.replace(voice.parameters, sigma0_per_s=0.0, sigma1_m2_s=0.0), RATE))
    voice.trigger()  # held out and let go: nothing touches the bar after
    out = [scheme_energy(voice)]
    for _ in range(steps):
        voice.process(1, dtype=np.float64)
        out.append(scheme_energy(voice))
    return np.array(out)


@pytest.mark.parametrize("steps,hardness,velocity", [(1, 1.0, 5.0), (4, 0.7, 1.0)])
def test_a_strike_on_the_thick_bar_never_adds_energy(steps, hardness, velocity):
    """The bar's scheme energy plus the mallet's after a strike is the mallet's before it."""
    mass = 0.03
    voice = FdVoice({**THICK, "oversampling": steps, "mallet_hardness": hardness, "mallet_mass_kg": mass,
                     "mallet_velocity_m_s": velocity, "sigma0_per_s": 0.01}, sample_rate=RATE)
    voice.trigger()
    voice.process(int(0.05 * RATE), dtype=np.float64)
    mallet = voice._mallet_state[0]
    mallet_velocity = (mallet["z_m"] - mallet["z_prev_m"]) * voice._design.scheme.step_rate
    total = scheme_energy(voice) + 0.5 * mass * mallet_velocity ** 2
    assert total == pytest.approx(0.5 * mass * velocity ** 2, rel=2e-3)
    assert mallet_velocity < 0 and scheme_energy(voice) > 0.01 * total  # it bounced off, the bar rings


@pytest.mark.parametrize("theta", [0.5, 0.25, 0.0])
@pytest.mark.parametrize("shape", [{}, UNDERCUT], ids=["uniform", "undercut"])
def test_the_scheme_keeps_its_energy_without_losses_and_loses_it_with_them(theta, shape):
    p = {**THICK, **shape, "theta": theta, "strike_position": 0.8}
    kept = energies(p, 10_000, lossless=True)
    assert kept[0] > 0 and np.abs(kept / kept[0] - 1.0).max() < 1e-11  # measured: 2e-13 to 5e-13
    lost = energies({**p, "sigma0_per_s": 3.0, "sigma1_m2_s": 0.004}, 10_000, lossless=False)
    assert np.all(np.diff(lost) <= 1e-12 * lost[0]) and lost[-1] < 0.6 * lost[0]


def test_the_shear_modes_bound_theta_above_one_half_and_below_it_any_step_is_stable():
    with pytest.raises(ParameterError) as info:
        raw({**THICK, "theta": 0.6}, 0.05)
    assert "theta = 0.6 makes the scheme unstable" in str(info.value) and "\n" not in str(info.value)
    x = raw({**THICK, "oversampling": 1, "points": 200, "mallet_hardness": 1.0}, 0.5, rate=8000)
    assert np.all(np.isfinite(x)) and 0.0 < np.max(np.abs(x)) < 10.0


@pytest.mark.parametrize("excitation", ["strike", "pluck", "bow"])
def test_every_exciter_plays_the_thick_bar_and_a_free_one_stays_put(excitation):
    p = {**THICK, "excitation": excitation, "bow_duration_s": 0.5, "points": 60}
    x = raw(p, 1.0)
    f1 = MODEL.describe(p, sample_rate=RATE)[0].frequency_hz
    assert peak_near(x[RATE // 10:], RATE, f1, width=0.02)[0] == pytest.approx(f1, rel=2e-3)
    assert abs(np.mean(x)) < 2e-3 * np.sqrt(np.mean(x ** 2))


@pytest.mark.parametrize("bc,position", [("clamped-free", 1.0), ("free-free", 0.8)])
def test_a_pluck_holds_the_thick_bar_out_where_asked(bc, position):
    """The static deflection of the two-field grid (eigh of K and M, its rigid motions left out)."""
    voice = FdVoice({**THICK, "bc": bc, "excitation": "pluck", "pluck_displacement_mm": 2.0,
                     "strike_position": position}, sample_rate=RATE)
    voice.trigger()
    assert float(np.dot(voice._mallet.at, voice._bar.u)) == pytest.approx(2e-3, rel=1e-9)
    rotations = np.delete(voice._bar.u[2:-2], voice._design.grid.w_index)
    assert np.abs(rotations).max() > 1e-3  # radians: a held-out bar is bent, its sections turn


def test_a_material_sets_the_shear_and_euler_bernoulli_is_the_default():
    assert MODEL.resolve({}).theory == "euler-bernoulli"
    # no shear modulus given: an isotropic solid's with nu = 0.33 (the default aluminium's)
    given = MODEL.describe({"theory": "timoshenko", "shear_modulus_pa": 69e9 / 2.66}, sample_rate=RATE)
    assert MODEL.describe({"theory": "timoshenko"}, sample_rate=RATE) == given
    assert given[3].frequency_hz < 0.99 * MODEL.describe({}, sample_rate=RATE)[3].frequency_hz
    p = MODEL.resolve({"material": "aluminium", "theory": "timoshenko"})
    assert (p.shear_modulus_pa, p.shear_coefficient) == material_shear("aluminium")
    assert p.youngs_modulus_pa / p.shear_modulus_pa == pytest.approx(2.66, rel=0.02)  # nu about 0.33
    assert raw({"material": "aluminium", "theory": "timoshenko", "points": 40}, 0.05).any()


@pytest.mark.parametrize("bad,words", [
    ({"theory": "timoshenko", "shear_modulus_pa": -1e9}, "shear_modulus_pa"),
    ({"theory": "timoshenko", "shear_modulus_pa": 1e12}, "shear_modulus_pa"),
    ({"theory": "timoshenko", "shear_modulus_pa": 1e9, "shear_coefficient": 1.2}, "shear_coefficient"),
    ({"theory": "mindlin"}, "theory"),
])
def test_bad_settings_are_refused_in_one_line(bad, words):
    with pytest.raises(ParameterError) as info:
        raw(bad, 0.05)
    assert words in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ParameterError):
        MODEL.describe(bad, sample_rate=RATE)
