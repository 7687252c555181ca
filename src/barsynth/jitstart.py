"""A quicker start for numba's CPU target: no SciPy or CFFI imports that barsynth's kernels do not need.

The first call of any numba kernel in a process (even one loaded from numba's on-disk
cache) loads numba's CPU target, and with it ``numba.np.arraymath``, whose import runs
``_check_blas()``: ``import scipy.linalg.cython_blas``, that is the whole of
``scipy.linalg`` (about 150 ms and 15 MiB here), only to learn whether ``np.dot`` inside
``np.correlate`` / ``np.convolve`` may use BLAS. barsynth's kernels use no BLAS at all,
and SciPy is one of barsynth's own requirements, so the answer is known: yes.

:func:`defer_blas_probe` imports ``numba.np.arraymath`` itself with that probe answered
"yes" without importing anything; numba's linear algebra keeps its own check
(``numba.np.linalg.ensure_blas``, restored at once), so a kernel that does use BLAS
still imports SciPy and checks its integer width when it is compiled. If numba's
internals are not as expected (another version), nothing is changed.

Two more imports are made at numba's start for features barsynth does not use: ``import
numba`` imports SciPy's top level (about 8 ms) only to check that its version is at least
1.0 (barsynth requires 1.11), and numba's CPU target builds a ``cffi.FFI()`` (importing
pycparser and building its lexer: about 40 ms here) to type CFFI functions passed to a
kernel. :func:`quick_start` (the program calls it before its first kernel, through
:func:`program_start`) imports numba
with that version check skipped and loads numba's CFFI typing without CFFI: in that process
numba does not type CFFI functions (barsynth passes none; ``import cffi`` itself still works).
A library user's process is left alone unless it calls :func:`quick_start`.

The largest part of loading a cached kernel was numba refreshing its whole CPU target first
(every typing and lowering registry, about 70 ms), which only compiling needs and which a
compile does by itself: :func:`lighten_cache_loads`.

:func:`compiled_for` is the other cost of a kernel call, paid on every call: numba's
dispatcher types each argument, and it types a NamedTuple record in Python (about 1 us a
record), where an array or a number takes a few tens of ns in C. A voice whose kernel takes
records resolves the compiled overload once and calls its entry point. It types the
arguments itself (:func:`argument_type`, numba's types without numba's test for a masked
array, which imports ``numpy.ma``: about 10 ms of a render that needs it for nothing else).
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["argument_type", "compiled_for", "defer_blas_probe", "for_the_program", "is_the_program",
           "lighten_cache_loads", "program_start", "quick_start"]

_PROGRAM = {"on": False}


def for_the_program(on: bool = True) -> None:
    """Say that this process is the ``barsynth`` program (:mod:`barsynth.entry`, the studio's
    workers), whose first kernel :func:`program_start` then prepares; a library user's process,
    or a test calling :func:`barsynth.cli.main`, is left alone."""
    _PROGRAM["on"] = bool(on)


def is_the_program() -> bool:
    """Whether :func:`for_the_program` was said in this process."""
    return _PROGRAM["on"]


def program_start() -> None:
    """:func:`quick_start` if this process is the program (:func:`for_the_program`); else nothing."""
    if _PROGRAM["on"]:
        quick_start()


def quick_start() -> None:
    """Before the program's first kernel: numba imported without its SciPy version check,
    its BLAS probe deferred (:func:`defer_blas_probe`), its CFFI typing loaded without CFFI,
    and its cache loads lightened (:func:`lighten_cache_loads`). Each step that comes too late
    (the module already imported) or finds numba other than expected is skipped."""
    _without("scipy", "numba")
    defer_blas_probe()
    _without("cffi", "numba.core.typing.cffi_utils")
    lighten_cache_loads()


LOAD_OVERLOAD_NAMES = ("refresh", "_guard_against_spurious_io_errors", "_load_overload")
"""The names numba's own ``Cache.load_overload`` uses, exactly: any other code there is left alone."""


