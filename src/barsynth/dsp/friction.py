"""The bow table: friction force of a bow on a bar as a function of relative velocity.

Sources: G. Essl and P. R. Cook, "Banded waveguides", Proc. ICMC 1999 (barsynth
spec 3.1: a curve that sticks at small relative velocity, slips at large, with the
bow force scaling its steepness); the smooth friction curve of S. Bilbao, Numerical
Sound Synthesis (Wiley 2009), ``phi(x) = x exp((1 - x^2) / 2)``, which
rises through the origin (sticking), peaks at ``x = 1`` with ``phi = 1`` and falls
away slowly (slipping).

Here ``x = dv / w`` with ``dv = v_bow - v_bar`` (m/s) and a stick width
``w = BOW_WIDTH_M_S * sqrt(F / 1 N)`` that widens with the bow force ``F``: a
harder-pressed bow holds the bar over a wider range of relative velocity. The
friction force is ``F phi(dv / w)`` (N), so it never exceeds the bow force.

What follows, and what the tests measure: the bar sustains only where the
relative velocity sits on the falling side of the curve (``v_bow`` between about
``1.2 w`` and ``2.6 w``), so both the least and the greatest bow velocity that
sustain rise with the force; the steady amplitude follows the bow velocity.
"""

from __future__ import annotations

import math

from numba import njit

BOW_WIDTH_M_S = 0.1
"""Relative velocity (m/s) at which the friction of a 1 N bow peaks."""


@njit(cache=True, inline="always")
def stick_width(force_n: float) -> float:
    """The relative velocity (m/s) at which the friction peaks, for a bow force (N)."""
    return BOW_WIDTH_M_S * math.sqrt(force_n)


@njit(cache=True, inline="always")
def bow_friction(relative_velocity_m_s: float, force_n: float) -> float:
    """Friction force (N) on the bar from a bow pressed with ``force_n`` at ``relative_velocity_m_s``.

    Zero when the bow does not touch (``force_n <= 0``); odd in the relative
    velocity; at most ``force_n`` in size.
    """
    if force_n <= 0.0:
        return 0.0
    return friction_given_width(relative_velocity_m_s, force_n, 1.0 / stick_width(force_n))


@njit(cache=True, inline="always")
def friction_given_width(relative_velocity_m_s: float, force_n: float, inverse_width: float) -> float:
    """:func:`bow_friction` with ``1 / stick_width(force_n)`` worked out by the caller
    (once for a run of samples at one force)."""
    x = relative_velocity_m_s * inverse_width
    if abs(x) > 40.0:  # exp underflows; the friction is nil this far out
        return 0.0
    return force_n * x * math.exp(0.5 - 0.5 * x * x)


@njit(cache=True, inline="always")
def friction_slope(relative_velocity_m_s: float, force_n: float, inverse_width: float) -> float:
    """d(friction)/d(relative velocity) (N s/m): ``F (1 - x^2) exp((1 - x^2) / 2) / w``."""
    x = relative_velocity_m_s * inverse_width
    if abs(x) > 40.0:
        return 0.0
    return force_n * inverse_width * (1.0 - x * x) * math.exp(0.5 - 0.5 * x * x)
