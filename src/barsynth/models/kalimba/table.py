"""The kalimba's one parameter table, and its typed record :class:`KalimbaParams`."""

from __future__ import annotations

from dataclasses import dataclass

from ...checks import show_value
from ...parameters import CHOICE, INT, Parameter, ParameterTable
from ..constraints import Constraint
from ..notemap import NoteMap, VelocityCurve
from ..rows import level_parameter, resized_bar_parameters
from ..ruler.design import MIN_NODES_BEYOND

BRIDGES = ("one-sided", "pinned")
"""How the bridge holds the tine: pressed onto it from above (it may lift off), or both ways."""


@dataclass(frozen=True, kw_only=True)
class KalimbaParams:
    """Resolved parameters of the kalimba model (units, ranges and docs: :data:`KALIMBA_TABLE`)."""

    youngs_modulus_pa: float
    density_kg_m3: float
    material: str
    thickness_m: float
    width_m: float
    vibrating_length_m: float
    back_length_m: float
    bridge: str
    bridge_height_mm: float
    bridge_stiffness_n_m: float
    bridge_damping_n_s_m: float
    pluck_position: float
    pluck_displacement_mm: float
    q: float
    sigma0_per_s: float
    points: int
    level_db: float


def _tine_size() -> list[Parameter]:
    """The tine's material and size rows (no ``length_m``: the tine has two lengths), with the
    defaults of a 1.0 mm spring-steel tine: E and rho are the materials table's ``steel``, and
    ``material`` keeps its default ``custom`` (the choice a table turns back to when E or rho is
    given by hand; a default that is a material would set nothing when chosen)."""
    defaults = {"youngs_modulus_pa": 200e9, "density_kg_m3": 7850.0, "material": "custom", "thickness_m": 0.001,
                "width_m": 0.004}
    docs = {"thickness_m": "thickness of the tine (f1 grows with it)",
            "width_m": "width of the tine (sets its mass and how much air it moves, not its pitch)"}
    return resized_bar_parameters(defaults, docs, {"thickness_m": (0.0003, 0.005), "width_m": (0.002, 0.03)},
                                  leave_out=("length_m",))


KALIMBA_TABLE = ParameterTable(
    "kalimba",
    [
        *_tine_size(),
        Parameter("vibrating_length_m", "m", 0.01, 0.2, 0.043,
                  "the tine's length from the bridge to its tip: its pitch (f ~ 1/L^2)", scale="log"),
        Parameter("back_length_m", "m", 0.002, 0.05, 0.008,
                  "from the clamp (the pressure bar) to the bridge: it lets the tine turn over the bridge, "
                  "which lowers the pitch", scale="log"),
        Parameter("bridge", "", None, None, "one-sided",
                  "one-sided: the tine is pressed onto the bridge and may lift off it; pinned: the bridge "
                  "holds it both ways", kind=CHOICE, choices=BRIDGES),
        Parameter("bridge_height_mm", "mm", 0.0, 3.0, 0.5,
                  "how far the bridge lifts the tine above its clamp: the preload pressing it onto the bridge"),
        Parameter("bridge_stiffness_n_m", "N/m", 1e4, 1e9, 1e7,
                  "the bridge's stiffness under the tine (a softer bridge lowers the pitch)", scale="log"),
        Parameter("bridge_damping_n_s_m", "N s/m", 0.0, 100.0, 1.0,
                  "the bridge's damping while the tine presses on it"),
        Parameter("pluck_position", "", 0.3, 1.0, 0.9,
                  "where the thumb pushes the tine down: a fraction of the vibrating length from the bridge "
                  "(1: the tip)"),
        Parameter("pluck_displacement_mm", "mm", 0.05, 10.0, 1.5,
                  "how far the thumb pushes the tine down before it slips off", scale="log"),
        Parameter("q", "", 10.0, 1e4, 1500.0,
                  "the tine's Q, the same for every mode (spring steel a few thousand; the overtones die "
                  "faster in proportion to their frequency)", scale="log"),
        Parameter("sigma0_per_s", "1/s", 0.0, 50.0, 1.0,
                  "loss at every frequency (the mounting, the air): T60 = 6.91 / sigma0 alone"),
        Parameter("points", "", 20, 400, 60,
                  "grid nodes along the whole tine (clamp to tip): more are more accurate and slower", kind=INT),
        level_parameter("the pressure in Pa at 1 m"),
    ],
    record=KalimbaParams,
)

NOTES = (NoteMap("vibrating_length_m", "length", "tine on bridge", {None: VelocityCurve("pluck_displacement_mm", 0.2, 3.0)}),)
"""A note moves the tine's vibrating length; velocity the pluck's displacement (mm)."""

MAX_PLUCK_FRACTION = 0.3
"""The pluck point may be pushed down by at most this fraction of its distance from the bridge
(beyond it the small deflections of the bar equation no longer hold)."""


def cell_m(p: KalimbaParams) -> float:
    """The grid's cell (m): the whole tine, clamp to tip, over ``points - 1``."""
    return (p.back_length_m + p.vibrating_length_m) / (p.points - 1)


def _vibrating_cells(p: KalimbaParams, sample_rate: float | None) -> str | None:
    dx = cell_m(p)
    if p.vibrating_length_m >= MIN_NODES_BEYOND * dx:
        return None
    return (f"parameter vibrating_length_m = {show_value(p.vibrating_length_m)} m spans "
            f"{p.vibrating_length_m / dx:.3g} grid cells of {dx * 1000:.3g} mm; allowed: at least "
            f"{MIN_NODES_BEYOND * dx:.4g} m ({MIN_NODES_BEYOND} cells; or more points)")


def _back_cells(p: KalimbaParams, sample_rate: float | None) -> str | None:
    dx = cell_m(p)
    if p.back_length_m >= 2.0 * dx:
        return None
    return (f"parameter back_length_m = {show_value(p.back_length_m)} m is shorter than two grid cells of "
            f"{dx * 1000:.3g} mm; allowed: at least {2.0 * dx:.4g} m (or more points)")


def _pluck(p: KalimbaParams, sample_rate: float | None) -> str | None:
    reach = p.pluck_position * p.vibrating_length_m
    if p.pluck_displacement_mm / 1000.0 <= MAX_PLUCK_FRACTION * reach:
        return None
    return (f"parameter pluck_displacement_mm = {show_value(p.pluck_displacement_mm)} mm bends the tine too far "
            f"{reach * 1000:.3g} mm beyond the bridge; allowed: up to {MAX_PLUCK_FRACTION * reach * 1000:.4g} mm "
            f"({MAX_PLUCK_FRACTION:g} x pluck_position x vibrating_length_m)")


CONSTRAINTS = (
    Constraint(("vibrating_length_m", "back_length_m", "points"),
               f"`vibrating_length_m` >= {MIN_NODES_BEYOND} grid cells of (`back_length_m` + "
               "`vibrating_length_m`) / (`points` - 1)", _vibrating_cells),
    Constraint(("back_length_m", "vibrating_length_m", "points"),
               "`back_length_m` >= 2 grid cells of (`back_length_m` + `vibrating_length_m`) / (`points` - 1)",
               _back_cells),
    Constraint(("pluck_displacement_mm", "pluck_position", "vibrating_length_m"),
               f"`pluck_displacement_mm` <= {MAX_PLUCK_FRACTION:g} x `pluck_position` x `vibrating_length_m` "
               "(in mm)", _pluck),
)
"""Joint constraints (:mod:`barsynth.models.constraints`): every check of
:func:`~.model.kalimba_setup` (closed forms, no design)."""