def lighten_cache_loads() -> bool:
    """Load numba's cached kernels without refreshing its CPU target first; True if done.

    numba's ``Cache.load_overload`` refreshes the target (imports and installs every typing
    and lowering registry: about 70 ms) before it reads a cached kernel, though running
    compiled code needs only numba's runtime (NRT: its C symbols and atomic functions); a
    compile refreshes the target itself (``CompilerBase.__init__``) and so does numba's
    lowering when it meets a function it does not know. Here a load initialises the NRT
    only. Not done (False) if numba's code is not as expected."""
    try:
        from numba.core import caching, compiler
        from numba.core.runtime import nrt
    except ImportError:  # pragma: no cover - numba is a requirement
        return False
    real = getattr(caching.Cache, "load_overload", None)
    load_code = getattr(real, "__code__", None)
    compile_code = getattr(getattr(compiler.CompilerBase, "__init__", None), "__code__", None)
    # Only numba's load_overload as it is known (numba 0.59-0.68): refresh, the guard, the load
    # and nothing else; a numba that does more there keeps its own.
    if (getattr(real, "lightened", False) or load_code is None or compile_code is None
            or tuple(load_code.co_names) != LOAD_OVERLOAD_NAMES
            or "refresh" not in compile_code.co_names or not callable(getattr(nrt.rtsys, "initialize", None))):
        return False

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        nrt.rtsys.initialize(target_context)  # what loaded code needs of the target
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)

    load_overload.lightened = True  # type: ignore[attr-defined]
    load_overload.__doc__ = real.__doc__
    caching.Cache.load_overload = load_overload
    return True


def _without(blocked: str, module: str) -> bool:
    """Import ``module`` while ``import blocked`` raises ImportError (then ``blocked`` imports as
    usual again); True if it was done, False if either was imported already."""
    if module in sys.modules or blocked in sys.modules:
        return False
    sys.modules[blocked] = None  # type: ignore[assignment] # import machinery: "not available"
    try:
        __import__(module)
    except Exception:  # noqa: BLE001 # pragma: no cover - another numba: it will load as usual later
        return False
    finally:
        if sys.modules.get(blocked, 0) is None:
            del sys.modules[blocked]
    return True


def defer_blas_probe() -> bool:
    """Load numba's ``arraymath`` without importing SciPy; True if the probe was deferred.

    Call it before the first numba kernel runs (afterwards it is too late, and harmless).
    """
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return False
    try:
        from numba.np import linalg
    except ImportError:  # pragma: no cover - numba is a requirement
        return False
    real = getattr(linalg, "ensure_blas", None)
    if real is None or not callable(real):  # pragma: no cover - another numba
        return False

    def blas_is_there() -> None:  # SciPy is installed with barsynth: the answer is yes
        return None

    linalg.ensure_blas = blas_is_there
    try:
        from numba.np import arraymath
    except Exception:  # noqa: BLE001 # pragma: no cover - another numba; it will load as usual later
        return False
    finally:
        linalg.ensure_blas = real
    # later calls through arraymath's own name do the real check (and import SciPy then)
    if getattr(arraymath, "ensure_blas", None) is blas_is_there:
        arraymath.ensure_blas = real
    return True


def compiled_for(dispatcher: Any, *args: Any) -> Any:
    """``dispatcher``'s compiled function for the types of ``args`` (compiled, or loaded from
    numba's cache, now): its entry point, called as ``run(*args)`` without the dispatcher.

    The dispatcher would type every argument at every call; the entry point only unboxes
    them (numba's ``Dispatcher.overloads``, keyed by the argument types). It checks no
    types: call it only with arguments of the very types given here (the voice's own
    records, an ``out`` as :meth:`~barsynth.models.base.Voice._render` gets it: a writeable
    C-contiguous float64 array), and resolve again when a record's type may change.
    """
    signature = tuple(argument_type(arg) for arg in args)
    dispatcher.compile(signature)
    return dispatcher.overloads[signature].entry_point


def argument_type(value: Any) -> Any:
    """numba's type of ``value`` as a kernel argument (what ``numba.typeof`` gives): a plain
    ndarray, and a tuple or NamedTuple (of them), are typed here as numba types them, only
    without its test for a NumPy masked array (``numpy.ma``, imported for that test alone:
    about 10 ms; a plain ndarray is none); anything else by ``numba.typeof``."""
    import numpy as np
    from numba import typeof, types
    from numba.np.numpy_support import from_dtype, map_layout

    if type(value) is np.ndarray:
        return types.Array(from_dtype(value.dtype), value.ndim, map_layout(value), readonly=not value.flags.writeable)
    if isinstance(value, tuple):
        return types.BaseTuple.from_types([argument_type(item) for item in value], type(value))
    return typeof(value)
