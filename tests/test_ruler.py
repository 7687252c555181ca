"""The physical twang (models/ruler): what the mechanism must show, measured in the sound and the state.

Spec 9.3: the free phases ring at the clamped-free modes of the free length; slaps recur once a
cycle of the two cantilevers; the energy balance closes; partials settle as the grid is refined and
the contact stiffened; a softer desk slaps softer and lower; the desk's modes ring after the slaps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import barsynth.models.ruler.design as ruler_design
from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.models.ruler import kernel as K
from barsynth.models.ruler.model import cantilever_modes, ruler_setup

RATE = 48000
MODEL = get_model("ruler")


def voice(**settings):
    return MODEL.voice(settings, sample_rate=RATE)


def record(v, samples: int) -> dict:
    """Play ``v`` sample by sample: the sound, the edge's contact force (N), the force on the desk
    above its load at rest (N) and the tip's displacement (m)."""
    d, c = v._design, v._contacts
    out, edge, desk, tip = (np.zeros(samples) for _ in range(4))
    one = np.zeros(1)
    for i in range(samples):
        v.process(1, out=one)
        out[i], edge[i], desk[i], tip[i] = one[0], c.force[d.edge_index], v._output.force[0], v._bar.u[-K.PAD - 1]
    return {"out": out, "edge": edge, "desk": desk, "tip": tip}


def bearing(edge: np.ndarray) -> np.ndarray:
    """Where the ruler bears on the edge (a force above a thousandth of its largest)."""
    return edge > 1e-3 * np.max(edge)


def landings(edge: np.ndarray) -> np.ndarray:
    """The samples at which the ruler comes down on the edge again (the slaps; a slap's bounces
    within 5 ms are one slap)."""
    onsets = np.flatnonzero(np.diff(bearing(edge).astype(np.int8)) > 0) + 1
    kept = []
    for onset in onsets:
        if not kept or onset - kept[-1] > RATE // 200:
            kept.append(onset)
    return np.array(kept)


