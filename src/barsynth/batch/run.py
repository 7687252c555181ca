"""Render a batch's items to files and write its manifest (spec 11.2), on local processes.

``DIR/items/00000.wav`` (or ``.flac``, 24-bit PCM, peak-normalised to -1 dBFS as ``barsynth
render`` writes), each written to a temporary file in the same folder and renamed when
complete, so an interrupted run leaves no partial file. ``DIR/manifest.csv`` has one row per
finished item, in item order: :data:`FIXED_COLUMNS` (the file, its SHA-256, the render seed, the
duration and three features: f0, the T60 of the strongest partial, the spectral centroid),
then every parameter of the model's table, resolved. It is rewritten (atomically) as items
finish, so a run stopped part-way can be resumed. ``DIR/metadata.csv`` is the same table
in Hugging Face's audio-folder layout (a ``file_name`` column; rendered items only).

Every item is rendered from its own seed and parameters alone (:mod:`.items`), in a process of
a pool (started with ``spawn``, one BLAS thread each, even for one worker), so the files and
the manifest are byte-identical whatever the number of workers or the order they finish.
With ``resume`` an item whose manifest row matches (same seed and parameters) and whose
file's SHA-256 is the manifest's is kept; every other item is rendered again.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import multiprocessing
import os
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BarsynthError
from .items import Item, make_items
from .spec import BatchSpec

__all__ = ["FIXED_COLUMNS", "ITEMS_DIR", "MANIFEST", "item_file", "read_manifest", "render_item", "run_batch"]

ITEMS_DIR = "items"
MANIFEST = "manifest.csv"
METADATA = "metadata.csv"
FIXED_COLUMNS = ("id", "file", "sha256", "seed", "duration_s", "f0_hz", "t60_s", "centroid_hz", "error")
SUBTYPE = "PCM_24"
MAX_CHUNK = 16  # items per task of the pool (fewer round trips; at least 4 tasks per worker)
SAVE_EVERY_S = 2.0  # the manifest is rewritten at most this often while items finish (and at the end)
_FORMATS = {"wav": "WAV", "flac": "FLAC"}
_TMP_PREFIX, _TMP_SUFFIX = ".barsynth-", ".tmp"  # a file being written (see _write_atomically)
_MEASURED = ("sha256", "duration_s", "f0_hz", "t60_s", "centroid_hz", "error")  # known only once rendered


def item_file(spec: BatchSpec, index: int) -> str:
    """Item ``index``'s file, relative to the output folder: ``items/00042.wav``."""
    return f"{ITEMS_DIR}/{index:05d}.{spec.format}"


def render_item(spec: BatchSpec, item: Item, out_dir: str, features: bool = True) -> dict[str, str]:
    """Render ``item``, write its file atomically under ``out_dir`` and return its manifest row
    (every value as text). Settings the model refuses (or whose samples blow up) give a row
    with ``error`` set and no file (``file`` empty)."""
    import soundfile

    from ..models import get_model

    row = _row_start(spec, item)
    model = get_model(spec.model)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (an "auto" render that reached its cap: still a sound)
            samples = model.render(model.resolve(item.parameters), duration_s=spec.duration_s,
                                   sample_rate=spec.sample_rate, seed=item.seed)
    except BarsynthError as exc:
        row.update(file="", error=str(exc))
        return row
    buffer = io.BytesIO()
    soundfile.write(buffer, samples, int(spec.sample_rate), format=_FORMATS[spec.format], subtype=SUBTYPE)
    data = buffer.getvalue()
    _write_atomically(Path(out_dir) / row["file"], data)
    row["sha256"] = hashlib.sha256(data).hexdigest()
    row["duration_s"] = _text(samples.size / spec.sample_rate)
    if features:
        row.update(_features(samples, spec.sample_rate))
    return row


def render_chunk(spec: BatchSpec, items: list[Item], out_dir: str, features: bool = True) -> list[dict[str, str]]:
    """:func:`render_item` for each of ``items`` in turn (one task of the pool); after a Ctrl-C
    the worker starts no more items (a chunk already queued ends at once), nor does a Dask
    task whose client cancelled it."""
    from .cluster import task_cancelled

    rows = []
    for item in items:
        if _STOPPED:
            raise KeyboardInterrupt
        if task_cancelled():
            raise RuntimeError("cancelled by the client")  # (its result is never read)
        rows.append(render_item(spec, item, out_dir, features))
    return rows


