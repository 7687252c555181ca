"""The studio's heavy work (WAV renders, pictures, mode tables, fits of uploads) in worker processes, bounded.

Renders and pictures hold the interpreter for much of their time (designs, analysis,
JSON), so in the server's own process they would hold up the live streams, whose blocks
must go out every few milliseconds. They run instead in ``MAX_RENDERS`` worker
processes at a lower scheduling priority (nice 10), so a saturated studio slows its
downloads and pictures, not its sound. At most ``MAX_RENDERS`` jobs run at once; the
rest wait up to ``RENDER_WAIT_S`` for a turn and are then refused with 503. A job whose
client disconnects is stopped (its worker process is killed and replaced), and so is one
that runs longer than ``JOB_TIME_LIMIT_S`` (the client gets a 503 and one line).

The workers take plain data (a model's name and a dict of values, already checked by
the server; an upload's bytes, which only a worker reads) and give back bytes ready to send,
so nothing but the data and the answer crosses between the processes. Reading an upload in a
worker also keeps libsndfile's parsing of untrusted bytes out of the server's own process.
"""

from __future__ import annotations

import asyncio
import json
import multiprocessing
import os
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable

from ..audio_io import wav_bytes
from ..webserver import Refused

MAX_RENDERS = 2
RENDER_WAIT_S = 10.0
JOB_TIME_LIMIT_S = 60.0
DISCONNECT_POLL_S = 0.25
WORKER_NICENESS = 10


def _start_worker(program: bool = False, cache: bool = False) -> None:
    """In each worker: a lower priority than the server, and an end with the server's process
    (a watcher thread sees the parent gone, even after a SIGKILL, within a second); as the
    server's process is, the program's (numba's quick start) and with the design cache on."""
    from .. import designcache, jitstart

    jitstart.for_the_program(program)
    designcache.enable(cache)
    try:
        os.nice(WORKER_NICENESS)
    except OSError:  # not allowed here: run at the same priority
        pass
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(0)

    threading.Thread(target=watch, name="barsynth-parent-watch", daemon=True).start()


def render_wav(model_name: str, values: dict, duration_s: float, sample_rate: float) -> bytes:
    """One strike of the settings, offline, peak at -1 dBFS, as a WAV file."""
    from ..models import get_model

    model = get_model(model_name)
    return wav_bytes(model.render(model.table.resolve(values), duration_s=duration_s, sample_rate=sample_rate),
                     sample_rate)


def picture_json(model_name: str, values: dict, sample_rate: float, duration_s: float, width: int) -> bytes:
    """The page's pictures of the settings (:func:`barsynth.studio.pictures.picture`) as JSON."""
    from ..models import get_model
    from .pictures import picture

    model = get_model(model_name)
    found = picture(model, model.table.resolve(values), sample_rate=sample_rate, duration_s=duration_s, width=width)
    return json.dumps(found, allow_nan=False, separators=(",", ":")).encode()


def modes_json(model_name: str, values: dict, sample_rate: float) -> bytes:
    """The mode table of the settings as the JSON ``/api/describe`` answers."""
    from ..models import get_model
    from .pictures import mode_rows

    model = get_model(model_name)
    rows = mode_rows(model, model.table.resolve(values), sample_rate)
    return json.dumps({"model": model.name, "sample_rate": sample_rate, "modes": rows}, allow_nan=False).encode()


def fit_json(data: bytes, name: str, model: str, max_modes: int, nominal_hz: float | None, width: int) -> bytes:
    """An uploaded recording fitted (:func:`barsynth.studio.fitted.fit_answer`) as the JSON
    ``/api/fit`` answers."""
    from .fitted import fit_answer

    found = fit_answer(data, name, model, max_modes, nominal_hz, width)
    return json.dumps(found, allow_nan=False, separators=(",", ":")).encode()


