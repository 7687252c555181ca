"""The finite-difference bar: the accurate reference, uniform or undercut (spec 3.3, 1.6).

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the theta scheme,
losses ``sigma0``/``sigma1``, the bowed bar by Newton's method); A. Chaigne and
V. Doutaut, "Numerical simulations of xylophones. I.", JASA 101 (1997) (the
Hertzian mallet, non-uniform bars); G. Essl and P. R. Cook (ICMC 1999, JASA 2000) for
the bowed bar's behaviour the model must show.

The bar ``rho A(x) y_tt = -(E I(x) y_xx)_xx - 2 sigma0 rho A y_t + 2 sigma1 rho A y_txx + f``
lives on ``points`` grid nodes (:mod:`barsynth.physics.grid`), with any boundary
condition of spec 1.2 and any thickness profile (uniform, parabolic or circular
undercut, or sampled). Time steps are the implicit theta scheme of
:mod:`barsynth.dsp.fd_kernel`, one pentadiagonal solve per sample; at ``theta <= 0.5``
it is stable at any step, above 0.5 the step is checked against the grid's highest
frequency before anything runs, and a scheme that would blow up is refused with the
largest ``theta`` that would not.

Excitations: ``strike`` (a mallet, a mass on a Hertzian spring ``F = k d^2.5``,
coupled to the bar step by step), ``bow`` (the friction of :mod:`barsynth.dsp.friction`
at the bow point, solved with each step by Newton's method or, with
``bow_solver = explicit``, taken from the step before), ``pluck`` (the bar held out
``pluck_displacement_mm`` at the strike point and let go; near a clamped or pinned end, where
that would take a force without bound, no point is held out more than ``PLUCK_REACH`` times
that). A strike, bow or pluck at a fixed point does nothing. The output is the bar's
velocity at the pick-up (m/s) x ``level_db``; a free-free bar's rigid-body motion
(it would fly off when struck) is kept out of forces and output.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import kernel as K
from ...dsp.mallet import HERTZ_EXPONENT
from ...errors import ParameterError
from ...parameters import CHOICE, FLOATS, INT, Parameter, ParameterTable
from ...physics.boundary import BOUNDARY_CONDITIONS
from ...physics.profiles import PROFILE_KINDS, THINNEST, Profile
from ..base import Mode, resolve_parameters
from ..rendering import check_block_size, check_dtype, check_sample_rate
from ..shared import (BOWED, PLUCKED, STRUCK_OR_PLUCKED, PLUCK_DOC, PLUCK_REACH, BarModel, BowedBarVoice, bar_size_parameters, bow_parameters,
                     level_parameter, mallet_parameters, mallet_stiffness)

MAX_DESCRIBED = 24

UNDERCUT = {"profile": ("parabolic", "circular")}

FD_TABLE = ParameterTable(
    "fd",
    [
        *bar_size_parameters(),
        Parameter("bc", "", None, None, "free-free", "boundary conditions at the two ends (x = 0 first)",
                  kind=CHOICE, choices=BOUNDARY_CONDITIONS),
        Parameter("profile", "", None, None, "uniform",
                  "thickness along the bar: uniform, parabolic or circular (an undercut at the middle), or "
                  "samples (profile_samples)", kind=CHOICE, choices=PROFILE_KINDS),
        Parameter("undercut_depth", "", 0.0, 1.0 - THINNEST, 0.0,
                  "profile = parabolic or circular: depth of the undercut at the middle, fraction of the thickness",
                  when=UNDERCUT),
        Parameter("undercut_width", "", 0.05, 1.0, 0.6,
                  "profile = parabolic or circular: length of the undercut, fraction of the bar's length",
                  when=UNDERCUT),
        Parameter("profile_samples", "", THINNEST, 1.0, (),
                  "profile = samples: thickness / thickness_m at equally spaced points from end to end",
                  kind=FLOATS, max_items=64, when={"profile": ("samples",)}),
        Parameter("points", "", 8, 400, 100, "grid nodes along the bar: more are more accurate and slower",
                  kind=INT),
        Parameter("theta", "", 0.0, 1.0, 0.5,
                  "the scheme's implicitness: 0.5 or less is stable at any sample rate (0.5: no numerical "
                  "loss); above 0.5 only on coarse grids (checked)"),
        Parameter("oversampling", "", 1, 8, 4,
                  "scheme steps per output sample: each doubling cuts the step's flattening of high modes "
                  "fourfold (the output is low-passed and decimated)", kind=INT),
        Parameter("sigma0_per_s", "1/s", 0.01, 100.0, 1.0,
                  "loss at every frequency: T60 = 6.91 / sigma0 (modes near the step's limit decay slower: "
                  "see describe)",
                  scale="log"),
        Parameter("sigma1_m2_s", "m^2/s", 0.0, 0.1, 0.002,
                  "loss growing with frequency: adds sigma1 x wavenumber^2 to a mode's decay rate"),
        Parameter("excitation", "", None, None, "strike",
                  "what a trigger does: strike (a mallet), bow (a bow stroke) or pluck (a release)",
                  kind=CHOICE, choices=("strike", "bow", "pluck")),
        Parameter("bow_solver", "", None, None, "newton",
                  "the bow's friction: newton (solved with each step: stick and slip) or explicit (from the "
                  "step before: a forced oscillation)", kind=CHOICE, choices=("newton", "explicit"), when=BOWED),
        Parameter("strike_position", "", 0.0, 1.0, 0.7, "where it is struck or plucked: fraction of the length",
                  when=STRUCK_OR_PLUCKED),
        Parameter("pickup_position", "", 0.0, 1.0, 0.97, "where its velocity is picked up: fraction of the length"),
        *mallet_parameters(),
        Parameter("pluck_displacement_mm", "mm", 0.01, 20.0, 1.0, PLUCK_DOC, scale="log", when=PLUCKED),
        *bow_parameters(position=1.0),
        level_parameter(),
    ],
)


def _profile(p: Any) -> Profile:
    return Profile(p.profile, depth=p.undercut_depth, width=p.undercut_width, samples=tuple(p.profile_samples))


def _grid(p: Any):
    from ...physics.grid import bar_grid

    return bar_grid(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3, length_m=p.length_m,
                    thickness_m=p.thickness_m, width_m=p.width_m, bc=p.bc, points=p.points, profile=_profile(p))


def _rigid_free(grid: Any, vector: np.ndarray) -> np.ndarray:
    """``vector`` (a force or an interpolation vector) with the rigid-body parts taken out,
    ``v - M R R^T v`` for the M-orthonormal rigid motions R of a free-free bar."""
    from ...physics.grid import rigid_mode_count

    if rigid_mode_count(grid.bc) == 0:
        return vector
    m = grid.mass
    rigid = [np.ones_like(m), grid.x_m - np.sum(m * grid.x_m) / np.sum(m)]  # translation, rotation about the centre
    out = vector.copy()
    for r in rigid:
        r = r / math.sqrt(np.sum(m * r * r))
        out -= m * r * np.dot(r, vector)
    return out


def _point(grid: Any, position: float) -> np.ndarray:
    index, weight = grid.weights_at(position)
    vector = np.zeros(grid.mass.size)
    vector[index] = weight
    return _rigid_free(grid, vector)


def highest_grid_frequency(grid: Any) -> float:
    """The grid's highest angular frequency (rad/s): what the step must resolve."""
    from scipy.linalg import eig_banded

    from ...physics.grid import _upper_bands

    scale = 1.0 / np.sqrt(grid.mass)
    symmetric = grid.stiffness * scale[:, None] * scale[None, :]
    n = grid.mass.size
    top = eig_banded(_upper_bands(symmetric, 2), eigvals_only=True, select="i", select_range=(n - 1, n - 1))
    return math.sqrt(max(float(top[0]), 0.0))


