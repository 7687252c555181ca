"""The twang's parameter table, its typed record, and the kernel's control vector.

The kernel reads the parameters as one float64 vector with a slot for every table row, in
table order (:func:`control_vector`): a number as itself, a bool as 0 or 1, a choice as its
position among its choices (``gain_mapping``: linear 0, log 1, which the design cross-fades).
``material`` has its slot too, which the kernel never reads: it acts through the Young's
modulus and density it sets. The kernel finds a slot by name through :data:`ROWS`
(``values[rows.length_m]``), built here from the table, so no index is written by hand.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from ...parameters import BOOL, CHOICE, Compare, Parameter, ParameterTable
from ..constraints import Constraint
from ..notemap import ControlCurve, NoteMap, VelocityCurve
from ..rows import material_parameter

VIBRATO_ON = {"vibrato_rate_hz": Compare(">", 0.0)}
SHORT_HEARD = {"short_cantilever_gain": Compare(">", 0.0)}
FREE_BAR_HEARD = {"free_bar_gain": Compare(">", 0.0)}


@dataclass(frozen=True, kw_only=True)
class TwangParams:
    """Resolved parameters of the ruler twang (units and ranges: :data:`TWANG_TABLE`)."""

    youngs_modulus_pa: float = 3.2e9
    density_kg_m3: float = 1180.0
    material: str = "custom"
    length_m: float = 0.30
    thickness_m: float = 0.003
    q: float = 100.0
    shape: float = 1.5
    gain_mapping: str = "linear"
    vibrato_rate_hz: float = 0.0
    vibrato_depth_hz: float = 18.0
    slide: bool = False
    slide_time_s: float = 1.0
    short_length_ratio: float = 0.7
    full_cantilever_gain: float = 1.0
    short_cantilever_gain: float = 0.75
    free_bar_gain: float = 1.0
    noise_cutoff_hz: float = 4000.0
    free_band_q: float = 10.0
    level_db: float = -3.0


TWANG_TABLE = ParameterTable(
    "twang",
    [
        Parameter("youngs_modulus_pa", "Pa", 1e8, 4e11, 3.2e9,
                  "Young's modulus E of the ruler (acrylic 3.2 GPa, steel 200 GPa)", scale="log"),
        Parameter("density_kg_m3", "kg/m^3", 100.0, 22000.0, 1180.0,
                  "density rho of the ruler material", scale="log"),
        material_parameter(),
        Parameter("length_m", "m", 0.05, 1.0, 0.30,
                  "clamped length L, from the finger to the tip (the paper's 'whole bar')"),
        Parameter("thickness_m", "m", 0.0003, 0.02, 0.003,
                  "thickness h of the ruler in the bending direction", scale="log"),
        Parameter("q", "", 50.0, 800.0, 100.0,
                  "decay quality factor Q of every mode: alpha = pi f / Q", scale="log"),
        Parameter("shape", "", 0.5, 10.0, 1.5,
                  "beta-density gain shape l (m = 4): small favours low modes"),
        Parameter("gain_mapping", "", None, None, "linear",
                  "frequency axis of the gain shape: linear 0..fs/2 (paper) or log 1 Hz..fs/2",
                  kind=CHOICE, choices=("linear", "log")),
        Parameter("vibrato_rate_hz", "Hz", 0.0, 8.0, 0.0,
                  "vibrato rate; 0 turns vibrato off"),
        Parameter("vibrato_depth_hz", "Hz", 0.0, 50.0, 18.0,
                  "vibrato swing of the loudest mode (paper: 18 Hz), at most 6 %", when=VIBRATO_ON),
        Parameter("slide", "", None, None, False,
                  "slide: the short-cantilever modes rise 35 % (the ruler is shortened)",
                  kind=BOOL, when=SHORT_HEARD),
        Parameter("slide_time_s", "s", 0.05, 10.0, 1.0,
                  "duration of the slide's S-shaped rise, from the trigger", scale="log",
                  when={"slide": (True,), **SHORT_HEARD}),
        Parameter("short_length_ratio", "", 0.3, 0.95, 0.7,
                  "length of the short cantilever at the desk edge, as a fraction of L", when=SHORT_HEARD),
        Parameter("full_cantilever_gain", "", 0.0, 1.0, 1.0,
                  "mix of the full-length cantilever modes"),
        Parameter("short_cantilever_gain", "", 0.0, 1.0, 0.75,
                  "mix of the short cantilever modes, relative to the full-length ones (paper: 0.75)"),
        Parameter("free_bar_gain", "", 0.0, 4.0, 1.0,
                  "mix of the noise-excited free-bar modes"),
        Parameter("noise_cutoff_hz", "Hz", 100.0, 20000.0, 4000.0,
                  "cutoff of the one-pole low-pass on the free-bar noise", scale="log", when=FREE_BAR_HEARD),
        Parameter("free_band_q", "", 1.0, 100.0, 10.0,
                  "Q of each 2nd-order section of the free-bar 4th-order band-passes", scale="log",
                  when=FREE_BAR_HEARD),
        Parameter("level_db", "dB", -60.0, 0.0, -3.0,
                  "output level of a note's first peak, dB re full scale"),
    ],
    record=TwangParams,
)

Rows = namedtuple("Rows", TWANG_TABLE.names)  # type: ignore[misc]
ROWS = Rows(*(TWANG_TABLE.index(name) for name in TWANG_TABLE.names))
"""Each parameter's slot in the control vector, by name (``ROWS.length_m``), from the table."""


