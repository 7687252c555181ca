r"""A batch's items rendered on a Dask cluster (spec 11.3): ``barsynth batch --dask-scheduler ADDRESS``.

The client connects to a running ``dask.distributed`` scheduler and submits the items in
chunks, exactly as the local pool gets them (:func:`barsynth.batch.run.render_chunk`). Each
worker renders its chunk, writes the audio files itself (atomically, as locally) and sends
back the rows only (hash and features, never the audio); the manifest is written by the client
alone. The output folder must therefore be **shared**: the client and every worker see it at
the same absolute path (NFS or another shared file system); the client checks this before the
first item and refuses with one line otherwise. Every worker needs the same barsynth version.

Workers started by ``dask worker`` (with its nanny, the default) get one BLAS / OpenMP thread
per process from Dask's ``distributed.nanny.pre-spawn-environ``, as the local pool's processes
do: the files and the features are then byte-identical to a local run of the same spec.

Dask's defaults cost a worker about 30 % of the local pool's speed: its statistical profiler
samples the rendering thread every 10 ms, and the nanny's ``MALLOC_TRIM_THRESHOLD_=65536`` makes
glibc map and unmap every large NumPy array afresh. Workers dedicated to batches are best
started with :data:`WORKER_ENVIRONMENT` in their environment (the benchmark
``benchmarks/bench_batch.py`` measures both)::

    env DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False \
        DASK_DISTRIBUTED__NANNY__PRE_SPAWN_ENVIRON="{'MALLOC_TRIM_THRESHOLD_': 134217728, \
                                                    'MALLOC_MMAP_THRESHOLD_': 33554432}" \
        dask worker tcp://10.0.0.5:8786 --nthreads 1 --nworkers 8

(the nanny keeps setting one BLAS thread). The files are the same either way.

A worker lost mid-batch: the scheduler gives its chunks to another worker (which writes the
same bytes again); a temporary file it left beside the audio is removed by the client at the
end of the run. A Ctrl-C on the client cancels every future; a chunk already running stops
before its next item.

A cluster for trying this on one machine::

    dask scheduler --host 127.0.0.1 --port 8786 &
    dask worker tcp://127.0.0.1:8786 --nthreads 1 --nworkers 2 &
    barsynth batch twangs.toml -o twangs --dask-scheduler tcp://127.0.0.1:8786
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import os
import sys
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..checks import show_text
from ..errors import BarsynthError, ParameterError

__all__ = ["CONNECT_TIMEOUT_S", "WORKER_ENVIRONMENT", "DaskPool", "connect", "dask_pool", "disconnect",
           "task_cancelled"]

CONNECT_TIMEOUT_S = 10.0  # how long the client tries to reach the scheduler
WORKERS_TIMEOUT_S = 60.0  # how long a batch waits for a first worker on a scheduler that has none
WORKER_ENVIRONMENT = {  # for `dask worker` (see the module's docstring): as fast as the local pool
    "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
    "DASK_DISTRIBUTED__NANNY__PRE_SPAWN_ENVIRON": "{'MALLOC_TRIM_THRESHOLD_': 134217728, "
                                                  "'MALLOC_MMAP_THRESHOLD_': 33554432}",
}


def connect(address: str, timeout_s: float | None = None) -> Any:
    """A ``distributed.Client`` connected to the scheduler at ``address`` (``tcp://HOST:PORT``).

    Raises :class:`~barsynth.errors.BarsynthError` (one line, naming the address) when the
    scheduler cannot be reached within ``timeout_s`` (default :data:`CONNECT_TIMEOUT_S`) s or
    when Dask is not installed, :class:`~barsynth.errors.ParameterError` when the address
    cannot be read.
    """
    try:
        import distributed
    except ImportError:
        raise BarsynthError("--dask-scheduler needs dask.distributed: pip install 'barsynth[batch]'") from None
    timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    try:
        with _quiet_distributed():
            asyncio.run(_reach(address, timeout_s))  # (a Client that fails to connect complains again at exit)
            return distributed.Client(address, timeout=timeout_s, set_as_default=False)
    except (ValueError, TypeError):
        raise ParameterError(f"parameter dask-scheduler = {show_text(repr(address))} is not a scheduler's address; "
                             "allowed: tcp://HOST:PORT") from None
    except (OSError, TimeoutError):
        raise BarsynthError(f"could not reach the Dask scheduler at {show_text(str(address))} within {timeout_s:g} s "
                            "(is `dask scheduler` running there, and the port open?)") from None


async def _reach(address: str, timeout_s: float) -> None:
    """Open and close a connection to ``address`` (raises as ``distributed.Client`` would)."""
    from distributed.comm import connect as open_comm

    comm = await open_comm(address, timeout=timeout_s)
    await comm.close()


class DaskPool:
    """The part of :class:`concurrent.futures.Executor` a batch uses, on a Dask client: every
    :meth:`submit` is its own task (never merged with an equal one) and its future is a
    :class:`concurrent.futures.Future` (so :func:`concurrent.futures.wait` takes it)."""

    def __init__(self, client: Any) -> None:
        self.client = client
        self._executor = client.get_executor(pure=False)

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> concurrent.futures.Future:
        return self._executor.submit(fn, *args, **kwargs)

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        """``cancel_futures``: cancel every task at once (a running chunk stops before its
        next item, :func:`task_cancelled`) and return without waiting."""
        self._executor.shutdown(wait=wait and not cancel_futures)

    @property
    def slots(self) -> int:
        """The cluster's worker threads (at least 1): how many chunks run at once."""
        return max(1, sum(self.client.nthreads().values()))


@contextmanager
def dask_pool(scheduler: Any, out_dir: Any) -> Iterator[DaskPool]:
    """A :class:`DaskPool` on ``scheduler`` (an address, connected here and closed after, or a
    connected ``distributed.Client``, left open), once every worker is seen to run this barsynth
    version and to share ``out_dir``."""
    from distributed import KilledWorker

    client = connect(scheduler) if isinstance(scheduler, str) else scheduler
    try:
        _check_workers(client, Path(out_dir))
        with _quiet_distributed():
            yield DaskPool(client)
    except KilledWorker as exc:
        raise BarsynthError(f"a chunk of items was on {exc.allowed_failures + 1} Dask workers that died "
                            f"(the last {show_text(exc.last_worker.address)}); the scheduler gave it up: see the "
                            "workers' logs (memory?)") from None
    except concurrent.futures.CancelledError:
        raise BarsynthError(f"the Dask scheduler at {show_text(client.scheduler.address)} dropped the batch's work "
                            "(the connection lost?)") from None
    finally:
        if client is not scheduler:
            disconnect(client)


def disconnect(client: Any) -> None:
    """Close ``client`` without Dask's log of a scheduler already gone."""
    with _quiet_distributed():
        client.close()


def task_cancelled() -> bool:
    """True in a Dask worker's thread whose task has been cancelled (its client let go or was
    interrupted); False everywhere else (at once where ``distributed`` is not imported)."""
    if "distributed" not in sys.modules:
        return False
    from distributed import get_worker
    from distributed.worker import thread_state

    key = getattr(thread_state, "key", None)
    if key is None:
        return False
    try:
        task = get_worker().state.tasks.get(key)
    except ValueError:  # (not in a worker)
        return False
    return task is None or task.state in ("cancelled", "released", "forgotten")


def _check_workers(client: Any, out: Path) -> None:
    """Refuse (one line) unless every worker imports this barsynth version and sees a file the
    client just wrote in ``out``."""
    from .. import __version__

    if not client.scheduler_info().get("workers"):
        try:
            client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
        except TimeoutError:
            raise BarsynthError(f"no Dask worker is connected to the scheduler at "
                                f"{show_text(client.scheduler.address)} (waited {WORKERS_TIMEOUT_S:g} s); start "
                                "some with: dask worker ADDRESS --nthreads 1") from None
    marker = out.absolute() / f".barsynth-shared-{uuid.uuid4().hex}.tmp"
    marker.write_bytes(b"")
    try:
        seen = client.run(_probe, str(marker), on_error="return")
    finally:
        marker.unlink(missing_ok=True)
    for worker, answer in sorted(seen.items()):
        if isinstance(answer, BaseException):
            raise BarsynthError(f"the Dask worker {show_text(worker)} cannot run barsynth "
                                f"({type(answer).__name__}: {show_text(answer)}); install barsynth {__version__} "
                                "on every worker")
        if answer[1] != __version__:
            raise BarsynthError(f"the Dask worker {show_text(worker)} has barsynth {show_text(answer[1])}, the client "
                                f"{__version__}; allowed: the same version everywhere (the same sounds)")
    blind = sorted(worker for worker, answer in seen.items() if not answer[0])
    if blind:
        raise BarsynthError(f"the Dask worker {show_text(blind[0])} does not see the output folder "
                            f"{show_text(str(out.absolute()))}" + (f" (nor do {len(blind) - 1} more)"
                                                                  if len(blind) > 1 else "")
                            + "; the folder must be shared by the client and every worker, at the same path "
                              "(e.g. NFS)")


def _probe(marker: str) -> tuple[bool, str]:
    """On a worker: whether it sees ``marker`` and its barsynth version."""
    from .. import __version__

    return os.path.exists(marker), __version__


@contextmanager
def _quiet_distributed() -> Iterator[None]:
    """Dask's client logs a lost worker or scheduler (with a traceback); the batch reports
    through its own errors and progress instead."""
    import logging

    loggers = [logging.getLogger(name) for name in list(logging.root.manager.loggerDict)
               if name == "distributed" or name.startswith("distributed.")]  # (some have their own level)
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)
