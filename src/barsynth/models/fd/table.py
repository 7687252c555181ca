"""The finite-difference bar's one parameter table, and its typed record :class:`FdParams`."""

from __future__ import annotations

from dataclasses import dataclass

from ...errors import ParameterError
from ...exciters import BOWED, STRUCK_OR_PLUCKED, Bow, Pluck, Strike
from ...parameters import CHOICE, INT, Parameter, ParameterTable
from ...physics.boundary import BOUNDARY_CONDITIONS
from ..constraints import Constraint
from ..notemap import EXCITER_VELOCITIES, NoteMap
from ..rows import (bar_size_parameters, excitation_parameter, level_parameter, profile_constraint,
                    profile_parameters, theory_parameters)

FD_EXCITERS = (Strike, Bow, Pluck)
"""The exciters it offers, in the order of its ``excitation`` choices (the model's ``exciters``)."""


@dataclass(frozen=True, kw_only=True)
class FdParams:
    """Resolved parameters of the fd model (units, ranges and docs: :data:`FD_TABLE`)."""

    youngs_modulus_pa: float
    density_kg_m3: float
    material: str
    length_m: float
    thickness_m: float
    width_m: float
    theory: str
    shear_modulus_pa: float
    shear_coefficient: float
    bc: str
    profile: str
    undercut_depth: float
    undercut_width: float
    profile_samples: tuple[float, ...]
    points: int
    theta: float
    oversampling: int
    sigma0_per_s: float
    sigma1_m2_s: float
    excitation: str
    bow_solver: str
    strike_position: float
    pickup_position: float
    mallet_hardness: float
    mallet_velocity_m_s: float
    mallet_mass_kg: float
    pluck_displacement_mm: float
    bow_position: float
    bow_velocity_m_s: float
    bow_force_n: float
    bow_duration_s: float
    bow_ramp_ms: float
    level_db: float


FD_TABLE = ParameterTable(
    "fd",
    [
        *bar_size_parameters(shear=True),
        *theory_parameters(),
        Parameter("bc", "", None, None, "free-free", "boundary conditions at the two ends (x = 0 first)",
                  kind=CHOICE, choices=BOUNDARY_CONDITIONS),
        *profile_parameters(),
        Parameter("points", "", 8, 400, 100, "grid nodes along the bar: more are more accurate and slower",
                  kind=INT),
        Parameter("theta", "", 0.0, 1.0, 0.5,
                  "the scheme's implicitness: 0.5 or less is stable at any sample rate (0.5: no numerical "
                  "loss); above 0.5 only on coarse grids (checked)"),
        Parameter("oversampling", "", 1, 8, 4,
                  "scheme steps per output sample: each doubling cuts the step's flattening of high modes "
                  "fourfold (the output is low-passed and decimated)", kind=INT),
        Parameter("sigma0_per_s", "1/s", 0.01, 100.0, 1.0,
                  "loss at every frequency: T60 = 6.91 / sigma0 (modes near the step's limit decay slower: "
                  "see describe)",
                  scale="log"),
        Parameter("sigma1_m2_s", "m^2/s", 0.0, 0.1, 0.002,
                  "loss growing with frequency: adds sigma1 x wavenumber^2 to a mode's decay rate"),
        excitation_parameter(FD_EXCITERS),
        Parameter("bow_solver", "", None, None, "newton",
                  "the bow's friction: newton (solved with each step: stick and slip) or explicit (from the "
                  "step before: a forced oscillation)", kind=CHOICE, choices=("newton", "explicit"), when=BOWED),
        Parameter("strike_position", "", 0.0, 1.0, 0.7, "where it is struck or plucked: fraction of the length",
                  when=STRUCK_OR_PLUCKED),
        Parameter("pickup_position", "", 0.0, 1.0, 0.97, "where its velocity is picked up: fraction of the length"),
        *Strike.parameters(),
        *Pluck.parameters(release=False),  # the bar is let go at once: the scheme's step is the release
        *Bow.parameters(position=1.0),
        level_parameter(),
    ],
    record=FdParams,
)

NOTES = (NoteMap("length_m", "length", None, EXCITER_VELOCITIES),)
"""A note moves the bar's length (material kept); velocity drives the exciter."""


def _unstable(p: FdParams, sample_rate: float | None) -> str | None:
    """:func:`~.design.stability_refusal` on the bar's grid (no scheme designed), its highest mode
    from the banded solver, taken a hair (1e-9) low: the bound is then never stricter than the
    design's own check (:func:`~.design.check_stability`, dense)."""
    if p.theta <= 0.5 or sample_rate is None:  # stable at any rate (the bound is above 0.5)
        return None
    from ...physics.grid import highest_frequency_banded
    from .design import grid_of, stability_refusal

    try:
        grid = grid_of(p)
    except ParameterError:  # no grid: another constraint's refusal (the profile's)
        return None
    return stability_refusal(p, highest_frequency_banded(grid) * (1.0 - 1e-9), sample_rate)


CONSTRAINTS = (
    profile_constraint(),
    Constraint(("theta", "points", "oversampling"),
               "`theta` <= 0.5, or at most 0.5 + 2 / (Omega k)^2 for the grid's highest mode Omega (rad/s) and the "
               "step k = 1 / (sample rate x `oversampling`) (Bilbao 2009, ch. 7)", _unstable),
)
"""Joint constraints (:mod:`barsynth.models.constraints`): the profile's check and the scheme's
stability (:func:`~.design.check_stability` on the grid alone: a few ms, no scheme factored)."""
