"""Table rows several models share: a bar's material and size, the output level.

A model's table is built from these, its exciters' rows (:mod:`barsynth.exciters`) and its
own; names, units, ranges and docs stay the same in every model that has them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..parameters import CHOICE, Parameter, Sets

if TYPE_CHECKING:
    from ..exciters import Exciter


def bar_size_parameters(note: str = "", when: Any = ()) -> list[Parameter]:
    """Material and size of a rectangular bar; ``note`` prefixes each doc (e.g. when it applies)
    and ``when`` says when they act (see :class:`~barsynth.parameters.Parameter`)."""
    return [
        Parameter("youngs_modulus_pa", "Pa", 1e8, 4e11, 69e9, f"{note}Young's modulus E", scale="log", when=when),
        Parameter("density_kg_m3", "kg/m^3", 100.0, 22000.0, 2700.0, f"{note}density rho", scale="log", when=when),
        material_parameter(note, when),
        Parameter("length_m", "m", 0.02, 3.0, 0.30, f"{note}length of the bar", scale="log", when=when),
        Parameter("thickness_m", "m", 0.0003, 0.1, 0.01, f"{note}thickness h (bending direction)", scale="log",
                  when=when),
        Parameter("width_m", "m", 0.002, 0.5, 0.04, f"{note}width (sets the mass)", scale="log", when=when),
    ]


def excitation_parameter(exciters: tuple[type[Exciter], ...]) -> Parameter:
    """``excitation``: which of a model's ``exciters`` a trigger uses (the first by default), in
    their order, with their summaries as its doc."""
    words = [f"{e.name} ({e.summary})" for e in exciters]
    said = words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]
    return Parameter("excitation", "", None, None, exciters[0].name, f"what a trigger does: {said}",
                     kind=CHOICE, choices=tuple(e.name for e in exciters))


def level_parameter() -> Parameter:
    """``level_db``: the output gain of a bar model whose raw output is a velocity (m/s)."""
    return Parameter("level_db", "dB", -60.0, 40.0, 0.0, "output gain re the pick-up velocity in m/s")


def material_parameter(note: str = "", when: Any = ()) -> Parameter:
    """``material``: a name from the materials table that sets ``youngs_modulus_pa`` and
    ``density_kg_m3`` (``custom``: those two as given)."""
    from ..physics.materials import material, materials

    def lookup(name: str) -> tuple[float, float]:
        m = material(name)
        return m.youngs_modulus_pa, m.density_kg_m3

    return Parameter("material", "", None, None, "custom",
                     f"{note}a material from the materials table (barsynth materials): sets youngs_modulus_pa "
                     "and density_kg_m3; custom keeps those as given",
                     kind=CHOICE, choices=("custom", *materials()), when=when,
                     sets=Sets(("youngs_modulus_pa", "density_kg_m3"), lookup))
