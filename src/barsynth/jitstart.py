"""A quicker start for numba's CPU target: no SciPy import just to ask whether BLAS exists.

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

:func:`compiled_for` is the other cost of a kernel call, paid on every call: numba's
dispatcher types each argument, and it types a NamedTuple record in Python (about 1 us a
record), where an array or a number takes a few tens of ns in C. A voice whose kernel takes
records resolves the compiled overload once and calls its entry point.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["compiled_for", "defer_blas_probe"]


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
    from numba import typeof

    signature = tuple(typeof(arg) for arg in args)
    dispatcher.compile(signature)
    return dispatcher.overloads[signature].entry_point
