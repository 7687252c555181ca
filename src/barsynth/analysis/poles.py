"""Sums of damped complex exponentials fitted to a complex envelope.

``z(t) ~ sum_k a_k exp(s_k (t - t_ref))`` with complex rates ``s_k = -sigma_k + 2j pi
f_k`` (1/s; ``sigma_k`` is the decay rate of the amplitude, ``f_k`` the frequency offset
in Hz).

- :func:`matrix_pencil` gives the rates from the signal subspace of the data's Hankel
  matrix (Hua & Sarkar 1990, the matrix pencil; ESPRIT's rotational invariance, Roy &
  Kailath 1989, on the same subspace). Fast, no starting point needed.
- :func:`fit_poles` refines them by Gauss-Newton on the complex least-squares misfit
  (the maximum-likelihood fit in white noise). The model is holomorphic in ``log a_k``
  and ``s_k``, so a complex least-squares step is the exact Gauss-Newton step.

References: Y. Hua and T. K. Sarkar, "Matrix pencil method for estimating parameters of
exponentially damped/undamped sinusoids in noise", IEEE Trans. ASSP 38 (1990); R. Roy
and T. Kailath, "ESPRIT -- estimation of signal parameters via rotational invariance
techniques", IEEE Trans. ASSP 37 (1989).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PoleFit", "amplitudes", "fit_poles", "matrix_pencil", "zoomed_pencil"]

_MAX_PENCIL_COLUMNS = 48
_MAX_EXPONENT = 300.0  # e^300: beyond, a fitted exponential is not a measurement
_GN_STEPS = 8
_SETTLED = 1e-8  # a Gauss-Newton step that lowers the misfit by less than this share ends it


@dataclass(frozen=True)
class PoleFit:
    """A fit of ``z(t) ~ sum_k amps[k] exp(rates[k] (t - t_ref))``.

    Attributes
    ----------
    rates
        Complex rates ``-sigma + 2j pi f``, 1/s.
    amps
        Complex amplitudes at ``t_ref``.
    t_ref
        Reference time, s.
    misfit
        ``sum |z - model|^2`` over the samples fitted.
    energy
        ``sum |z|^2`` over the same samples.
    """

    rates: np.ndarray
    amps: np.ndarray
    t_ref: float
    misfit: float
    energy: float

    @property
    def coherence(self) -> float:
        """Share of the envelope's energy the model explains (0 to 1)."""
        if self.energy <= 0:
            return 0.0
        return max(0.0, 1.0 - self.misfit / self.energy)

    def model(self, t: np.ndarray) -> np.ndarray:
        """The fitted envelope at times ``t`` (s)."""
        return np.exp(np.outer(t - self.t_ref, self.rates)) @ self.amps


