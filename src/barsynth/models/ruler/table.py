"""The ruler's one parameter table, and its typed record :class:`RulerParams`."""

from __future__ import annotations

from dataclasses import dataclass

from ...checks import show_value
from ...parameters import CHOICE, INT, Parameter, ParameterTable, Sets
from ..constraints import Constraint
from ..notemap import NoteMap, VelocityCurve
from ..rows import level_parameter, resized_bar_parameters
from .design import MIN_NODES_BEYOND
from .desk import DESK_NAMES, DESKS


@dataclass(frozen=True, kw_only=True)
class RulerParams:
    """Resolved parameters of the ruler model (units, ranges and docs: :data:`RULER_TABLE`)."""

    youngs_modulus_pa: float
    density_kg_m3: float
    material: str
    length_m: float
    thickness_m: float
    width_m: float
    overhang_m: float
    finger_distance_m: float
    finger_force_n: float
    finger_stiffness_n_m: float
    finger_damping_n_s_m: float
    tip_displacement_mm: float
    q: float
    sigma0_per_s: float
    desk: str
    desk_stiffness_n_m2: float
    desk_damping_n_s_m2: float
    contact_exponent: float
    slide_m: float
    slide_time_s: float
    desk_balance: float
    points: int
    level_db: float


def _desk_parameter() -> Parameter:
    def lookup(name: str) -> tuple[float, float]:
        desk = DESKS[name]
        return desk.contact_stiffness_n_m2, desk.contact_damping_n_s_m2

    return Parameter("desk", "", None, None, "wood",
                     "the desk: its modes sound after each slap, and it sets desk_stiffness_n_m2 and "
                     "desk_damping_n_s_m2", kind=CHOICE, choices=DESK_NAMES,
                     sets=Sets(("desk_stiffness_n_m2", "desk_damping_n_s_m2"), lookup))


def _ruler_size() -> list[Parameter]:
    """The bar's material and size rows, with a 30 cm acrylic ruler's defaults (its E and density,
    the material left ``custom``: a chosen material sets them)."""
    defaults = {"youngs_modulus_pa": 3.2e9, "density_kg_m3": 1180.0, "material": "custom", "length_m": 0.30,
                "thickness_m": 0.003, "width_m": 0.03}
    docs = {"length_m": "length of the ruler", "thickness_m": "thickness of the ruler",
            "width_m": "width of the ruler (sets its mass and how much air it moves)"}
    return resized_bar_parameters(defaults, docs, {"length_m": (0.05, 1.0), "thickness_m": (0.0003, 0.02)})


RULER_TABLE = ParameterTable(
    "ruler",
    [
        *_ruler_size(),
        Parameter("overhang_m", "m", 0.02, 0.95, 0.18,
                  "how far the ruler reaches beyond the desk's edge: the short cantilever (less than the length)"),
        Parameter("finger_distance_m", "m", 0.005, 0.9, 0.04,
                  "how far behind the edge the finger presses (on the desk; within the ruler)"),
        Parameter("finger_force_n", "N", 0.5, 200.0, 20.0,
                  "how hard the finger presses the ruler onto the desk (a weak finger lets the ruler lift it)",
                  scale="log"),
        Parameter("finger_stiffness_n_m", "N/m", 1e3, 1e7, 1e5, "the finger's stiffness (it presses from above)",
                  scale="log"),
        Parameter("finger_damping_n_s_m", "N s/m", 0.0, 200.0, 10.0, "the finger's damping while it presses"),
        Parameter("tip_displacement_mm", "mm", 0.5, 60.0, 15.0,
                  "how far the other hand bends the tip down below the desk before letting go", scale="log"),
        Parameter("q", "", 2.0, 5000.0, 40.0,
                  "the ruler's material Q, the same for every mode (acrylic about 30, wood 50-100, steel "
                  "1000 or more)", scale="log"),
        Parameter("sigma0_per_s", "1/s", 0.0, 50.0, 0.5,
                  "loss at every frequency (air, the hand): T60 = 6.91 / sigma0 alone"),
        _desk_parameter(),
        Parameter("desk_stiffness_n_m2", "N/m^2", 1e6, 1e11, DESKS["wood"].contact_stiffness_n_m2,
                  "the contact's stiffness per metre of ruler on the desk (a softer desk: softer, lower slaps); "
                  "the edge bears as 1 cm of it", scale="log"),
        Parameter("desk_damping_n_s_m2", "N s/m^2", 0.0, 1e4, DESKS["wood"].contact_damping_n_s_m2,
                  "the contact's damping per metre of ruler, while pressed"),
        Parameter("contact_exponent", "", 1.0, 2.0, 1.0,
                  "the contact force's power of the penetration: 1 a linear penalty, 1.5 Hertzian"),
        Parameter("slide_m", "m", 0.0, 0.5, 0.0,
                  "how far the hand pulls the ruler back while it rings (the overhang shortens: the pitch rises); "
                  "0: no slide"),
        Parameter("slide_time_s", "s", 0.05, 5.0, 1.0, "how long the slide takes (from the release)",
                  scale="log"),
        Parameter("desk_balance", "", 0.0, 1.0, 0.5,
                  "0: only the ruler's sound, 1: only the desk's, 0.5: both as loud as physics makes them"),
        Parameter("points", "", 20, 400, 61, "grid nodes along the ruler: more are more accurate and slower",
                  kind=INT),
        level_parameter("the pressure in Pa at 1 m"),
    ],
    record=RulerParams,
)

