"""Pictures of sounds: a spectrogram as numbers, and a PNG with waveform and spectrogram.

Nothing heavy is imported at module level: SciPy loads when a spectrogram is
computed and matplotlib (Agg, without pyplot's global state) only when a plot is
drawn, so ``import barsynth.analysis`` stays fast.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import show_text
from ..errors import ParameterError
from .inputs import as_signal, positive
from .partial import Partial

__all__ = ["plot_sound", "spectrogram"]


def spectrogram(
    samples: Any,
    sample_rate: float,
    *,
    window_s: float = 0.046,
    hop_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Short-time spectrum of a mono sound, in dB re full scale.

    Parameters
    ----------
    window_s
        Length of the Hann window, s (0.046 s is 2048 samples at 44.1 kHz).
    hop_s
        Step between frames, s; default a quarter of the window.

    Returns
    -------
    times_s, freqs_hz, power_db
        Frame centres (s, the first at 0), bin frequencies (Hz, 0 to half the
        sample rate) and the level of each bin in each frame, shape
        ``(len(freqs_hz), len(times_s))``. A steady cosine of amplitude 1.0 shows
        as 0 dB (within the window's scalloping loss of 1.4 dB) in its bin.
    """
    from scipy.signal import ShortTimeFFT
    from scipy.signal.windows import hann

    x, fs = as_signal(samples, sample_rate)
    window_s = positive("window_s", window_s, "s")
    win_len = int(round(window_s * fs))
    if win_len < 4 or win_len > 2 * x.size:
        raise ParameterError(
            f"parameter window_s = {window_s!r} is out of range; allowed: {4 / fs:g} to "
            f"{max(4, 2 * x.size) / fs:g} s (4 samples to twice the sound's length)"
        )
    if hop_s is None:
        hop = max(1, win_len // 4)
    else:
        hop_s = positive("hop_s", hop_s, "s")
        hop = int(round(hop_s * fs))
        if hop < 1:
            raise ParameterError(
                f"parameter hop_s = {hop_s!r} is out of range; "
                f"allowed: >= {1 / fs:g} s (one sample)"
            )
    win = hann(win_len, sym=False)
    mfft = 1 << max(0, (win_len - 1).bit_length())
    sft = ShortTimeFFT(win, hop, fs, fft_mode="onesided", mfft=mfft, scale_to="magnitude")
    # frames centred from 0 to the last sample
    p1 = max(1, min(sft.p_max(x.size), (x.size - 1) // hop + 1))
    spec = sft.stft(x, p0=0, p1=p1)
    power_db = 20.0 * np.log10(2.0 * np.abs(spec) + 1e-12)
    times = sft.t(x.size, p0=0, p1=p1)
    return np.asarray(times, dtype=np.float64), np.asarray(sft.f, dtype=np.float64), power_db


def plot_sound(
    samples: Any,
    sample_rate: float,
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
    partials: Any = None,
    max_frequency_hz: float | None = None,
) -> Path:
    """Write a PNG with the waveform (top) and spectrogram (bottom) of a sound.

    Parameters
    ----------
    path
        Where to write the PNG (its folder must exist).
    title
        Shown above the figure.
    partials
        Optional :class:`~barsynth.analysis.Partial` objects (or frequencies in Hz)
        to mark on the spectrogram.
    max_frequency_hz
        Top of the frequency axis (default: just above the highest partial given,
        else half the sample rate). The axis is logarithmic when it spans more than
        four octaves, linear otherwise.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    x, fs = as_signal(samples, sample_rate)
    out = Path(os.fspath(path))
    if not out.parent.is_dir():
        raise ParameterError(
            f"parameter path = {show_text(os.fspath(path))}: folder {show_text(out.parent)} does not exist"
        )
    marks: list[float] = []
    for p in partials or []:
        f = p.frequency_hz if isinstance(p, Partial) else float(p)
        if math.isfinite(f) and 0 < f < fs / 2:
            marks.append(f)
    nyq = fs / 2.0
    if max_frequency_hz is None:
        top = min(nyq, 1.5 * max(marks)) if marks else nyq
    else:
        top = positive("max_frequency_hz", max_frequency_hz, "Hz")
        top = min(top, nyq)

    low = min(marks) / 1.5 if marks else 20.0
    low = max(low, 1.0)
    use_log = top / low > 16.0
    # the window: 46 ms, or six periods of the lowest frequency shown on a log
    # axis; at most an eighth of the sound, so that there are frames to see
    window_s = max(0.046, 6.0 / low) if use_log else 0.046
    window_s = min(window_s, max(8.0 / fs, x.size / fs / 8.0))
    # (a sound shorter than the window is padded with silence)
    padded = np.concatenate([x, np.zeros(max(0, int(round(window_s * fs)) - x.size))])
    times, freqs, power_db = spectrogram(padded, fs, window_s=window_s)

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 7.0), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax_wave, ax_spec = fig.subplots(2, 1, height_ratios=(1, 2.2))
    t = np.arange(x.size) / fs
    step = max(1, x.size // 20000)  # enough points for the eye, few for the file
    if step > 1:
        n = (x.size // step) * step
        blocks = x[:n].reshape(-1, step)
        tb = t[:n:step]
        ax_wave.fill_between(
            tb,
            blocks.min(axis=1),
            blocks.max(axis=1),
            facecolor="tab:blue",
            edgecolor="tab:blue",
            lw=0.6,
        )
    else:
        ax_wave.plot(t, x, color="tab:blue", lw=0.6)
    ax_wave.set_xlim(0.0, max(t[-1], 1.0 / fs))
    ax_wave.set_xlabel("time (s)")
    ax_wave.set_ylabel("amplitude")
    ax_wave.grid(True, alpha=0.3)

    vmax = float(np.max(power_db))
    vmin = vmax - 100.0
    low = max(low, freqs[1] if freqs.size > 1 else 1.0)
    mesh = ax_spec.pcolormesh(
        times,
        freqs,
        power_db,
        shading="nearest",
        cmap="magma",
        vmin=vmin,
        vmax=vmax,
        rasterized=True,
    )
    if use_log:
        ax_spec.set_yscale("log")
        ax_spec.set_ylim(low, top)
    else:
        ax_spec.set_ylim(0.0, top)
    ax_spec.set_xlim(0.0, max(t[-1], 1.0 / fs))
    ax_spec.set_xlabel("time (s)")
    ax_spec.set_ylabel("frequency (Hz)")
    fig.colorbar(mesh, ax=ax_spec, label="level (dB re full scale)")
    for f in marks:
        if f <= top:
            ax_spec.axhline(f, color="cyan", lw=0.7, ls="--", alpha=0.8)
            ax_spec.annotate(
                f"{f:.1f} Hz",
                xy=(1.0, f),
                xycoords=("axes fraction", "data"),
                xytext=(3, 0),
                textcoords="offset points",
                va="center",
                fontsize=7,
                color="black",
                annotation_clip=False,
            )
    if title:
        fig.suptitle(title)
    fig.savefig(out, format="png")
    return out