def matrix_pencil(z: np.ndarray, dt: float, order: int) -> np.ndarray:
    """Complex rates (1/s) of the ``order`` strongest damped exponentials in ``z``.

    ``z`` is sampled every ``dt`` seconds. The right singular vectors of the Hankel
    matrix come from its (small) Gram matrix; the pencil of the signal subspace and its
    shift gives the poles (Hua & Sarkar 1990).
    """
    n = z.size
    columns = int(min(_MAX_PENCIL_COLUMNS, max(order + 1, n // 3)))
    rows = n - columns
    if rows < order or columns < order + 1:
        return np.zeros(0, dtype=np.complex128)
    idx = np.arange(rows)[:, None] + np.arange(columns + 1)[None, :]
    hankel = z[idx]
    if not np.all(np.isfinite(hankel)):
        return np.zeros(0, dtype=np.complex128)
    gram = hankel.conj().T @ hankel
    try:
        _, vectors = np.linalg.eigh(gram)
    except np.linalg.LinAlgError:
        return np.zeros(0, dtype=np.complex128)
    v = vectors[:, ::-1][:, :order]  # the signal subspace: the largest eigenvalues
    v1, v2 = v[:-1], v[1:]
    try:
        poles = np.linalg.eigvals(np.linalg.lstsq(v1, v2, rcond=None)[0])
    except np.linalg.LinAlgError:
        return np.zeros(0, dtype=np.complex128)
    poles = poles[np.isfinite(poles) & (np.abs(poles) > 0)]
    return np.log(poles.astype(np.complex128)) / dt


def zoomed_pencil(z: np.ndarray, dt: float, order: int, centre_rate: complex) -> np.ndarray:
    """:func:`matrix_pencil` on ``z`` shifted by ``centre_rate``'s frequency, averaged and
    decimated so that the pencil's window spans about a third of the data: close poles
    (a slow beat) that a short window cannot tell apart. Rates in 1/s, unshifted."""
    stride = max(1, z.size // (3 * (_MAX_PENCIL_COLUMNS + 1)))
    if stride == 1:
        return matrix_pencil(z, dt, order)
    omega = complex(centre_rate).imag
    t = np.arange(z.size) * dt
    shifted = z * np.exp(-1j * omega * t)
    count = z.size // stride
    averaged = shifted[: count * stride].reshape(count, stride).mean(axis=1)
    rates = matrix_pencil(averaged, dt * stride, order)
    return rates + 1j * omega


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``argmin |a x - b|`` for a few columns, by the normal equations with the columns
    scaled to unit norm (a Gram matrix near 1 on its diagonal). None when it fails."""
    norms = np.sqrt((a.real * a.real + a.imag * a.imag).sum(axis=0))
    if not (np.isfinite(norms.sum()) and norms.min() > 0):
        return None
    scaled = a / norms
    herm = scaled.conj().T
    try:
        x = np.linalg.solve(herm @ scaled, herm @ b) / norms
    except np.linalg.LinAlgError:
        return None
    return x if np.isfinite(x.sum()) else None


def amplitudes(t: np.ndarray, z: np.ndarray, rates: np.ndarray, t_ref: float) -> tuple[np.ndarray, float]:
    """Least-squares complex amplitudes (at ``t_ref``) for given rates, and the misfit.

    Rates that would overflow over the samples give zero amplitudes and an infinite misfit.
    """
    exponent = np.outer(t - t_ref, rates)
    if exponent.size and not float(np.max(exponent.real)) < _MAX_EXPONENT:
        return np.zeros(rates.size, dtype=np.complex128), math.inf
    basis = np.exp(exponent)
    amps = _least_squares(basis, z)
    if amps is None:
        return np.zeros(rates.size, dtype=np.complex128), math.inf
    r = z - basis @ amps
    return amps, float(np.vdot(r, r).real)


def fit_poles(t: np.ndarray, z: np.ndarray, rates: np.ndarray, t_ref: float | None = None) -> PoleFit:
    """Gauss-Newton refinement of damped exponentials with starting ``rates`` (1/s).

    Steps that do not lower the misfit are halved (up to 8 steps in all). Returns the
    best fit found.
    """
    t_ref = float(t[0]) if t_ref is None else float(t_ref)
    rates = np.asarray(rates, dtype=np.complex128)
    energy = float(np.vdot(z, z).real)
    amps, misfit = amplitudes(t, z, rates, t_ref)
    tau = t - t_ref
    k = rates.size
    for _ in range(_GN_STEPS):
        if k == 0:
            break
        if not math.isfinite(misfit):
            break
        e = np.exp(np.outer(tau, rates))
        model = e * amps
        jac = np.concatenate((model, model * tau[:, None]), axis=1)
        step = _least_squares(jac, z - model.sum(axis=1))
        if step is None:
            break
        ds = step[k:]
        improved = False
        for scale in (1.0, 0.5, 0.25):
            trial = rates + scale * ds
            trial_amps, trial_misfit = amplitudes(t, z, trial, t_ref)
            if trial_misfit < misfit:
                improved = misfit - trial_misfit > _SETTLED * misfit
                rates, amps, misfit = trial, trial_amps, trial_misfit
                break
        if not improved:
            break
    return PoleFit(rates=rates, amps=amps, t_ref=t_ref, misfit=misfit, energy=energy)
