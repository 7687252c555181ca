"""The finite-difference bar's design: parameters and a sample rate in, the scheme out (no state).

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the theta scheme, its
stability and its losses); A. Chaigne and V. Doutaut, JASA 101 (1997) (non-uniform bars).
The grid operator ``M, K, L`` comes from :mod:`barsynth.physics.grid` (Euler–Bernoulli) or
:mod:`barsynth.physics.timoshenko_grid` (``theory = timoshenko``: deflections and rotations
interleaved, the same pentadiagonal layout, so the same step); here it becomes the step's matrices (see :mod:`.kernel`), the points where exciters and the pick-up meet the bar,
the decimation filter, and the modes and T60s the scheme really rings.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...errors import ParameterError
from ...exciters import PluckHold, StaticPoint
from ...physics.grid import BarGrid, bar_grid, grid_eigen, grid_modes, highest_frequency, rigid_mode_count
from ...physics.timoshenko_grid import TwoFieldGrid, timoshenko_grid, timoshenko_grid_modes
from ..rows import profile_of, shear_of
from . import kernel as K
from .table import FdParams


def grid_of(p: FdParams) -> BarGrid | TwoFieldGrid:
    """The grid operator of the bar ``p`` describes (spec 1.6; a two-field grid for a
    Timoshenko bar, spec 8.2)."""
    bar = dict(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3, length_m=p.length_m,
               thickness_m=p.thickness_m, width_m=p.width_m, bc=p.bc, points=p.points, profile=profile_of(p))
    if p.theory == "timoshenko":
        g, kappa = shear_of(p)
        return timoshenko_grid(shear_modulus_pa=g, shear_coefficient=kappa, **bar)
    return bar_grid(**bar)


def deflection(grid: BarGrid | TwoFieldGrid, vector: np.ndarray) -> np.ndarray:
    """The entries of ``vector`` (over the grid's unknowns) at its moving deflection nodes (a
    two-field grid's rotations left out)."""
    return grid.deflection(vector) if isinstance(grid, TwoFieldGrid) else vector


def deflection_mass(grid: BarGrid | TwoFieldGrid) -> np.ndarray:
    """The mass (kg) at each moving deflection node (a two-field grid's rotations left out)."""
    return deflection(grid, grid.mass)


def rigid_motions(grid: BarGrid | TwoFieldGrid) -> list[np.ndarray]:
    """The grid's rigid-body motions over all its unknowns (none unless free-free): translation
    and rotation about the centre of mass (with a two-field grid's rotations at 1)."""
    if rigid_mode_count(grid.bc) == 0:
        return []
    if isinstance(grid, TwoFieldGrid):
        return grid.rigid_motions()
    m = grid.mass
    return [np.ones_like(m), grid.x_m - np.sum(m * grid.x_m) / np.sum(m)]


def rigid_free(grid: BarGrid | TwoFieldGrid, vector: np.ndarray) -> np.ndarray:
    """``vector`` (a force or an interpolation vector) with the rigid-body parts taken out,
    ``v - M R R^T v`` for the M-orthonormal rigid motions R of a free-free bar (they are
    M-orthogonal: the rotation is about the centre of mass)."""
    rigid = rigid_motions(grid)
    if not rigid:
        return vector
    m = grid.mass
    out = vector.copy()
    for r in rigid:
        r = r / math.sqrt(np.sum(m * r * r))
        out -= m * r * np.dot(r, vector)
    return out


def point_vector(grid: BarGrid | TwoFieldGrid, position: float) -> np.ndarray:
    """The interpolation vector of ``position`` (fraction of the length), rigid motion left out:
    a unit force there, and the reading of a displacement there. Zero at a fixed node."""
    index, weight = grid.weights_at(position)
    vector = np.zeros(grid.mass.size)
    vector[index] = weight
    return rigid_free(grid, vector)


def largest_stable_theta(omega: float, oversampling: int, output_rate: float) -> float:
    """The largest stable theta for a grid whose highest mode is ``omega`` (rad/s), stepped
    ``oversampling`` times an output sample at ``output_rate`` Hz (inf when any theta is):
    0.5 + 2 / (Omega k)^2 (Bilbao 2009, ch. 7)."""
    courant = (omega / (output_rate * oversampling)) ** 2  # (Omega k)^2
    largest = 0.5 + 2.0 / courant if courant > 0 else math.inf
    return math.inf if largest >= 1.0 else largest


def stability_refusal(p: FdParams, omega: float, output_rate: float) -> str | None:
    """The refusal of ``p.theta`` above :func:`largest_stable_theta` for a grid whose highest
    mode is ``omega`` (rad/s); None where it is stable."""
    largest = largest_stable_theta(omega, p.oversampling, output_rate)
    if not p.theta > largest:
        return None
    steps = f" x {p.oversampling} steps a sample" if p.oversampling > 1 else ""
    return (f"parameter theta = {p.theta:g} makes the scheme unstable for {p.points} points at {output_rate:g} Hz"
            f"{steps} (the grid's highest mode is at {omega / (2 * math.pi):.0f} Hz); allowed: theta up to "
            f"{math.floor(largest * 1e4) / 1e4:.4f}, or fewer points")


def check_stability(p: FdParams, grid: BarGrid | TwoFieldGrid, output_rate: float) -> float:
    """The largest stable theta for this grid and step (inf when any is); refuses ``p.theta`` above it."""
    omega = highest_frequency(grid)
    refusal = stability_refusal(p, omega, output_rate)
    if refusal:
        raise ParameterError(refusal)
    return largest_stable_theta(omega, p.oversampling, output_rate)


def decimation_filter(factor: int, output_rate: float) -> np.ndarray:
    """The low-pass FIR (Kaiser window, -6 dB at 0.45 x the output rate, 90 dB down past about
    0.54 x, a span of 32 output samples, delay 16) that keeps the scheme's partials above the
    output Nyquist from folding; [1] without oversampling.

    SciPy's ``firwin(32 * factor + 1, 0.45 * output_rate, fs=output_rate * factor,
    window=("kaiser", 9.0))`` in NumPy, step by step (a symmetric window, the cutoff relative
    to the scheme's Nyquist, scaled so the DC gain is 1): importing scipy.signal took about
    0.9 s and 50 MiB. The taps are firwin's to the bit for factors 2, 4 (the default) and 7;
    for 3, 5, 6 and 8, ``np.i0`` (in ``np.kaiser``) and ``scipy.special.i0`` round a few window
    points differently in the last bit, so 2 to 8 taps differ by at most 7e-18 (of taps summing
    to 1): such a sound moves by rounding.
    """
    if factor == 1:
        return np.ones(1)
    count = 32 * factor + 1
    cutoff = 0.45 * output_rate / (0.5 * (output_rate * factor))  # of the scheme's Nyquist
    m = np.arange(0, count, dtype=np.float64) - 0.5 * (count - 1)
    taps = cutoff * np.sinc(cutoff * m)  # the ideal low-pass, centred
    taps *= np.kaiser(count, 9.0)
    return taps / np.sum(taps)


def history_size(taps: np.ndarray) -> int:
    """The decimation filter's ring of past inputs: a power of two above the taps' count."""
    return 1 << max(1, int(taps.size).bit_length())


# -- the step's matrices -------------------------------------------------------------------
def factor(diagonal: np.ndarray, first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``L D L^T`` of a symmetric pentadiagonal matrix: ``(l1, l2, 1 / d)``, where ``l1[i]``
    and ``l2[i]`` are ``L[i, i-1]`` and ``L[i, i-2]``."""
    n = diagonal.size
    l1, l2, d = np.zeros(n), np.zeros(n), np.zeros(n)
    for i in range(n):
        if i >= 2:
            l2[i] = second[i - 2] / d[i - 2]
        if i >= 1:
            l1[i] = (first[i - 1] - (l2[i] * d[i - 2] * l1[i - 1] if i >= 2 else 0.0)) / d[i - 1]
        d[i] = diagonal[i] - l1[i] ** 2 * (d[i - 1] if i >= 1 else 0.0) - l2[i] ** 2 * (d[i - 2] if i >= 2 else 0.0)
        if not d[i] > 0.0:
            raise ValueError("the step matrix is not positive definite")
    return l1, l2, 1.0 / d


def loss_reach(c: np.ndarray) -> int:
    """How far apart the unknowns are that the loss matrix ``c`` couples (1 or 2: the kernel
    takes one pair of its off-diagonal bands; a tridiagonal or diagonal one counts as 1)."""
    if np.any(np.diagonal(c, 1)):
        if np.any(np.diagonal(c, 2)):
            raise ValueError("the loss matrix couples neighbours one and two apart")
        return 1
    return 2 if np.any(np.diagonal(c, 2)) else 1


def stencils(b: np.ndarray, c: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The kernel's coefficient rows (:class:`.kernel.Scheme`) from the dense matrices ``B``,
    ``C / k`` and ``A``: ``bands`` and ``factors``, each row padded; ``C``'s off-diagonal pair is
    the one :func:`loss_reach` finds."""
    n = b.shape[0]
    reach = loss_reach(c)
    bands = np.zeros((8, n + 2 * K.PAD))
    for row, (matrix, offset) in enumerate(((b, 0), (b, -1), (b, 1), (b, -2), (b, 2),
                                            (c, 0), (c, -reach), (c, reach))):
        for i in range(n):
            j = i + offset
            if 0 <= j < n:
                bands[row, K.PAD + i] = matrix[i, j]
    l1, l2, inv_d = factor(np.diagonal(a).copy(), np.diagonal(a, 1).copy(), np.diagonal(a, 2).copy())
    return bands, np.array([K.padded(l1), K.padded(l2), K.padded(inv_d)]), reach


class Point(NamedTuple):
    """Where a force meets the bar: the point's vector, ``A^-1`` times it (both padded), and
    ``gain = vector . A^-1 vector``, the displacement there per newton of one step's force (m/N)."""

    at: np.ndarray
    response: np.ndarray
    gain: float


class Design(NamedTuple):
    """Everything the voice needs for ``p`` at an output rate, none of it state."""

    grid: BarGrid | TwoFieldGrid
    scheme: K.Scheme
    strike: Point
    bow: Point
    pickup: np.ndarray
    """The pick-up's vector (padded)."""
    taps: np.ndarray
    level: float
    """The output gain: ``level_db`` as a factor."""


def design(p: FdParams, output_rate: float) -> Design:
    """The scheme for ``p`` at ``output_rate`` Hz: checked for stability, factored, with its points.
    Raises :class:`ParameterError` for a scheme that would blow up or cannot be solved."""
    grid = grid_of(p)
    rate = output_rate * p.oversampling  # the scheme's own rate
    check_stability(p, grid, output_rate)
    k = 1.0 / rate
    m, stiff, lap = grid.mass, grid.stiffness, grid.damping_laplacian
    damping = 2.0 * p.sigma0_per_s * np.diag(m) + 2.0 * p.sigma1_m2_s * lap
    a = np.diag(m) / k ** 2 + 0.5 * (1.0 - p.theta) * stiff + damping / (2.0 * k)
    b = 2.0 * np.diag(m) / k ** 2 - p.theta * stiff
    c = damping / k
    try:
        bands, factors, reach = stencils(b, c, a)
    except ValueError:
        raise ParameterError("parameters give a step matrix that cannot be solved; allowed: a bar whose grid "
                             "is well conditioned (try fewer points)") from None

    def point(position: float) -> Point:
        at = point_vector(grid, position)
        response = K.solve(at, factors)
        return Point(K.padded(at), K.padded(response), float(np.dot(at, response)))

    return Design(grid, K.Scheme(bands, factors, rate, p.oversampling, reach), point(p.strike_position),
                  point(p.bow_position), K.padded(point_vector(grid, p.pickup_position)),
                  decimation_filter(p.oversampling, output_rate), 10.0 ** (p.level_db / 20.0))


# -- the pluck -----------------------------------------------------------------------------
def plucked_shape(hold: PluckHold, grid: BarGrid | TwoFieldGrid, position: float) -> np.ndarray:
    """The bar held out ``hold.displacement_m`` at ``position`` (fraction of the length) by a
    point force (rigid motion left out): the static deflection under the force
    :meth:`~barsynth.exciters.PluckHold.force_n` gives (the pluck's coupled form,
    :meth:`~barsynth.exciters.Pluck.coupling`), so near a clamped or pinned end no point is held
    out more than ``PLUCK_REACH`` times the displacement. A fixed point: no pluck (zeros)."""
    from scipy.linalg import eigh

    values, vectors = eigh(grid.stiffness, np.diag(grid.mass))
    elastic = slice(rigid_mode_count(grid.bc), None)
    values, vectors = values[elastic], vectors[:, elastic]
    force_at = point_vector(grid, position)  # (the point vector is also the unit force vector)
    shape = vectors @ ((vectors.T @ force_at) / values)  # the deflection under a unit force (m/N)
    largest = float(np.max(np.abs(deflection(grid, shape)))) if shape.size else 0.0  # (m: rotations left out)
    there = float(np.dot(force_at, shape))
    if there > np.finfo(float).tiny:
        return shape * hold.force_n(StaticPoint(there, largest))
    if not largest > 0.0:
        return shape * 0.0
    unit = shape / largest  # near a fixed node the deflection can be subnormal: scaled first
    return unit * hold.force_n(StaticPoint(float(np.dot(force_at, unit)), 1.0))


# -- what the scheme rings -----------------------------------------------------------------
def discrete_frequency(omega: np.ndarray, theta: float, sample_rate: float) -> np.ndarray:
    """The frequency (Hz) at which the theta scheme rings a grid mode of angular frequency ``omega``:
    ``sin^2(w k / 2) = (Omega k)^2 / (4 + 2 (1 - theta) (Omega k)^2)``."""
    ok = omega / sample_rate
    return 2.0 * sample_rate * np.arcsin(np.sqrt(ok ** 2 / (4.0 + 2.0 * (1.0 - theta) * ok ** 2))) / (2.0 * math.pi)


def discrete_t60(omega: np.ndarray, sigma: np.ndarray, theta: float, step_rate: float) -> np.ndarray:
    """The T60 (s) at which the scheme rings a grid mode (angular frequency ``omega``, decay rate
    ``sigma``): its two roots multiply to ``|z|^2 = c / a`` with ``a, c = 1/k^2 + (1 - theta)
    Omega^2 / 2 +- sigma / k``, so high modes decay more slowly than ``sigma`` says."""
    k = 1.0 / step_rate
    common = 1.0 / k ** 2 + 0.5 * (1.0 - theta) * omega ** 2
    per_step = -0.5 * np.log((common - sigma / k) / (common + sigma / k))
    return math.log(1000.0) / (per_step * step_rate)


class SchemeModes(NamedTuple):
    """The modes the scheme rings below the output's Nyquist (see :func:`scheme_modes`)."""

    frequency_hz: np.ndarray
    t60_s: np.ndarray
    shapes: np.ndarray
    """Mass-normalised shapes (unknowns x modes)."""
    grid: BarGrid | TwoFieldGrid


def scheme_modes(p: FdParams, sample_rate: float, count: int) -> SchemeModes:
    """The modes of the grid the model runs on, up to ``count`` and below the output's Nyquist:
    the frequencies the scheme rings them at (Hz), T60s (s) and shapes."""
    grid = grid_of(p)
    check_stability(p, grid, sample_rate)
    count = min(count, grid.mass.size - rigid_mode_count(grid.bc))
    omega, shapes = grid_eigen(grid, count)
    sigma = p.sigma0_per_s + p.sigma1_m2_s * np.einsum("in,ij,jn->n", shapes, grid.damping_laplacian, shapes)
    ringing = discrete_frequency(omega, p.theta, sample_rate * p.oversampling)
    heard = ringing < sample_rate / 2  # (with oversampling, the modes above the output's Nyquist are filtered out)
    return SchemeModes(ringing[heard],
                       discrete_t60(omega[heard], sigma[heard], p.theta, sample_rate * p.oversampling),
                       shapes[:, heard], grid)


def reference_errors_cents(p: FdParams, sample_rate: float, count: int) -> np.ndarray:
    """How far (cents) each mode the scheme rings lies from the converged bar's: spec 1.2's
    closed form for a uniform bar (spec 8.2's for a Timoshenko one), the Richardson-extrapolated
    operator for any other profile. Negative: the grid and the step ring it flat."""
    found = scheme_modes(p, sample_rate, count).frequency_hz
    if found.size == 0:
        return found
    bar = dict(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3, length_m=p.length_m,
               thickness_m=p.thickness_m, bc=p.bc)
    if p.theory == "timoshenko":  # spec 8.2's closed form, or the extrapolated two-field operator
        g, kappa = shear_of(p)
        shear = dict(shear_modulus_pa=g, shear_coefficient=kappa)
        if p.profile == "uniform":
            from ...physics.timoshenko import timoshenko_frequencies

            reference = timoshenko_frequencies(count=found.size, **shear, **bar)
        else:
            reference = timoshenko_grid_modes(count=found.size, width_m=p.width_m, profile=profile_of(p), **shear,
                                              **bar)
    elif p.profile == "uniform":
        from ...physics import bar_frequencies

        reference = bar_frequencies(count=found.size, **bar)
    else:
        reference = grid_modes(count=found.size, width_m=p.width_m, profile=profile_of(p), **bar)
    return 1200.0 * np.log2(found / reference)
