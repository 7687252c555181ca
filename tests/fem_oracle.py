"""An independent finite-element oracle for bar frequencies (scikit-fem), for the tests only.

Euler–Bernoulli: cubic Hermite elements (``ElementLineHermite``), ``K = ∫ E I w'' v''``,
``M = ∫ ρ A w v``; Richardson extrapolation over two meshes removes the ``dx⁴`` error term.
Timoshenko: ``w`` of degree p + 1 and ``θ`` of degree p (``ElementLinePp``), so the shear strain
``w' − θ`` of the discrete space can vanish exactly and the element does not lock;
``K = ∫ E I θ' φ' + κ G A (w' − θ)(v' − φ)``, ``M = ∫ ρ A w v + ρ I θ φ``. Thickness ``h(x)`` from a
:class:`~barsynth.physics.profiles.Profile`; mesh nodes at the undercut's edges (where a parabolic
cut has a kink), so the error falls at the full rate. Essential ends: clamped ``w = 0`` and
``w' = 0`` (``θ = 0``), pinned ``w = 0``; free ends and the moments are natural. The generalised
eigenproblem is solved densely as the largest ``μ`` of ``M v = μ (K + s M) v`` (``s`` far below the
first mode), which keeps the digits of the lowest modes and lifts the free bar's rigid motions.
"""

from __future__ import annotations

import math
from functools import cache
from itertools import pairwise

import numpy as np
from scipy.sparse import diags
from scipy.sparse.linalg import eigsh
from skfem import Basis, BilinearForm, ElementLineHermite, ElementLinePp, MeshLine, asm

from barsynth.physics.profiles import Profile

RIGID = {"free-free": 2}
UNIFORM = Profile()


def _nodes(profile: Profile, elements: int) -> np.ndarray:
    """Mesh nodes on [0, 1]: about ``elements`` equal cells, with nodes at the undercut's edges."""
    breaks = [0.0, 1.0]
    if profile.kind in ("parabolic", "circular") and profile.width < 1.0:
        breaks += [0.5 - 0.5 * profile.width, 0.5 + 0.5 * profile.width]
    breaks = np.unique(breaks)
    parts = []
    for a, b in pairwise(breaks):
        cells = max(2, round(elements * (b - a)))
        parts.append(np.linspace(a, b, cells + 1)[:-1])
    return np.append(np.concatenate(parts), 1.0)


def _fixed(basis: Basis, bc: str, length_m: float, names: dict[str, tuple[str, ...]]) -> np.ndarray:
    """Indices of the essential degrees of freedom of both ends."""
    left, right = bc.split("-")
    out = []
    for end, where in ((left, 0.0), (right, length_m)):
        dofs = basis.get_dofs(lambda x, where=where: np.isclose(x[0], where)).nodal
        out += [dofs[name] for name in names[end]]
    return np.concatenate(out) if out else np.array([], dtype=int)


def _solve(stiffness, mass, fixed: np.ndarray, count: int, skip: int, shift: float) -> np.ndarray:
    """Angular frequencies of the lowest ``count`` modes (the first ``skip``, rigid, left out): the
    eigenvalues of ``K v = w² M v`` nearest ``−shift`` by shift-invert Lanczos (sparse LU of ``K + shift
    M``, ARPACK to machine precision)."""
    keep = np.setdiff1d(np.arange(stiffness.shape[0]), fixed)
    k = stiffness.tocsr()[keep][:, keep].tocsc()
    m = mass.tocsr()[keep][:, keep].tocsc()
    scale = diags(1.0 / np.sqrt(m.diagonal()))  # degrees of freedom of one size (metres and slopes)
    k, m = (scale @ k @ scale).tocsc(), (scale @ m @ scale).tocsc()
    omega2 = eigsh(k, k=count + skip, M=m, sigma=-shift, which="LM", tol=0.0, return_eigenvectors=False)
    return np.sqrt(np.maximum(np.sort(omega2)[skip:], 0.0))


@cache
def euler_bernoulli_fem(*, youngs_modulus_pa: float, density_kg_m3: float, length_m: float, thickness_m: float,
                        bc: str, count: int, profile: Profile = UNIFORM, elements: int = 64,
                        extrapolate: bool = True) -> np.ndarray:
    """Mode frequencies (Hz) of an Euler–Bernoulli bar of thickness ``thickness_m × profile(x)``."""
    if extrapolate:
        args = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, length_m=length_m,
                    thickness_m=thickness_m, bc=bc, count=count, profile=profile)
        coarse = euler_bernoulli_fem(elements=elements, extrapolate=False, **args)
        fine = euler_bernoulli_fem(elements=2 * elements, extrapolate=False, **args)
        return (16.0 * fine - coarse) / 15.0
    mesh = MeshLine(_nodes(profile, elements) * length_m)
    basis = Basis(mesh, ElementLineHermite(), intorder=12)

    def height(x):
        return thickness_m * profile.relative_thickness(x / length_m, length_m=length_m, thickness_m=thickness_m)

    @BilinearForm
    def stiffness(u, v, w):
        return youngs_modulus_pa * height(w.x[0]) ** 3 / 12.0 * u.hess[0][0] * v.hess[0][0]

    @BilinearForm
    def mass(u, v, w):
        return density_kg_m3 * height(w.x[0]) * u * v

    fixed = _fixed(basis, bc, length_m, {"clamped": ("u", "u_x"), "pinned": ("u",), "free": ()})
    shift = youngs_modulus_pa * thickness_m**2 / (12.0 * density_kg_m3 * length_m**4)
    omega = _solve(asm(stiffness, basis), asm(mass, basis), fixed, count, RIGID.get(bc, 0), shift)
    return omega / (2.0 * math.pi)


@cache
def timoshenko_fem(*, youngs_modulus_pa: float, density_kg_m3: float, shear_modulus_pa: float,
                   shear_coefficient: float, length_m: float, thickness_m: float, bc: str, count: int,
                   profile: Profile = UNIFORM, elements: int = 48, degree: int = 4) -> np.ndarray:
    """Mode frequencies (Hz) of a Timoshenko bar of thickness ``thickness_m × profile(x)``: ``w`` of
    degree ``degree + 1``, ``θ`` of degree ``degree`` on about ``elements`` cells."""
    mesh = MeshLine(_nodes(profile, elements) * length_m)
    basis = Basis(mesh, ElementLinePp(degree + 1) * ElementLinePp(degree), intorder=2 * degree + 8)
    e, rho, kga = youngs_modulus_pa, density_kg_m3, shear_coefficient * shear_modulus_pa

    def height(x):
        return thickness_m * profile.relative_thickness(x / length_m, length_m=length_m, thickness_m=thickness_m)

    @BilinearForm
    def stiffness(u, theta, v, phi, w):
        h = height(w.x[0])
        bend = e * h**3 / 12.0 * theta.grad[0] * phi.grad[0]
        shear = kga * h * (u.grad[0] - theta) * (v.grad[0] - phi)
        return bend + shear

    @BilinearForm
    def mass(u, theta, v, phi, w):
        h = height(w.x[0])
        return rho * h * u * v + rho * h**3 / 12.0 * theta * phi

    fixed = _fixed(basis, bc, length_m, {"clamped": ("u^1", "u^2"), "pinned": ("u^1",), "free": ()})
    shift = e * thickness_m**2 / (12.0 * rho * length_m**4)
    omega = _solve(asm(stiffness, basis), asm(mass, basis), fixed, count, RIGID.get(bc, 0), shift)
    return omega / (2.0 * math.pi)
