"""Table rows several models share: a bar's material and size, the output level.

A model's table is built from these, its exciters' rows (:mod:`barsynth.exciters`) and its
own; names, units, ranges and docs stay the same in every model that has them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..parameters import CHOICE, FLOATS, Compare, Parameter, Sets
from .constraints import Constraint

if TYPE_CHECKING:
    from ..exciters import Exciter


def bar_size_parameters(note: str = "", when: Any = (), shear: bool = False) -> list[Parameter]:
    """Material and size of a rectangular bar; ``note`` prefixes each doc (e.g. when it applies)
    and ``when`` says when they act (see :class:`~barsynth.parameters.Parameter`). With ``shear``
    the material also sets the rows of :func:`theory_parameters` (which the table must have)."""
    return [
        Parameter("youngs_modulus_pa", "Pa", 1e8, 4e11, 69e9, f"{note}Young's modulus E", scale="log", when=when),
        Parameter("density_kg_m3", "kg/m^3", 100.0, 22000.0, 2700.0, f"{note}density rho", scale="log", when=when),
        material_parameter(note, when, shear=shear),
        Parameter("length_m", "m", 0.02, 3.0, 0.30, f"{note}length of the bar", scale="log", when=when),
        Parameter("thickness_m", "m", 0.0003, 0.1, 0.01, f"{note}thickness h (bending direction)", scale="log",
                  when=when),
        Parameter("width_m", "m", 0.002, 0.5, 0.04, f"{note}width (sets the mass)", scale="log", when=when),
    ]


def resized_bar_parameters(defaults: dict[str, Any], docs: dict[str, str] | None = None,
                           ranges: dict[str, tuple[float, float]] | None = None,
                           leave_out: tuple[str, ...] = ()) -> list[Parameter]:
    """:func:`bar_size_parameters` for a model whose bar is a thing of its own size (a ruler, a
    tine): each row's default from ``defaults``, and where given its doc from ``docs`` and its
    range from ``ranges`` (minimum, maximum); the rows named in ``leave_out`` left out."""
    import dataclasses

    rows = []
    for row in bar_size_parameters():
        if row.name in leave_out:
            continue
        changes: dict[str, Any] = {"default": defaults[row.name]}
        if docs and row.name in docs:
            changes["doc"] = docs[row.name]
        if ranges and row.name in ranges:
            changes["minimum"], changes["maximum"] = ranges[row.name]
        rows.append(dataclasses.replace(row, **changes))
    return rows


def excitation_parameter(exciters: tuple[type[Exciter], ...]) -> Parameter:
    """``excitation``: which of a model's ``exciters`` a trigger uses (the first by default), in
    their order, with their summaries as its doc."""
    words = [f"{e.name} ({e.summary})" for e in exciters]
    said = words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]
    return Parameter("excitation", "", None, None, exciters[0].name, f"what a trigger does: {said}",
                     kind=CHOICE, choices=tuple(e.name for e in exciters))


def level_parameter(reference: str = "the pick-up velocity in m/s") -> Parameter:
    """``level_db``: the output gain of a bar model, re what its raw output is (by default a
    velocity, m/s)."""
    return Parameter("level_db", "dB", -60.0, 40.0, 0.0, f"output gain re {reference}")


def material_parameter(note: str = "", when: Any = (), shear: bool = False) -> Parameter:
    """``material``: a name from the materials table that sets ``youngs_modulus_pa`` and
    ``density_kg_m3`` (``custom``: those two as given); with ``shear`` also ``shear_modulus_pa``
    and ``shear_coefficient`` (:func:`material_shear`)."""
    from ..physics.materials import material, materials

    def lookup(name: str) -> tuple[float, ...]:
        m = material(name)
        return (m.youngs_modulus_pa, m.density_kg_m3, *(material_shear(name) if shear else ()))

    names = ("youngs_modulus_pa", "density_kg_m3", *(("shear_modulus_pa", "shear_coefficient") if shear else ()))
    sets_text = ", ".join(names[:-1]) + " and " + names[-1]
    return Parameter("material", "", None, None, "custom",
                     f"{note}a material from the materials table (barsynth materials): sets {sets_text}; "
                     "custom keeps those as given",
                     kind=CHOICE, choices=("custom", *materials()), when=when, sets=Sets(names, lookup))


ASSUMED_POISSON_RATIO = 0.33
"""The Poisson ratio taken where no shear stiffness is given (a material's entry without one, a
``shear_modulus_pa`` of 0)."""


def material_shear(name: str) -> tuple[float, float]:
    """The shear modulus ``G`` (Pa) and shear coefficient ``kappa`` of material ``name``, as its
    entry in the materials table gives them (every entry has both, spec 8.3)."""
    from ..physics.materials import material

    m = material(name)
    return float(m.shear_modulus_pa), float(m.shear_coefficient)


THEORIES = ("euler-bernoulli", "timoshenko")  # physics.theory.THEORIES (not imported: it loads NumPy)
TIMOSHENKO = {"theory": ("timoshenko",)}


def theory_parameters(note: str = "", when: Any = (), default: str = "euler-bernoulli") -> list[Parameter]:
    """``theory`` (Euler–Bernoulli or Timoshenko, spec 8.2) and the shear stiffness the thick bar
    needs (acting only with ``theory = timoshenko``); a ``material`` made with ``shear`` sets them.
    ``note`` prefixes each doc, ``when`` (one clause) says when the theory acts at all, ``default``
    is the theory's default."""
    thick = {**(when or {}), **TIMOSHENKO}
    return [
        Parameter("theory", "", None, None, default,
                  f"{note}the bar's physics: euler-bernoulli (thin: bending only) or timoshenko (thick: shear and "
                  "rotary inertia lower the high modes)", kind=CHOICE, choices=THEORIES, when=when),
        Parameter("shear_modulus_pa", "Pa", 0.0, 4e11, 0.0,
                  f"{note}shear modulus G (a wood's across the grain, G_LT); a material sets it; 0: an isotropic "
                  "solid's, E / (2 (1 + 0.33))", when=thick),
        Parameter("shear_coefficient", "", 0.5, 1.0, 5.0 / 6.0,  # physics.timoshenko.SHEAR_COEFFICIENT_RANGE
                  f"{note}the cross-section's shear coefficient kappa: 5/6 for a rectangle, Cowper's "
                  "10 (1 + nu) / (12 + 11 nu) for an isotropic one (a material sets it)", when=thick),
    ]


