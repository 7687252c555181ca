"""Force pulses that excite a bar: a Hertzian mallet and a released displacement.

Sources: A. Chaigne and V. Doutaut, "Numerical simulations of xylophones. I. Time-domain
modeling of the vibrating bars", JASA 101 (1997): the mallet as a mass on a
non-linear contact spring, ``F = k d^p``; barsynth spec 3.1 (excitations).

Each pulse is returned as the force averaged over each sample interval (N), so the
impulse it delivers, ``sum(F) / sample_rate``, does not depend on the sample rate.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

HERTZ_EXPONENT = 2.5  # felt-covered mallets: 2.3 to 2.8 (Chaigne & Doutaut)
SUBSTEPS = 32  # integration steps per sample


def _contact_integral(p: float) -> float:
    """``I(p) = integral_0^1 du / sqrt(1 - u^(p+1))``, so that ``tau = 2 I d_max / v``."""
    a = 1.0 / (p + 1.0)
    return math.sqrt(math.pi) * math.gamma(1.0 + a) / math.gamma(0.5 + a)


def hertz_stiffness(contact_s: float, mass_kg: float, p: float = HERTZ_EXPONENT, velocity_m_s: float = 1.0) -> float:
    """The contact stiffness k (N/m^p) that gives ``contact_s`` for a rigid target at ``velocity_m_s``."""
    d_max = contact_s * velocity_m_s / (2.0 * _contact_integral(p))
    return (p + 1.0) * mass_kg * velocity_m_s ** 2 / (2.0 * d_max ** (p + 1.0))


def mallet_pulse(*, mass_kg: float, velocity_m_s: float, stiffness: float, sample_rate: float,
                 p: float = HERTZ_EXPONENT) -> np.ndarray:
    """The contact force of a mallet bouncing off a rigid surface, per sample (N).

    The mallet (mass, velocity) compresses a spring ``F = k d^p`` until it comes to
    rest and leaves: the pulse lasts ``2 I(p) d_max / v`` and delivers ``2 m v``.
    A faster or harder mallet makes a shorter pulse, so more high modes.
    """
    d_max = ((p + 1.0) * mass_kg * velocity_m_s ** 2 / (2.0 * stiffness)) ** (1.0 / (p + 1.0))
    contact = 2.0 * _contact_integral(p) * d_max / velocity_m_s
    samples = int(contact * sample_rate) + 2
    pulse = _integrate(mass_kg, velocity_m_s, stiffness, p, 1.0 / (sample_rate * SUBSTEPS), samples) * sample_rate
    # Rounding in the last steps leaves the total a hair off 2 m v; restore it exactly.
    return pulse * (2.0 * mass_kg * velocity_m_s / (pulse.sum() / sample_rate))


@njit(cache=True, nogil=True)
def _integrate(mass, velocity, stiffness, p, dt, samples):  # pragma: no cover - compiled
    """Impulse of the contact force in each sample (velocity Verlet, SUBSTEPS a sample)."""
    impulses = np.zeros(samples)
    d, v = 0.0, velocity
    a = 0.0
    for n in range(samples):
        acc = 0.0
        for _ in range(SUBSTEPS):
            v_half = v + 0.5 * dt * a
            d += dt * v_half
            a_next = -stiffness * max(d, 0.0) ** p / mass
            v = v_half + 0.5 * dt * a_next
            acc -= 0.5 * (a + a_next) * mass * dt
            a = a_next
            if d <= 0.0 and v < 0.0:
                impulses[n] = acc
                return impulses[:n + 1]
        impulses[n] = acc
    return impulses


def release_ramp(force_n: float, release_s: float, sample_rate: float) -> np.ndarray:
    """The force change of a release: 0 to ``force_n`` along a raised cosine (N per sample)."""
    n = max(1, int(round(release_s * sample_rate)))
    t = (np.arange(n) + 0.5) / n
    return force_n * 0.5 * (1.0 - np.cos(np.pi * t))
