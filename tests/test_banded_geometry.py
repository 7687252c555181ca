"""The banded model's ``tuning = geometry`` (issue 15, item 4): a bar built from its material,
size, undercut and theory rings at that theory's frequencies, and its positions act through the
profile's own mode shapes (measured in the sound)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.optimize import brentq
from streaming import play

from barsynth.analysis import measure_partial
from barsynth.cli import main
from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.models.banded.geometry import geometry_bar
from barsynth.physics import bar_frequencies
from barsynth.physics.profiles import Profile
from barsynth.physics.timoshenko_grid import (
    timoshenko_grid,
    timoshenko_grid_modes,
    two_field_eigen,
)
from barsynth.presets import preset_parameters

MODEL = get_model("banded")
RATE = 48000
ROSEWOOD = {"youngs_modulus_pa": 20e9, "density_kg_m3": 1000.0, "shear_modulus_pa": 1.33e9,
            "shear_coefficient": 5.0 / 6.0}
MARIMBA = preset_parameters("banded", "concert-marimba-bar")  # rosewood 40 x 5 x 2 cm, 1 : 4 in Timoshenko
RINGING = {**MARIMBA, "tube": "none", "mode_t60s_s": (1.0,) * 4}  # the bar alone, every partial long enough to measure


def raw(parameters, seconds, rate=RATE):
    return MODEL.render(parameters, duration_s=seconds, sample_rate=rate, normalize=False, dtype=np.float64)


def cents(a, b):
    return 1200.0 * math.log2(a / b)


def marimba_profile() -> Profile:
    return Profile("parabolic", depth=MARIMBA["undercut_depth"], width=MARIMBA["undercut_width"])


def theory_modes(count=4, points=250):
    """The marimba bar's modes from the Timoshenko grid on its own (another resolution than the model's)."""
    return timoshenko_grid_modes(**ROSEWOOD, length_m=0.4, thickness_m=0.02, width_m=0.05, bc="free-free",
                                 count=count, profile=marimba_profile(), points=points)


def test_a_geometry_bar_rings_at_its_theorys_frequencies():
    expected = theory_modes()
    modes = MODEL.describe(RINGING, sample_rate=RATE)
    described = np.array([m.frequency_hz for m in modes if m.group == "mode"])  # (not the tube's entry)
    assert described == pytest.approx(expected, rel=1e-4)  # grids of 161/321 against 250/499 nodes
    assert described[1] / described[0] == pytest.approx(4.0, rel=1e-3)  # the preset's tuning
    x = raw(RINGING, 1.0)
    skip = int(0.05 * RATE)
    for f_model, f_theory in zip(described, expected):
        heard = measure_partial(x[skip:], RATE, f_model).frequency_hz
        assert abs(cents(heard, f_theory)) < 1.0, (heard, f_theory)


def first_node(profile: Profile, mode: int, after: float = 0.0) -> float:
    """The first node of ``mode`` beyond ``after`` (fraction of the length), from the bar's own shape
    on a Timoshenko grid of 250 nodes (not the model's grids)."""
    grid = timoshenko_grid(**ROSEWOOD, length_m=0.4, thickness_m=0.02, width_m=0.05, bc="free-free", points=250,
                           profile=profile)
    _, vectors = two_field_eigen(grid, mode)
    shape = grid.deflection(vectors[:, mode - 1])
    x = grid.x_m / 0.4
    k = int(next(k for k in np.flatnonzero(np.sign(shape[:-1]) != np.sign(shape[1:])) if x[k + 1] > after))
    return float(brentq(lambda at: np.interp(at, x, shape), x[k], x[k + 1]))


def mode_level_db(mode: int, strike_position: float) -> float:
    p = {**RINGING, "strike_position": strike_position, "pickup_position": 0.02}
    x = raw(p, 0.6)
    skip = int(0.05 * RATE)
    return measure_partial(x[skip:], RATE, MODEL.describe(p, sample_rate=RATE)[mode - 1].frequency_hz).level_db


@pytest.mark.parametrize("mode, after", [(1, 0.0), (3, 0.2)])
def test_a_strike_at_a_node_of_the_undercut_bar_leaves_its_mode_silent(mode, after):
    """The node comes from the undercut bar's own shape; the uniform bar's node is elsewhere, and
    striking there rings the mode well: the model's shapes are the profile's. (Mode 2's outer
    node lies outside this undercut and barely moves, 0.1339 to 0.1340; its middle one is the
    middle: modes 1 and 3 show it.)"""
    node = first_node(marimba_profile(), mode, after)
    uniform_node = first_node(Profile(), mode, after)
    assert abs(node - uniform_node) > 0.005, (node, uniform_node)
    at_node, at_uniform_node, at_antinode = (mode_level_db(mode, s) for s in (node, uniform_node, 0.5))
    assert at_node < at_antinode - 25.0, (at_node, at_antinode)
    assert at_uniform_node > at_node + 50.0, (at_uniform_node, at_node)
    print(f"mode {mode}: node {node:.4f} (uniform {uniform_node:.4f}); level re the middle: at the node "
          f"{at_node - at_antinode:.1f} dB, at the uniform bar's node {at_uniform_node - at_antinode:.1f} dB")


def test_a_uniform_euler_bernoulli_geometry_bar_is_tuning_physics():
    bar = {"youngs_modulus_pa": 20e9, "density_kg_m3": 1000.0, "length_m": 0.4, "thickness_m": 0.02,
           "width_m": 0.05, "mode_count": 5, "strike_position": 0.3, "pickup_position": 0.1}
    physics = raw(bar, 0.3)
    assert np.array_equal(raw({**bar, "tuning": "geometry", "theory": "euler-bernoulli"}, 0.3), physics)
    # the same bar through the grid (a profile sampled flat): modes and shapes within the grid's error
    gridded = {**bar, "tuning": "geometry", "theory": "euler-bernoulli", "profile": "samples",
               "profile_samples": (1.0, 1.0)}
    f = [m.frequency_hz for m in MODEL.describe(gridded, sample_rate=RATE)]
    assert f == pytest.approx(bar_frequencies(youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4,
                                              thickness_m=0.02, bc="free-free", count=5), rel=1e-6)
    assert np.max(np.abs(raw(gridded, 0.3) - physics)) < 5e-4 * np.max(np.abs(physics))  # measured 1.3e-4


def test_a_thin_timoshenko_bar_tends_to_the_euler_bernoulli_one():
    """Shear and rotary inertia lower a mode by about (h / wavelength)^2: a quarter as much at half
    the thickness."""
    ruler = {"youngs_modulus_pa": 200e9, "density_kg_m3": 7850.0, "length_m": 0.3, "mode_count": 3}
    lowered = []
    for thickness in (0.002, 0.001):
        thin = [m.frequency_hz for m in MODEL.describe({**ruler, "thickness_m": thickness})]
        thick = [m.frequency_hz for m in MODEL.describe({**ruler, "thickness_m": thickness, "tuning": "geometry"})]
        lowered.append(1.0 - np.array(thick) / np.array(thin))
    assert np.all(lowered[1] > 0.0) and lowered[1][0] < 1e-4
    assert lowered[0] / lowered[1] == pytest.approx([4.0] * 3, rel=0.02)


def test_timoshenko_lowers_the_higher_modes_in_the_sound():
    bar = {"tuning": "geometry", **ROSEWOOD, "length_m": 0.4, "thickness_m": 0.02, "width_m": 0.05,
           "mode_count": 4, "mode_t60s_s": (1.0,) * 4, "strike_position": 0.3, "pickup_position": 0.02}
    skip = int(0.05 * RATE)
    heard = {}
    for theory in ("euler-bernoulli", "timoshenko"):
        p = {**bar, "theory": theory}
        x = raw(p, 0.8)
        heard[theory] = [measure_partial(x[skip:], RATE, m.frequency_hz).frequency_hz
                         for m in MODEL.describe(p, sample_rate=RATE)]
    shift = [cents(t, e) for t, e in zip(heard["timoshenko"], heard["euler-bernoulli"])]
    thin = bar_frequencies(youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4, thickness_m=0.02,
                           bc="free-free", count=4)
    thick = timoshenko_grid_modes(**ROSEWOOD, length_m=0.4, thickness_m=0.02, width_m=0.05, bc="free-free", count=4)
    assert shift == pytest.approx([cents(a, b) for a, b in zip(thick, thin)], abs=1.0)
    # a 40 x 2 cm rosewood bar with E/G = 15 (spec 8.1: thick-bar effects grow with (h / wavelength)^2):
    # -47, -153, -293, -452 cents
    assert shift[0] < -30.0 and all(b < a - 100.0 for a, b in zip(shift, shift[1:])), shift


def test_shear_rows_act_only_in_timoshenko():
    quiet = {"tuning": "geometry", "theory": "euler-bernoulli", "profile": "parabolic", "undercut_depth": 0.5}
    table = MODEL.table
    assert not table["shear_modulus_pa"].acts_under(table.resolve(quiet))
    assert table["shear_modulus_pa"].acts_under(table.resolve({**quiet, "theory": "timoshenko"}))
    assert table["profile"].acts_under(table.resolve(quiet)) and not table["profile"].acts_under(table.resolve())
    assert np.array_equal(raw({**quiet, "shear_modulus_pa": 1e9}, 0.1), raw({**quiet, "shear_modulus_pa": 5e9}, 0.1))
    thick = {**quiet, "theory": "timoshenko"}
    assert not np.array_equal(raw({**thick, "shear_modulus_pa": 1e9}, 0.1), raw({**thick, "shear_modulus_pa": 5e9},
                                                                                   0.1))


def test_shear_comes_from_the_material_unless_given():
    """A material sets the shear rows (as it sets E and rho); a shear modulus of 0 is an isotropic
    solid's with nu = 0.33; given ones act as given."""
    aluminium = {"tuning": "geometry", "youngs_modulus_pa": 69e9, "density_kg_m3": 2700.0, "length_m": 0.2,
                 "thickness_m": 0.02, "mode_count": 3}
    assumed = geometry_bar(MODEL.resolve(aluminium)).frequencies_hz
    given = geometry_bar(MODEL.resolve({**aluminium, "shear_modulus_pa": 69e9 / 2.66})).frequencies_hz
    assert np.array_equal(assumed, given)
    softer = geometry_bar(MODEL.resolve({**aluminium, "shear_modulus_pa": 69e9 / 15})).frequencies_hz
    assert np.all(softer < assumed)
    from barsynth.models.rows import material_shear

    rosewood = MODEL.resolve({"tuning": "geometry", "material": "rosewood"})
    assert (rosewood.shear_modulus_pa, rosewood.shear_coefficient) == material_shear("rosewood")


def test_blocks_of_any_size_give_the_offline_samples():
    p = {**MARIMBA, "strike_position": 0.37}
    offline = MODEL.render(p, duration_s=0.2, sample_rate=RATE, normalize=False, dtype=np.float64, seed=1)
    voice = MODEL.voice(p, sample_rate=RATE, seed=1, max_block=512)
    streamed = play(voice, {0: ("trigger", {})}, offline.size, 173)
    assert np.array_equal(streamed, offline)


@pytest.mark.parametrize("settings, needles", [
    ({"profile": "samples"}, ["profile_samples", "at least 2"]),
    ({"profile": "parabolic", "undercut_depth": 0.99}, ["undercut_depth", "0.99", "0 to 0.98"]),
    ({"theory": "thick"}, ["theory", "euler-bernoulli, timoshenko"]),
    ({"shear_modulus_pa": -1.0}, ["shear_modulus_pa", "0 to 4e+11 Pa"]),
    ({"shear_coefficient": 0.2}, ["shear_coefficient", "0.5 to 1"]),
])
def test_bad_input_is_one_line_naming_it(settings, needles):
    with pytest.raises(ParameterError) as caught:
        MODEL.describe({"tuning": "geometry", **settings})
    message = str(caught.value)
    assert "\n" not in message and all(n in message for n in needles), message
    result = CliRunner().invoke(main, ["render", "banded", "--set", "tuning=geometry",
                                       *[f"--set={k}={v}" for k, v in settings.items()], "-o", "/dev/null"])
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output


@pytest.mark.parametrize("preset, ratio", [("concert-marimba-bar", 4.0), ("vibraphone-bar", 4.0),
                                           ("xylophone-bar", 3.0)])
def test_the_tuned_presets_ring_at_their_ratio(preset, ratio):
    p = {**preset_parameters("banded", preset), "mode_t60s_s": (1.0,) * 4}
    f = [m.frequency_hz for m in MODEL.describe(p, sample_rate=RATE)]
    x = raw(p, 0.5)
    skip = int(0.05 * RATE)
    heard = [measure_partial(x[skip:], RATE, fk).frequency_hz for fk in f[:2]]
    assert heard[1] / heard[0] == pytest.approx(ratio, rel=1e-3), heard


def test_a_design_from_disk_is_the_computed_one_bit_for_bit(tmp_path, monkeypatch):
    from barsynth import designcache
    from barsynth.models.banded import geometry

    monkeypatch.setenv("BARSYNTH_CACHE_DIR", str(tmp_path))
    designcache.enable()
    try:
        p = MODEL.resolve({**MARIMBA, "undercut_depth": 0.4})
        geometry._kept.cache_clear()
        computed = geometry_bar(p)
        geometry._kept.cache_clear()
        stored = geometry_bar(p)
        geometry._kept.cache_clear()
    finally:
        designcache.enable(False)
    assert stored is not computed and len(list((tmp_path / "designs").glob("geometrybar-*.json"))) == 1
    for name in ("frequencies_hz", "x", "shapes"):
        assert np.array_equal(getattr(stored, name), getattr(computed, name))
    assert stored.mass_kg == computed.mass_kg


def test_the_dense_solver_stands_in_when_arpack_fails(monkeypatch):
    import scipy.sparse.linalg
    from scipy.sparse.linalg import ArpackNoConvergence

    from barsynth.models.banded import geometry

    p = MODEL.resolve({**MARIMBA, "undercut_depth": 0.3})
    geometry._kept.cache_clear()
    sparse = geometry_bar(p)

    def fails(*args, **kwargs):
        raise ArpackNoConvergence("no convergence", np.zeros(0), np.zeros((0, 0)))

    monkeypatch.setattr(scipy.sparse.linalg, "eigsh", fails)
    geometry._kept.cache_clear()
    dense = geometry_bar(p)
    geometry._kept.cache_clear()
    # main's dense solver shifts far below the first mode, which costs it digits (measured 2.9e-6)
    assert dense.frequencies_hz == pytest.approx(sparse.frequencies_hz, rel=2e-5)
    assert np.max(np.abs(dense.shapes - sparse.shapes)) < 1e-4


def test_a_uniform_thick_bar_rings_at_the_closed_forms_frequencies():
    from barsynth.physics.timoshenko import timoshenko_frequencies

    p = {**preset_parameters("banded", "glockenspiel-bar"), "mode_t60s_s": (1.0,) * 4}  # steel 19.23 x 0.75 cm
    closed = timoshenko_frequencies(youngs_modulus_pa=200e9, density_kg_m3=7850.0, shear_modulus_pa=77.5e9,
                                    shear_coefficient=0.8492, length_m=0.1923, thickness_m=0.0075, bc="free-free",
                                    count=4)
    described = [m.frequency_hz for m in MODEL.describe(p, sample_rate=RATE)]
    assert described == pytest.approx(closed, rel=1e-12)
    flat = {**p, "profile": "samples", "profile_samples": (1.0, 1.0)}  # the same bar through the model's grid
    gridded = [m.frequency_hz for m in MODEL.describe(flat, sample_rate=RATE)]
    assert closed == pytest.approx(gridded, rel=1e-6)  # the grid whose shapes the model takes agrees
    x = raw(p, 0.5)
    skip = int(0.05 * RATE)
    for f in closed:
        assert abs(cents(measure_partial(x[skip:], RATE, f).frequency_hz, f)) < 1.0
