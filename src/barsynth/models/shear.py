"""A thick bar's shear modulus and shear coefficient, from a model's rows (spec 8.2, 8.3).

``shear_modulus_pa`` and ``shear_coefficient`` (:func:`~barsynth.models.rows.theory_parameters`)
are 0 by default: the material's then (:class:`~barsynth.physics.materials.Material`: ``G``
from its Poisson ratio for a metal, ``G_LT`` as measured for a wood; Cowper's coefficient
from its Poisson ratio, 5/6 for a wood). A custom material (its E and rho as given) has no
shear stiffness of its own: an isotropic one with ``nu = 0.33`` is assumed,
``G = E / (2 (1 + nu))`` and Cowper's ``kappa = 10 (1 + nu) / (12 + 11 nu)`` (G. R. Cowper,
J. Appl. Mech. 33, 1966). For a wood that is far too stiff in shear (E/G of 10 to 20 along
the grain against 2.66): give ``shear_modulus_pa`` or choose the material.
"""

from __future__ import annotations

from typing import Any

ASSUMED_POISSON_RATIO = 0.33
"""Poisson's ratio assumed for a custom material (a metal's: aluminium 0.33, steel 0.29)."""


def cowper(poisson_ratio: float) -> float:
    """Cowper's shear coefficient of a rectangular section, ``10 (1 + nu) / (12 + 11 nu)``.

    Examples
    --------
    >>> round(cowper(0.33), 4)
    0.8509
    """
    return 10.0 * (1.0 + poisson_ratio) / (12.0 + 11.0 * poisson_ratio)


def shear_of(p: Any) -> tuple[float, float]:
    """``(G in Pa, kappa)`` of a record with ``youngs_modulus_pa``, ``material`` and the shear rows:
    each as given, or 0 for the material's (see the module docstring).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> g, kappa = shear_of(SimpleNamespace(youngs_modulus_pa=69e9, material="custom", shear_modulus_pa=0.0,
    ...                                     shear_coefficient=0.0))
    >>> round(g / 1e9, 2), round(kappa, 4)
    (25.94, 0.8509)
    """
    from ..physics.materials import material

    known = material(p.material) if p.material != "custom" else None
    g = p.shear_modulus_pa or getattr(known, "shear_modulus_pa", None) \
        or p.youngs_modulus_pa / (2.0 * (1.0 + ASSUMED_POISSON_RATIO))
    kappa = p.shear_coefficient or getattr(known, "shear_coefficient", None) or cowper(ASSUMED_POISSON_RATIO)
    return float(g), float(kappa)
