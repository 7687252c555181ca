"""`pip install barsynth` installs what rendering needs; the web stack and matplotlib are extras,
and a command that needs a missing one says, in one line, how to install it."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
WEB_STACK = {"fastapi", "uvicorn", "websockets", "starlette", "httpx", "httpx2"}


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def _names(requirements: list[str]) -> set[str]:
    return {re.match(r"[A-Za-z0-9_.-]+", r).group().lower() for r in requirements}


def test_the_base_install_has_no_web_stack_and_no_matplotlib():
    base = _names(_project()["dependencies"])
    assert base == {"numpy", "scipy", "numba", "soundfile", "click", "mido"}  # mido: reading MIDI files (small, pure Python)
    assert not base & WEB_STACK
    assert "matplotlib" not in base


def test_the_extras_hold_the_web_stack_and_matplotlib_and_test_pulls_them_in():
    extras = _project()["optional-dependencies"]
    assert _names(extras["studio"]) == {"fastapi", "uvicorn", "websockets"}
    assert _names(extras["plot"]) == {"matplotlib"}
    assert any(re.fullmatch(r"barsynth\[(.*,)?studio(,.*)?\]", r) for r in extras["test"])
    assert any(re.fullmatch(r"barsynth\[(.*,)?plot(,.*)?\]", r) for r in extras["test"])


DISTRIBUTIONS = {"rtmidi": "python-rtmidi", "distributed": "dask"}  # (dask[distributed] brings distributed)
"""Modules imported under another name than their PyPI package's (IPython is ipython: case only)."""


def test_the_extras_module_names_the_same_extras_as_pyproject():
    from barsynth.extras import EXTRAS

    extras = _project()["optional-dependencies"]
    assert set(EXTRAS) == set(extras) - {"all", "test", "docs", "dev"}
    for extra, modules in EXTRAS.items():
        assert {DISTRIBUTIONS.get(m, m).lower() for m in modules} == _names(extras[extra])
    assert _names(extras["play"]) == {"sounddevice", "python-rtmidi"}
    assert any(re.fullmatch(r"barsynth\[(.*,)?play(,.*)?\]", r) for r in extras["test"])


def _run_without(blocked: tuple[str, ...], *args: str, cwd: Path) -> subprocess.CompletedProcess:
    """`barsynth ARGS` in a process where importing each of ``blocked`` fails, as if not installed."""
    code = ("import sys\n"
            f"for name in {blocked!r}: sys.modules[name] = None\n"
            f"sys.argv = ['barsynth', *{list(args)!r}]\n"
            "from barsynth.entry import run\n"
            "run()\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd, timeout=120,
                          check=False)


def _one_line(result: subprocess.CompletedProcess, install: str) -> str:
    assert result.returncode == 2, result.stderr
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("barsynth: error: ")
    assert install in lines[0]
    return lines[0]


@pytest.mark.parametrize("blocked", [("fastapi",), ("uvicorn",), ("websockets",), ("fastapi", "uvicorn", "websockets")])
def test_studio_without_the_web_stack_says_how_to_install_it(tmp_path, blocked):
    line = _one_line(_run_without(blocked, "studio", "--port", "0", cwd=tmp_path), "pip install 'barsynth[studio]'")
    assert "barsynth studio" in line


def test_listen_serve_without_the_web_stack_says_how_to_install_it(tmp_path):
    config = tmp_path / "test.toml"
    config.write_text("", encoding="utf-8")
    result = _run_without(("fastapi", "uvicorn", "websockets"), "listen", "serve", str(config), "--port", "0",
                          cwd=tmp_path)
    assert "barsynth listen serve" in _one_line(result, "pip install 'barsynth[studio]'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["test.toml"]  # no results file made


def test_render_and_report_work_without_the_web_stack(tmp_path):
    result = _run_without(("fastapi", "uvicorn", "websockets", "starlette"), "render", "twang", "--duration", "0.2",
                          "-o", "x.wav", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "x.wav").stat().st_size > 0


def test_render_plot_without_matplotlib_says_how_to_install_it_and_writes_nothing(tmp_path):
    result = _run_without(("matplotlib",), "render", "twang", "--duration", "0.2", "--plot", "x.png",
                          "-o", "x.wav", cwd=tmp_path)
    _one_line(result, "pip install 'barsynth[plot]'")
    assert list(tmp_path.iterdir()) == []


def test_bow_map_without_matplotlib_says_how_to_install_it(tmp_path):
    result = _run_without(("matplotlib",), "bow-map", "banded", "--preset", "vibraphone", "-o", "map.png",
                          cwd=tmp_path)
    assert "barsynth bow-map" in _one_line(result, "pip install 'barsynth[plot]'")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("blocked", [("sounddevice",), ("rtmidi",), ("sounddevice", "rtmidi")])
def test_play_without_sounddevice_or_rtmidi_says_how_to_install_them(tmp_path, blocked):
    line = _one_line(_run_without(blocked, "play", "banded", "--seconds", "1", cwd=tmp_path),
                     "pip install 'barsynth[play]'")
    assert "barsynth play" in line and "sounddevice, python-rtmidi" in line


def test_play_without_the_portaudio_library_names_it(tmp_path):
    """sounddevice installed, the system's PortAudio not (sounddevice raises OSError on import)."""
    code = ("import sys, types\n"
            "class Finder:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'sounddevice': raise OSError('PortAudio library not found')\n"
            "sys.meta_path.insert(0, Finder())\n"
            "sys.argv = ['barsynth', 'play', 'banded', '--seconds', '1']\n"
            "from barsynth.entry import run\n"
            "run()\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120,
                            check=False)
    line = _one_line(result, "apt-get install libportaudio2")
    assert "PortAudio library not found" in line