_STOPPED = False  # a pool worker's: a Ctrl-C has arrived


def _worker_start() -> None:
    """In each pool process: a Ctrl-C interrupts the item it renders (its temporary file is
    removed) and stops it taking more."""
    import signal

    def stop(signum: int, frame: Any) -> None:
        global _STOPPED
        _STOPPED = True
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, stop)


def run_batch(spec: BatchSpec, out_dir: Any, *, workers: int = 1, resume: bool = False, features: bool = True,
              spec_text: str | None = None,
              progress: Callable[[int, int], None] | None = None,
              scheduler: Any = None) -> list[dict[str, str]]:
    """Render every item of ``spec`` into ``out_dir`` on ``workers`` local processes; return the
    manifest's rows (in item order).

    ``scheduler``: a Dask scheduler's address (or a connected ``distributed.Client``) to render
    on that cluster instead (``workers`` is then unused; ``out_dir`` must be shared with the
    workers: :mod:`.cluster`). The files and the manifest are the same either way.

    ``resume``: keep the items the manifest in ``out_dir`` already holds whose files are
    intact (see the module's docstring). ``features``: measure f0, T60 and centroid (the
    costly part of a short item). ``spec_text``: also written as ``DIR/spec.toml``.
    ``progress(done, total)`` is called as items finish (first with the items kept).

    The pool's processes are spawned, so a script that calls this needs Python's usual guard,
    ``if __name__ == "__main__":`` (``barsynth batch`` and notebooks need nothing).
    """
    out = Path(out_dir)
    (out / ITEMS_DIR).mkdir(parents=True, exist_ok=True)
    if spec_text is not None:
        _write_atomically(out / "spec.toml", spec_text.encode("utf-8"))
    items = make_items(spec)
    rows: dict[int, dict[str, str]] = {}
    if resume:
        rows = {item.index: row for item, row in _kept(spec, items, out)}
    todo = [item for item in items if item.index not in rows]
    total = len(items)
    if progress:
        progress(len(rows), total)
    saved_at = time.monotonic()

    def finished(row: dict[str, str]) -> None:
        nonlocal saved_at
        rows[int(row["id"])] = row
        if progress:
            progress(len(rows), total)
        if time.monotonic() - saved_at > SAVE_EVERY_S:
            _save(spec, out, rows)
            saved_at = time.monotonic()

    try:
        if todo:
            with _pool(workers, len(todo), scheduler, out) as (pool, slots):
                size = max(1, min(MAX_CHUNK, len(todo) // (4 * slots)))
                pending = {pool.submit(render_chunk, spec, todo[i:i + size], str(out.absolute()), features)
                           for i in range(0, len(todo), size)}
                try:
                    while pending:
                        done, pending = wait(pending, return_when=FIRST_COMPLETED)
                        for future in done:
                            for row in future.result():
                                finished(row)
                except BaseException:
                    pool.shutdown(wait=True, cancel_futures=True)
                    raise
            _remove_temporaries(out / ITEMS_DIR)  # (a lost worker's)
    finally:  # (a Ctrl-C too: what is finished is in the manifest, for --resume)
        _save(spec, out, rows)
    return [rows[i] for i in sorted(rows)]


@contextmanager
def _pool(workers: int, count: int, scheduler: Any, out: Path) -> Iterator[tuple[Any, int]]:
    """The executor the chunks are submitted to and how many run at once: ``workers`` local
    processes (at most ``count``), or a Dask cluster's threads when ``scheduler`` is given."""
    if scheduler is not None:
        from .cluster import dask_pool

        with dask_pool(scheduler, out) as pool:
            yield pool, pool.slots
        return
    with _single_threaded_blas(), ProcessPoolExecutor(
            max_workers=min(workers, count), mp_context=multiprocessing.get_context("spawn"),
            initializer=_worker_start) as pool:
        yield pool, workers


@contextmanager
def _single_threaded_blas() -> Iterator[None]:
    """While the pool starts its processes: one BLAS / OpenMP thread each. The analysis's small
    eigenproblems run 6 times slower with OpenBLAS's threads on a loaded machine (0.24 s against
    1.5 s for a 1 s twang), and a fixed thread count keeps the features' last digits the same
    whatever the number of workers."""
    names = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    saved = {name: os.environ.get(name) for name in names}
    os.environ.update(dict.fromkeys(names, "1"))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def read_manifest(path: Any) -> dict[int, dict[str, str]]:
    """A manifest's rows by item index (empty when there is none or it is unreadable)."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            return {int(row["id"]): row for row in csv.DictReader(f)}
    except (OSError, ValueError, KeyError, csv.Error):
        return {}


def file_sha256(path: Any) -> str | None:
    """The SHA-256 (hex) of the file at ``path``, or None if it cannot be read."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()


def _kept(spec: BatchSpec, items: list[Item], out: Path):
    """The ``(item, row)`` pairs of the old manifest that a resume keeps."""
    old = read_manifest(out / MANIFEST)
    for item in items:
        row = old.get(item.index)
        if row is None or row.get("error"):
            continue
        expected = _row_start(spec, item)
        if any(row.get(k) != v for k, v in expected.items() if k not in _MEASURED):
            continue  # another spec's item (or another file name)
        if row.get("sha256") and file_sha256(out / row["file"]) == row["sha256"]:
            yield item, row


def _row_start(spec: BatchSpec, item: Item) -> dict[str, str]:
    """An item's row before rendering: every column present, the features empty."""
    row = dict.fromkeys(FIXED_COLUMNS, "")
    row.update(id=str(item.index), file=item_file(spec, item.index), seed=str(item.seed))
    row.update({name: _text(value) for name, value in item.parameters.items()})
    return row


def _features(samples: np.ndarray, sample_rate: float) -> dict[str, str]:
    """f0 (Hz), the T60 of the strongest partial (s) and the spectral centroid (Hz), as text
    (empty where the analysis finds no partial)."""
    from ..analysis.note import analyze_note

    x = np.asarray(samples, dtype=np.float64)
    power = np.abs(np.fft.rfft(x)) ** 2
    freqs = np.fft.rfftfreq(x.size, 1.0 / sample_rate)
    total = float(power.sum())
    centroid = float((freqs * power).sum() / total) if total > 0 else math.nan
    note = analyze_note(x, sample_rate)
    strongest = max(note.partials, key=lambda p: p.level_db, default=None)
    return {"f0_hz": _text(note.f0_hz), "t60_s": _text(None if strongest is None else strongest.t60_s),
            "centroid_hz": _text(centroid)}


def _text(value: Any) -> str:
    """A value as manifest text: floats round-trip (``repr``), lists comma-separated, None and NaN empty."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (float, np.floating)):
        return "" if math.isnan(value) else repr(float(value))
    if isinstance(value, tuple):
        return ",".join(_text(v) for v in value)
    return str(value)


def _save(spec: BatchSpec, out: Path, rows: dict[int, dict[str, str]]) -> None:
    """Write the manifest and the audio-folder metadata (atomically), rows in item order."""
    from ..models import get_model

    columns = list(FIXED_COLUMNS) + list(get_model(spec.model).table.names)
    ordered = [rows[i] for i in sorted(rows)]
    _write_atomically(out / MANIFEST, _csv(columns, ordered))
    rendered = [{"file_name": r["file"], **{k: v for k, v in r.items() if k not in ("file", "error")}}
                for r in ordered if not r["error"]]
    _write_atomically(out / METADATA, _csv(["file_name"] + [c for c in columns if c not in ("file", "error")],
                                           rendered))


def _csv(columns: list[str], rows: list[dict[str, str]]) -> bytes:
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return text.getvalue().encode("utf-8")


def _write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it over ``path``: never a
    partial file at ``path``, whatever interrupts the write."""
    fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX, suffix=_TMP_SUFFIX, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _remove_temporaries(folder: Path) -> None:
    """Remove the temporary files :func:`_write_atomically` left in ``folder`` (a process killed
    mid-write leaves one): our own names only."""
    for path in folder.glob(f"{_TMP_PREFIX}*{_TMP_SUFFIX}"):
        path.unlink(missing_ok=True)
