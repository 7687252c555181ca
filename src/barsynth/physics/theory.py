"""Which bar theory gives the modes: Euler–Bernoulli or Timoshenko, uniform or profiled (spec 8.1, 8.2).

One dispatcher, :func:`bar_modes_hz`, so the command line, the undercut tuner and the models
ask for a bar's modes in one way: a uniform bar from its closed form
(:func:`~barsynth.physics.modes.bar_frequencies`, or
:func:`~barsynth.physics.timoshenko.timoshenko_frequencies`), any other profile from its grid
(:func:`~barsynth.physics.grid.grid_modes`, or
:func:`~barsynth.physics.timoshenko_grid.timoshenko_grid_modes`), Richardson extrapolated.

Timoshenko's bar (S. Timoshenko, Phil. Mag. 41, 1921) adds shear and rotary inertia; it
needs the shear modulus ``G`` and the shear coefficient ``kappa`` of the section, which
:func:`shear_constants` takes from a Poisson ratio (isotropic: ``G = E / (2 (1 + nu))`` and
Cowper's ``kappa``) or from ``G`` itself (a wood; ``kappa = 5/6``).
"""

from __future__ import annotations

import numpy as np

from ..checks import check_number, show_value
from ..errors import ParameterError
from .materials import PLAIN_SHEAR_COEFFICIENT
from .profiles import Profile
from .timoshenko import SHEAR_COEFFICIENT_RANGE, isotropic_shear_modulus
from .timoshenko import shear_coefficient as cowper_shear_coefficient

THEORIES = ("euler-bernoulli", "timoshenko")
"""The bar theories :func:`bar_modes_hz` knows, thin first (the default everywhere)."""


def check_theory(theory: str) -> str:
    """``theory`` if it is one of :data:`THEORIES`, else a :class:`ParameterError`."""
    if theory not in THEORIES:
        raise ParameterError(f"parameter theory = {show_value(theory)} is unknown; allowed: one of "
                             f"{', '.join(THEORIES)}")
    return theory


def shear_constants(*, youngs_modulus_pa: float, poisson_ratio: float | None = None,
                    shear_modulus_pa: float | None = None,
                    shear_coefficient: float | None = None) -> tuple[float | None, float]:
    """The shear modulus ``G`` (Pa, or None if neither ``nu`` nor ``G`` is given) and the shear
    coefficient ``kappa`` (dimensionless) of a rectangular bar.

    ``nu`` gives ``G = E / (2 (1 + nu))`` and Cowper's ``kappa = 10 (1 + nu) / (12 + 11 nu)``;
    ``G`` alone gives ``kappa = 5/6``; a ``shear_coefficient`` given overrides ``kappa``.

    Examples
    --------
    >>> g, kappa = shear_constants(youngs_modulus_pa=69e9, poisson_ratio=0.33)
    >>> round(g / 1e9, 2), round(kappa, 4)
    (25.94, 0.8509)
    >>> shear_constants(youngs_modulus_pa=20e9, shear_modulus_pa=1.33e9)[1] == 5 / 6
    True
    """
    if poisson_ratio is not None and shear_modulus_pa is not None:
        raise ParameterError(f"parameters poisson_ratio = {show_value(poisson_ratio)} and shear_modulus_pa = "
                             f"{show_value(shear_modulus_pa)} given together; allowed: one of them (the other "
                             "follows: G = E / (2 (1 + nu)))")
    kappa = None
    if shear_coefficient is not None:
        kappa = check_number("shear_coefficient", shear_coefficient, "(dimensionless)",
                             minimum=SHEAR_COEFFICIENT_RANGE[0], maximum=SHEAR_COEFFICIENT_RANGE[1])
    if poisson_ratio is not None:
        nu = check_number("poisson_ratio", poisson_ratio, "(dimensionless)", minimum=0.0, maximum=0.5,
                          maximum_exclusive=True)
        youngs_modulus_pa = check_number("youngs_modulus_pa", youngs_modulus_pa, "Pa", minimum=0.0,
                                         minimum_exclusive=True)
        return isotropic_shear_modulus(youngs_modulus_pa, nu), cowper_shear_coefficient(nu) if kappa is None else kappa
    if shear_modulus_pa is not None:
        shear_modulus_pa = check_number("shear_modulus_pa", shear_modulus_pa, "Pa", minimum=0.0,
                                        minimum_exclusive=True)
    return shear_modulus_pa, PLAIN_SHEAR_COEFFICIENT if kappa is None else kappa