def control_vector(p: TwangParams, out: np.ndarray | None = None) -> np.ndarray:
    """``p`` as the kernel's control vector (see the module docstring), into ``out`` if given."""
    values = np.empty(len(TWANG_TABLE)) if out is None else out
    for row, param in enumerate(TWANG_TABLE):
        value = getattr(p, param.name)
        values[row] = param.choices.index(value) if param.kind == CHOICE else float(value)
    return values

NOTES = (NoteMap("length_m", "length", "short-cantilever", {None: VelocityCurve("level_db", -40.0, 0.0, 0.5)},
                 controls={1: ControlCurve("vibrato_rate_hz", 0.0, 8.0)}),)
"""A note moves the ruler's overhang (its short cantilever's pitch); velocity the level (dB); CC 1
(the modulation wheel) the vibrato's rate (0: none)."""

AUDIBLE_MIN_HZ = 20.0  # an offline render needs one mode at least this high


def _audible(p: TwangParams, sample_rate: float | None) -> str | None:
    """The refusal of a ruler none of whose modes is audible at ``sample_rate`` (its modes at the
    trigger, :func:`~.design.design_modes`: closed forms, microseconds)."""
    if sample_rate is None:
        return None
    from .design import design_modes

    if any(m.frequency_hz >= AUDIBLE_MIN_HZ for m in design_modes(p, sample_rate=sample_rate)):
        return None
    return (f"parameters length_m = {p.length_m:g} m, thickness_m = {p.thickness_m:g} m, youngs_modulus_pa = "
            f"{p.youngs_modulus_pa:g} Pa, density_kg_m3 = {p.density_kg_m3:g} kg/m^3 put every mode of this ruler "
            f"below {AUDIBLE_MIN_HZ:g} Hz, at or above Nyquist ({sample_rate / 2:g} Hz) or at zero gain; allowed: "
            "settings with at least one audible mode (change length, thickness or material, or the sample_rate)")


CONSTRAINTS = (
    Constraint(("length_m", "thickness_m", "youngs_modulus_pa", "density_kg_m3", "short_length_ratio",
                "full_cantilever_gain", "short_cantilever_gain", "free_bar_gain"),
               f"some mode at or above {AUDIBLE_MIN_HZ:g} Hz, below Nyquist and at a gain above 0", _audible),
)
"""Joint constraints (:mod:`barsynth.models.constraints`): one mode audible (the model's
:meth:`~.model.TwangModel.check_renderable` raises this constraint's refusal)."""
