"""An on-disk cache of designs that take long to compute, for the program only.

A design (the all-pass waveguide's fitted filters: 0.1-0.25 s of fitting) is a pure function
of its inputs, of barsynth's code and of the arithmetic underneath (NumPy, its BLAS, the C
library's ``exp`` / ``log``, the CPU's SIMD paths: each can move a last bit). The program
(:mod:`barsynth.entry`) turns the cache on; a library user's process and the test suite's
own renders do not use it unless they call :func:`enable`.

* Where: ``$BARSYNTH_CACHE_DIR`` if set (empty: no cache), else
  ``$XDG_CACHE_HOME/barsynth`` or ``~/.cache/barsynth``, in a ``designs`` folder made for
  it (``0o700``); nothing else there is read, written or deleted.
* Key: a SHA-256 over the kind, every input, barsynth's version, a digest of the sources
  that compute the design (so an edited source tree recomputes), Python's, NumPy's and the
  C library's versions, the machine and the CPU features NumPy dispatches on. The whole key
  is also stored in the file and compared on loading.
* Files: JSON only (floats written exactly, as hex; arrays as little-endian bytes in
  base64): loading one runs no code. Written to a temporary file in the same folder and
  renamed into place, so a reader never sees half a file. Anything unreadable, mismatched
  or malformed is ignored (and written anew). At most ``MAX_FILES`` designs of a kind are
  kept: the oldest are deleted when a new one is written.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

# (base64, hashlib, json, platform and tempfile are imported where used: the program imports
# this module at its start, before it knows whether a design will be asked for)

__all__ = ["MAX_FILES", "array_from", "array_record", "cached", "enable", "enabled", "folder"]

ENV = "BARSYNTH_CACHE_DIR"
FORMAT = 1
MAX_FILES = 256
"""Designs of one kind kept on disk (the oldest beyond this are deleted)."""

_state: dict[str, Any] = {"enabled": False}
_digests: dict[tuple[str, ...], str] = {}


def enable(on: bool = True) -> None:
    """Turn the on-disk cache on (or off) for this process."""
    _state["enabled"] = bool(on)


def enabled() -> bool:
    """Whether this process keeps designs on disk (:func:`enable`, and a folder to keep them in)."""
    return _state["enabled"] and folder() is not None


def folder() -> Path | None:
    """The cache's ``designs`` folder (not created here); None if ``$BARSYNTH_CACHE_DIR`` is empty."""
    chosen = os.environ.get(ENV)
    if chosen is not None:
        return Path(chosen) / "designs" if chosen else None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "barsynth" / "designs"


def cached(kind: str, inputs: list[Any], sources: tuple[str, ...], compute: Callable[[], Any],
           to_record: Callable[[Any], dict], from_record: Callable[[dict], Any]) -> Any:
    """``compute()``, or the stored result for the same key if the cache is on and has it.

    ``kind``: a short name (letters and digits); ``inputs``: every input, as JSON values
    (floats as ``float.hex`` to be exact); ``sources``: the dotted names of the modules and
    packages whose code computes it; ``to_record`` / ``from_record``: the result as a JSON
    object and back (``from_record`` raises on a malformed record)."""
    if not kind.isalnum():
        raise ValueError(f"cache kind {kind!r}: letters and digits only")
    if not enabled():
        return compute()
    import hashlib
    import json

    try:
        key = _key(kind, inputs, sources)
        name = f"{kind}-{hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()}.json"
        where = folder()
    except Exception:  # noqa: BLE001 - no key to be sure of (a source not found...): not cached
        return compute()
    if not _private(where):  # a folder someone else could write to: neither read nor written
        return compute()
    try:
        with open(where / name, encoding="utf-8") as file:
            stored = json.load(file)
        if stored.get("format") == FORMAT and stored.get("key") == key:
            result = from_record(stored["record"])
            try:
                os.utime(where / name)  # used now: the last to be pruned
            except OSError:
                pass
            return result
    except Exception:  # noqa: BLE001 - missing, unreadable, corrupt or malformed: computed anew
        pass
    result = compute()
    try:
        content = {"format": FORMAT, "key": key, "record": to_record(result)}
    except Exception:  # noqa: BLE001 # pragma: no cover - a result the record cannot hold: not stored
        return result
    _write(where, name, content, kind)
    return result


def _private(where: Path) -> bool:
    """Whether the ``designs`` folder is ours alone: missing (it will be made with mode 0o700),
    or a real folder owned by this user that no group or other user may write to. A record is
    data the program trusts (it runs no code, but a planted one would give wrong sounds)."""
    import stat

    try:
        info = os.lstat(where)
    except FileNotFoundError:
        return True
    except OSError:
        return False
    getuid = getattr(os, "getuid", None)
    owner_ok = getuid is None or info.st_uid == getuid()
    return stat.S_ISDIR(info.st_mode) and owner_ok and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def array_record(array) -> dict:
    """A float64 array as a JSON object: its shape and its bytes (little-endian, base64)."""
    import base64

    import numpy as np

    data = np.ascontiguousarray(array, dtype="<f8")
    return {"shape": list(data.shape), "f8": base64.b64encode(data.tobytes()).decode("ascii")}


