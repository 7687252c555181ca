"""The ruler as a barsynth :class:`~barsynth.models.base.Model`: its setup and what it describes."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...checks import show_value
from ..base import Mode, Model
from ..constraints import check_constraints
from ..rendering import check_sample_rate
from .design import EDGE_LENGTH_M, Setup, decay_rate, desk_modes_for
from .table import CONSTRAINTS, NOTES, RULER_TABLE, RulerParams
from .voice import EngineVoice

MODES_PER_CANTILEVER = 6


def ruler_setup(p: RulerParams) -> Setup:
    """The engine's setup for the ruler ``p``; bad geometry refused in one line."""
    check_constraints(CONSTRAINTS, p)
    edge = p.length_m - p.overhang_m
    tip = p.tip_displacement_mm / 1000.0
    return Setup(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3, length_m=p.length_m,
                 thickness_m=p.thickness_m, width_m=p.width_m, clamped_back=False, points=p.points,
                 sigma0_per_s=p.sigma0_per_s, q=p.q, edge_m=edge, desk_under=True,
                 contact_stiffness_n_m2=p.desk_stiffness_n_m2, contact_damping_n_s_m2=p.desk_damping_n_s_m2,
                 contact_exponent=p.contact_exponent, edge_stiffness_n_m=p.desk_stiffness_n_m2 * EDGE_LENGTH_M,
                 edge_damping_n_s_m=p.desk_damping_n_s_m2 * EDGE_LENGTH_M, edge_height_m=0.0, edge_two_sided=False,
                 finger_m=edge - p.finger_distance_m, finger_force_n=p.finger_force_n,
                 finger_stiffness_n_m=p.finger_stiffness_n_m, finger_damping_n_s_m=p.finger_damping_n_s_m,
                 pluck_m=p.length_m, pluck_displacement_m=tip, slide_m=p.slide_m, slide_time_s=p.slide_time_s,
                 desk=p.desk, desk_balance=p.desk_balance, level=10.0 ** (p.level_db / 20.0))


class RulerVoice(EngineVoice):
    """A ruler clamped by a finger on a desk, bent down at the tip and let go.

    Examples
    --------
    >>> voice = RulerVoice({"points": 40}, sample_rate=48000)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, bool(abs(block).max() > 0)
    ((256,), True)
    """

    def setup(self) -> Setup:
        return ruler_setup(self._params)

    def no_rest_message(self) -> str:
        p = self._params
        return (f"the ruler finds no rest on these supports with finger_force_n = {show_value(p.finger_force_n)} N "
                f"{p.finger_distance_m * 100:.3g} cm behind the edge and tip_displacement_mm = "
                f"{show_value(p.tip_displacement_mm)} mm; allowed: a larger finger_force_n or finger_stiffness_n_m, "
                f"or a smaller tip_displacement_mm")


def cantilever_modes(s: Setup, length_m: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and T60s (s) of the clamped-free modes of the bar ``s`` cut to ``length_m``."""
    from ...physics import bar_frequencies

    f = bar_frequencies(youngs_modulus_pa=s.youngs_modulus_pa, density_kg_m3=s.density_kg_m3, length_m=length_m,
                        thickness_m=s.thickness_m, bc="clamped-free", count=count)
    return f, math.log(1000.0) / decay_rate(s, 2.0 * math.pi * f)


def describe_engine(s: Setup, groups: list[tuple[str, float]], sample_rate: float) -> list[Mode]:
    """The modes of each cantilever in ``groups`` (name, free length in m) below Nyquist, and the desk's."""
    modes = []
    nyquist = 0.5 * sample_rate
    for group, length in groups:
        f, t60 = cantilever_modes(s, length, MODES_PER_CANTILEVER)
        for i, (fi, ti) in enumerate(zip(f, t60)):
            if fi < nyquist:
                modes.append(Mode(group, float(fi), 1.0 / (i + 1) ** 2, float(ti)))
    if s.desk is not None:
        found = desk_modes_for(s.desk, sample_rate)
        for fi, ti, gi in zip(found.frequency_hz, found.t60_s, found.gain):
            modes.append(Mode("desk", float(fi), float(gi), float(ti)))
    return modes


class RulerModel(Model):
    """The physical twang: a ruler, a finger and a desk (see :mod:`barsynth.models.ruler`)."""

    name = "ruler"
    summary = "physical twang: a finite-difference ruler clamped by a finger, slapping on a desk (spec 9)"
    table = RULER_TABLE
    note_maps = NOTES
    constraints = CONSTRAINTS
    voice_class = RulerVoice

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The clamped-free modes of the long cantilever (finger to tip: while it swings up, off
        the desk), of the short one (edge to tip: while it bears on the edge) and the desk's modes.
        Gains: 1 / n^2 for a cantilever's n-th mode (the slap spreads over them), the desk's
        pressure per newton."""
        p = self.resolve(parameters)
        s = ruler_setup(p)
        return describe_engine(s, [("long cantilever", p.overhang_m + p.finger_distance_m),
                                   ("short cantilever", p.overhang_m)], check_sample_rate(sample_rate))


MODEL = RulerModel()