def check_stability(p: Any, grid: Any, output_rate: float) -> float:
    """The largest stable theta for this grid and step (inf when any is); refuses ``p.theta`` above it."""
    omega = highest_grid_frequency(grid)
    courant = (omega / (output_rate * p.oversampling)) ** 2  # (Omega k)^2
    largest = 0.5 + 2.0 / courant if courant > 0 else math.inf
    if largest >= 1.0:
        return math.inf
    if p.theta > largest:
        steps = f" x {p.oversampling} steps a sample" if p.oversampling > 1 else ""
        raise ParameterError(f"parameter theta = {p.theta:g} makes the scheme unstable for {p.points} points at "
                             f"{output_rate:g} Hz{steps} (the grid's highest mode is at {omega / (2 * math.pi):.0f} Hz)"
                             f"; allowed: theta up to {math.floor(largest * 1e4) / 1e4:.4f}, or fewer points")
    return largest


def decimation_filter(factor: int, output_rate: float) -> np.ndarray:
    """The low-pass FIR (Kaiser window, -6 dB at 0.45 x the output rate, 90 dB down past about
    0.54 x, a span of 32 output samples, delay 16) that keeps the scheme's partials above the
    output Nyquist from folding; [1] without oversampling."""
    if factor == 1:
        return np.ones(1)
    from scipy.signal import firwin

    return firwin(32 * factor + 1, 0.45 * output_rate, fs=output_rate * factor, window=("kaiser", 9.0))


