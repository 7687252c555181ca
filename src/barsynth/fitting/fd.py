"""Fitting the finite-difference bar to a recording: the physical bar whose modes match it.

A physics inversion (spec 7.2): the bar's material, length, thickness and undercut depth,
found by least squares on the log-frequencies of the recording's sustained partials, each
mode's residual reported in cents. Frequencies alone cannot tell the material, the length and
the thickness apart (a bar's modes scale with ``sqrt(E/rho) h / L^2``), so:

* the **material** is given, or chosen as the one whose typical Q (``barsynth materials``) is
  nearest, on a log scale, to the Q the recording's partials decay with (a metal rings for
  thousands of cycles, a wood for about a hundred): a guess the user can override;
* the **thickness** is given (or the model's default), and the **length** follows from the
  frequencies in closed form (a profile's modes scale exactly as ``1 / L^2``);
* the **undercut** (parabolic or circular, its depth, and its width where three or more
  partials tell it, as tuned bars are made) sets the ratios: searched first (bounded), with the
  modes of each profile from the very grid the model runs on (``points`` nodes, no
  extrapolation: :func:`barsynth.physics.grid.grid_modes`) as the theta scheme rings them at the
  recording's rate (``discrete_frequency``: a few cents flat up high), so the fitted bar plays
  the partials where they were, not where a converged bar would put them; a uniform bar (depth
  0) is kept unless an undercut brings the partials clearly closer;
* the **losses** ``sigma0`` and ``sigma1`` by non-negative least squares on the partials'
  decay rates, relative (each partial's T60 counts alike). A mode's decay rate is linear in the
  two, but its coefficients are the fitted bar's as the scheme plays it (an undercut bar's
  wavenumbers are not a uniform one's, and the step slows the decay of high modes): they are
  read off ``describe`` of the fitted bar at two probe settings.

Each measured partial is matched to the nearest mode the fitted bar plays (``barsynth describe
fd`` at the recording's rate gives the same frequencies; capped at 100 cents) and its residual
reported in cents; a partial no mode comes near (a torsional mode, a resonator's, a hum) is
reported unmatched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..physics import materials as all_materials
from .targets import Target, article, cents, strongest

__all__ = ["FdFit", "fit_fd"]

CAP_CENTS = 100.0
MODES = 10  # modes of the model the partials may be matched to
PROFILE_KINDS = ("parabolic", "circular")
SETTLED_CENTS = 0.5  # a uniform bar this close (rms, cents) is not undercut
IMPROVEMENT_CENTS = 1.0  # an undercut must bring the rms this much closer
DEPTH_GRID = np.linspace(0.0, 0.9, 19)
LN1000 = math.log(1000.0)


@dataclass(frozen=True)
class ModeMatch:
    """A measured partial, the bar's mode it was matched to (1-based) and that mode's frequency."""

    target: Target
    number: int
    model_hz: float

    @property
    def cents(self) -> float:
        """The model's mode against the partial (cents; positive: the model is sharp)."""
        return float(cents(self.model_hz, self.target.frequency_hz))


@dataclass(frozen=True)
class FdFit:
    """The fitted bar: parameters (the fd table's names) and each partial's match."""

    parameters: dict[str, Any]
    matches: tuple[ModeMatch, ...]
    unmatched: tuple[Target, ...] = field(default=())
    material_chosen_by_q: bool = False


def _q_of(targets: list[Target]) -> float | None:
    qs = [math.pi * t.frequency_hz * t.t60_s / LN1000 for t in targets
          if t.t60_s is not None and math.isfinite(t.t60_s) and t.t60_s > 0]
    return float(np.median(qs)) if qs else None


def _choose_material(q: float | None) -> str:
    known = {name: m.typical_q for name, m in all_materials().items() if m.typical_q}
    if q is None:
        return "aluminium"
    return min(known, key=lambda name: abs(math.log(known[name] / q)))


@lru_cache(maxsize=1024)
def _shape_ratios(bc: str, depth: float, width: float, kind: str = "parabolic",
                  points: int = 100) -> tuple[float, ...]:
    """The first MODES frequencies (Hz) of a reference bar on a grid of ``points`` nodes (only the
    ratios and the scale law matter: a grid's modes scale exactly as ``sqrt(E/rho) h / L^2``), for
    an undercut ``depth`` (fraction of the thickness) over ``width`` of the length."""
    from ..physics.grid import grid_modes, rigid_mode_count
    from ..physics.profiles import Profile

    profile = None if depth <= 0.0 else Profile(kind, depth=depth, width=width)
    count = min(MODES, points - rigid_mode_count(bc))
    f = grid_modes(youngs_modulus_pa=1e10, density_kg_m3=1000.0, length_m=1.0, thickness_m=0.01, bc=bc,
                   count=count, profile=profile, points=points, extrapolate=False)
    return tuple(float(v) for v in f)


