"""The banded model's one parameter table and its typed record, :class:`BandedParams`.

The mallet, pluck, bow and recorded-attack rows are the exciters' own (:mod:`barsynth.exciters`);
the bar's material and size rows are shared with the other bar models (:mod:`barsynth.parameters`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ...exciters import Bow, Pluck, Sample, Strike
from ...parameters import CHOICE, FLOATS, INT, Compare, Parameter, ParameterTable
from ..constraints import Constraint
from ..notemap import EXCITER_VELOCITIES, ControlCurve, NoteMap
from ..rows import (bar_size_parameters, excitation_parameter, level_parameter, profile_constraint,
                    profile_parameters, theory_parameters)
from .resonator import resonator_parameters

MAX_MODES = 24
"""The most modes (loops) an object may have."""
MIN_Q = 3.0
"""The lowest quality factor of a mode: below it a mode is no ringing loop (see design.py)."""
LOWEST_HZ = 20.0
"""Modes below this are left out (Hz)."""

PHYSICS = {"tuning": ("physics",)}
RATIOS = {"tuning": ("ratios",)}
GEOMETRY = {"tuning": ("geometry",)}
A_BAR = {"tuning": ("physics", "geometry")}
"""Where the modes come from a bar's material and size (physics: uniform; geometry: any profile)."""
SOME_MODE_WITHOUT_T60 = [{**A_BAR, "mode_t60s_s": Compare("<", "mode_count", count=True)},
                         {**RATIOS, "mode_t60s_s": Compare("<", "mode_ratios", count=True)}]
"""When ``q`` acts: while some mode has no T60 of its own in ``mode_t60s_s`` (design.mode_table)."""
SHAPED = [A_BAR, {"shape": ("bar", "ring")}]
"""When a position acts: while the modes have shapes (``shape = none`` makes every mode the same
at every point)."""
STRUCK_PLUCKED_OR_SAMPLED = {"excitation": ("strike", "pluck", "sample")}


BANDED_EXCITERS = (Strike, Bow, Pluck, Sample)
"""The exciters it offers, in the order of its ``excitation`` choices (the model's ``exciters``)."""


def where_shaped(row: Parameter) -> Parameter:
    """``row`` (a position) acting only where it acted and the modes have shapes (:data:`SHAPED`)."""
    clauses = [dict(clause) for clause in row.when] or [{}]
    return dataclasses.replace(row, when=[{**clause, **shaped} for clause in clauses for shaped in SHAPED])


@dataclass(frozen=True, kw_only=True)
class BandedParams:
    """Resolved parameters of the banded model (units and ranges: :data:`BANDED_TABLE`)."""

    tuning: str
    youngs_modulus_pa: float
    density_kg_m3: float
    material: str
    length_m: float
    thickness_m: float
    width_m: float
    mode_count: int
    theory: str
    shear_modulus_pa: float
    shear_coefficient: float
    profile: str
    undercut_depth: float
    undercut_width: float
    profile_samples: tuple[float, ...]
    frequency_hz: float
    mode_ratios: tuple[float, ...]
    mode_t60s_s: tuple[float, ...]
    mode_gains_db: tuple[float, ...]
    q: float
    shape: str
    mass_kg: float
    excitation: str
    strike_position: float
    pickup_position: float
    mallet_hardness: float
    mallet_velocity_m_s: float
    mallet_mass_kg: float
    pluck_displacement_mm: float
    release_time_ms: float
    bow_position: float
    bow_velocity_m_s: float
    bow_force_n: float
    bow_duration_s: float
    bow_ramp_ms: float
    attack_samples: tuple[float, ...]
    attack_rate_hz: int
    attack_pitch_hz: float
    attack_level_db: float
    # the tube, the motor and the damper (resonator.resonator_parameters)
    tube: str
    tube_mode: int
    tube_radius_m: float
    tube_detune_cents: float
    tube_position: float
    tube_gain_db: float
    tube_damping: float
    motor_rate_hz: float
    motor_depth: float
    damper: str
    damper_t60_s: float
    level_db: float