def shear_of(p: Any) -> tuple[float, float]:
    """The shear modulus (Pa) and shear coefficient of a Timoshenko bar's record ``p`` (rows of
    :func:`theory_parameters`): as given or as its material set them; a shear modulus of 0 is an
    isotropic solid's with :data:`ASSUMED_POISSON_RATIO`."""
    from ..physics.timoshenko import isotropic_shear_modulus

    g = p.shear_modulus_pa or isotropic_shear_modulus(p.youngs_modulus_pa, ASSUMED_POISSON_RATIO)
    return float(g), float(p.shear_coefficient)


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


def profile_constraint(acts: Callable[[Any], bool] | None = None, when: tuple[str, str] | None = None) -> Constraint:
    """The profile's own check (:class:`~barsynth.physics.profiles.Profile`: ``profile = samples``
    needs at least two ``profile_samples``) as a joint constraint, where ``acts(p)`` (by default
    always; ``when``: the row and value that make it act, for the docs): the same check, run on
    the record, so one copy of it and of its message."""
    from ..errors import ParameterError
    from ..physics.profiles import THINNEST

    def refusal(p: Any, sample_rate: float | None) -> str | None:
        if acts is not None and not acts(p):
            return None
        try:
            profile_of(p)
        except ParameterError as exc:
            return str(exc)
        return None

    where = f"`{when[0]} = {when[1]}` and " if when else ""
    return Constraint(("profile", "profile_samples", *when[:1]) if when else ("profile", "profile_samples"),
                      f"{where}`profile = samples`: at least 2 `profile_samples`, each {THINNEST:g} to 1", refusal)


def profile_of(p: Any):
    """The :class:`~barsynth.physics.profiles.Profile` of a record with :func:`profile_parameters`."""
    from ..physics.profiles import Profile

    return Profile(p.profile, depth=p.undercut_depth, width=p.undercut_width, samples=tuple(p.profile_samples))
