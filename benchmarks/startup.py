"""How long `barsynth render` takes from the shell, and where the time goes (run by hand).

    python benchmarks/startup.py                      # everything, with this Python
    python benchmarks/startup.py --runs 9 --skip-cold
    python benchmarks/startup.py --python .venv/bin/python --models twang fd

Every figure is a whole process (`PYTHON -m barsynth ...`), timed from outside: wall time
around the child, its CPU time and peak memory from ``os.wait4`` (the same accounting as
``resource.getrusage(RUSAGE_CHILDREN)``, but per child); medians of ``--runs`` runs after
one warm-up run. It reports

(a) warm renders: ``render twang --duration 1`` and every model at ``--duration 0.5``,
    numba's on-disk cache filled by the warm-up run;
(b) the first render after an install: ``NUMBA_CACHE_DIR`` (the kernels use ``cache=True``)
    and ``BARSYNTH_CACHE_DIR`` (the program's stored designs) pointed at a new empty folder
    for each run, pinned to one core (``--no-pin``: not);
(c) where the time goes: the top imports of ``python -X importtime`` and a breakdown
    measured inside one process: Python's start, importing NumPy and numba, the CLI and
    the model, loading the cached kernels (the first call, minus a second call's pure
    render), rendering, writing the file, and the rest (the interpreter's exit);
(d) peak memory (max RSS) of each render.

``PYTHONDONTWRITEBYTECODE`` is dropped from the children's environment: an installed
package has its ``.pyc`` files (pip compiles them), and a run from a source tree should
too, else every run compiles barsynth's sources again. Give ``--python`` an installed
venv's Python to measure an install; with PYTHONPATH=src it measures the source tree.

Figures of 2026-11-25 (2-core AMD EPYC VM shared with other work: wall times swing by
+-30 % under load, CPU seconds are steadier; medians of 7 whole processes, 3 for first
renders; numba 0.68.1, NumPy 2.4.6, Python 3.11.7). "start" is commit cc8cf22 (before the
lighter start), "before" b129079 (after it), "after" the perf branch (measured in the same
hour as "before")::

                                       start                  before                 after
  warm render twang --duration 1       1.08 s wall, 1.28 CPU  0.48 s wall, 0.48 CPU  0.49 s wall, 0.49 CPU
  warm render --duration 0.5, CPU s:
      twang / farnell / banded         0.99 / 1.08 / 0.94     0.46 / 0.44 / 0.57     0.43 / 0.50 / 0.53
      allpass / fd                     1.13 / 1.54            0.80 / 1.28            0.74 / 0.56
  first render after install, CPU s (one core):
      twang                            8.9 (6.7 quieter)      7.3                    4.5
      farnell / banded / allpass       1.6 / 1.85 / 2.9       1.40 / 1.19 / 1.44     1.42 / 1.32 / 1.59
      fd                               5.95                   4.8                    2.6
  peak memory (max RSS), MiB, warm:
      twang / farnell / banded         158.8 / 155.9 / 157.6  147.5 / 144.3 / 145.8  146.6 / 144.3 / 145.8
      allpass / fd                     160.3 / 206.2          148.5 / 206.5          148.6 / 147.4
  peak memory, first render: twang 204.6 -> 185.0 MiB, fd 254.3 -> 180.5 MiB (before -> after)

  where a warm render twang --duration 1 goes (after; in-process medians, ms):
      Python start 11, import NumPy 60, import numba 144, barsynth.cli (mostly click) 26,
      numba.np.arraymath etc. (jitstart) 29, the model module 16, numba's CPU target
      (registries; cffi/pycparser, numpy.ma) + loading the cached kernel 124, rendering
      1 s 2.3, writing the WAV 6; the exit ~1 (skipped tear-down). Whole: 427 ms.
  taken away by the lighter start: numba's BLAS probe importing scipy.linalg (~150 ms,
  12 MiB), OpenBLAS starting a thread per core at NumPy's import (~50 ms on 2 cores), the
  interpreter's tear-down after numba (~200 ms).
  taken away by the perf branch: fd's scipy.signal (firwin, now NumPy: ~0.9 s CPU and
  ~50 MiB the first time) and scipy.linalg (eig_banded for the stability check, now
  np.linalg.eigvalsh) on every strike or bow render (the pluck still imports
  scipy.linalg for eigh); twang's 11 compiled functions, _render compiled twice
  (Literal[int](0) and int64), each with Python and C wrappers, callees three levels deep
  (numba optimises and emits a callee's code again in each caller's module): now one level,
  no wrappers, one _render; fd's exciters numba-inlined (inline="always": typed and
  lowered at every call site) and _friction compiled twice: now compiled once each.
  still there: twang's first render (4.5 s: numba types and lowers its ten functions,
  0.1-0.8 s each; design and process are the largest); allpass fits its all-pass chains
  (Levenberg-Marquardt in Python, ~0.1-0.27 s) on every render.

Twang's static kernel, figures of 2026-11-26 (same machine, load average about 2 from other
work; medians of 5 first renders, 7 warm ones). "before" is 16323dc, "after" the kern-tw
branch, run in the same minutes; ``PYTHONPATH`` must be absolute (the children run in a
temporary folder, so ``PYTHONPATH=src`` would measure the installed barsynth)::

                                       before                 after
  first render twang --duration 0.5    4.03 s wall, 4.00 CPU  2.12 s wall, 2.11 CPU
    (one core; range of 5)             (3.90..4.09 s wall)    (2.09..2.14 s wall)
  first render with vibrato_rate_hz=5  3.97 s wall, 3.71 CPU  3.87 s wall, 3.70 CPU   (3 runs by hand)
  warm render twang --duration 0.5     0.44 s wall, 0.44 CPU  0.45 s wall, 0.44 CPU
  peak memory, first render            184.5 MiB              171.4 MiB

  where the first render goes (after; CPU s in one process, numba's compile events,
  medians of 3): Python, NumPy, numba, the CLI and the model imported 0.25; numba's CPU
  target 0.14; compiling the static kernel 1.55: process 1.0 (about 0.5 of it LLVM
  optimising and emitting the module its callees are linked into), _render 0.23,
  _band_pair 0.19, _band 0.13; designing the note in Python 0.1 ms; rendering, writing
  and the exit about 0.05. Before, compiling took 3.25 s: process 0.82, design 0.57,
  _band_pair 0.34, _render 0.30, _follow 0.29, _control 0.28, _cull 0.20, _band 0.17,
  _end_frame 0.11-0.16, bandpass 0.06, the min/max/int overloads 0.08.
  taken away: a note that holds still (no vibrato, no slide, no change: every preset)
  runs the static kernel, compiled without the ramps, the design and the gain ramps
  (the voice designs the note once in Python, with the same doubles); the frame start
  and end written into process (as functions, even numba-inlined, they cost ~0.1 s
  more); min(), max(), int() and array slices written out of the compiled code. A note
  that moves, or a voice's first change, compiles the dynamic kernel as before (about
  3.5 s once per install; a few ms from numba's cache; TwangVoice.warm_up() does it
  ahead of time).

Figures of 2026-11-26 (the same VM, quieter: wall within 0.01 s of CPU for warm renders;
medians of 9 whole processes, 2 for first renders; the same versions). "before" is commit
16323dc, "after" the kern-ba branch (kernel records, the quick start, stored designs),
measured in the same ten minutes; allpass's warm render reads its design stored by the
warm-up run, its first render fits it (``BARSYNTH_CACHE_DIR`` empty too)::

                                       before                 after
  warm render twang --duration 1       0.43 s wall, 0.43 CPU  0.33 s wall, 0.33 CPU
  warm render --duration 0.5, wall s (CPU within 0.005 s):
      twang / farnell / banded         0.44 / 0.43 / 0.44     0.32 / 0.33 / 0.34
      allpass / fd                     0.59 / 0.50            0.34 / 0.40
  first render after install, CPU s (one core):
      twang / farnell / banded         3.90 / 1.16 / 1.34     3.68 / 1.12 / 1.26
      allpass / fd                     1.88 / 2.57            1.63 / 2.44
  peak memory (max RSS), MiB, warm: 144.6-149.0 -> 134.7-136.4 (every model)

  where a warm render goes (after; in-process medians, ms):
      twang --duration 1: Python start 11, import NumPy 67, barsynth.cli 11, import numba and
      numba.np.arraymath (jitstart.quick_start) 173, the model module 16, numba's runtime (NRT,
      compiled at every start: ~18) + loading the cached kernel 31, rendering 1 s 2.5, writing
      the WAV 8. Whole: 321 ms.
      fd --duration 0.5: as twang, the model module 23, NRT + kernel 26, rendering 0.5 s 80
      (the kernel itself: 4 scheme steps a sample over 100 nodes and a 129-tap decimation FIR;
      fd's design is 3 ms, and a second render in one process is the same 80 ms: nothing is
      designed twice, one eigvalsh). Whole: 406 ms.
      allpass --duration 0.5: as twang, the stored design 1.6 (fitting it: 109 ms CPU, was
      141), NRT + 4 kernels 31, rendering 2. Whole: 333 ms.
  taken away this round (all models unless said): numba's cache load refreshing its whole
  CPU target, every typing and lowering registry (~70 ms; a compile refreshes by itself:
  jitstart.lighten_cache_loads; with the imports below, ~11 MiB of peak memory); cffi.FFI() in numba's CFFI typing (pycparser and its
  lexer, ~20-40 ms); numba's import of SciPy's top level for a version check (~8 ms);
  numpy.ma, imported by numba.typeof for arrays (~10 ms: compiled_for types arguments
  itself; farnell's kernel now too, through compiled_for); allpass:
  its design fitted on every render (now stored on disk by the program, barsynth.designcache;
  the fit itself 23 % faster, bit for bit: the loss fits' Jacobians in one NumPy call) and
  start_ramp loaded as a kernel of its own (banded too).
  still there: import numba (~170 ms) and NumPy (~65 ms), about 80 % of a warm render;
  twang's first render (numba compiling its kernel).

The first-render figures are the kernels' compile times; they are the models' to reduce
(see the report of the "lighter start and install" work).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MODELS = ("twang", "farnell", "banded", "allpass", "fd")

BREAKDOWN = r"""
import os, sys, time
t0 = time.perf_counter()
try:  # the program (barsynth.entry) keeps OpenBLAS to one thread: so does this imitation of it
    import barsynth.entry
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
except ImportError:
    pass