def array_from(record: dict):
    """The array of :func:`array_record` (a new, writeable, native float64 array)."""
    import base64

    import numpy as np

    shape = tuple(int(n) for n in record["shape"])
    return np.frombuffer(base64.b64decode(record["f8"], validate=True), dtype="<f8").reshape(shape).astype(np.float64)


def _key(kind: str, inputs: list[Any], sources: tuple[str, ...]) -> dict:
    from . import __version__

    return {"kind": kind, "inputs": inputs, "barsynth": __version__, "sources": _source_digest(sources),
            "arithmetic": _arithmetic()}


def _arithmetic() -> dict:
    """What else can move a last bit of a design: the versions and the CPU paths (once a process)."""
    if "arithmetic" not in _state:
        _state["arithmetic"] = _versions_and_cpu()
    return _state["arithmetic"]


def _versions_and_cpu() -> dict:
    import platform

    import numpy as np

    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # pragma: no cover - another NumPy
        from numpy.core._multiarray_umath import __cpu_features__ as features
    try:
        libc = os.confstr("CS_GNU_LIBC_VERSION")
    except (AttributeError, ValueError, OSError):  # pragma: no cover - not glibc
        libc = None
    return {"python": sys.version, "numpy": np.__version__, "libc": libc or platform.libc_ver()[1],
            "machine": platform.machine(), "cpu": sorted(name for name, on in features.items() if on),
            "cpu_model": _cpu_model(), "blas": _blas()}


def _cpu_model() -> str:
    """The CPU's model name (Linux: /proc/cpuinfo), else the platform's word for it."""
    import platform

    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as file:
            for line in file:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def _blas() -> str:
    """NumPy's BLAS and LAPACK (name and version), whose arithmetic the fits' solves use."""
    try:
        from numpy.__config__ import CONFIG

        deps = CONFIG.get("Build Dependencies", {})
        return " ".join(f"{k}={deps.get(k, {}).get('name')}-{deps.get(k, {}).get('version')}"
                        for k in ("blas", "lapack"))
    except Exception:  # noqa: BLE001 - an older NumPy: its version stands for its BLAS
        return "unknown"


def _source_digest(sources: tuple[str, ...]) -> str:
    """SHA-256 over the ``.py`` files of the named modules and packages (once a process)."""
    if sources not in _digests:
        import hashlib
        import importlib.util

        digest = hashlib.sha256()
        for name in sources:
            spec = importlib.util.find_spec(name)
            if spec is None or spec.origin is None:
                raise ImportError(f"no source for {name}")
            origin = Path(spec.origin)
            if origin.suffix != ".py":  # only compiled files (.pyc): no source to be sure of
                raise ImportError(f"no .py source for {name}")
            files = sorted(origin.parent.rglob("*.py")) if origin.name == "__init__.py" else [origin]
            for file in files:
                digest.update(f"{name}/{file.relative_to(origin.parent).as_posix()}\0".encode())
                digest.update(file.read_bytes())
        _digests[sources] = digest.hexdigest()
    return _digests[sources]


STALE_TEMPORARY_S = 3600.0
"""A temporary file of ours older than this was left by a process that was killed mid-write."""


def _prune(where: Path, kind: str) -> None:
    """Keep the ``MAX_FILES`` designs of ``kind`` used last (a hit touches its file); remove our
    temporary files that a killed process left."""
    import time

    mine = []
    for path in where.glob(f"{kind}-*.json"):
        try:
            mine.append((path.stat().st_mtime, path))
        except OSError:  # removed by another process meanwhile
            continue
    mine.sort()
    for _, old in mine[:-MAX_FILES]:
        old.unlink(missing_ok=True)
    now = time.time()
    for path in where.glob(f".{kind}-*.tmp"):
        try:
            if now - path.stat().st_mtime > STALE_TEMPORARY_S:
                path.unlink(missing_ok=True)
        except OSError:
            continue


def _write(where: Path, name: str, content: dict, kind: str) -> None:
    """Write ``content`` to ``where / name`` atomically, then keep the newest ``MAX_FILES`` of the
    kind; any failure (a read-only disk, no space) only leaves the design uncached."""
    import json
    import tempfile

    temporary = None
    try:
        where.mkdir(mode=0o700, parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=where, prefix=f".{kind}-", suffix=".tmp")
        with os.fdopen(handle, "w", encoding="utf-8") as file:
            json.dump(content, file, separators=(",", ":"))
        os.replace(temporary, where / name)
        temporary = None
        _prune(where, kind)
    except Exception:  # noqa: BLE001 - a read-only disk, no space, a value JSON cannot hold: not stored
        pass
    finally:
        if temporary is not None:
            try:
                os.unlink(temporary)
            except OSError:
                pass
