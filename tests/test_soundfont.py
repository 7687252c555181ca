"""The SoundFont reader (barsynth.soundfont): presets, zones and samples of SF2 and SF3 files.

Real files: Debian's timgm6mb-soundfont (SF2) and musescore-general-soundfont-small (SF3, Ogg
Vorbis samples), which the test set-up installs; a small SF2 written here checks the parts
exactly. (fluid-soundfont-gm and freepats are kept for independent evaluation: never used.)
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from barsynth.errors import AudioFileError
from barsynth.soundfont import GM_PROGRAMS, SoundFont

TIMGM = Path("/usr/share/sounds/sf2/TimGM6mb.sf2")
MUSESCORE = Path("/usr/share/sounds/sf3/MuseScore_General_Lite.sf3")


def chunk(tag: bytes, data: bytes) -> bytes:
    return tag + struct.pack("<I", len(data)) + data + (b"\0" if len(data) % 2 else b"")


def riff_list(kind: bytes, *chunks: bytes) -> bytes:
    return chunk(b"LIST", kind + b"".join(chunks))


def tiny_sf2(samples: np.ndarray, *, rate: int = 22050, root: int = 60, loop=(100, 200)) -> bytes:
    """A SoundFont of one preset (program 12, keys 0-127), one instrument, one sample."""
    pcm = (np.clip(samples, -1, 32767 / 32768) * 32768).astype("<i2").tobytes() + b"\0" * 92  # 46 zero points
    n = samples.size
    phdr = struct.pack("<20sHHHIII", b"Test marimba", 12, 0, 0, 0, 0, 0) + struct.pack("<20sHHHIII", b"EOP", 0, 0, 1, 0,
                                                                                         0, 0)
    pbag = struct.pack("<HH", 0, 0) + struct.pack("<HH", 1, 0)
    pgen = struct.pack("<HH", 41, 0) + struct.pack("<HH", 0, 0)
    inst = struct.pack("<20sH", b"Marimba", 0) + struct.pack("<20sH", b"EOI", 1)
    ibag = struct.pack("<HH", 0, 0) + struct.pack("<HH", 2, 0)
    igen = struct.pack("<HBB", 43, 0, 127) + struct.pack("<HH", 53, 0) + struct.pack("<HH", 0, 0)
    shdr = (struct.pack("<20sIIIIIBbHH", b"Marimba C4", 0, n, loop[0], loop[1], rate, root, -7, 0, 1)
            + struct.pack("<20sIIIIIBbHH", b"EOS", 0, 0, 0, 0, 0, 0, 0, 0, 0))
    body = (b"sfbk" + riff_list(b"INFO", chunk(b"ifil", struct.pack("<HH", 2, 1)))
            + riff_list(b"sdta", chunk(b"smpl", pcm))
            + riff_list(b"pdta", chunk(b"phdr", phdr), chunk(b"pbag", pbag), chunk(b"pmod", b"\0" * 10),
                        chunk(b"pgen", pgen), chunk(b"inst", inst), chunk(b"ibag", ibag), chunk(b"imod", b"\0" * 10),
                        chunk(b"igen", igen), chunk(b"shdr", shdr)))
    return b"RIFF" + struct.pack("<I", len(body)) + body


def test_a_written_sf2_reads_back_exactly(tmp_path):
    rate = 22050
    t = np.arange(4000) / rate
    x = np.round(0.5 * np.sin(2 * np.pi * 262.0 * t) * 32768) / 32768
    path = tmp_path / "tiny.sf2"
    path.write_bytes(tiny_sf2(x, rate=rate))
    font = SoundFont(path)
    preset = font.preset(program=12)
    assert preset.name == "Test marimba" and len(preset.zones) == 1
    zone = preset.zone_for(60)
    assert (zone.key_low, zone.key_high, zone.root_key) == (0, 127, 60)
    assert zone.nominal_hz == pytest.approx(261.6256 * 2 ** (7 / 1200), rel=1e-6)  # -7 cents of correction
    samples, got_rate = font.read(zone.sample)
    assert got_rate == rate and np.array_equal(samples, x)
    assert font.loop(zone.sample) == (100, 200)
    assert preset.zone_for(200) is zone  # outside every range: the nearest


@pytest.mark.parametrize("content, needle", [(b"", "not a SoundFont"), (b"RIFF\x04\0\0\0WAVE", "not a SoundFont"),
                                             (b"RIFF\x04\0\0\0sfbk", "no smpl chunk")])
def test_what_is_not_a_soundfont_is_one_line(tmp_path, content, needle):
    path = tmp_path / "bad.sf2"
    path.write_bytes(content)
    with pytest.raises(AudioFileError, match=needle) as info:
        SoundFont(path)
    assert "\n" not in str(info.value)


def test_a_missing_file_is_one_line(tmp_path):
    with pytest.raises(AudioFileError, match="soundfont"):
        SoundFont(tmp_path / "none.sf2")


@pytest.mark.parametrize("path", [TIMGM, MUSESCORE], ids=["sf2", "sf3"])
def test_debians_fonts_give_every_bar_and_bell_instrument(path):
    if not path.exists():
        pytest.skip(f"{path} is not installed (the test set-up installs it)")
    font = SoundFont(path)
    for name, program in GM_PROGRAMS.items():
        preset = font.preset(program=program)
        zone = preset.zone_for(72)
        samples, rate = font.read(zone.sample)
        assert samples.ndim == 1 and samples.size > 0.05 * rate, name
        assert 0.1 < np.abs(samples).max() <= 1.0, name
        assert 8000 <= rate <= 96000, name
        assert 20.0 < zone.nominal_hz < 10000.0, name