def discrete_frequency(omega: np.ndarray, theta: float, sample_rate: float) -> np.ndarray:
    """The frequency (Hz) at which the theta scheme rings a grid mode of angular frequency ``omega``:
    ``sin^2(w k / 2) = (Omega k)^2 / (4 + 2 (1 - theta) (Omega k)^2)``."""
    ok = omega / sample_rate
    return 2.0 * sample_rate * np.arcsin(np.sqrt(ok ** 2 / (4.0 + 2.0 * (1.0 - theta) * ok ** 2))) / (2.0 * math.pi)


class FdVoice(BowedBarVoice):
    """Streaming finite-difference bar: ``prepare`` / ``reset`` / ``trigger`` / ``release`` / ``process``.

    Examples
    --------
    >>> voice = FdVoice({"bc": "clamped-free", "points": 40}, sample_rate=44100)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, bool(abs(block).max() > 0)
    ((256,), True)
    """

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Set the sample rate (Hz), build and check the scheme, and reset. A refused rate changes nothing."""
        rate = check_sample_rate(sample_rate)
        design = self._design(self._params, rate)
        self.sample_rate = rate
        self._apply(design)
        self.reset()

    def _design(self, p: Any, output_rate: float) -> dict:
        grid = _grid(p)
        rate = output_rate * p.oversampling  # the scheme's own rate
        check_stability(p, grid, output_rate)
        k = 1.0 / rate
        m, stiff, lap = grid.mass, grid.stiffness, grid.damping_laplacian
        damping = 2.0 * p.sigma0_per_s * np.diag(m) + 2.0 * p.sigma1_m2_s * lap
        a = np.diag(m) / k ** 2 + 0.5 * (1.0 - p.theta) * stiff + damping / (2.0 * k)
        b = 2.0 * np.diag(m) / k ** 2 - p.theta * stiff
        c = damping / k
        try:
            bands, factors = K.stencils(b, c, a)
        except ValueError:
            raise ParameterError("parameters give a step matrix that cannot be solved; allowed: a bar whose grid "
                                 "is well conditioned (try fewer points)") from None
        contact_at = _point(grid, p.strike_position)
        contact_response = K.solve(contact_at, factors)
        bow_at = _point(grid, p.bow_position)
        bow_response = K.solve(bow_at, factors)
        constants = np.zeros(K.N_CONSTANTS)
        constants[K.K_MALLET_MASS] = p.mallet_mass_kg
        constants[K.K_MALLET_STIFFNESS] = mallet_stiffness(p)
        constants[K.K_MALLET_EXPONENT] = HERTZ_EXPONENT
        constants[K.K_SAMPLE_RATE] = rate
        constants[K.K_NEWTON] = 1.0 if p.bow_solver == "newton" else 0.0
        constants[K.K_BOW_GAIN] = 0.5 * rate * float(np.dot(bow_at, bow_response))
        constants[K.K_LEVEL] = 10.0 ** (p.level_db / 20.0)
        constants[K.K_SUBSTEPS] = p.oversampling
        constants[K.K_MALLET_GAIN] = float(np.dot(contact_at, contact_response))
        taps = decimation_filter(p.oversampling, output_rate)
        pad = K.padded
        return {"grid": grid, "bands": bands, "factors": factors,
                "contact": np.array([pad(contact_at), pad(contact_response)]),
                "bow": np.array([pad(bow_at), pad(bow_response)]),
                "pickup": pad(_point(grid, p.pickup_position))[None, :], "constants": constants, "taps": taps}

    def _apply(self, design: dict) -> None:
        self._grid = design["grid"]
        self._bands, self._factors = design["bands"], design["factors"]
        self._contact, self._bow_vectors, self._pickup = design["contact"], design["bow"], design["pickup"]
        self._constants, self._taps = design["constants"], design["taps"]

    def reset(self) -> None:
        """Silence: the bar at rest, no mallet, the bow lifted."""
        n = self._grid.mass.size + 2 * K.PAD  # node vectors are padded for the kernel
        self._u, self._u_prev = np.zeros(n), np.zeros(n)
        self._scalars = np.zeros(K.N_SCALARS)
        self._history = np.zeros(1 << max(1, int(self._taps.size).bit_length()))
        self._bow = self._new_bow()

    def set_parameters(self, **values: Any) -> None:
        """Change parameters (validated, the scheme checked); on the same grid what rings keeps ringing."""
        params = resolve_parameters(MODEL, {**FD_TABLE.as_dict(self._params), **values})
        design = self._design(params, self.sample_rate)
        old, self._params = self._params, params
        same_grid = design["grid"].mass.size + 2 * K.PAD == self._u.size
        self._apply(design)
        if not same_grid:
            bow = self._bow
            self.reset()
            self._bow = bow
        elif params.oversampling != old.oversampling:
            self._change_step(old.oversampling, params.oversampling)
        self._glide_bow(old, params)

    def _change_step(self, old_steps: int, new_steps: int) -> None:
        """Keep the bar's and the mallet's velocities through a change of step, and resample the
        decimation filter's past to the new step, so the output carries on. (Going to one step
        a sample, the output keeps what lies near Nyquist, unfiltered.)"""
        ratio = old_steps / new_steps  # k_new / k_old
        self._u_prev = self._u - (self._u - self._u_prev) * ratio
        z = self._scalars[K.X_MALLET]
        self._scalars[K.X_MALLET_PREV] = z - (z - self._scalars[K.X_MALLET_PREV]) * ratio
        old, written = self._history, int(self._scalars[K.X_HISTORY])
        if old_steps == 1:  # no past was kept: the last output stands for it
            past = np.full(2, self._scalars[K.X_LAST])
        else:
            past = old[(written - 1 - np.arange(old.size)) & (old.size - 1)]  # newest first, one old step apart
        size = 1 << max(1, int(self._taps.size).bit_length())
        ages = np.arange(size) * ratio  # the new steps' ages, in old steps (0 = the newest value)
        self._history = np.interp(ages, np.arange(past.size), past)[::-1].copy()
        self._scalars[K.X_HISTORY] = 0.0  # the next write goes at 0: the newest value sits at size - 1

    def trigger(self) -> None:
        """Strike, start a bow stroke, or pluck now, on top of whatever still rings."""
        p = self._params
        if p.excitation == "bow":
            self._start_stroke()
        elif p.excitation == "strike":  # the mallet arrives at the bar as it is now
            here = float(np.dot(self._contact[0], self._u))  # (pads are zero in both)
            self._scalars[K.X_MALLET] = here
            self._scalars[K.X_MALLET_PREV] = here - p.mallet_velocity_m_s / (self.sample_rate * p.oversampling)
            self._scalars[K.X_MALLET_ON] = 1.0
        else:
            shape = K.padded(self._static_shape())
            self._u += shape
            self._u_prev += shape

    def _static_shape(self) -> np.ndarray:
        """The bar held out ``pluck_displacement_mm`` at the strike point by a point force (rigid motion
        left out), or less where that would move some point more than ``PLUCK_REACH`` times as far
        (near a clamped or pinned end): then the largest deflection is that. A fixed point: no pluck."""
        from scipy.linalg import eigh

        from ...physics.grid import rigid_mode_count

        grid = self._grid
        values, vectors = eigh(grid.stiffness, np.diag(grid.mass))
        elastic = slice(rigid_mode_count(grid.bc), None)
        values, vectors = values[elastic], vectors[:, elastic]
        force_at = self._contact[0][K.PAD:-K.PAD]  # (the point vector is also the unit force vector)
        shape = vectors @ ((vectors.T @ force_at) / values)  # the deflection under a unit force
        there = float(np.dot(force_at, shape))
        largest = float(np.max(np.abs(shape))) if shape.size else 0.0
        displacement = self._params.pluck_displacement_mm * 1e-3
        if there >= largest / PLUCK_REACH and there > np.finfo(float).tiny:
            return shape * (displacement / there)
        if not largest > 0.0:
            return shape * 0.0
        unit = shape / largest  # (scaled first: near a fixed node the shape can be subnormal)
        return unit * (displacement / max(float(np.dot(force_at, unit)), 1.0 / PLUCK_REACH))

    def process(self, num_samples: int, *, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples: velocity at the pick-up (m/s) times the level."""
        dtype = check_dtype(dtype)
        n = check_block_size(num_samples)
        out = np.empty(n)
        K.process(out, self._u, self._u_prev, self._bands, self._factors, self._contact, self._bow_vectors,
                  self._pickup, self._bow.lines, self._bow.now, self._scalars, self._constants, self._taps,
                  self._history)
        self._bow.now += n
        return out.astype(dtype, copy=False)