def is_uniform(profile: Profile | None) -> bool:
    """True for no profile or a uniform one (the closed forms apply)."""
    return profile is None or profile.kind == "uniform"


def bar_modes_hz(*, theory: str, youngs_modulus_pa: float, density_kg_m3: float, length_m: float,
                 thickness_m: float, width_m: float = 0.04, bc: str, count: int, profile: Profile | None = None,
                 shear_modulus_pa: float | None = None, shear_coefficient: float | None = None,
                 points: int = 250) -> np.ndarray:
    """Mode frequencies (Hz, increasing, shape ``(count,)``) of a bar in the chosen theory.

    Parameters
    ----------
    theory : str
        ``"euler-bernoulli"`` (thin bar) or ``"timoshenko"`` (shear and rotary inertia).
    youngs_modulus_pa, density_kg_m3 : float
        ``E`` (Pa, along the grain for woods) and ``rho`` (kg/m³).
    length_m, thickness_m, width_m : float
        The bar's length, full thickness (bending direction) and width in m. A uniform
        Euler–Bernoulli bar does not depend on its width.
    bc : str
        Boundary conditions, one of :data:`~barsynth.physics.boundary.BOUNDARY_CONDITIONS`.
    count : int
        Number of modes.
    profile : Profile or None
        The thickness profile; None or ``uniform`` use the closed forms, any other the grids
        (``points`` nodes, Richardson extrapolated).
    shear_modulus_pa : float or None
        ``G`` in Pa; required by ``timoshenko`` (see :func:`shear_constants`), unused otherwise.
    shear_coefficient : float or None
        ``kappa``; None takes 5/6 (give Cowper's value through :func:`shear_constants`).

    Examples
    --------
    A rosewood marimba bar tuned to 1 : 4 in Euler–Bernoulli rings flat of it (spec 8.1):

    >>> bar = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4, thickness_m=0.02, width_m=0.05,
    ...            bc="free-free", count=2, profile=Profile("parabolic", depth=0.5895, width=0.6))
    >>> thin = bar_modes_hz(theory="euler-bernoulli", **bar)
    >>> thick = bar_modes_hz(theory="timoshenko", shear_modulus_pa=1.33e9, **bar)
    >>> round(float(thin[1] / thin[0]), 3), round(float(thick[1] / thick[0]), 3)
    (4.0, 3.854)
    """
    check_theory(theory)
    bar = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, length_m=length_m,
               thickness_m=thickness_m, bc=bc, count=count)
    if theory == "euler-bernoulli":
        if is_uniform(profile):
            from .modes import bar_frequencies

            return bar_frequencies(**bar)
        from .grid import grid_modes

        return grid_modes(width_m=width_m, profile=profile, points=points, **bar)
    if shear_modulus_pa is None:
        raise ParameterError("parameter shear_modulus_pa is missing; theory = timoshenko needs the shear modulus G "
                             "in Pa (above 0): give G, a Poisson ratio, or a material that has one")
    shear_modulus_pa = check_number("shear_modulus_pa", shear_modulus_pa, "Pa", minimum=0.0, minimum_exclusive=True)
    kappa = PLAIN_SHEAR_COEFFICIENT if shear_coefficient is None else check_number(
        "shear_coefficient", shear_coefficient, "(dimensionless)", minimum=SHEAR_COEFFICIENT_RANGE[0],
        maximum=SHEAR_COEFFICIENT_RANGE[1])
    shear = dict(shear_modulus_pa=shear_modulus_pa, shear_coefficient=kappa)
    if is_uniform(profile):
        from .timoshenko import timoshenko_frequencies

        return np.asarray(timoshenko_frequencies(**shear, **bar), dtype=np.float64)
    from .timoshenko_grid import timoshenko_grid_modes

    return timoshenko_grid_modes(width_m=width_m, profile=profile, points=points, **shear, **bar)


def cents(frequencies_hz: np.ndarray, reference_hz: np.ndarray) -> np.ndarray:
    """``1200 log2(f / f_ref)`` elementwise: how far ``f`` lies above the reference, in cents."""
    return 1200.0 * np.log2(np.asarray(frequencies_hz, dtype=np.float64) / np.asarray(reference_hz, dtype=np.float64))


__all__ = ["THEORIES", "bar_modes_hz", "cents", "check_theory", "is_uniform", "shear_constants"]
