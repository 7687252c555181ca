"""Instrument samples out of SoundFont files: SF2 (16-bit PCM) and MuseScore's SF3 (Ogg Vorbis).

Recordings of real marimbas, glockenspiels, kalimbas and tubular bells ship in Debian's
soundfont packages; barsynth reads them to measure its fits (``scripts/fit_quality.py``). A
SoundFont is a RIFF file (SoundFont 2.04 specification, E-mu/Creative, 2006): ``sdta/smpl``
holds the sample data, ``pdta`` the hydra: presets (``phdr``, ``pbag``, ``pgen``), instruments
(``inst``, ``ibag``, ``igen``) and sample headers (``shdr``: name, start, end, loop, rate,
root key). SF3 is the same file with each sample stored as Ogg Vorbis: a sample header's
``start``/``end`` are then byte offsets into ``smpl`` and its loop points count decoded frames
from the sample's start (MuseScore's convention).

Only what reading a preset's samples needs is parsed: key ranges, the sample of each zone
and its root key. Modulators, envelopes and filters are not (the samples are the recording).
Written here because no maintained Python package reads SF3's compressed samples.

>>> font = SoundFont("/usr/share/sounds/sf2/TimGM6mb.sf2")        # doctest: +SKIP
>>> marimba = font.preset(program=12)                               # doctest: +SKIP
>>> zone = marimba.zone_for(key=60)                                 # doctest: +SKIP
>>> samples, rate = font.read(zone.sample)                          # doctest: +SKIP
"""

from __future__ import annotations

import io
import os
import struct
from dataclasses import dataclass
from typing import Any

from .checks import show_text
from .errors import AudioFileError

__all__ = ["GM_PROGRAMS", "Preset", "SampleHeader", "SoundFont", "Zone"]

GM_PROGRAMS = {
    "celesta": 8, "glockenspiel": 9, "music box": 10, "vibraphone": 11, "marimba": 12,
    "xylophone": 13, "tubular bells": 14, "kalimba": 108, "steel drums": 114,
}
"""General MIDI programs (counted from 0) of the bar, bell and tine instruments."""

COMPRESSED = 0x10  # sfSampleType flag of SF3: the sample is Ogg Vorbis
ROM = 0x8000  # a sample in the synthesiser's ROM: no data in the file
# Generator numbers (SoundFont 2.04, section 8.1.2)
GEN_INSTRUMENT = 41
GEN_KEY_RANGE = 43
GEN_SAMPLE_ID = 53
GEN_ROOT_KEY = 58
MAX_CHUNK_BYTES = 1 << 31  # a SoundFont's sample chunk is addressed by 32-bit offsets


@dataclass(frozen=True)
class SampleHeader:
    """One ``shdr`` record: where a sample lies, its loop, rate (Hz) and root key (MIDI)."""

    index: int
    name: str
    start: int
    end: int
    loop_start: int
    loop_end: int
    sample_rate: int
    original_key: int
    pitch_correction_cents: int
    kind: int

    @property
    def compressed(self) -> bool:
        return bool(self.kind & COMPRESSED)


@dataclass(frozen=True)
class Zone:
    """One key range of a preset and the sample it plays; ``root_key`` is the MIDI key at
    which the sample sounds at its recorded pitch."""

    key_low: int
    key_high: int
    root_key: int
    sample: SampleHeader

    @property
    def nominal_hz(self) -> float:
        """The pitch the font says the sample has (its root key, 440 Hz tuning, with the
        header's pitch correction)."""
        return 440.0 * 2.0 ** ((self.root_key - 69 - self.sample.pitch_correction_cents / 100.0) / 12.0)


@dataclass(frozen=True)
class Preset:
    """A preset (an instrument as a MIDI program plays it): its zones, lowest key first."""

    name: str
    program: int
    bank: int
    zones: tuple[Zone, ...]

    def zone_for(self, key: int) -> Zone:
        """The zone that plays MIDI ``key`` (the nearest one when none covers it)."""
        covering = [z for z in self.zones if z.key_low <= key <= z.key_high]
        if covering:
            return covering[0]
        return min(self.zones, key=lambda z: min(abs(key - z.key_low), abs(key - z.key_high)))