try:  # and it keeps designs on disk
    from barsynth import designcache
    designcache.enable()
except ImportError:
    pass
marks = []
def mark(name):
    marks.append((name, time.perf_counter()))
import numpy; mark("import numpy")
import barsynth.cli as cli; mark("import barsynth.cli (click, ...)")
try:
    from barsynth.jitstart import quick_start
    quick_start(); mark("import numba, numba arraymath (jitstart.quick_start)")
except ImportError:
    try:
        from barsynth.jitstart import defer_blas_probe
        defer_blas_probe(); mark("import numba, numba arraymath, BLAS probe deferred (jitstart)")
    except ImportError:
        pass
model = cli._model(sys.argv[1]); mark("import the model (its kernels' dispatchers, physics, presets)")
resolved = cli._resolve(model, None, ())
seconds = float(sys.argv[2])
model.voice(resolved, sample_rate=48000.0, seed=0); mark("a first voice: its design (and any kernel it calls)")
t = time.perf_counter()
samples = model.render(resolved, duration_s=seconds, sample_rate=48000.0, seed=0)
first = time.perf_counter() - t
t = time.perf_counter()
model.render(resolved, duration_s=seconds, sample_rate=48000.0, seed=0)
pure = time.perf_counter() - t
marks.append(("numba CPU target + load (or compile) kernels", marks[-1][1] + first - pure))
marks.append((f"render {seconds:g} s (a second call)", marks[-1][1] + pure))
t = time.perf_counter()
from barsynth.audio_io import write_audio
write_audio(sys.argv[3], samples, 48000.0, fmt="WAV", subtype="PCM_24")
marks.append(("write the WAV", marks[-1][1] + time.perf_counter() - t))
prev = t0
for name, at in marks:
    print(f"{(at - prev) * 1000:.1f}\t{name}")
    prev = at
