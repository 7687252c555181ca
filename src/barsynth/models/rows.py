"""Table rows several models share: a bar's material and size, the output level.

A model's table is built from these, its exciters' rows (:mod:`barsynth.exciters`) and its
own; names, units, ranges and docs stay the same in every model that has them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..parameters import CHOICE, FLOATS, Compare, Parameter, Sets

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


def profile_parameters(note: str = "", when: Any = ()) -> list[Parameter]:
    """A bar's thickness profile (:class:`~barsynth.physics.profiles.Profile`): ``profile``,
    ``undercut_depth``, ``undercut_width`` and ``profile_samples``; ``note`` prefixes each doc and
    ``when`` (one clause, or a list of them) says when the profile acts at all."""
    from ..physics.profiles import PROFILE_KINDS, THINNEST

    def acting(clause: dict[str, Any]) -> list[dict[str, Any]]:
        clauses = [when] if isinstance(when, dict) else list(when)
        return [{**outer, **clause} for outer in clauses] if clauses else [clause] if clause else []

    undercut = {"profile": ("parabolic", "circular")}
    return [
        Parameter("profile", "", None, None, "uniform",
                  f"{note}thickness along the bar: uniform, parabolic or circular (an undercut at the middle), or "
                  "samples (profile_samples)", kind=CHOICE, choices=PROFILE_KINDS, when=acting({})),
        Parameter("undercut_depth", "", 0.0, 1.0 - THINNEST, 0.0,
                  f"{note}profile = parabolic or circular: depth of the undercut at the middle, fraction of the "
                  "thickness", when=acting(undercut)),
        Parameter("undercut_width", "", 0.05, 1.0, 0.6,
                  f"{note}profile = parabolic or circular: length of the undercut, fraction of the bar's length",
                  when=acting({**undercut, "undercut_depth": Compare(">", 0.0)})),
        Parameter("profile_samples", "", THINNEST, 1.0, (),
                  f"{note}profile = samples: thickness / thickness_m at equally spaced points from end to end",
                  kind=FLOATS, max_items=64, when=acting({"profile": ("samples",)})),
    ]


def profile_of(p: Any):
    """The :class:`~barsynth.physics.profiles.Profile` of a record with :func:`profile_parameters`."""
    from ..physics.profiles import Profile

    return Profile(p.profile, depth=p.undercut_depth, width=p.undercut_width, samples=tuple(p.profile_samples))


THEORIES = ("euler-bernoulli", "timoshenko")
"""The bar theories a model may offer (``theory``): thin (Euler–Bernoulli) or thick (Timoshenko:
shear and rotary inertia)."""


def theory_parameters(note: str = "", when: Any = (), default: str = "timoshenko") -> list[Parameter]:
    """``theory`` and the thick bar's shear rows, ``shear_modulus_pa`` and ``shear_coefficient``
    (each 0 by default: from the material, :func:`barsynth.models.shear.shear_of`); ``note``
    prefixes each doc and ``when`` (one clause) says when the theory acts."""
    thick = {**when, "theory": ("timoshenko",)}
    return [
        Parameter("theory", "", None, None, default,
                  f"{note}the bar's physics: euler-bernoulli (thin: bending only) or timoshenko (thick: shear and "
                  "rotary inertia, which lower the higher modes of short, thick or wooden bars)",
                  kind=CHOICE, choices=THEORIES, when=when),
        Parameter("shear_modulus_pa", "Pa", 0.0, 2e11, 0.0,
                  f"{note}shear modulus G (0: the material's; for custom, E / (2 (1 + nu)) with nu = 0.33)",
                  when=thick),
        Parameter("shear_coefficient", "", 0.0, 1.0, 0.0,
                  f"{note}shear coefficient kappa of the cross-section (0: the material's; for custom, Cowper's "
                  "for a rectangle, 10 (1 + nu) / (12 + 11 nu) with nu = 0.33)", when=thick),
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