def _name(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("latin-1").strip()


class SoundFont:
    """A SoundFont file's presets and samples (see the module docstring).

    Raises :class:`~barsynth.errors.AudioFileError` (one line, naming the file) when the file
    is missing or is not a SoundFont.
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = os.fspath(path)
        try:
            with open(self.path, "rb") as file:
                head = file.read(12)
                if len(head) < 12 or head[:4] != b"RIFF" or head[8:12] != b"sfbk":
                    raise AudioFileError(f"soundfont {show_text(self.path)}: not a SoundFont (RIFF sfbk) file")
                self._chunks = self._read_lists(file)
        except OSError as exc:
            if isinstance(exc, AudioFileError):
                raise
            raise AudioFileError(f"soundfont {show_text(self.path)}: {exc.strerror or exc}") from None
        try:
            self.samples = self._sample_headers()
            self.presets = self._presets()
        except (KeyError, struct.error, IndexError) as exc:
            raise AudioFileError(f"soundfont {show_text(self.path)}: damaged hydra ({exc})") from None

    # -- the RIFF structure -----------------------------------------------------------------
    def _read_lists(self, file: Any) -> dict[str, Any]:
        """``pdta`` sub-chunks as bytes; ``smpl``'s place in the file as (offset, size)."""
        chunks: dict[str, Any] = {}
        while True:
            header = file.read(8)
            if len(header) < 8:
                break
            tag, size = header[:4].decode("latin-1"), struct.unpack("<I", header[4:])[0]
            if tag != "LIST":
                file.seek(size + (size & 1), 1)
                continue
            kind = file.read(4)
            end = file.tell() + size - 4
            while file.tell() < end:
                sub = file.read(8)
                if len(sub) < 8:
                    break
                name, length = sub[:4].decode("latin-1"), struct.unpack("<I", sub[4:])[0]
                if kind == b"sdta" and name == "smpl":
                    chunks["smpl"] = (file.tell(), length)
                    file.seek(length + (length & 1), 1)
                elif kind == b"pdta":
                    chunks[name] = file.read(length)
                    if length & 1:
                        file.read(1)
                else:
                    file.seek(length + (length & 1), 1)
            file.seek(end)
        for needed in ("smpl", "phdr", "pbag", "pgen", "inst", "ibag", "igen", "shdr"):
            if needed not in chunks:
                raise AudioFileError(f"soundfont {show_text(self.path)}: no {needed} chunk")
        return chunks

    def _sample_headers(self) -> list[SampleHeader]:
        raw = self._chunks["shdr"]
        headers = []
        for i in range(len(raw) // 46 - 1):  # the last record is the terminal "EOS"
            fields = struct.unpack_from("<20sIIIIIBbHH", raw, 46 * i)
            headers.append(SampleHeader(i, _name(fields[0]), *fields[1:6], fields[6], fields[7], fields[9]))
        return headers

    def _zones(self, bags: bytes, gens: bytes, first: int, last: int) -> list[dict[int, int]]:
        """The generators (number -> raw 16-bit amount) of bags ``first`` .. ``last - 1``."""
        zones = []
        for bag in range(first, last):
            g0 = struct.unpack_from("<H", bags, 4 * bag)[0]
            g1 = struct.unpack_from("<H", bags, 4 * (bag + 1))[0]
            zones.append({struct.unpack_from("<H", gens, 4 * g)[0]: struct.unpack_from("<H", gens, 4 * g + 2)[0]
                          for g in range(g0, g1)})
        return zones

    def _instrument_zones(self, index: int) -> list[tuple[dict[int, int], dict[int, int]]]:
        """(global zone, zone) pairs of instrument ``index`` that name a sample."""
        inst = self._chunks["inst"]
        first = struct.unpack_from("<H", inst, 22 * index + 20)[0]
        last = struct.unpack_from("<H", inst, 22 * (index + 1) + 20)[0]
        zones = self._zones(self._chunks["ibag"], self._chunks["igen"], first, last)
        glob = zones[0] if zones and GEN_SAMPLE_ID not in zones[0] else {}
        return [(glob, z) for z in zones if GEN_SAMPLE_ID in z]

    def _presets(self) -> list[Preset]:
        raw = self._chunks["phdr"]
        presets = []
        for i in range(len(raw) // 38 - 1):  # the last record is the terminal "EOP"
            name, program, bank, bag = struct.unpack_from("<20sHHH", raw, 38 * i)
            next_bag = struct.unpack_from("<H", raw, 38 * (i + 1) + 24)[0]
            pzones = self._zones(self._chunks["pbag"], self._chunks["pgen"], bag, next_bag)
            zones = []
            for pz in pzones:
                if GEN_INSTRUMENT not in pz:
                    continue
                plo, phi = _key_range(pz)
                for glob, iz in self._instrument_zones(pz[GEN_INSTRUMENT]):
                    merged = {**glob, **iz}
                    lo, hi = _key_range(merged)
                    lo, hi = max(lo, plo), min(hi, phi)
                    if lo > hi:
                        continue
                    sample = self.samples[merged[GEN_SAMPLE_ID]]
                    if sample.kind & ROM:
                        continue
                    root = merged.get(GEN_ROOT_KEY, 0xFFFF)
                    root = sample.original_key if root > 127 else root
                    zones.append(Zone(lo, hi, root, sample))
            zones.sort(key=lambda z: (z.key_low, z.key_high))
            presets.append(Preset(_name(name), program, bank, tuple(zones)))
        return presets

    # -- what users ask for ----------------------------------------------------------------
    def preset(self, program: int, bank: int = 0) -> Preset:
        """The preset of MIDI ``program`` (0-127) in ``bank``."""
        for p in self.presets:
            if p.program == program and p.bank == bank and p.zones:
                return p
        raise KeyError(f"soundfont {self.path}: no preset {program} in bank {bank}")

    def read(self, sample: SampleHeader) -> tuple[Any, float]:
        """A sample's data as float64 (full scale 1.0, the whole recording: attack, loop and
        what the font stores after it) and its sample rate in Hz."""
        import numpy as np
        import soundfile

        offset, size = self._chunks["smpl"]
        if sample.compressed:
            start, end = sample.start, sample.end
        else:
            start, end = 2 * sample.start, 2 * sample.end
        if not 0 <= start < end <= size:
            raise AudioFileError(f"soundfont {show_text(self.path)}: sample {sample.name!r} lies outside the data")
        with open(self.path, "rb") as file:
            file.seek(offset + start)
            data = file.read(end - start)
        if sample.compressed:
            try:
                samples, rate = soundfile.read(io.BytesIO(data), dtype="float64", always_2d=True)
            except (RuntimeError, soundfile.SoundFileError) as exc:
                raise AudioFileError(f"soundfont {show_text(self.path)}: sample {sample.name!r} "
                                     f"cannot be decoded ({exc})") from None
            return samples.mean(axis=1), float(rate)
        return np.frombuffer(data, dtype="<i2").astype(np.float64) / 32768.0, float(sample.sample_rate)

    def loop(self, sample: SampleHeader) -> tuple[int, int] | None:
        """The sample's loop as (first, end) frame indices into :meth:`read`'s samples, or None
        when the font gives no usable loop."""
        if sample.compressed:
            first, end = sample.loop_start, sample.loop_end
        else:
            first, end = sample.loop_start - sample.start, sample.loop_end - sample.start
        length = sample.end - sample.start if not sample.compressed else None
        if end - first < 2 or first < 0 or (length is not None and end > length):
            return None
        return first, end


def _key_range(generators: dict[int, int]) -> tuple[int, int]:
    amount = generators.get(GEN_KEY_RANGE)
    if amount is None:
        return 0, 127
    return amount & 0xFF, amount >> 8