print(f"{(prev - t0) * 1000:.1f}\tTOTAL in-process")
print("loaded:", " ".join(m for m in ("scipy", "scipy.linalg", "matplotlib", "fastapi") if m in sys.modules))
"""


def _env(cache_dir: str | None = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    if cache_dir is not None:  # a fresh install: no kernel compiled, no design stored
        env["NUMBA_CACHE_DIR"] = cache_dir
        env["BARSYNTH_CACHE_DIR"] = os.path.join(cache_dir, "barsynth")
    return env


def run_once(cmd: list[str], *, env: dict[str, str], cwd: str, cpu: int | None = None) -> tuple[float, float, float]:
    """(wall s, cpu s, peak MiB) of one child process; raises if it fails."""
    preexec = (lambda: os.sched_setaffinity(0, {cpu})) if cpu is not None else None
    start = time.perf_counter()
    child = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             preexec_fn=preexec)  # noqa: PLW1509 - no threads here
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    err = child.stderr.read().decode(errors="replace")
    child.stderr.close()
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({child.returncode}): {err[-500:]}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def median_runs(cmd, *, runs, env, cwd, warmup=1, cpu=None):
    for _ in range(warmup):
        run_once(cmd, env=env, cwd=cwd, cpu=cpu)
    rows = [run_once(cmd, env=env, cwd=cwd, cpu=cpu) for _ in range(runs)]
    return tuple(statistics.median(r[i] for r in rows) for i in range(3)), rows


def show(label: str, figures: tuple[float, float, float], rows=None) -> None:
    spread = ""
    if rows and len(rows) > 1:
        walls = [r[0] for r in rows]
        spread = f"  (wall {min(walls):.3f}..{max(walls):.3f})"
    print(f"  {label:<44} wall {figures[0]:6.3f} s  cpu {figures[1]:6.3f} s  peak {figures[2]:6.1f} MiB{spread}")


def importtime_summary(python: str, cwd: str, top: int = 15) -> None:
    result = subprocess.run([python, "-X", "importtime", "-m", "barsynth", "render", "twang", "--duration", "1",
                             "-o", "x.wav"], env=_env(), cwd=cwd, capture_output=True, text=True, check=True)
    rows = []
    for line in result.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)", line)
        if m:
            rows.append((int(m.group(1)), int(m.group(2)), len(m.group(3)) // 2, m.group(4)))
    total = sum(r[0] for r in rows)
    print(f"  {len(rows)} modules imported, {total / 1000:.0f} ms in imports (self times summed; "
          "modules imported through importlib.import_module are not listed, their imports are)")
    print("  top-level imports by cumulative time:")
    for self_us, cum, _, name in sorted((r for r in rows if r[2] == 0), key=lambda r: -r[1])[:top]:
        print(f"    {cum / 1000:7.1f} ms  {name}")
    print("  largest self times:")
    for self_us, cum, _, name in sorted(rows, key=lambda r: -r[0])[:10]:
        print(f"    {self_us / 1000:7.1f} ms  {name}")


def breakdown(python: str, cwd: str, model: str, seconds: float, runs: int) -> None:
    results: list[list[tuple[float, str]]] = []
    loaded = ""
    for _ in range(runs + 1):
        out = subprocess.run([python, "-c", BREAKDOWN, model, str(seconds), str(Path(cwd) / "b.wav")], env=_env(),
                             cwd=cwd, capture_output=True, text=True, check=True).stdout
        lines = out.splitlines()
        loaded = lines[-1]
        results.append([(float(a), b) for a, b in (line.split("\t", 1) for line in lines[:-1])])
    results = results[1:]  # the first run filled caches
    start, _, _ = median_runs([python, "-c", "pass"], runs=runs, env=_env(), cwd=cwd)[0]
    whole = median_runs([python, "-m", "barsynth", "render", model, "--duration", f"{seconds:g}", "-o", "x.wav"],
                        runs=runs, env=_env(), cwd=cwd)[0][0]
    print(f"  {start * 1000:7.1f} ms  Python start (python -c pass, whole process)")
    names = [name for _, name in results[0]]
    medians = [statistics.median(r[i][0] for r in results) for i in range(len(names))]
    for value, name in zip(medians, names):
        print(f"  {value:7.1f} ms  {name}")
    rest = whole * 1000 - start * 1000 - medians[-1]
    print(f"  {rest:7.1f} ms  the rest: the whole `barsynth render` ({whole * 1000:.0f} ms) minus the above "
          "(argument parsing, checks, the interpreter's exit)")
    print(f"  {loaded}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--python", default=sys.executable, help="the Python that has barsynth (default: this one)")
    parser.add_argument("--runs", type=int, default=7, help="runs per figure (median)")
    parser.add_argument("--cold-runs", type=int, default=2, help="runs per model for the first render")
    parser.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    parser.add_argument("--skip-cold", action="store_true", help="skip (b), the first render after install")
    parser.add_argument("--no-pin", action="store_true", help="do not pin (b) to one core")
    parser.add_argument("--breakdown", nargs="+", default=["twang"], choices=MODELS, metavar="MODEL",
                        help="models whose warm render (c) breaks down (default: twang, at --duration 1; "
                        "others at 0.5)")
    args = parser.parse_args()
    python = args.python
    work = tempfile.mkdtemp(prefix="barsynth-startup-")
    probe = ("import barsynth, numba, numpy, sys; print(barsynth.__file__, "
             "'numba', numba.__version__, 'numpy', numpy.__version__, sys.version.split()[0])")
    version = subprocess.run([python, "-c", probe],
                             env=_env(), capture_output=True, text=True, check=True).stdout.strip()
    print(f"barsynth start-up, {time.strftime('%Y-%m-%d')}, {os.cpu_count()} cores; {version}")

    print("\n(a, d) warm renders (numba cache filled by the warm-up run), whole processes:")
    base = [python, "-m", "barsynth", "render"]
    figures, rows = median_runs(base + ["twang", "--duration", "1", "-o", "x.wav"], runs=args.runs, env=_env(), cwd=work)
    show("render twang --duration 1", figures, rows)
    for model in args.models:
        figures, rows = median_runs(base + [model, "--duration", "0.5", "-o", "x.wav"], runs=args.runs, env=_env(),
                                    cwd=work)
        show(f"render {model} --duration 0.5", figures, rows)
    import resource

    print(f"  largest child max RSS (getrusage RUSAGE_CHILDREN): "
          f"{resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024:.1f} MiB")

    if not args.skip_cold:
        cpu = None if args.no_pin else min(os.sched_getaffinity(0))
        where = "unpinned" if cpu is None else f"pinned to core {cpu}"
        print(f"\n(b) first render after install (NUMBA_CACHE_DIR empty for each run, {where}):")
        for model in args.models:
            rows = []
            for _ in range(args.cold_runs):
                with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
                    rows.append(run_once(base + [model, "--duration", "0.5", "-o", "x.wav"], env=_env(cache), cwd=work,
                                         cpu=cpu))
            show(f"first render {model} --duration 0.5", tuple(statistics.median(r[i] for r in rows)
                                                                 for i in range(3)), rows)

    print("\n(c) where the time goes: python -X importtime -m barsynth render twang --duration 1")
    importtime_summary(python, work)
    for model in args.breakdown:
        seconds = 1.0 if model == "twang" else 0.5
        print(f"\n(c) breakdown of a warm render {model} --duration {seconds:g} (medians; in one process unless said):")
        breakdown(python, work, model, seconds, args.runs)


if __name__ == "__main__":
    main()
