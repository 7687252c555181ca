"""Batches on a Dask cluster (spec 11.3): a real scheduler and two workers on loopback give the
same files and manifest as a local run, lose nothing when a worker is killed mid-batch, and an
unreachable scheduler is one line and nothing written."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from barsynth.batch.run import AUDIO_DIR, MANIFEST, METADATA, file_sha256, read_manifest, run_batch
from barsynth.batch.spec import parse_spec

SRC = Path(__file__).resolve().parents[1] / "src"
SPEC = """model = "twang"
preset = "plastic-30cm"
count = {count}
seed = 11
duration_s = 0.2
format = "flac"
[vary.q]
grid = [60, 200]
[vary.length_m]
random = [0.15, 0.4]
[vary.shape]
mutate = 0.2
"""
COUNT = 16


def _stop(proc: subprocess.Popen) -> None:
    """SIGTERM to the process's group (a worker's nanny and its worker), then SIGKILL."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        except ProcessLookupError:
            pass


def _start_cluster(work: Path, workers: int, procs: list) -> str:
    """``dask scheduler`` and ``workers`` ``dask worker`` processes (one thread each) on
    127.0.0.1, importing this barsynth, the second with the recommended WORKER_ENVIRONMENT
    (appended to ``procs``); returns the scheduler's address."""
    from barsynth.batch.cluster import WORKER_ENVIRONMENT

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(SRC), os.environ.get("PYTHONPATH")])))
    common = {"cwd": work, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "start_new_session": True}
    scheduler_file = work / "scheduler.json"
    procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                   "--port", "0", "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                                  env=env, **common))
    for _ in range(600):
        if scheduler_file.exists() and scheduler_file.stat().st_size:
            break
        assert procs[0].poll() is None, "the scheduler stopped"
        time.sleep(0.05)
    address = json.loads(scheduler_file.read_text())["address"]
    for i in range(workers):
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                                       "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
                                       "--no-dashboard", "--name", f"w{i}", "--local-directory", str(work / f"w{i}")],
                                      env=dict(env, **(WORKER_ENVIRONMENT if i else {})), **common))
    return address


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A scheduler and two workers on loopback (:func:`_start_cluster`); yields a connected client."""
    from distributed import Client

    procs = []
    try:
        address = _start_cluster(tmp_path_factory.mktemp("dask"), 2, procs)
        client = Client(address, timeout=30, set_as_default=False)
        client.wait_for_workers(2, timeout=60)
        try:
            yield client
        finally:
            client.close()
    finally:
        for proc in reversed(procs):
            _stop(proc)


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """The reference: the spec rendered on one local process."""
    out = tmp_path_factory.mktemp("local")
    run_batch(parse_spec(SPEC.format(count=COUNT), source="b.toml"), out, workers=1)
    return out


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_the_cluster_writes_the_local_runs_bytes(cluster, local_run, tmp_path):
    out = tmp_path / "out"
    rows = run_batch(parse_spec(SPEC.format(count=COUNT), source="b.toml"), out, scheduler=cluster.scheduler.address)
    assert len(rows) == COUNT and not any(r["error"] for r in rows)
    assert float(rows[0]["f0_hz"]) > 20  # features measured on the workers
    tree = _tree(out)
    assert len([name for name in tree if name.endswith(".flac")]) == COUNT
    assert tree == _tree(local_run)  # audio, manifest and metadata


def test_the_command_renders_on_the_cluster_with_single_threaded_workers(cluster, local_run, tmp_path):
    """``barsynth batch --dask-scheduler ADDRESS``; the workers' BLAS is single-threaded as in
    the local pool."""
    from click.testing import CliRunner

    from barsynth.cli import main

    names = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MALLOC_MMAP_THRESHOLD_")
    env = sorted(cluster.run(lambda: tuple(os.environ.get(k) for k in names)).values(), key=str)
    assert env == [("1", "1", "33554432"), ("1", "1", None)]  # (the second: WORKER_ENVIRONMENT)
    spec_path, out = tmp_path / "b.toml", tmp_path / "out"
    spec_path.write_text(SPEC.format(count=4))
    result = CliRunner().invoke(main, ["batch", str(spec_path), "-o", str(out), "--dask-scheduler",
                                       cluster.scheduler.address], catch_exceptions=False)
    assert result.exit_code == 0 and "wrote 4 items" in result.output
    assert _tree(out / AUDIO_DIR) == dict(sorted(_tree(local_run / AUDIO_DIR).items())[:4])


def _free_address() -> str:
    import socket

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{s.getsockname()[1]}"


@pytest.mark.parametrize("address, words", [
    (None, "barsynth: error: could not reach the Dask scheduler at {address} within 1 s"),
    ("http://127.0.0.1:1", ("barsynth: error: parameter dask-scheduler = 'http://127.0.0.1:1' is not a "
                            "scheduler's address; allowed: tcp://HOST:PORT")),
])
def test_an_unreachable_scheduler_exits_2_in_one_line_and_writes_nothing(tmp_path, address, words):
    """In a process of its own: what Dask might print at exit counts too."""
    address = address or _free_address()
    spec_path = tmp_path / "b.toml"
    spec_path.write_text(SPEC.format(count=2))
    code = ("import sys; import barsynth.batch.cluster as c; c.CONNECT_TIMEOUT_S = 1.0; "
            "from barsynth.cli import main; main(sys.argv[1:])")
    result = subprocess.run([sys.executable, "-c", code, "batch", str(spec_path), "-o", str(tmp_path / "out"),
                             "--dask-scheduler", address], check=False, capture_output=True, text=True, timeout=60,
                            env=dict(os.environ, PYTHONPATH=str(SRC)))
    assert result.returncode == 2 and result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(words.format(address=address)), result.stderr
    assert not (tmp_path / "out").exists()


def test_workers_with_the_dask_scheduler_is_refused(tmp_path):
    from click.testing import CliRunner

    from barsynth.cli import main

    spec_path = tmp_path / "b.toml"
    spec_path.write_text(SPEC.format(count=2))
    result = CliRunner().invoke(main, ["batch", str(spec_path), "-o", str(tmp_path / "out"), "--workers", "2",
                                       "--dask-scheduler", "tcp://127.0.0.1:1"])
    assert result.exit_code == 2 and "parameter workers = 2 is not allowed with --dask-scheduler" in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("answers, words", [
    ({"tcp://127.0.0.1:1": (False, None), "tcp://127.0.0.1:2": (True, None)},
     "the Dask worker tcp://127.0.0.1:1 does not see the output folder .* must be shared"),
    ({"tcp://127.0.0.1:1": (True, None), "tcp://127.0.0.1:2": ModuleNotFoundError("No module named 'barsynth'")},
     "the Dask worker tcp://127.0.0.1:2 cannot run barsynth .*No module named 'barsynth'"),
    ({"tcp://127.0.0.1:1": (True, "0.0.1")}, "the Dask worker tcp://127.0.0.1:1 has barsynth 0.0.1, the client"),
])
def test_workers_that_cannot_do_the_batch_are_refused(cluster, tmp_path, monkeypatch, answers, words):
    """(The workers' answers are made up: a real one sees the folder and runs this barsynth.)"""
    from barsynth import __version__
    from barsynth.errors import BarsynthError

    answers = {w: (a[0], a[1] or __version__) if isinstance(a, tuple) else a for w, a in answers.items()}
    real = cluster.run(__import__("barsynth.batch.cluster", fromlist=["_probe"])._probe, __file__)
    assert real and all(answer == (True, __version__) for answer in real.values())
    monkeypatch.setattr(type(cluster), "run", lambda self, *a, **k: answers)
    with pytest.raises(BarsynthError, match=words):
        run_batch(parse_spec(SPEC.format(count=2), source="b.toml"), tmp_path / "out", scheduler=cluster)
    assert not list((tmp_path / "out" / AUDIO_DIR).iterdir())


def test_a_worker_killed_mid_batch_loses_nothing(cluster, local_run, tmp_path):
    """SIGKILL to a worker that is rendering a chunk: the scheduler gives its chunk to the other
    worker, the batch completes with every file the local run's, and no temporary file is left."""
    out = tmp_path / "out"
    killed = []

    def progress(done: int, total: int) -> None:
        if done and not killed:
            busy = [w for w, keys in cluster.processing().items() if keys]
            assert busy, "no worker has a chunk left to lose"
            pid = cluster.run(os.getpid, workers=busy[:1])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
            # what a worker killed while it wrote a file leaves (the timing cannot be chosen)
            (out / AUDIO_DIR / ".barsynth-left-by-a-killed-worker.tmp").write_bytes(b"partial")
            (out / AUDIO_DIR / "notes.tmp").write_bytes(b"not ours")

    spec = parse_spec(SPEC.format(count=COUNT), source="b.toml")
    rows = run_batch(spec, out, scheduler=cluster, progress=progress)
    assert killed and len(rows) == COUNT
    log = cluster.run_on_scheduler(lambda dask_scheduler: [t[:5] for t in dask_scheduler.transition_log])
    lost = {key for key, start, finish, _, stimulus in log
            if start == "processing" and finish == "released" and stimulus.startswith("handle-worker-cleanup")}
    redone = {key for key, start, finish, _, _ in log if key in lost and start == "processing" and finish == "memory"}
    assert lost and redone == lost  # a chunk was running on the killed worker, and ran again elsewhere
    tree = _tree(out)
    assert tree.pop(f"{AUDIO_DIR}/notes.tmp") == b"not ours"  # (only our temporary names are removed)
    assert tree == _tree(local_run)
    assert all(file_sha256(out / r["file"]) == r["sha256"] for r in read_manifest(out / MANIFEST).values())
    assert (out / METADATA).exists()


def test_ctrl_c_on_the_client_cancels_the_clusters_work(cluster, tmp_path):
    """The command interrupted mid-batch: status 130 in one line, every manifest row's file has
    its hash, and the workers stop: each ends at most the item it was rendering."""
    spec_path, out = tmp_path / "many.toml", tmp_path / "out"
    spec_path.write_text(SPEC.format(count=3000))  # (two workers render about 50 a second each, idle)
    env = dict(os.environ, PYTHONPATH=str(SRC))
    proc = subprocess.Popen([sys.executable, "-m", "barsynth", "batch", str(spec_path), "-o", str(out),
                             "--dask-scheduler", cluster.scheduler.address],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))  # (as in a background job)
    try:
        for _ in range(1200):  # until a few items are written (at most 60 s)
            if (out / AUDIO_DIR).is_dir() and len(os.listdir(out / AUDIO_DIR)) >= 40:
                break
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)  # the client only (the workers are elsewhere)
        _, err = proc.communicate(timeout=60)
    finally:
        _stop(proc)
    written = len(os.listdir(out / AUDIO_DIR))
    for _ in range(600):  # until the workers are idle (at most 30 s)
        if not any(cluster.run(lambda dask_worker: len(dask_worker.state.executing)).values()):
            break
        time.sleep(0.05)
    assert proc.returncode == 130 and err.decode().strip() == "barsynth: interrupted"
    names = os.listdir(out / AUDIO_DIR)
    assert not [n for n in names if n.startswith(".")]
    assert len(names) - written <= 2 and len(names) < 3000  # (each worker ends at most the item it renders)
    rows = read_manifest(out / MANIFEST)
    assert rows and all(file_sha256(out / r["file"]) == r["sha256"] for r in rows.values())
    assert not cluster.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks))