class Workers:
    """A bounded pool of worker processes (or threads, with ``processes=False``, for tests
    that count what runs). Made on first use, in the event loop that uses it.

    Each process is an executor of its own, so the one running a job can be stopped: a job
    whose client has gone (``gone()`` says so, checked every ``DISCONNECT_POLL_S``) or that
    runs over ``time_limit_s`` (default ``JOB_TIME_LIMIT_S``) has its process killed, and a
    new process is started in its place at once. Threads cannot be stopped; their job is
    abandoned (its turn is freed) and runs to its end.
    """

    def __init__(self, *, count: int = MAX_RENDERS, processes: bool = True, time_limit_s: float | None = None):
        self.count = count
        self.processes = processes
        self.time_limit_s = time_limit_s
        self._pool: Any = None  # the thread pool
        self._idle: list[Any] = []  # process executors waiting for a job
        self._busy: set[Any] = set()
        self._turns: asyncio.Semaphore | None = None
        self._closed = False

    def _new_process(self) -> Any:
        from .. import designcache, jitstart

        executor = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=_start_worker,
                                       initargs=(jitstart.is_the_program(), designcache.enabled()))
        executor.submit(os.getpid)  # start the process now, not when the next job comes
        return executor

    def _take(self) -> Any:
        if not self.processes:
            if self._pool is None:
                from concurrent.futures import ThreadPoolExecutor

                self._pool = ThreadPoolExecutor(self.count, thread_name_prefix="barsynth-studio")
            return self._pool
        executor = self._idle.pop() if self._idle else self._new_process()
        self._busy.add(executor)
        return executor

    def _give_back(self, executor: Any, *, healthy: bool) -> None:
        if not self.processes:
            return
        self._busy.discard(executor)
        if healthy and not self._closed:
            self._idle.append(executor)
        else:
            _kill(executor)
            if not self._closed:
                try:
                    self._idle.append(self._new_process())
                except OSError:  # out of processes or files now: the next job starts one when it can
                    pass

    def processes_running(self) -> list[int]:
        """The process ids of the workers (for tests and benchmarks)."""
        return [p.pid for e in (*self._idle, *self._busy) for p in (getattr(e, "_processes", None) or {}).values()
                if p.is_alive()]

    async def _turn(self, gone: Callable[[], Any] | None) -> None:
        """Wait up to ``RENDER_WAIT_S`` for a free worker (else 503), or until the client has gone."""
        from . import work as this

        if self._turns is None:
            self._turns = asyncio.Semaphore(self.count)
        loop = asyncio.get_running_loop()
        until = loop.time() + this.RENDER_WAIT_S
        acquire = asyncio.ensure_future(self._turns.acquire())
        try:
            while not acquire.done():
                await asyncio.wait({acquire}, timeout=min(this.DISCONNECT_POLL_S, max(0.0, until - loop.time())))
                if acquire.done():
                    break
                if gone is not None and await gone():
                    raise Refused(400, "the client went away before its job started")
                if loop.time() >= until:
                    raise Refused(503, f"the studio is busy ({self.count} renders at once); try again")
        except BaseException:
            acquire.cancel()
            if acquire.done() and not acquire.cancelled():
                self._turns.release()
            raise

    async def run(self, work: Callable[..., Any], *args: Any, gone: Callable[[], Any] | None = None) -> Any:
        """``work(*args)`` in a worker, when one is free within ``RENDER_WAIT_S``; else 503. Stopped
        when ``gone()`` (an async callable, e.g. ``request.is_disconnected``) becomes true or after the
        time limit (503)."""
        from . import work as this

        limit = self.time_limit_s if self.time_limit_s is not None else this.JOB_TIME_LIMIT_S
        await self._turn(gone)
        assert self._turns is not None
        loop = asyncio.get_running_loop()
        executor, healthy = None, False
        try:
            try:
                executor = self._take()
            except OSError as exc:  # out of processes or file descriptors (a flood of clients)
                raise Refused(503, f"the studio cannot start a worker now ({exc.strerror or exc}); "
                                   "try again") from None
            job = loop.run_in_executor(executor, work, *args)
            job.add_done_callback(_retrieve)  # a stopped job's error is nobody's to log
            started = loop.time()
            while True:
                done, _ = await asyncio.wait({job}, timeout=this.DISCONNECT_POLL_S)
                if done:
                    result = job.result()
                    healthy = True
                    return result
                if loop.time() - started > limit:
                    raise Refused(503, f"the job ran over the studio's time limit of {limit:g} s and was stopped; "
                                       "ask for less (shorter, a lower sample rate, fewer points)")
                if gone is not None and await gone():
                    raise Refused(400, "the client went away; its job was stopped")
        except BrokenProcessPool:  # a worker died (killed, out of memory): a new one takes its place
            raise Refused(503, "a studio worker stopped while rendering; try again") from None
        except Exception:  # the job's own error (a bad value): the worker is fine
            healthy = not isinstance(sys.exc_info()[1], Refused)
            raise
        finally:
            try:
                if executor is not None:
                    self._give_back(executor, healthy=healthy)
            finally:
                self._turns.release()  # whatever happened, the turn comes back

    def close(self) -> None:
        """Stop the workers now, renders under way included (the server is stopping)."""
        self._closed = True
        for executor in (*self._idle, *self._busy):
            _kill(executor)
        self._idle, self._busy = [], set()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None


def _kill(executor: Any) -> None:
    """Stop a one-process executor at once, its job under way included."""
    processes = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.kill()


def _retrieve(job: Any) -> None:
    if not job.cancelled():
        job.exception()