def fd_modes(parameters: Any = None, *, sample_rate: float = 48000.0, count: int = MAX_DESCRIBED) -> dict:
    """The modes of the grid the model runs on, up to ``count`` and below the output's Nyquist:
    grid frequencies, the frequencies the scheme rings them at (Hz), T60s (s) and
    mass-normalised shapes (as a dict of arrays)."""
    from ...physics.grid import grid_eigen, rigid_mode_count

    p = resolve_parameters(MODEL, parameters)
    rate = check_sample_rate(sample_rate)
    grid = _grid(p)
    check_stability(p, grid, rate)
    count = min(count, grid.mass.size - rigid_mode_count(grid.bc))
    omega, shapes = grid_eigen(grid, count)
    sigma = p.sigma0_per_s + p.sigma1_m2_s * np.einsum("in,ij,jn->n", shapes, grid.damping_laplacian, shapes)
    ringing = discrete_frequency(omega, p.theta, rate * p.oversampling)
    heard = ringing < rate / 2  # (with oversampling, the modes above the output's Nyquist are filtered out)
    return {"grid_hz": omega[heard] / (2 * math.pi), "frequency_hz": ringing[heard],
            "t60_s": discrete_t60(omega[heard], sigma[heard], p.theta, rate * p.oversampling),
            "shapes": shapes[:, heard], "grid": grid}


