"""Where a bowed object sustains: the bow-velocity x bow-force map (spec 3.1, 3.4).

Source: G. Essl and P. R. Cook, "Measurements and efficient simulations of bowed
bars", JASA 108 (2000): a bowed bar sustains only inside a region of bow velocity
and bow force, whose least and greatest velocity both rise with the force, with a
steady amplitude that follows the velocity. The same measurement as on a real
bar: bow at each setting long enough to settle, then read the velocity of the
bar at the bow point.

Works with any barsynth model that takes the :class:`~barsynth.exciters.Bow` (its
``exciters``; the bow's rows come with it) and has a ``pickup_position``, as every bar
model does (the pick-up is moved to the bow so the output is the bar's velocity there).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..checks import check_number, show_value
from ..errors import ParameterError

STEADY_WINDOW_S = 0.25
"""The steady amplitude is the RMS velocity over the last window of this length (s)."""
SHORTEST_S = 1.0
"""The shortest bowing a map accepts (s): two windows after the bow's attack (up to 0.5 s)."""
SUSTAIN_FRACTION = 0.05
"""A setting sustains when the steady RMS velocity is at least this fraction of the bow velocity ..."""
STEADY_TOLERANCE = 0.1
"""... and it differs from the window before by less than this fraction (it has settled)."""


@dataclass(frozen=True)
class BowMap:
    """Steady bow-point velocity (RMS, m/s) over a grid of bow velocities and forces.

    ``amplitude_m_s`` and ``sustained`` have shape ``(len(forces_n), len(velocities_m_s))``.
    """

    model: str
    velocities_m_s: np.ndarray
    forces_n: np.ndarray
    amplitude_m_s: np.ndarray
    sustained: np.ndarray

    def velocity_limits(self) -> list[tuple[float, float, float]]:
        """``(force_n, least_velocity_m_s, greatest_velocity_m_s)`` for each force that sustains anywhere."""
        limits = []
        for force, row in zip(self.forces_n, self.sustained):
            if row.any():
                inside = self.velocities_m_s[row]
                limits.append((float(force), float(inside.min()), float(inside.max())))
        return limits

    def to_json(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "velocities_m_s": self.velocities_m_s.tolist(),
            "forces_n": self.forces_n.tolist(),
            "amplitude_m_s": self.amplitude_m_s.tolist(),
            "sustained": self.sustained.tolist(),
            "velocity_limits": [{"force_n": f, "least_velocity_m_s": lo, "greatest_velocity_m_s": hi}
                                for f, lo, hi in self.velocity_limits()],
        }


def steady_amplitude(velocity: np.ndarray, sample_rate: float) -> tuple[float, float]:
    """RMS of the last ``STEADY_WINDOW_S`` of a signal and of the window before it."""
    n = int(round(STEADY_WINDOW_S * sample_rate))
    if velocity.size < 2 * n:
        raise ParameterError(f"parameter duration_s = {velocity.size / sample_rate:g} is too short to measure a "
                             f"steady amplitude; allowed: at least {2 * STEADY_WINDOW_S:g} s")
    last, before = velocity[-n:], velocity[-2 * n:-n]
    return float(np.sqrt(np.mean(last ** 2))), float(np.sqrt(np.mean(before ** 2)))


