"""The all-pass waveguide bar's parameter table and its typed record.

The bar's material and size and the output level are the rows the bar models share
(:mod:`barsynth.parameters`); the mallet and the pluck bring their own
(:meth:`barsynth.exciters.Strike.parameters`, :meth:`barsynth.exciters.Pluck.parameters`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ...exciters import STRUCK_OR_PLUCKED, Pluck, Strike
from ...parameters import CHOICE, INT, Parameter, ParameterTable
from ...physics.boundary import BOUNDARY_CONDITIONS
from ..constraints import Constraint
from ..notemap import EXCITER_VELOCITIES, NoteMap
from ..rows import bar_size_parameters, excitation_parameter, level_parameter

ALLPASS_EXCITERS = (Strike, Pluck)
"""The exciters it offers, in the order of its ``excitation`` choices (the model's ``exciters``)."""


@dataclass(frozen=True, kw_only=True)
class AllpassParams:
    """Resolved parameters of the all-pass waveguide bar (units and ranges: :data:`TABLE`)."""

    youngs_modulus_pa: float
    density_kg_m3: float
    material: str
    length_m: float
    thickness_m: float
    width_m: float
    bc: str
    allpass_order: int
    q: float
    excitation: str
    strike_position: float
    pickup_position: float
    mallet_hardness: float
    mallet_velocity_m_s: float
    mallet_mass_kg: float
    pluck_displacement_mm: float
    release_time_ms: float
    level_db: float


TABLE = ParameterTable(
    "allpass",
    [
        *bar_size_parameters(),
        Parameter("bc", "", None, None, "free-free",
                  "boundary conditions: the x = 0 end first (clamped-free: clamped at 0, free at the far end)",
                  kind=CHOICE, choices=BOUNDARY_CONDITIONS),
        Parameter("allpass_order", "", 1, 64, 24,
                  "all-pass sections round the loop in all (an upper limit: a bar that needs fewer gets "
                  "fewer); more fits more modes, closer", kind=INT),
        Parameter("q", "", 3.0, 10000.0, 300.0,
                  "quality factor of every mode: T60 = Q ln(1000) / (pi f)", scale="log"),
        excitation_parameter(ALLPASS_EXCITERS),
        Parameter("strike_position", "", 0.0, 1.0, 0.1, "where it is struck or plucked: fraction of the length",
                  when=STRUCK_OR_PLUCKED),
        Parameter("pickup_position", "", 0.0, 1.0, 0.0, "where its velocity is picked up: fraction of the length"),
        *Strike.parameters(),
        *Pluck.parameters(),
        level_parameter(),
    ],
    record=AllpassParams,
)

NOTES = (NoteMap("length_m", "length", "fitted", {k: v for k, v in EXCITER_VELOCITIES.items() if k != "bow"}),)
"""A note moves the bar's length (material kept); velocity drives the strike or pluck."""


def _first_mode(p: AllpassParams, sample_rate: float | None) -> str | None:
    """:func:`~.plan.first_mode_refusal` of the bar's first mode (closed form: no fit)."""
    from ...physics import bar_frequencies
    from .plan import first_mode_refusal

    f_1 = float(bar_frequencies(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3,
                                length_m=p.length_m, thickness_m=p.thickness_m, bc=p.bc, count=1)[0])
    return first_mode_refusal(f_1, sample_rate, youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3,
                              length_m=p.length_m, thickness_m=p.thickness_m)


CONSTRAINTS = (
    Constraint(("length_m", "thickness_m", "youngs_modulus_pa", "density_kg_m3", "bc"),
               "the first mode (Euler-Bernoulli, closed form) at or above 1 Hz and below 0.8 x the fitted band's "
               "top, min(0.45 x sample rate, 20 kHz)", _first_mode),
)
"""Joint constraints (:mod:`barsynth.models.constraints`): the first mode in the band the filters are
fitted over (checked before any fit, 0.1-0.4 s each)."""