BANDED_TABLE = ParameterTable(
    "banded",
    [
        Parameter("tuning", "", None, None, "physics",
                  "where the modes come from: physics (a uniform free-free Euler-Bernoulli bar of the material "
                  "and size below), ratios (frequency_hz x mode_ratios, with mode_t60s_s) or geometry (a "
                  "free-free bar of the material, size and thickness profile below, in the chosen theory: its "
                  "modes and its own mode shapes)",
                  kind=CHOICE, choices=("physics", "ratios", "geometry")),
        *bar_size_parameters("tuning = physics or geometry: ", A_BAR, shear=True),
        Parameter("mode_count", "", 1, MAX_MODES, 4, "tuning = physics or geometry: how many modes", kind=INT,
                  when=A_BAR),
        # tuning = geometry (issue 15): the theory and the thickness profile of a real bar (free-free only:
        # a banded bar rests on its nodes). The resonator tube and the vibraphone's motor go after these.
        *theory_parameters("tuning = geometry: ", GEOMETRY, default="timoshenko"),
        *profile_parameters("tuning = geometry: ", GEOMETRY),
        Parameter("frequency_hz", "Hz", 20.0, 5000.0, 220.0, "tuning = ratios: the fundamental", scale="log",
                  when=RATIOS),
        Parameter("mode_ratios", "", 0.25, 200.0, (1.0, 4.0, 10.0),
                  "tuning = ratios: each mode's frequency / frequency_hz", kind=FLOATS, max_items=MAX_MODES,
                  when=RATIOS),
        Parameter("mode_t60s_s", "s", 0.005, 120.0, (),
                  "T60 of the first modes, in order (the rest follow q)", kind=FLOATS, max_items=MAX_MODES),
        Parameter("mode_gains_db", "dB", -120.0, 40.0, (),
                  "output level of the first modes, in order (the rest 0 dB): a gain on what each mode gives the "
                  "output, on top of the positions and the excitation (its decay and pitch stay)",
                  kind=FLOATS, max_items=MAX_MODES),
        Parameter("q", "", MIN_Q, 10000.0, 300.0,
                  "quality factor of every mode without its own T60: T60 = Q ln(1000) / (pi f)", scale="log",
                  when=SOME_MODE_WITHOUT_T60),
        Parameter("shape", "", None, None, "bar",
                  "tuning = ratios: mode shapes for positions: bar (a free-free bar tuned to mode_ratios by its "
                  "thickness profile; ratios no bar has are refused), ring (cos(n 2 pi x), n = 2, 3, ... around a "
                  "glass or bowl) or none (every mode the same at every point: positions have no effect)",
                  kind=CHOICE, choices=("bar", "ring", "none"), when=RATIOS),
        Parameter("mass_kg", "kg", 0.001, 100.0, 0.3, "tuning = ratios: the object's mass", scale="log", when=RATIOS),
        excitation_parameter(BANDED_EXCITERS),
        where_shaped(Parameter("strike_position", "", 0.0, 1.0, 0.1,
                               "where it is struck or plucked (a recorded attack's impulse too): fraction "
                               "of the length (bar) or of the circumference (ring)",
                               when=STRUCK_PLUCKED_OR_SAMPLED)),
        where_shaped(Parameter("pickup_position", "", 0.0, 1.0, 0.0,
                               "where its velocity is picked up, as strike_position")),
        *Strike.parameters(also=(Sample.name,)),
        *Pluck.parameters(),
        *[where_shaped(row) if row.name == "bow_position" else row for row in Bow.parameters()],
        *Sample.parameters(),
        *[where_shaped(row) if row.name == "tube_position" else row for row in resonator_parameters(MAX_MODES)],
        level_parameter(),
    ],
    record=BandedParams,
)

_MOTOR = ControlCurve("motor_rate_hz", 0.0, 12.0, when={"tube": "on"})
NOTES = (NoteMap("frequency_hz", "frequency", None, EXCITER_VELOCITIES, when={"tuning": "ratios"}, controls={1: _MOTOR}),
         NoteMap("length_m", "length", None, EXCITER_VELOCITIES, controls={1: _MOTOR}))
