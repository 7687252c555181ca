"""barsynth's optional parts and the one line that says how to install each.

``pip install barsynth`` installs what rendering needs (NumPy, SciPy, numba,
soundfile, click). Extras add the rest:

* ``plot`` (matplotlib): the PNG pictures of ``render --plot``, ``analyze --plot``,
  ``bow-map`` and ``listen report --plot``;
* ``studio`` (fastapi, uvicorn, websockets): the web stack of ``barsynth studio`` and of
  the listening-test server ``barsynth listen serve``;
* ``notebook`` (IPython): hearing sounds in Jupyter (:mod:`barsynth.notebook`);
* ``play`` (sounddevice, python-rtmidi): live audio and MIDI input of ``barsynth play``
  (sounddevice also needs the system's PortAudio library, Debian's ``libportaudio2``);
* ``batch`` (pyarrow, rich, dask.distributed): ``barsynth batch``'s Parquet manifest, its
  progress with an ETA and its runs on a Dask cluster.

``pip install 'barsynth[plot,studio]'`` installs two of them, ``'barsynth[all]'`` all.

>>> sorted(EXTRAS)
['batch', 'notebook', 'play', 'plot', 'studio']
"""

from __future__ import annotations

import importlib

from .errors import BarsynthError

__all__ = ["EXTRAS", "MissingExtraError", "missing_modules", "require"]

# extra -> the top-level modules it provides (as imported, not as named on PyPI)
EXTRAS: dict[str, tuple[str, ...]] = {
    "plot": ("matplotlib",),
    "studio": ("fastapi", "uvicorn", "websockets"),
    "notebook": ("IPython",),
    "play": ("sounddevice", "rtmidi"),
    "batch": ("pyarrow", "rich", "distributed"),
}
_WHAT = {"plot": "matplotlib", "studio": "the web stack (fastapi, uvicorn, websockets)", "notebook": "IPython",
         "play": "live audio and MIDI (sounddevice, python-rtmidi)",
         "batch": "the batch stack (pyarrow, rich, dask.distributed)"}
_SYSTEM = {"sounddevice": " (PortAudio; on Debian: apt-get install libportaudio2)"}


class MissingExtraError(BarsynthError):
    """A command needs an extra that is not installed; the message says how to install it."""


def missing_modules(extra: str) -> list[str]:
    """The modules of ``extra`` that cannot be imported (importing is the only sure test:
    a package can be present but broken, or one of its own dependencies missing)."""
    missing = []
    for name in EXTRAS[extra]:
        try:
            importlib.import_module(name)
        except ImportError:
            missing.append(name)
        except OSError as error:  # installed, but a system library it loads is not (sounddevice: PortAudio)
            raise MissingExtraError(f"{name} is installed but could not load a system library: "
                                    f"{' '.join(str(error).split())}" + _SYSTEM.get(name, "")) from None
    return missing


def require(extra: str, what: str) -> None:
    """Raise :class:`MissingExtraError` (one line: ``what`` needs ..., and the pip command)
    unless every module of ``extra`` imports."""
    if missing_modules(extra):
        raise MissingExtraError(f"{what} needs {_WHAT[extra]}, which is not installed; "
                                f"install it with: pip install 'barsynth[{extra}]'")
