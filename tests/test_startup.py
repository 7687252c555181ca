"""A plain render starts light: no SciPy linear algebra, no matplotlib, no web stack, no CFFI
parser; numba's BLAS probe is deferred without breaking kernels that do use BLAS; SciPy and
CFFI still import afterwards; the program's quick exit keeps its output and exit status.
(benchmarks/startup.py measures the times.)"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

HEAVY = ("scipy.linalg", "scipy.signal", "scipy.optimize", "matplotlib", "fastapi", "uvicorn", "websockets",
         "pycparser")


def _imported(stderr: str) -> set[str]:
    """Module names from ``python -X importtime`` output."""
    return {line.rsplit("|", 1)[-1].strip() for line in stderr.splitlines() if line.startswith("import time:")}


@pytest.mark.parametrize("model", ["twang", "fd"])
def test_a_render_imports_no_scipy_linalg_or_signal_matplotlib_or_web_stack(tmp_path, model):
    result = subprocess.run([sys.executable, "-X", "importtime", "-m", "barsynth", "render", model,
                             "--duration", "0.2", "-o", "x.wav"], capture_output=True, text=True, cwd=tmp_path,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout == "wrote x.wav (0.2 s at 48000 Hz)\n"  # flushed before the quick exit
    imported = _imported(result.stderr)
    assert f"barsynth.models.{model}.kernel" in imported and "numba" in imported
    assert not imported & set(HEAVY), sorted(imported & set(HEAVY))


def test_importing_the_cli_loads_neither_numpy_nor_numba():
    code = "import sys, barsynth.cli; print(sorted({'numpy', 'numba', 'scipy'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_program_keeps_its_exit_status_and_its_one_line_error(tmp_path):
    result = subprocess.run([sys.executable, "-m", "barsynth", "render", "twang", "--set", "q=-1", "-o", "x.wav"],
                            capture_output=True, text=True, cwd=tmp_path, timeout=300, check=False)
    assert result.returncode == 2
    assert result.stdout == ""
    assert len(result.stderr.splitlines()) == 1 and result.stderr.startswith("barsynth: error: parameter q")
    assert list(tmp_path.iterdir()) == []


def test_the_deferred_blas_probe_leaves_blas_kernels_working():
    code = """
import sys
import numpy as np
from numba import njit
from barsynth.jitstart import defer_blas_probe
assert defer_blas_probe()
assert 'scipy.linalg' not in sys.modules
plain = njit(lambda x: x + 1.0)
assert plain(1.0) == 2.0
assert 'scipy.linalg' not in sys.modules
dot = njit(lambda a, b: np.dot(a, b))
a = np.arange(3.0)
assert dot(a, a) == 5.0
assert 'scipy.linalg' in sys.modules  # the real check ran when BLAS was needed
conv = njit(lambda a, b: np.convolve(a, b))
assert np.allclose(conv(a, a), np.convolve(a, a))
assert not defer_blas_probe()  # once only
print('ok')
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert result.stdout.strip() == "ok", result.stderr[-2000:]


def test_the_quick_start_leaves_scipy_and_cffi_importable_and_kernels_working():
    code = """
import sys
from barsynth.jitstart import quick_start
quick_start()
assert 'numba' in sys.modules and 'numba.np.arraymath' in sys.modules
assert not {'scipy', 'cffi', 'pycparser'} & set(sys.modules), sorted({'scipy', 'cffi', 'pycparser'} & set(sys.modules))
from numba import njit
assert njit(lambda x: x + 1.0)(1.0) == 2.0
import scipy, cffi
assert cffi.FFI().sizeof('int') == 4
from numba.core.typing import cffi_utils
assert not cffi_utils.SUPPORTED  # numba types no CFFI function in this process
print('ok')
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert result.stdout.strip() == "ok", result.stderr[-2000:]


def test_kernel_arguments_are_typed_as_numba_types_them():
    """jitstart.argument_type (compiled_for's, without numba's numpy.ma import) gives
    numba.typeof's type for every array and record the voices pass, and for odd arrays."""
    from typing import NamedTuple

    import numpy as np
    from numba import typeof

    from barsynth.jitstart import argument_type
    from barsynth.models import get_model, model_names

    class Mixed(NamedTuple):
        a: np.ndarray
        n: int
        x: float
        flag: bool

    frozen = np.zeros(3)
    frozen.flags.writeable = False
    values = [frozen, np.zeros((3, 4), order="F"), np.zeros((4, 4))[:, ::2], np.zeros((2, 2), dtype=[("v", "f8")]),
              np.zeros(3, dtype=np.int32), np.zeros(()), Mixed(np.zeros(2), 1, 2.0, True), (np.zeros(2), np.ones(2)),
              (1.0, np.zeros(1, dtype=np.int64)), 3, 0.5, np.float64(0.5), True]
    for name in model_names():
        voice = get_model(name).voice(sample_rate=48000.0, seed=0, max_block=64)
        voice.trigger()
        voice.process(64)
        for owner in [voice, *vars(voice).values()]:
            for value in getattr(owner, "__dict__", {}).values():
                if type(value) is np.ndarray or (isinstance(value, tuple) and hasattr(value, "_fields")):
                    values.append(value)
    assert len(values) > 30
    typed = 0
    for value in values:
        try:
            expected = typeof(value)
        except ValueError:  # a record that is no kernel's argument (numba cannot type a member)
            with pytest.raises(ValueError):
                argument_type(value)
            continue
        assert argument_type(value) == expected, value
        typed += 1
    assert typed > 30


CACHED_MODULE = '''
import math
import numpy as np
from numba import njit


@njit(cache=True)
def ring(out, gain):
    for i in range(out.size):
        out[i] = gain * math.sin(0.1 * i)
    return out.sum()
'''

LIGHT_LOAD = """
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from barsynth.jitstart import quick_start
quick_start()
from numba.core.registry import cpu_target
from cached_kernel import ring
out = np.empty(50)
total = ring(out, 2.0)
assert ring.stats.cache_hits and not ring.stats.cache_misses, ring.stats
assert 'numba.typed.typeddict' not in sys.modules  # the registries were not loaded for the load
assert abs(total - 2.0 * sum(np.sin(0.1 * np.arange(50)))) < 1e-9
from numba import njit
fresh = njit(lambda n: np.cumsum(np.arange(n) * 0.5)[-1] + math.gamma(4.0) + len([k for k in range(n)]))
import math
assert fresh(5) == 5.0 + 6.0 + 5  # a compile in the same process refreshes the target itself
assert ring(np.empty(3), 0.0) == 0.0
print('ok')
"""


def test_a_kernel_loads_from_numbas_cache_without_the_registries_and_compiling_still_works(tmp_path):
    """quick_start lightens numba's cache loads (no target refresh): a cached kernel loads and
    runs, and a new function compiled afterwards in the same process still compiles."""
    (tmp_path / "cached_kernel.py").write_text(CACHED_MODULE)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    fill = subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {str(tmp_path)!r}); "
                           "import numpy as np; from cached_kernel import ring; ring(np.empty(3), 1.0)"],
                          env=env, capture_output=True, text=True, timeout=300, check=False)
    assert fill.returncode == 0, fill.stderr[-2000:]
    result = subprocess.run([sys.executable, "-c", LIGHT_LOAD, str(tmp_path)], env=env, capture_output=True,
                            text=True, timeout=300, check=False)
    assert result.stdout.strip() == "ok", result.stderr[-2000:]
