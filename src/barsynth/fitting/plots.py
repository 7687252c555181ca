"""A picture of a fit: the recording and its resynthesis side by side (matplotlib, Agg)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plot_fit"]


def plot_fit(fit: Any, path: str | os.PathLike[str], *, title: str | None = None) -> Path:
    """Write a PNG: the spectrograms of the recording (left) and the resynthesis (right) on the
    same axes and levels, each partial of the recording marked on both (dashed: a partial the
    resynthesis has, dotted: one it lacks), and below them each partial's error in cents and dB."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..analysis.plots import spectrogram

    rate = fit.sample_rate
    onset = int(round(fit.analysis.onset_s * rate))
    recording = fit.recording[onset:]
    heard = fit.heard()
    seconds = min(2.0, max(recording.size, 1) / rate)
    n = max(16, int(seconds * rate))
    marks = [c.frequency_hz for c in fit.comparison]
    top = min(0.5 * rate, 1.3 * max(marks)) if marks else 0.5 * rate
    low = max(20.0, min(marks) / 1.5) if marks else 20.0
    fig = Figure(figsize=(12.0, 7.5), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, height_ratios=(2.2, 1))
    spectra = []
    for x in (recording, heard):
        padded = np.zeros(n)
        padded[:min(n, x.size)] = x[:n]
        spectra.append(spectrogram(padded, rate, window_s=0.046))
    vmax = max(float(np.max(s[2])) for s in spectra)
    for ax, (times, freqs, power_db), label in zip(axes[0], spectra, ("recording", f"{fit.model} fit")):
        mesh = ax.pcolormesh(times, freqs, power_db, shading="nearest", cmap="magma", vmin=vmax - 90.0, vmax=vmax,
                             rasterized=True)
        ax.set_yscale("log")
        ax.set_ylim(low, top)
        ax.set_title(label)
        ax.set_xlabel("time from the onset (s)")
        ax.set_ylabel("frequency (Hz)")
        for c in fit.comparison:
            style = "--" if c.resynthesis_hz is not None else ":"
            ax.axhline(c.frequency_hz, color="cyan", lw=0.7, ls=style, alpha=0.8)
    fig.colorbar(mesh, ax=list(axes[0]), label="level (dB re full scale)")
    matched = [c for c in fit.comparison if c.cents is not None]
    freqs = [c.frequency_hz for c in matched]
    axes[1, 0].bar(range(len(matched)), [c.cents for c in matched], color="tab:blue")
    axes[1, 0].set_ylabel("fit - recording (cents)")
    axes[1, 1].bar(range(len(matched)), [c.level_error_db for c in matched], color="tab:orange")
    axes[1, 1].set_ylabel("fit - recording (dB)")
    for ax in axes[1]:
        ax.set_xticks(range(len(matched)), [f"{f:.0f}" for f in freqs], rotation=60, fontsize=7)
        ax.set_xlabel("partial (Hz)")
        ax.axhline(0.0, color="black", lw=0.6)
        ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle(f"{title + ': ' if title else ''}spectral distance {fit.distance_db:.2f} dB "
                 f"(one sine at f0: {fit.baseline_db:.2f} dB)")
    out = Path(os.fspath(path))
    fig.savefig(out, format="png")
    return out