def _reference_scale() -> float:
    """``sqrt(E/rho) h / L^2`` of the reference bar of :func:`_shape_ratios`."""
    return math.sqrt(1e10 / 1000.0) * 0.01 / 1.0 ** 2


def _match(targets: list[Target], modes_hz: np.ndarray) -> tuple[list[ModeMatch], list[Target]]:
    matches, unmatched, used = [], [], set()
    for t in sorted(targets, key=lambda t: -t.level_db):  # the strongest choose first
        distance = np.abs(cents(t.frequency_hz, modes_hz))
        for k in used:
            distance[k] = np.inf
        k = int(np.argmin(distance))
        if distance[k] <= CAP_CENTS:
            matches.append(ModeMatch(t, k + 1, float(modes_hz[k])))
            used.add(k)
        else:
            unmatched.append(t)
    return sorted(matches, key=lambda m: m.number), unmatched


def _scale_for(targets: list[Target], ratios: np.ndarray, played: Any = None) -> tuple[float, float]:
    """The frequency scale (Hz of the reference bar's mode list x scale) that best fits the
    partials to the modes ``ratios`` (each partial to its nearest mode), and the level-weighted
    mean squared cents. ``played`` maps a grid's frequencies (Hz) to those the scheme rings
    (default: as they are). The lowest partial is the bar's first mode (the fit is given the
    note's partials from its fundamental up): else two partials fit any undercut deep enough."""
    freqs = np.array([t.frequency_hz for t in targets])
    weights = 10.0 ** ((np.array([t.level_db for t in targets]) - max(t.level_db for t in targets)) / 40.0)
    ring = played if played is not None else (lambda f: f)
    scale = freqs.min() / ratios[0]
    score = CAP_CENTS ** 2
    for _ in range(3):  # the scheme's warp is smooth and small: a few fixed-point steps settle it
        distance = cents(freqs[:, None], ring(scale * ratios)[None, :])
        nearest = np.abs(distance).argmin(axis=1)
        close = np.abs(distance[np.arange(freqs.size), nearest]) <= CAP_CENTS
        if not close.any():
            break
        # the weighted mean of log-frequency offsets of the matched partials
        offset = np.average(distance[np.arange(freqs.size), nearest][close], weights=weights[close])
        scale *= 2.0 ** (offset / 1200.0)
        d = np.abs(cents(freqs[:, None], ring(scale * ratios)[None, :])).min(axis=1)
        score = float((weights * np.minimum(d, CAP_CENTS) ** 2).sum() / weights.sum())
    return scale, score


PROBE_SIGMA0, PROBE_SIGMA1 = 1.0, 0.01  # the two loss settings describe is asked at


def _losses(matches: list[ModeMatch], parameters: dict[str, Any], sample_rate: float) -> tuple[float, float]:
    """``(sigma0, sigma1)`` (1/s, m^2/s) from the matched partials' decay rates by non-negative
    least squares on relative errors. Each mode's rate is ``sigma0 c0 + sigma1 c1``; ``c0`` and
    ``c1`` come from ``describe`` of the fitted bar with ``(PROBE_SIGMA0, 0)`` and with
    ``(0.01, PROBE_SIGMA1)`` (the table's least ``sigma0``), at the recording's rate."""
    from scipy.optimize import nnls

    from ..models.fd.model import MODEL

    def rates(sigma0: float, sigma1: float) -> np.ndarray:
        modes = MODEL.describe({**parameters, "sigma0_per_s": sigma0, "sigma1_m2_s": sigma1}, sample_rate=sample_rate)
        return np.array([LN1000 / m.t60_s if m.t60_s else 0.0 for m in modes])

    timed = [m for m in matches if m.target.t60_s is not None and math.isfinite(m.target.t60_s) and m.target.t60_s > 0]
    if not timed:
        return 1.0, 0.002  # the model's defaults
    first, second = rates(PROBE_SIGMA0, 0.0), rates(0.01, PROBE_SIGMA1)
    c0 = first / PROBE_SIGMA0
    c1 = (second - 0.01 * c0) / PROBE_SIGMA1
    wanted = np.array([LN1000 / m.target.t60_s for m in timed])
    index = [m.number - 1 for m in timed]
    columns = np.stack([c0[index], c1[index]], axis=1) / wanted[:, None]
    solution, _ = nnls(columns, np.ones(len(timed)))
    return float(solution[0]), float(solution[1])