def test_a_lost_scheduler_ends_the_command_in_one_line(tmp_path):
    """The scheduler killed mid-batch: status 2, one line, and the manifest holds what finished."""
    from distributed import Client

    procs = []
    try:
        address = _start_cluster(tmp_path, 1, procs)
        with Client(address, timeout=30, set_as_default=False) as client:
            client.wait_for_workers(1, timeout=60)
        spec_path, out = tmp_path / "many.toml", tmp_path / "out"
        spec_path.write_text(SPEC.format(count=400))
        proc = subprocess.Popen([sys.executable, "-m", "barsynth", "batch", str(spec_path), "-o", str(out),
                                 "--dask-scheduler", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                env=dict(os.environ, PYTHONPATH=str(SRC)), start_new_session=True)
        procs.append(proc)
        for _ in range(1200):  # until a few chunks are written (at most 60 s)
            if (out / AUDIO_DIR).is_dir() and len(os.listdir(out / AUDIO_DIR)) >= 40:
                break
            time.sleep(0.05)
        os.killpg(procs[0].pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=60)
    finally:
        for p in reversed(procs):
            _stop(p)
    lines = err.decode().strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, err.decode()
    assert lines[0] == f"barsynth: error: the Dask scheduler at {address} dropped the batch's work " \
                      "(the connection lost?)"
    rows = read_manifest(out / MANIFEST)
    assert rows and all(file_sha256(out / r["file"]) == r["sha256"] for r in rows.values())


def test_a_scheduler_without_workers_is_one_line_after_a_wait(tmp_path, monkeypatch):
    from barsynth.batch import cluster as cluster_module
    from barsynth.errors import BarsynthError

    monkeypatch.setattr(cluster_module, "WORKERS_TIMEOUT_S", 1.0)
    procs = []
    try:
        address = _start_cluster(tmp_path, 0, procs)
        with pytest.raises(BarsynthError) as info:
            run_batch(parse_spec(SPEC.format(count=2)), tmp_path / "out", scheduler=address)
    finally:
        for p in reversed(procs):
            _stop(p)
    assert str(info.value) == f"no Dask worker is connected to the scheduler at {address} (waited 1 s); " \
                              "start some with: dask worker ADDRESS --nthreads 1"
    assert read_manifest(tmp_path / "out" / MANIFEST) == {}


@pytest.mark.parametrize("failure, words", [
    ("killed", "a chunk of items was on 4 Dask workers that died \\(the last tcp://10.0.0.9:1234\\)"),
    ("cancelled", "the Dask scheduler at .* dropped the batch's work"),
])
def test_work_the_cluster_gave_up_is_one_line(cluster, tmp_path, monkeypatch, failure, words):
    """(The failure made up: a chunk whose workers all died, or a future the scheduler dropped.)"""
    import concurrent.futures
    from types import SimpleNamespace

    from distributed import KilledWorker

    from barsynth.batch.cluster import DaskPool
    from barsynth.errors import BarsynthError

    def submit(self, fn, *args, **kwargs):
        future = concurrent.futures.Future()
        if failure == "killed":
            future.set_exception(KilledWorker("render_chunk-1", SimpleNamespace(address="tcp://10.0.0.9:1234"), 3))
        else:
            future.cancel()
            future.set_running_or_notify_cancel()
        return future

    monkeypatch.setattr(DaskPool, "submit", submit)
    with pytest.raises(BarsynthError, match=words):
        run_batch(parse_spec(SPEC.format(count=2), source="b.toml"), tmp_path / "out", scheduler=cluster)


def test_resume_on_the_cluster_renders_only_what_is_missing(cluster, local_run, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(local_run, out)
    missing = sorted((out / AUDIO_DIR).iterdir())[3:7]
    kept = {p.name: p.stat().st_mtime_ns for p in (out / AUDIO_DIR).iterdir() if p not in missing}
    for path in missing:
        path.unlink()
    done = []
    run_batch(parse_spec(SPEC.format(count=COUNT), source="b.toml"), out, resume=True, scheduler=cluster,
              progress=lambda n, total: done.append(n))
    assert done[0] == COUNT - 4 and done[-1] == COUNT
    assert {p.name: p.stat().st_mtime_ns for p in (out / AUDIO_DIR).iterdir() if p.name in kept} == kept
    assert _tree(out) == _tree(local_run)