def discrete_t60(omega: np.ndarray, sigma: np.ndarray, theta: float, step_rate: float) -> np.ndarray:
    """The T60 (s) at which the scheme rings a grid mode (angular frequency ``omega``, decay rate
    ``sigma``): its two roots multiply to ``|z|^2 = c / a`` with ``a, c = 1/k^2 + (1 - theta)
    Omega^2 / 2 +- sigma / k``, so high modes decay more slowly than ``sigma`` says."""
    k = 1.0 / step_rate
    common = 1.0 / k ** 2 + 0.5 * (1.0 - theta) * omega ** 2
    per_step = -0.5 * np.log((common - sigma / k) / (common + sigma / k))
    return math.log(1000.0) / (per_step * step_rate)


def mode_errors_cents(parameters: Any = None, *, sample_rate: float = 48000.0, count: int = 8) -> np.ndarray:
    """How far (cents) each mode the scheme rings lies from the converged bar's: spec 1.2's
    closed form for a uniform bar, the Richardson-extrapolated operator for any other
    profile. Negative: the grid and the step ring it flat."""
    from ...physics.grid import grid_modes

    p = resolve_parameters(MODEL, parameters)
    found = fd_modes(p, sample_rate=sample_rate, count=count)["frequency_hz"]
    if found.size == 0:
        return found
    bar = dict(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3, length_m=p.length_m,
               thickness_m=p.thickness_m, bc=p.bc)
    if p.profile == "uniform":
        from ...physics import bar_frequencies

        reference = bar_frequencies(count=found.size, **bar)
    else:
        reference = grid_modes(count=found.size, width_m=p.width_m, profile=_profile(p), **bar)
    return 1200.0 * np.log2(found / reference)


class FdModel(BarModel):
    """The finite-difference bar as a barsynth model (see the module docstring)."""

    reports_reference_errors = True
    name = "fd"
    summary = "finite-difference bar (implicit theta scheme): any boundary, undercut profiles; struck, bowed, plucked"
    table = FD_TABLE

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The modes the scheme rings (below Nyquist): frequency, gain (strike x pick-up shapes), T60."""
        p = resolve_parameters(self, parameters)
        found = fd_modes(p, sample_rate=sample_rate)
        grid = found["grid"]
        total = math.sqrt(float(np.sum(grid.mass)))
        strike, pickup = _point(grid, p.strike_position), _point(grid, p.pickup_position)
        modes = []
        for f, t60, shape in zip(found["frequency_hz"], found["t60_s"], found["shapes"].T):
            gain = float(np.dot(strike, shape) * np.dot(pickup, shape)) * total ** 2
            modes.append(Mode("mode", float(f), gain, float(t60)))
        return modes

    def errors_cents(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[float]:
        """Each described mode's error (cents) against the converged bar: see :func:`mode_errors_cents`."""
        return [float(e) for e in mode_errors_cents(parameters, sample_rate=sample_rate, count=MAX_DESCRIBED)]


MODEL = FdModel()
FdModel.voice_class = FdVoice
FdVoice.model = MODEL