NOTES = (NoteMap("overhang_m", "length", "short cantilever",
                 {None: VelocityCurve("tip_displacement_mm", 0.02, 0.25, 1.0, per="overhang_m", factor=1000.0)}),)
"""A note moves the overhang (finger distance kept); velocity bends the tip by 2-25 % of the overhang."""

MAX_TIP_FRACTION = 0.3
"""The tip may be bent down by at most this fraction of the overhang (beyond it the small
deflections of the bar equation no longer hold)."""


def _overhang(p: RulerParams, sample_rate: float | None) -> str | None:
    if p.overhang_m < p.length_m:
        return None
    return (f"parameter overhang_m = {show_value(p.overhang_m)} m is not shorter than the ruler "
            f"(length_m = {show_value(p.length_m)} m); allowed: less than length_m")


def _finger(p: RulerParams, sample_rate: float | None) -> str | None:
    edge = p.length_m - p.overhang_m
    if p.finger_distance_m < edge:
        return None
    return (f"parameter finger_distance_m = {show_value(p.finger_distance_m)} m puts the finger beyond the "
            f"ruler's back end; allowed: less than length_m - overhang_m = {edge:.6g} m")


def _cells_beyond(p: RulerParams, sample_rate: float | None) -> str | None:
    dx = p.length_m / (p.points - 1)
    beyond = p.overhang_m - p.slide_m
    if beyond >= MIN_NODES_BEYOND * dx:
        return None
    named = (f"parameters overhang_m = {show_value(p.overhang_m)} m and slide_m = {show_value(p.slide_m)} m leave"
             if p.slide_m > 0 else f"parameter overhang_m = {show_value(p.overhang_m)} m leaves")
    left = f"{beyond * 100:.3g} cm beyond the edge" if beyond > 0 else "nothing beyond the edge"
    return (f"{named} {left}{' after the slide' if p.slide_m > 0 else ''}: "
            f"{max(beyond, 0.0) / dx:.3g} grid cells of {dx * 1000:.3g} mm (points = {p.points}); "
            f"allowed: at least {MIN_NODES_BEYOND} grid cells, overhang_m - slide_m >= "
            f"{MIN_NODES_BEYOND * dx:.4g} m (a longer overhang_m, a shorter slide_m or more points)")


def _tip(p: RulerParams, sample_rate: float | None) -> str | None:
    if p.tip_displacement_mm / 1000.0 <= MAX_TIP_FRACTION * p.overhang_m:
        return None
    return (f"parameter tip_displacement_mm = {show_value(p.tip_displacement_mm)} mm bends the "
            f"{p.overhang_m * 100:.3g} cm overhang too far; allowed: up to "
            f"{MAX_TIP_FRACTION * p.overhang_m * 1000:.4g} mm ({MAX_TIP_FRACTION:g} x overhang_m)")


CONSTRAINTS = (
    Constraint(("overhang_m", "length_m"), "`overhang_m` < `length_m`", _overhang),
    Constraint(("finger_distance_m", "length_m", "overhang_m"),
               "`finger_distance_m` < `length_m` - `overhang_m` (the finger on the ruler)", _finger),
    Constraint(("overhang_m", "slide_m", "length_m", "points"),
               f"`overhang_m` - `slide_m` >= {MIN_NODES_BEYOND} grid cells of `length_m` / (`points` - 1) "
               "(the part beyond the edge, after the slide)", _cells_beyond),
    Constraint(("tip_displacement_mm", "overhang_m"),
               f"`tip_displacement_mm` <= {MAX_TIP_FRACTION:g} x `overhang_m` (in mm)", _tip),
)
"""Joint constraints (:mod:`barsynth.models.constraints`): :func:`~.model.ruler_setup`'s geometry
checks, all of them closed forms (the rest on the supports needs the statics: a design check)."""