"""A bar tuned by ratios moves its frequency, one built from its geometry its length (material kept);
velocity drives the exciter; CC 1 (the modulation wheel) the vibraphone motor's rate."""


def _frequencies(p: BandedParams):
    """The object's mode frequencies (Hz) where they come in closed form, else None."""
    from .design import closed_form_frequencies

    return closed_form_frequencies(p)


def _tube_mode(p: BandedParams, sample_rate: float | None) -> str | None:
    from .resonator import tube_mode_refusal

    return tube_mode_refusal(p, len(p.mode_ratios) if p.tuning == "ratios" else p.mode_count)


def _band(p: BandedParams, sample_rate: float | None) -> str | None:
    from .design import band_refusal

    freqs = _frequencies(p) if sample_rate is not None else None
    if freqs is None or not freqs.size:  # (no ratios: the model's own refusal)
        return None
    return band_refusal(p, freqs, sample_rate)


def _tube_mode_frequency(p: BandedParams, sample_rate: float | None):
    """The frequency (Hz) of the mode the tube is tuned to, and whether it sounds at
    ``sample_rate``; None without a tube, a rate, closed-form modes or that mode."""
    if p.tube != "on" or sample_rate is None:
        return None
    freqs = _frequencies(p)
    if freqs is None or p.tube_mode > freqs.size:
        return None
    from .design import playable

    return freqs, bool(playable(freqs, sample_rate)[p.tube_mode - 1])


def _tube_sounds(p: BandedParams, sample_rate: float | None) -> str | None:
    from .resonator import tube_sounds_refusal

    tuned = _tube_mode_frequency(p, sample_rate)
    return None if tuned is None else tube_sounds_refusal(p, tuned[0], tuned[1], sample_rate)


def _tube_fits(p: BandedParams, sample_rate: float | None) -> str | None:
    from ...errors import ParameterError
    from .resonator import tube_for

    tuned = _tube_mode_frequency(p, sample_rate)
    if tuned is None or not tuned[1]:
        return None
    try:
        tube_for(p, float(tuned[0][p.tube_mode - 1]), sample_rate)
    except ParameterError as exc:
        return str(exc)
    return None


_MODES = ("tuning", "mode_count", "mode_ratios", "frequency_hz", "length_m", "thickness_m", "youngs_modulus_pa",
          "density_kg_m3")
CONSTRAINTS = (
    Constraint(("tube_mode", "tube", "tuning", "mode_count", "mode_ratios"),
               "`tube = on`: `tube_mode` at most the object's modes (`mode_count`, or as many as `mode_ratios`)",
               _tube_mode),
    profile_constraint(lambda p: p.tuning == "geometry", ("tuning", "geometry")),
    Constraint(_MODES, f"some mode between {LOWEST_HZ:g} Hz and a quarter of the sample rate (modes in closed form: "
               "`tuning = ratios`, `physics`, or `geometry` of a uniform Euler-Bernoulli bar)", _band),
    Constraint(("tube_mode", "tube", *_MODES), f"`tube = on`: the mode `tube_mode` between {LOWEST_HZ:g} Hz and a "
               "quarter of the sample rate (modes in closed form)", _tube_sounds),
    Constraint(("tube_radius_m", "tube", "tube_mode", "tube_detune_cents", *_MODES),
               "`tube = on`: a tube of `tube_radius_m` fits the tuned mode (its end correction, 0.6 x the radius, "
               "under a quarter wavelength; the tube below an eighth of the sample rate; modes in closed form)",
               _tube_fits),
)
"""Joint constraints (:mod:`barsynth.models.constraints`): the design's checks that need no loop
designed (each calls the design's own rule: :func:`.resonator.tube_mode_refusal`,
:func:`.design.band_refusal`, :func:`.resonator.tube_sounds_refusal`, :func:`.resonator.tube_for`,
the profile's); where the modes need a grid solved (``tuning = geometry`` of a profiled or
Timoshenko bar) only the tube's mode count and the profile are checked here."""
