"""Bar materials: Young's modulus, density and a typical Q.

The numbers live in a data file, ``barsynth/data/materials.toml``, each entry with
the reference it comes from (spec 1.7). Woods are given along the grain, the
direction that governs the bending of a bar cut lengthwise.
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
    """

    name: str
    youngs_modulus_pa: float
    density_kg_m3: float
    typical_q: float | None
    description: str
    source: str


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
        e = entry["youngs_modulus_pa"]
        rho = entry["density_kg_m3"]
        out[name] = Material(
            name=name,
            youngs_modulus_pa=_positive_number(name, "youngs_modulus_pa", e),
            density_kg_m3=_positive_number(name, "density_kg_m3", rho),
            typical_q=None if q is None else _positive_number(name, "typical_q", q),
            description=str(entry["description"]),
            source=str(entry["source"]),
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
