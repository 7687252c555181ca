"""Bar materials: Young's modulus, density, shear stiffness and a typical Q.

The numbers live in a data file, ``barsynth/data/materials.toml``, each entry with
the reference it comes from (spec 1.7, 8.3). Woods are given along the grain, the
direction that governs the bending of a bar cut lengthwise.

Shear (for thick bars, spec 8.2): an isotropic material gives its Poisson ratio ``nu``
and ``G = E / (2 (1 + nu))``; a wood, orthotropic, gives ``G`` itself (``G_LT``, between
the grain and the thickness of a quartersawn bar; the data file says why). The shear
coefficient of a rectangle is Cowper's, ``kappa = 10 (1 + nu) / (12 + 11 nu)`` (G. R. Cowper,
J. Appl. Mech. 33, 1966), and 5/6 where no ``nu`` is given.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from functools import cache
from importlib import resources

from ..checks import show_value
from ..errors import ParameterError

__all__ = ["Material", "material", "materials"]

PLAIN_SHEAR_COEFFICIENT = 5.0 / 6.0
"""The shear coefficient of a rectangle without a Poisson ratio (Timoshenko's 5/6)."""

_DATA_PACKAGE = "barsynth"
_DATA_FILE = ("data", "materials.toml")


@dataclass(frozen=True)
class Material:
    """One material of the table.

    Attributes
    ----------
    name : str
        Key in the table, e.g. ``"acrylic"``.
    youngs_modulus_pa : float
        Young's modulus ``E`` in Pa (along the grain for woods).
    density_kg_m3 : float
        Density ``rho`` in kg/m³.
    typical_q : float or None
        A typical quality factor of bar modes (dimensionless), or None if unknown.
    description : str
        What exactly the entry describes (grade, species, moisture content).
    source : str
        Where the numbers come from.
    poisson_ratio : float or None
        Poisson's ratio ``nu`` (dimensionless) of an isotropic material; None for a wood.
    shear_modulus_pa : float
        Shear modulus ``G`` in Pa: as given for a wood (``G_LT``), else ``E / (2 (1 + nu))``.
    """

    name: str
    youngs_modulus_pa: float
    density_kg_m3: float
    typical_q: float | None
    description: str
    source: str
    poisson_ratio: float | None
    shear_modulus_pa: float

    @property
    def isotropic(self) -> bool:
        """True when the shear modulus follows from ``nu`` (metals, plastics, glass)."""
        return self.poisson_ratio is not None

    @property
    def shear_coefficient(self) -> float:
        """Cowper's shear coefficient of a rectangle from ``nu``; 5/6 where only ``G`` is given.

        Examples
        --------
        >>> round(material("aluminium").shear_coefficient, 4), round(material("rosewood").shear_coefficient, 4)
        (0.8509, 0.8333)
        """
        from .timoshenko import shear_coefficient

        if self.poisson_ratio is None:
            return PLAIN_SHEAR_COEFFICIENT
        return shear_coefficient(self.poisson_ratio)

    @property
    def modulus_ratio(self) -> float:
        """``E / G`` (dimensionless): about 2.6 for metals, 10-20 for woods along the grain."""
        return self.youngs_modulus_pa / self.shear_modulus_pa


def _positive_number(name: str, key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"materials.toml: [{name}] {key} = {value!r} is not a number")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"materials.toml: [{name}] {key} = {value!r} must be > 0")
    return float(value)


@cache
def _load() -> dict[str, Material]:
    path = resources.files(_DATA_PACKAGE).joinpath(*_DATA_FILE)
    with path.open("rb") as fh:
        table = tomllib.load(fh)
    out: dict[str, Material] = {}
    for name, entry in table.items():
        q = entry.get("typical_q")
        e = _positive_number(name, "youngs_modulus_pa", entry["youngs_modulus_pa"])
        rho = entry["density_kg_m3"]
        nu, g = entry.get("poisson_ratio"), entry.get("shear_modulus_pa")
        if (nu is None) == (g is None):
            raise ValueError(f"materials.toml: [{name}] gives {'both' if nu is not None else 'neither'} "
                             "poisson_ratio and shear_modulus_pa; give exactly one")
        if nu is not None:
            nu = _positive_number(name, "poisson_ratio", nu)
            if nu >= 0.5:
                raise ValueError(f"materials.toml: [{name}] poisson_ratio = {nu!r} must be < 0.5")
            from .timoshenko import isotropic_shear_modulus

            g = isotropic_shear_modulus(e, nu)
        out[name] = Material(
            name=name,
            youngs_modulus_pa=e,
            density_kg_m3=_positive_number(name, "density_kg_m3", rho),
            typical_q=None if q is None else _positive_number(name, "typical_q", q),
            description=str(entry["description"]),
            source=str(entry["source"]),
            poisson_ratio=nu,
            shear_modulus_pa=_positive_number(name, "shear_modulus_pa", g),
        )
    return out


def materials() -> dict[str, Material]:
    """All materials of the table, by name (a new dict on each call).

    Returns
    -------
    dict[str, Material]
        In the order of the data file.

    Examples
    --------
    >>> materials()["acrylic"].youngs_modulus_pa
    3200000000.0
    """
    return dict(_load())


def material(name: str) -> Material:
    """The material called ``name`` (case, spaces and underscores are forgiven).

    Raises
    ------
    ParameterError
        If there is no such material; the message lists those available.

    Examples
    --------
    >>> material("Stainless steel").density_kg_m3
    8000.0
    """
    table = _load()
    key = str(name).strip().lower().replace("_", "-").replace(" ", "-")
    try:
        return table[key]
    except KeyError:
        raise ParameterError(
            f"unknown material {show_value(name)}; available: {', '.join(table)}"
        ) from None