def _grid(name: str, values: Any, parameter: Any) -> np.ndarray:
    try:
        grid = np.asarray(values, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ParameterError(f"parameter {name} = {show_value(values)} is not a list of numbers; allowed: 1 to 200 values, "
                             f"each {parameter.range_text()}") from None
    if grid.size == 0 or grid.size > 200:
        raise ParameterError(f"parameter {name} has {grid.size} values; allowed: 1 to 200 values")
    for value in grid:
        parameter.validate(float(value))
    return np.sort(grid)


def bow_map(model: Any, parameters: Any = None, *, velocities_m_s: Any = None, forces_n: Any = None,
            duration_s: float = 2.0, sample_rate: float = 44100.0) -> BowMap:
    """Bow ``model`` at every velocity x force and measure where it sustains.

    Parameters
    ----------
    model
        A barsynth model that can be bowed (e.g. ``get_model("banded")``).
    parameters
        The object: a mapping or resolved parameters (a preset's, for instance).
    velocities_m_s, forces_n
        The grid; default 24 velocities and 16 forces spread logarithmically over
        the parameters' ranges.
    duration_s
        How long each setting is bowed before its amplitude is read (s, 1 to 30).

    Examples
    --------
    >>> from barsynth.models import get_model
    >>> found = bow_map(get_model("banded"), velocities_m_s=[0.03, 0.3, 3.0], forces_n=[3.0])
    >>> found.sustained.tolist()
    [[False, True, False]]
    """
    from ..exciters import Bow
    from ..models.base import Model, resolve_parameters
    from ..models.rendering import check_sample_rate

    if not (isinstance(model, Model) and Bow in model.exciters):
        shown = repr(model.name) if isinstance(model, Model) else show_value(model)
        raise ParameterError(f"model {shown} cannot be bowed; allowed: a model with excitation = bow")
    table = model.table
    duration_s = check_number("duration_s", duration_s, "s", minimum=SHORTEST_S, maximum=30.0)
    rate = check_sample_rate(sample_rate)
    base = table.as_dict(resolve_parameters(model, parameters))
    v_param, f_param = table["bow_velocity_m_s"], table["bow_force_n"]
    if velocities_m_s is None:
        velocities_m_s = np.geomspace(v_param.minimum, v_param.maximum, 24)
    if forces_n is None:
        forces_n = np.geomspace(f_param.minimum, f_param.maximum, 16)
    velocities = _grid("velocities_m_s", velocities_m_s, v_param)
    forces = _grid("forces_n", forces_n, f_param)
    base.update(excitation=Bow.name, pickup_position=base["bow_position"], bow_duration_s=duration_s + 1.0,
                level_db=0.0)  # (every model has a level_db: tests/test_voice_contract.py)
    count = int(round(duration_s * rate))
    amplitude = np.zeros((forces.size, velocities.size))
    sustained = np.zeros_like(amplitude, dtype=bool)
    for i, force in enumerate(forces):
        for j, velocity in enumerate(velocities):
            voice = model.voice({**base, "bow_force_n": force, "bow_velocity_m_s": velocity}, sample_rate=rate)
            voice.trigger()
            last, before = steady_amplitude(voice.process(count, dtype=np.float64), rate)
            amplitude[i, j] = last
            sustained[i, j] = (last >= SUSTAIN_FRACTION * velocity
                               and abs(last - before) <= STEADY_TOLERANCE * max(last, before))
    return BowMap(model.name, velocities, forces, amplitude, sustained)


def plot_bow_map(found: BowMap, path: Any, *, title: str | None = None) -> Any:
    """Draw a bow map as a PNG: the steady amplitude where it sustains, the limits as lines."""
    from pathlib import Path

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    out = Path(path)
    fig = Figure(figsize=(8.0, 6.0), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    shown = np.where(found.sustained, found.amplitude_m_s, np.nan)
    ax.set_facecolor("0.92")
    if found.sustained.any():
        positive = shown[np.isfinite(shown) & (shown > 0)]
        mesh = ax.pcolormesh(found.velocities_m_s, found.forces_n, shown, shading="nearest", cmap="viridis",
                             norm=LogNorm(vmin=float(positive.min()), vmax=float(positive.max())))
        fig.colorbar(mesh, ax=ax, label="steady velocity at the bow, RMS (m/s)")
        limits = found.velocity_limits()
        force, low, high = (np.array(column) for column in zip(*limits))
        ax.plot(low, force, "o-", color="tab:red", lw=1.2, ms=3, label="least velocity that sustains")
        ax.plot(high, force, "s-", color="tab:orange", lw=1.2, ms=3, label="greatest velocity that sustains")
        ax.legend(loc="upper left", fontsize=8)
    else:
        ax.text(0.5, 0.5, "no setting sustains", transform=ax.transAxes, ha="center", va="center")
    ax.set_xscale("log")
    ax.set_yscale("log")
    v, f = found.velocities_m_s, found.forces_n
    ax.set_xlim(v[0] / 1.15, v[-1] * 1.15)
    ax.set_ylim(f[0] / 1.15, f[-1] * 1.15)
    ax.set_xlabel("bow velocity (m/s)")
    ax.set_ylabel("bow force (N)")
    ax.grid(True, which="both", alpha=0.25)
    ax.set_title(title or f"{found.model}: where bowing sustains (grey: it dies away)")
    fig.savefig(out, format="png")
    return out