def fit_fd(targets: list[Target], *, sample_rate: float = 48000.0, material: str | None = None,
           thickness_m: float | None = None, width_m: float | None = None, bc: str = "free-free",
           points: int | None = None, undercut_width: float = 0.6, fit_undercut: bool = True) -> FdFit:
    """The bar whose modes, as the model plays them at ``sample_rate`` Hz on a grid of ``points``
    nodes (default: the model's), best match ``targets`` (see the module docstring)."""
    from scipy.optimize import minimize, minimize_scalar

    from ..models.fd.design import discrete_frequency
    from ..models.fd.model import MODEL
    from ..models.fd.table import FD_TABLE
    from ..physics import material as find_material

    kept = strongest(targets, within_db=40.0, at_most=MODES)
    if not kept:
        raise ParameterError("the recording has no sustained partial to fit a bar to; allowed: a recording with at "
                             "least one partial above 20 Hz")
    row = {p.name: p for p in FD_TABLE}
    chosen = material is None
    name = _choose_material(_q_of(kept)) if chosen else material
    mat = find_material(name)
    h = thickness_m if thickness_m is not None else row["thickness_m"].default
    width = width_m if width_m is not None else row["width_m"].default
    nodes = int(points) if points is not None else int(row["points"].default)
    theta, steps = float(row["theta"].default), float(row["oversampling"].default) * float(sample_rate)

    def played(f_hz: np.ndarray) -> np.ndarray:
        return discrete_frequency(2.0 * math.pi * np.asarray(f_hz), theta, steps)

    def cost(depth: float, cut_width: float = undercut_width, kind: str = "parabolic") -> float:
        ratios = np.array(_shape_ratios(bc, round(depth, 4), round(cut_width, 4), kind, nodes))
        return _scale_for(kept, ratios, played)[1]

    depth, cut_width, kind = 0.0, undercut_width, "parabolic"
    plain = cost(0.0)
    if fit_undercut and bc == "free-free" and len(kept) >= 2 and plain > SETTLED_CENTS ** 2:
        best = (plain, 0.0, undercut_width, "parabolic")
        for shape in PROFILE_KINDS:
            # a coarse look over the depths first (the cost has several valleys), then the best refined
            coarse = min((cost(d, undercut_width, shape), d) for d in DEPTH_GRID)
            low, high = max(0.0, coarse[1] - 0.05), min(0.9, coarse[1] + 0.05)
            found = minimize_scalar(lambda d: cost(d, undercut_width, shape), bounds=(low, high), method="bounded",
                                    options={"xatol": 1e-4})
            candidate = (float(found.fun), round(float(found.x), 4), undercut_width, shape)
            if len(kept) >= 3:  # the width too, where three or more partials tell it
                found = minimize(lambda x: cost(x[0], x[1], shape), [candidate[1], undercut_width],
                                 method="Nelder-Mead", bounds=[(0.0, 0.9), (0.2, 1.0)],
                                 options={"xatol": 1e-4, "fatol": 1e-4, "maxfev": 200})
                if found.fun < candidate[0]:
                    candidate = (float(found.fun), round(float(found.x[0]), 4), round(float(found.x[1]), 4), shape)
            best = min(best, candidate, key=lambda c: c[0])
        if best[0] < plain - IMPROVEMENT_CENTS ** 2:  # only an undercut that clearly explains more
            _, depth, cut_width, kind = best
    ratios = np.array(_shape_ratios(bc, depth, cut_width, kind, nodes))
    scale, _ = _scale_for(kept, ratios, played)
    # modes of the reference bar are `ratios` (Hz); ours are `scale` times them: frequencies go as
    # sqrt(E/rho) h / L^2, so L = sqrt(reference scale law x ... ) in closed form
    length = math.sqrt(math.sqrt(mat.youngs_modulus_pa / mat.density_kg_m3) * h / (_reference_scale() * scale))
    for label, value in (("length_m", length), ("thickness_m", h)):
        p = row[label]
        if not p.minimum <= value <= p.maximum:
            raise ParameterError(
                f"{article(name)} {name} bar {h * 1000:.3g} mm thick would need {label} = {value:.4g} {p.unit} to "
                f"ring as recorded, out of range; allowed: {p.minimum:g} to {p.maximum:g} {p.unit} (give another material or thickness)")
    parameters: dict[str, Any] = {"material": name, "length_m": length, "thickness_m": h, "width_m": width, "bc": bc,
                                  "points": nodes}
    if depth > 0.0:
        parameters.update(profile=kind, undercut_depth=depth, undercut_width=cut_width)
    # the residuals are those of the modes the fitted bar plays (what `barsynth describe fd` says)
    modes_hz = np.array([m.frequency_hz for m in MODEL.describe(parameters, sample_rate=sample_rate)])
    matches, unmatched = _match(kept, modes_hz)
    sigma0, sigma1 = _losses(matches, parameters, sample_rate)
    parameters["sigma0_per_s"] = float(min(max(sigma0, row["sigma0_per_s"].minimum), row["sigma0_per_s"].maximum))
    parameters["sigma1_m2_s"] = float(min(max(sigma1, row["sigma1_m2_s"].minimum), row["sigma1_m2_s"].maximum))
    return FdFit(parameters, tuple(matches), tuple(unmatched), chosen)
