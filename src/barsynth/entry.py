"""The ``barsynth`` program (console script and ``python -m barsynth``): :func:`barsynth.cli.main`
with a quicker start and a quicker end.

* OpenBLAS (NumPy's and SciPy's) starts one thread per core when it loads; barsynth's
  commands do no linear algebra big enough to gain from them, so unless the user set
  ``OPENBLAS_NUM_THREADS`` it is set to 1 before NumPy loads (tens of ms, more on big
  machines).
* Designs that take long to fit (the all-pass waveguide's) are kept on disk between runs
  (:mod:`barsynth.designcache`: ``~/.cache/barsynth``, or ``$BARSYNTH_CACHE_DIR``; empty: off).
* numba starts without imports its kernels do not need and loads cached kernels without
  refreshing its whole CPU target (:mod:`barsynth.jitstart`, before the first kernel).
* When a command that loaded numba has finished (its files written and closed), the
  interpreter's tear-down (a garbage collection over numba's many objects and the
  clearing of some 600 modules, about 0.2 s after a render) is skipped: the ``atexit``
  functions run, Python's and C's output streams are flushed, and the process ends with
  the command's exit status. A command that leaves another thread running, or exits with
  a message instead of a status, ends the usual way.

Only the program does this: :func:`barsynth.cli.main` itself (as tests and other programs
call it) exits as usual.
"""

from __future__ import annotations

import os
import sys

__all__ = ["run"]


def run() -> None:
    """Run the command line and end the process with its exit status."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from . import designcache, jitstart
    from .cli import main

    designcache.enable()
    jitstart.for_the_program()

    try:
        main()
        code: object = 0
    except SystemExit as exc:
        code = exc.code
    _exit(code)


def _exit(code: object) -> None:
    import atexit
    import threading

    if code is None:
        code = 0
    # the tear-down is slow only once numba is loaded (and ctypes with it, for C's fflush)
    if (not isinstance(code, int) or threading.active_count() > 1 or "numba" not in sys.modules
            or "ctypes" not in sys.modules):
        sys.exit(code)
    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        import ctypes

        ctypes.CDLL(None).fflush(None)  # C's own buffered streams too (e.g. -X importtime's report)
    except Exception:  # noqa: BLE001 - e.g. a full disk: let the usual exit report it
        sys.exit(code)
    os._exit(code)