def runs(on: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lengths (samples) of the stretches where ``on`` holds and where it does not, whole ones only."""
    edges = np.flatnonzero(np.diff(on.astype(np.int8))) + 1
    lengths = np.diff(edges)
    starts_on = on[edges[:-1]]
    return lengths[starts_on], lengths[~starts_on]


def cantilever_f1(p, length_m: float) -> float:
    return float(cantilever_modes(ruler_setup(p), length_m, 1)[0][0])


def peak_hz(x: np.ndarray, low: float, high: float) -> float:
    """The strongest spectral peak between ``low`` and ``high`` Hz (Hann window, parabolic interpolation)."""
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), 8 * x.size))
    f = np.fft.rfftfreq(8 * x.size, 1.0 / RATE)
    band = np.flatnonzero((f > low) & (f < high))
    i = band[np.argmax(spectrum[band])]
    a, b, c = np.log(spectrum[i - 1:i + 2])
    return float(f[i] + 0.5 * (a - c) / (a - 2 * b + c) * (f[1] - f[0]))


@pytest.fixture
def no_weight(monkeypatch):
    """The ruler without its weight: the swing above the desk is then a whole half period (under
    its weight the long cantilever's rest lies below the desk plane, and the swing is cut short)."""
    monkeypatch.setattr(ruler_design, "GRAVITY_M_S2", 0.0)


# -- the two cantilevers -----------------------------------------------------------------------------
def test_bearing_on_the_edge_it_rings_as_the_short_cantilever():
    """Let go from just below its rest (the overhang sags 0.8 mm under its weight) it stays on the
    edge: the overhang rings as the clamped-free cantilever of its own length, modes 1-3 within 3 %.
    The root is a clamp here: the finger presses hard right behind the edge, on a stiff desk, on a
    fine grid. A softer finger or one further back, a softer desk (the ruler sinks into its penalty
    over (4 E I / k)^(1/4)) or a coarser grid (the last node on the desk clamps half a cell back)
    let the root give, and the overhang rings lower (docs/ruler.md gives the figures)."""
    clamp = {"tip_displacement_mm": 1.0, "finger_distance_m": 0.005, "finger_stiffness_n_m": 1e7,
             "finger_force_n": 50.0, "desk_stiffness_n_m2": 1e11, "points": 121, "desk_balance": 0.0}
    p = MODEL.resolve(clamp)
    v = voice(**clamp)
    v.trigger()
    x = v.process(2 * RATE, dtype=np.float64)
    state = record(v, 2000)
    assert np.all(state["edge"] > 0.0)  # still bearing on the edge
    expected = cantilever_modes(ruler_setup(p), p.overhang_m, 3)[0]
    for f in expected:
        measured = peak_hz(x, 0.85 * f, 1.15 * f)
        assert abs(measured / f - 1.0) < 0.03, (f, measured)


def test_swinging_above_the_desk_it_rings_as_the_long_cantilever(no_weight):
    """Off the edge (between finger and edge it leaves the desk) each swing lasts half a period of
    the clamped-free cantilever from the finger to the tip, within 3 %."""
    p = MODEL.resolve({})
    state = record(voice(), 0)  # (compiles)
    v = voice()
    v.trigger()
    state = record(v, RATE // 2)
    _, off = runs(bearing(state["edge"]))
    half_period = RATE / (2.0 * cantilever_f1(p, p.overhang_m + p.finger_distance_m))
    swings = off[off > 0.5 * half_period]
    assert swings.size >= 6
    assert np.all(np.abs(swings / half_period - 1.0) < 0.03), (swings, half_period)


def test_slaps_come_once_a_cycle_of_the_two_cantilevers():
    """Each swing down ends in a slap on the edge: contact-force pulses, one per cycle, at the rate
    of half a long and half a short cantilever period (within 10 %), between the two cantilevers'
    own rates; each a broadband onset in the sound."""
    p = MODEL.resolve({})
    v = voice()
    v.trigger()
    state = record(v, RATE // 2)
    onsets = landings(state["edge"])
    periods = np.diff(onsets)
    f_long = cantilever_f1(p, p.overhang_m + p.finger_distance_m)
    f_short = cantilever_f1(p, p.overhang_m)
    rate = RATE / float(np.median(periods))
    predicted = 2.0 / (1.0 / f_long + 1.0 / f_short)
    assert f_long < rate < f_short
    assert abs(rate / predicted - 1.0) < 0.10, (rate, predicted)
    assert np.std(periods) / np.mean(periods) < 0.1
    # broadband: above 2 kHz the sound is loudest just after each slap
    high = np.diff(state["out"], 2) ** 2
    after = np.concatenate([high[o:o + 48] for o in onsets[1:6]])
    assert np.mean(after) > 3.0 * np.mean(high)


# -- energy -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("settings", [{}, {"contact_exponent": 1.5}, {"desk": "steel", "finger_damping_n_s_m": 50.0},
                                      {"points": 121, "desk_stiffness_n_m2": 1e10}])
def test_the_energy_lost_is_the_energy_the_losses_and_contacts_took(settings):
    v = voice(**settings)
    v.trigger()
    v.track_energy()
    start = v.energy_j()
    totals = []
    for _ in range(40):
        v.process(1200, dtype=np.float64)
        totals.append(v.energy_j()["total"])
    end = v.energy_j()
    taken = end["lost_losses"] + end["lost_contact"]
    assert taken > 0.5 * start["total"]  # most of it is gone in a second
    assert abs(start["total"] - end["total"] - taken) < 1e-5 * start["total"]  # (spec: 1 %; measured <= 2e-6)
    assert np.all(np.diff(totals) <= 1e-9 * start["total"])  # never gained
    assert end["lost_contact"] > 0.0


# -- convergence --------------------------------------------------------------------------------------
def slap_rate(**settings) -> float:
    v = voice(**settings)
    v.trigger()
    return RATE / float(np.mean(np.diff(landings(record(v, RATE // 3)["edge"]))))


def test_the_slap_rate_settles_as_the_grid_is_refined():
    rates = [slap_rate(points=n) for n in (31, 61, 121)]
    first, second = abs(rates[1] - rates[0]), abs(rates[2] - rates[1])
    assert second < 0.6 * first, rates
    assert second / rates[2] < 0.01, rates


def test_the_slap_rate_settles_as_the_contact_stiffens():
    rates = [slap_rate(desk_stiffness_n_m2=k) for k in (2e7, 2e8, 2e9, 2e10)]
    steps = np.abs(np.diff(rates))
    assert steps[2] < steps[0], rates
    assert steps[2] / rates[3] < 0.01, rates


def test_partials_settle_as_the_grid_is_refined():
    """The bearing ruler's second partial (the short cantilever's mode 2) on 31, 61, 121 points."""
    found = []
    for n in (31, 61, 121):
        v = voice(points=n, tip_displacement_mm=1.0, desk_balance=0.0)
        v.trigger()
        found.append(peak_hz(v.process(RATE, dtype=np.float64), 120.0, 190.0))
    assert abs(found[2] - found[1]) < 0.5 * abs(found[1] - found[0]), found


# -- the desk -----------------------------------------------------------------------------------------
def first_slap(**settings) -> tuple[float, float]:
    """The first landing's slap: the peak force on the desk (N, above its load at rest) and the
    spectral centroid (Hz) of that force over the 10 ms from the landing."""
    v = voice(**settings)
    v.trigger()
    state = record(v, RATE // 10)
    start = landings(state["edge"])[0] - 24
    pulse = state["desk"][start:start + 480]
    pulse = pulse - pulse[0]
    spectrum = np.abs(np.fft.rfft(pulse, 8192))
    f = np.fft.rfftfreq(8192, 1.0 / RATE)
    return float(np.max(pulse)), float(np.sum(f * spectrum) / np.sum(spectrum))


def test_a_softer_desk_slaps_softer_and_lower():
    soft_peak, soft_centroid = first_slap(desk_stiffness_n_m2=2e7, desk_damping_n_s_m2=300.0)
    hard_peak, hard_centroid = first_slap(desk_stiffness_n_m2=2e9, desk_damping_n_s_m2=300.0)
    assert soft_peak < 0.7 * hard_peak, (soft_peak, hard_peak)
    assert soft_centroid < 0.8 * hard_centroid, (soft_centroid, hard_centroid)


def test_the_desk_rings_after_the_slaps():
    """Only the desk heard: its strongest described mode is a peak of the sound."""
    p = MODEL.resolve({"desk_balance": 1.0})
    modes = [m for m in MODEL.describe(p, sample_rate=RATE) if m.group == "desk"]
    strongest = max(modes, key=lambda m: abs(m.gain))
    v = voice(desk_balance=1.0)
    v.trigger()
    x = v.process(RATE, dtype=np.float64)
    assert np.max(np.abs(x)) > 0.0
    measured = peak_hz(x, 0.97 * strongest.frequency_hz, 1.03 * strongest.frequency_hz)
    assert abs(measured / strongest.frequency_hz - 1.0) < 0.01  # (its neighbours pull the peak a little)


def test_without_the_desk_the_ruler_alone_is_heard():
    v = voice(desk_balance=0.0)
    v.trigger()
    x = v.process(RATE // 2, dtype=np.float64)
    assert np.max(np.abs(x)) > 0.0
    both = voice()
    both.trigger()
    assert not np.array_equal(x, both.process(RATE // 2, dtype=np.float64))


# -- the ring is shaped by the contact ------------------------------------------------------------------
def test_the_ring_dies_faster_than_the_material_alone_lets_it():
    """The slaps and the finger take energy: the twang dies well before its slowest material decay."""
    p = MODEL.resolve({})
    t60_material = max(m.t60_s for m in MODEL.describe(p, sample_rate=RATE) if "cantilever" in m.group)
    v = voice()
    v.trigger()
    v.track_energy()
    start = v.energy_j()["total"] - voice().energy_j()["total"]  # above the rest's energy
    rest = voice().energy_j()["total"]
    elapsed = 0.0
    while v.energy_j()["total"] - rest > 1e-6 * start and elapsed < t60_material:
        v.process(2400, dtype=np.float64)
        elapsed += 0.05
    assert elapsed < 0.7 * t60_material, (elapsed, t60_material)


# -- the slide ---------------------------------------------------------------------------------------------
def test_the_slide_shortens_the_overhang_and_raises_the_pitch_without_a_click():
    """Pulled back 6 cm in 0.4 s (the finger keeps its place behind the edge), the ruler slaps
    at the rate of its shorter cantilevers afterwards (within 15 %); the sound has no step larger
    than the unslid twang's own."""
    p = MODEL.resolve({"slide_m": 0.06, "slide_time_s": 0.4})
    v = voice(slide_m=0.06, slide_time_s=0.4)
    v.trigger()
    state = record(v, int(0.8 * RATE))
    onsets = landings(state["edge"])
    late = RATE / np.mean(np.diff(onsets[onsets > 0.5 * RATE]))
    still = record(_triggered(), int(0.8 * RATE))
    unslid = RATE / np.mean(np.diff(landings(still["edge"])))
    q = MODEL.resolve({"overhang_m": p.overhang_m - 0.06})
    predicted = 2.0 / (1.0 / cantilever_f1(q, q.overhang_m + q.finger_distance_m) + 1.0 / cantilever_f1(q, q.overhang_m))
    assert late > 1.5 * unslid, (late, unslid)
    assert abs(late / predicted - 1.0) < 0.15, (late, predicted)
    assert np.max(np.abs(np.diff(state["out"]))) < 2.0 * np.max(np.abs(np.diff(still["out"])))


def _triggered(**settings):
    v = voice(**settings)
    v.trigger()
    return v


# -- what it says and what it refuses ----------------------------------------------------------------------
def test_describe_gives_both_cantilevers_and_the_desk():
    p = MODEL.resolve({})
    modes = MODEL.describe(p, sample_rate=RATE)
    groups = {m.group for m in modes}
    assert groups == {"long cantilever", "short cantilever", "desk"}
    long1 = min(m.frequency_hz for m in modes if m.group == "long cantilever")
    short1 = min(m.frequency_hz for m in modes if m.group == "short cantilever")
    c = math.sqrt(p.youngs_modulus_pa * p.thickness_m ** 2 / (12 * p.density_kg_m3))
    for f, length in ((long1, p.overhang_m + p.finger_distance_m), (short1, p.overhang_m)):
        assert f == pytest.approx(1.8751040687 ** 2 * c / (2 * math.pi * length ** 2), rel=1e-9)
    assert all(m.frequency_hz < RATE / 2 for m in modes)


@pytest.mark.parametrize("settings,words", [
    ({"overhang_m": 0.35}, "overhang_m = 0.35 m is not shorter than the ruler"),
    ({"finger_distance_m": 0.2}, "finger_distance_m = 0.2 m puts the finger beyond the ruler's back end"),
    ({"tip_displacement_mm": 60.0}, "tip_displacement_mm = 60"),
    ({"overhang_m": 0.025, "tip_displacement_mm": 5.0}, "grid cells"),
    ({"slide_m": 0.17}, "slide_m = 0.17 m leave 1 cm beyond the edge after the slide"),
])
def test_bad_geometry_is_one_clear_line(settings, words):
    with pytest.raises(ParameterError) as info:
        voice(**settings)
    message = str(info.value)
    assert words in message and "allowed" in message and "\n" not in message


@pytest.mark.parametrize("setting,words", [
    ("overhang_m=0.35", "not shorter than the ruler"),
    ("finger_distance_m=0.2", "beyond the ruler's back end"),
    ("tip_displacement_mm=59", "too far"),
])
def test_the_cli_refuses_bad_geometry_in_one_line_and_writes_nothing(tmp_path, setting, words):
    from click.testing import CliRunner

    from barsynth.cli import main

    out = tmp_path / "twang.wav"
    result = CliRunner().invoke(main, ["render", "ruler", "--set", setting, "-o", str(out)], catch_exceptions=False)
    assert result.exit_code == 2
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and words in lines[0] and "allowed" in lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_render_describe_params_and_presets_through_the_cli(tmp_path):
    import json

    import soundfile
    from click.testing import CliRunner

    from barsynth.cli import main

    runner = CliRunner()
    out = tmp_path / "steel.wav"
    assert runner.invoke(main, ["render", "ruler", "--preset", "steel-ruler-metal-desk", "--duration", "0.5", "-o",
                                str(out)]).exit_code == 0
    assert soundfile.info(str(out)).frames == 24000
    described = json.loads(runner.invoke(main, ["describe", "ruler", "--json"]).stdout)
    assert {m["group"] for m in described["modes"]} == {"long cantilever", "short cantilever", "desk"}
    names = [row["name"] for row in json.loads(runner.invoke(main, ["params", "ruler", "--json"]).stdout)]
    assert {"overhang_m", "finger_distance_m", "finger_force_n", "tip_displacement_mm", "desk", "slide_m",
            "desk_balance"} <= set(names)
    listed = runner.invoke(main, ["presets", "ruler"]).stdout
    for ruler in ("plastic", "wooden", "steel"):
        for desk in ("wooden", "metal"):
            assert f"{ruler}-ruler-{desk}-desk" in listed
