"""Band-limited, decimated complex envelopes of a sound (heterodyne + low-pass + decimate).

Around a frequency the sound's spectrum is cut out, shifted to 0 Hz and low-passed with
the zero-phase response ``H(nu) = exp(-0.5 (nu / f1)**4)`` (-6 dB at the cutoff, -96 dB
at twice the cutoff); a short inverse FFT gives the complex envelope at a rate of about
ten times ``f1``. This is :class:`.demodulation.Engine`'s band extraction: one FFT of
the whole sound, then one short inverse FFT per band.

A cosine ``A cos(2 pi f t + phi)`` inside the band gives ``(A/2) exp(j(2 pi (f - f_bin) t
+ phi))``; a decaying one, ``A exp(-sigma t) cos(...)``, gives the same times
``H(nu)`` at the complex offset ``nu = f - f_bin + j sigma / (2 pi)`` once the filter
has settled (:meth:`BandEnvelope.response`), so fits can undo the filter exactly.
White noise of variance ``v`` gives ``E|z|^2 = v * enbw_hz / sample_rate``.

Reference: J. O. Smith, *Spectral Audio Signal Processing* (complex demodulation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .demodulation import SG_6DB, Engine, Mode

__all__ = ["SETTLE_F1", "BandEnvelope", "Bands"]

SETTLE_F1 = 2.0  # after a step the filter settles (to -96 dB) within 2 / f1 seconds
# integral over all nu of exp(-(nu/f1)^4), per f1: Gamma(1/4) / 2
_ENBW_PER_F1 = math.gamma(0.25) / 2.0


@dataclass(frozen=True)
class BandEnvelope:
    """The complex envelope of one band.

    Attributes
    ----------
    t
        Sample times, s from the sound's first sample (uniform, step ``dt``).
    z
        Complex envelope (see the module docstring for its scale).
    f_bin_hz
        The frequency shifted to 0 Hz, Hz.
    cutoff_hz
        Where the low-pass is 6 dB down, Hz.
    """

    t: np.ndarray
    z: np.ndarray
    f_bin_hz: float
    centre_hz: float
    cutoff_hz: float

    @property
    def f1_hz(self) -> float:
        """The low-pass's scale ``f1`` (``H = exp(-0.5 (nu/f1)^4)``), Hz."""
        return self.cutoff_hz / SG_6DB

    @property
    def dt(self) -> float:
        """Sample interval of the envelope, s."""
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else 0.0

    @property
    def settle_s(self) -> float:
        """Time the low-pass takes to settle after a step (the onset, the file's end), s."""
        return SETTLE_F1 / self.f1_hz

    @property
    def enbw_hz(self) -> float:
        """Equivalent noise bandwidth of the low-pass (``integral of |H|^2``), Hz."""
        return _ENBW_PER_F1 * self.f1_hz

    def response(self, offset_hz: complex) -> complex:
        """The low-pass at a (complex) offset from ``f_bin_hz``: ``f - f_bin + j sigma/(2 pi)``."""
        nu = complex(offset_hz) / self.f1_hz
        if abs(nu) > 6.0:  # far outside the band: nothing passes (and nu**4 would overflow exp)
            return 0j
        return complex(np.exp(-0.5 * nu**4))


class Bands:
    """Envelopes of bands of one sound; the sound's FFT is taken once.

    ``narrowest_cutoff_hz`` sets the zero padding: room for the narrowest band's
    smear, so that the end of the sound does not wrap onto its start.
    """

    def __init__(self, x: np.ndarray, sample_rate: float, narrowest_cutoff_hz: float) -> None:
        self.engine = Engine(x, sample_rate)
        self.engine.prepare([Mode(1.0, 1.0, cutoff_hz=narrowest_cutoff_hz)])
        self.spectrum = self.engine.spectrum(x)

    def envelope(self, centre_hz: float, cutoff_hz: float) -> BandEnvelope:
        """The band of cutoff ``cutoff_hz`` (Hz, -6 dB) around ``centre_hz`` (Hz)."""
        engine = self.engine
        band = engine.band(centre_hz, cutoff_hz)
        z = engine.envelope(band, engine.band_values(self.spectrum, band))
        return BandEnvelope(
            t=band.t, z=z, f_bin_hz=float(band.f_bin), centre_hz=float(centre_hz),
            cutoff_hz=float(cutoff_hz),
        )
