"""The studio's heavy work (WAV renders, pictures, mode tables) in worker processes, bounded.

Renders and pictures hold the interpreter for much of their time (designs, analysis,
JSON), so in the server's own process they would hold up the live streams, whose blocks
must go out every few milliseconds. They run instead in ``MAX_RENDERS`` worker
processes at a lower scheduling priority (nice 10), so a saturated studio slows its
downloads and pictures, not its sound. At most ``MAX_RENDERS`` jobs run at once; the
rest wait up to ``RENDER_WAIT_S`` for a turn and are then refused with 503.

The workers take plain data (a model's name and a dict of values, already checked by
the server) and give back bytes ready to send, so nothing but small messages crosses
between the processes.
"""

from __future__ import annotations

import asyncio
import json
import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable

from ..webserver import Refused, wav_bytes

MAX_RENDERS = 2
RENDER_WAIT_S = 10.0
WORKER_NICENESS = 10


def _start_worker() -> None:
    """In each worker: a lower priority than the server, and an end with the server's process
    (a watcher thread sees the parent gone, even after a SIGKILL, within a second)."""
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


class Workers:
    """A bounded pool of worker processes (or threads, with ``processes=False``, for tests
    that count what runs). Made on first use, in the event loop that uses it."""

    def __init__(self, *, count: int = MAX_RENDERS, processes: bool = True):
        self.count = count
        self.processes = processes
        self._pool: Any = None
        self._turns: asyncio.Semaphore | None = None

    def _executor(self) -> Any:
        if self._pool is None:
            if self.processes:
                self._pool = ProcessPoolExecutor(self.count, mp_context=multiprocessing.get_context("spawn"),
                                                 initializer=_start_worker)
            else:
                from concurrent.futures import ThreadPoolExecutor

                self._pool = ThreadPoolExecutor(self.count, thread_name_prefix="barsynth-studio")
        return self._pool

    async def run(self, work: Callable[..., Any], *args: Any) -> Any:
        """``work(*args)`` in a worker, when one is free within ``RENDER_WAIT_S``; else 503."""
        from . import work as this

        if self._turns is None:
            self._turns = asyncio.Semaphore(self.count)
        try:
            await asyncio.wait_for(self._turns.acquire(), this.RENDER_WAIT_S)
        except TimeoutError:
            raise Refused(503, f"the studio is busy ({self.count} renders at once); try again") from None
        try:
            return await asyncio.get_running_loop().run_in_executor(self._executor(), work, *args)
        except BrokenProcessPool:  # a worker died (killed, out of memory): a new pool next time
            self._pool = None
            raise Refused(503, "a studio worker stopped while rendering; try again") from None
        finally:
            self._turns.release()

    def close(self) -> None:
        """Stop the workers now, renders under way included (the server is stopping)."""
        if self._pool is not None:
            processes = list(getattr(self._pool, "_processes", {}).values()) if self.processes else []
            self._pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()
            self._pool = None
