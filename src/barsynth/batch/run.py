"""Render a batch's items to files and write its manifest (spec 11.2), on local processes.

``DIR/audio/00000042.wav`` (or ``.flac``; 24-bit PCM, peak-normalised to -1 dBFS as ``barsynth
render`` writes), each written to a temporary file in the same folder and renamed when
complete, so an interrupted run leaves no partial file. ``DIR/manifest.csv`` and
``DIR/manifest.parquet`` have one row per finished item, in item order: :data:`FIXED_COLUMNS`
(the file, its SHA-256, the render seed, the draws the model refused before the item's, the
duration and three features: f0, the T60 of the strongest partial, the spectral centroid;
``error`` when the model refused the item), then every parameter of the model's table,
resolved (typed in the Parquet file: numbers, bools, text, lists). They are rewritten
(atomically) as items finish, so a run stopped part-way can be resumed. ``DIR/metadata.csv``
is the same table in Hugging Face's audio-folder layout (a ``file_name`` column; rendered
items only), and ``DIR/spec.toml`` the spec.

Every item is drawn and rendered from the spec and its index alone (:mod:`.items`), in a
process of a pool (started with ``spawn``, one BLAS thread each, even for one worker), so the
files and the manifest are byte-identical whatever the number of workers or the order they
finish. With ``resume`` an item is kept when the folder holds the same spec (its count aside),
its manifest row has the item's seed and its file's SHA-256 is the manifest's; every other
item is rendered again. Without ``resume`` a folder's earlier items are replaced.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import multiprocessing
import os
import re
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import show_text
from ..errors import BarsynthError, BatchSpecError
from .items import Item, base_parameters, designed_item, item_seed
from .spec import BatchSpec, parse_spec, spec_toml

__all__ = ["AUDIO_DIR", "FIXED_COLUMNS", "MANIFEST", "PARQUET", "item_file", "read_manifest", "render_item",
           "run_batch"]

AUDIO_DIR = "audio"
MANIFEST = "manifest.csv"
PARQUET = "manifest.parquet"
METADATA = "metadata.csv"
SPEC_COPY = "spec.toml"
FIXED_COLUMNS = ("id", "file", "sha256", "seed", "rejected", "duration_s", "f0_hz", "t60_s", "centroid_hz", "error")
SUBTYPE = "PCM_24"
MAX_CHUNK = 16  # items per task of the pool (fewer round trips; at least 4 tasks per worker)
SAVE_EVERY_S = 2.0  # the manifest is rewritten at most this often while items finish (and at the end)
_FORMATS = {"wav": "WAV", "flac": "FLAC"}
_TMP_PREFIX, _TMP_SUFFIX = ".barsynth-", ".tmp"  # a file being written (see _write_atomically)
_AUDIO_NAME = re.compile(r"\d{8}\.(wav|flac)")  # an item's file, as item_file names it


def item_file(spec: BatchSpec, index: int) -> str:
    """Item ``index``'s file, relative to the output folder: ``audio/00000042.wav``."""
    return f"{AUDIO_DIR}/{index:08d}.{spec.format}"


def render_item(spec: BatchSpec, index: int, out_dir: str, features: bool = True, *,
                base: Any = None) -> dict[str, str]:
    """Draw item ``index`` (:func:`~.items.designed_item`), render it, write its file atomically
    under ``out_dir`` and return its manifest row (every value as text). Settings the model
    refuses (or whose samples blow up) give a row with ``error`` set and no file (``file`` empty)."""
    import soundfile

    from ..models import get_model
    from ..models.rendering import render_voice

    item, voice = designed_item(spec, index, base=base)
    row = _row_start(spec, item)
    if item.error:
        row.update(file="", error=item.error)
        return row
    model = get_model(spec.model)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (an "auto" render that reached its cap: still a sound)
            if voice is None:
                samples = model.render(model.resolve(item.parameters), duration_s=spec.duration_s,
                                       sample_rate=spec.sample_rate, seed=item.seed)
            else:  # designed and checked while drawing: rendered as Model.render would
                samples = render_voice(voice, spec.duration_s)
    except BarsynthError as exc:
        row.update(file="", error=str(exc))
        return row
    buffer = io.BytesIO()
    soundfile.write(buffer, samples, int(spec.sample_rate), format=_FORMATS[spec.format], subtype=SUBTYPE)
    data = buffer.getvalue()
    row["sha256"] = hashlib.sha256(data).hexdigest()
    row["duration_s"] = _text(samples.size / spec.sample_rate)
    if features:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (the analysis overflows on some long decays: not for the terminal)
            row.update(_features(samples, spec.sample_rate))
    _write_atomically(Path(out_dir) / row["file"], data)  # last: a Ctrl-C after it finds the row ready
    return row


def render_chunk(spec: BatchSpec, indices: list[int], out_dir: str, features: bool = True) -> list[dict[str, str]]:
    """:func:`render_item` for each of ``indices`` in turn (one task of the pool); after a Ctrl-C
    the worker starts no more items (a chunk already queued ends at once) and the rows of the
    items it finished are returned (the one interrupted has neither row nor file), nor does a
    Dask task whose client cancelled it."""
    from .cluster import task_cancelled

    global _RENDERING
    rows = []
    base = base_parameters(spec)
    _RENDERING = True
    try:
        for index in indices:
            if _STOPPED:
                break
            if task_cancelled():
                raise RuntimeError("cancelled by the client")  # (its result is never read)
            rows.append(render_item(spec, index, out_dir, features, base=base))
    except KeyboardInterrupt:
        _RENDERING = False
        if not _STOPPED:  # (not a pool worker's Ctrl-C)
            raise
    finally:
        _RENDERING = False
    return rows


_STOPPED = False  # a pool worker's: a Ctrl-C has arrived
_RENDERING = False  # a pool worker's: inside render_chunk (where a Ctrl-C may interrupt)


def _worker_start() -> None:
    """In each pool process: a Ctrl-C interrupts the item it renders (its temporary file is
    removed) and stops it taking more. Outside a chunk it only sets the flag: an interrupt
    while the worker waits for work or sends a result would end the process with a
    traceback on the terminal (multiprocessing prints it); the pool's shutdown ends it."""
    import signal

    def stop(signum: int, frame: Any) -> None:
        global _STOPPED
        _STOPPED = True
        if _RENDERING:
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
    costly part of a short item). ``spec_text``: the spec as the user wrote it, copied to
    ``DIR/spec.toml`` (else the spec is written there in its canonical form).
    ``progress(done, total)`` is called as items finish (first with the items kept).

    The pool's processes are spawned, so a script that calls this needs Python's usual guard,
    ``if __name__ == "__main__":`` (``barsynth batch`` and notebooks need nothing).
    """
    out = Path(out_dir)
    if resume:
        _check_same_spec(spec, out)
    earlier = (out / SPEC_COPY).is_file() or (out / MANIFEST).is_file()  # (a batch's folder: its files are ours)
    (out / AUDIO_DIR).mkdir(parents=True, exist_ok=True)
    rows: dict[int, dict[str, str]] = dict(_kept(spec, out)) if resume else {}
    _remove_others(spec, out, rows, earlier)
    if spec_text is not None or _stored_spec(out, source=spec.source) != spec:  # (a copy of this very spec is left as it is)
        _write_atomically(out / SPEC_COPY, (spec_toml(spec) if spec_text is None else spec_text).encode("utf-8"))
    todo = [index for index in range(spec.count) if index not in rows]
    total = spec.count
    if progress:
        progress(len(rows), total)
    saved_at, save_cost = time.monotonic(), 0.0

    def finished(row: dict[str, str]) -> None:
        nonlocal saved_at, save_cost
        rows[int(row["id"])] = row
        if progress:
            progress(len(rows), total)
        if time.monotonic() - saved_at > max(SAVE_EVERY_S, 20.0 * save_cost):  # (a long manifest: less often)
            began = time.monotonic()
            _save(spec, out, rows)
            saved_at = time.monotonic()
            save_cost = saved_at - began

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
                    _interrupt_workers(pool)  # (a Ctrl-C the command alone got: kill -INT, a notebook)
                    pool.shutdown(wait=True, cancel_futures=True)
                    for future in pending:  # the items finished meanwhile are in the manifest too
                        if future.done() and not future.cancelled() and future.exception() is None:
                            for row in future.result():
                                rows[int(row["id"])] = row
                    raise
            _remove_temporaries(out / AUDIO_DIR)  # (a lost worker's)
    finally:  # (a Ctrl-C too: what is finished is in the manifest, for --resume)
        _save(spec, out, rows)
    return [rows[i] for i in sorted(rows)]


def _interrupt_workers(pool: Any) -> None:
    """Send a Ctrl-C to a local pool's processes (each ends the item it renders, as on a
    terminal's Ctrl-C, which reaches them anyway); nothing for a Dask pool."""
    import signal

    for process in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            os.kill(process.pid, signal.SIGINT)
        except (OSError, AttributeError):
            pass


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


def _kept(spec: BatchSpec, out: Path) -> Iterator[tuple[int, dict[str, str]]]:
    """The ``(index, row)`` pairs of the folder's manifest that a resume keeps: none unless the
    folder holds the same spec (its count aside; another is refused by :func:`_check_same_spec`);
    then each row of an item of ``spec`` with the item's seed and file, no error, and a file
    whose SHA-256 is the row's."""
    old_spec = _stored_spec(out, source=spec.source)
    if old_spec is None or replace(old_spec, count=spec.count) != spec:
        return
    for index, row in read_manifest(out / MANIFEST).items():
        if not 0 <= index < spec.count or row.get("error") or not row.get("sha256"):
            continue
        if row.get("seed") != str(item_seed(spec.seed, index)) or row.get("file") != item_file(spec, index):
            continue
        if file_sha256(out / row["file"]) == row["sha256"]:
            yield index, row


def _check_same_spec(spec: BatchSpec, out: Path) -> None:
    """Refuse (one line) to resume in a folder that holds another spec's batch: resuming would
    replace every item of it; only a run without ``resume`` may do that."""
    old = _stored_spec(out, source=spec.source)
    if old is None or replace(old, count=spec.count) == spec:
        return
    differ = [name for name in ("model", "preset", "seed", "sample_rate", "duration_s", "format", "vary")
              if getattr(old, name) != getattr(spec, name)]
    raise BatchSpecError(f"{spec.source}: cannot resume in {show_text(str(out))}: it holds the batch of another "
                         f"spec (its {', '.join(differ)} differ); allowed: the same spec (its count may change), "
                         "or a run without --resume, which replaces that batch")


def _stored_spec(out: Path, source: str = "<spec>") -> BatchSpec | None:
    """The spec copied into the folder (named ``source``), or None if there is none or it does not read."""
    try:
        return parse_spec((out / SPEC_COPY).read_text(encoding="utf-8"), source=source)
    except (OSError, UnicodeDecodeError, BarsynthError):
        return None


def _remove_others(spec: BatchSpec, out: Path, kept: dict[int, dict[str, str]], earlier: bool = True) -> None:
    """Remove the folder's item files (only names :func:`item_file` gives, and our temporaries)
    that are not among ``kept``: an earlier batch's items, which the manifest no longer lists.
    Unless the folder held an ``earlier`` batch (its spec copy or manifest), only our temporaries:
    a folder of someone's own recordings named like items keeps them."""
    keep = {row["file"].rpartition("/")[2] for row in kept.values()}
    for entry in os.scandir(out / AUDIO_DIR):
        name = entry.name
        ours = (earlier and _AUDIO_NAME.fullmatch(name)) or (name.startswith(_TMP_PREFIX) and name.endswith(_TMP_SUFFIX))
        if ours and name not in keep and entry.is_file(follow_symlinks=False):
            os.unlink(entry.path)


def _row_start(spec: BatchSpec, item: Item) -> dict[str, str]:
    """An item's row before rendering: every column present, the features empty."""
    row = dict.fromkeys(FIXED_COLUMNS, "")
    row.update(id=str(item.index), file=item_file(spec, item.index), seed=str(item.seed), rejected=str(item.rejected))
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
    """Write the manifest (CSV and Parquet) and the audio-folder metadata (atomically), rows in item order."""
    from ..models import get_model

    table = get_model(spec.model).table
    columns = list(FIXED_COLUMNS) + list(table.names)
    ordered = [rows[i] for i in sorted(rows)]
    _write_atomically(out / MANIFEST, _csv(columns, ordered))
    _write_atomically(out / PARQUET, _parquet(table, columns, ordered))
    rendered = [{"file_name": r["file"], **{k: v for k, v in r.items() if k not in ("file", "error")}}
                for r in ordered if not r["error"]]
    _write_atomically(out / METADATA, _csv(["file_name"] + [c for c in columns if c not in ("file", "error")],
                                           rendered))


_INTEGER_COLUMNS = ("id", "seed", "rejected")
_FLOAT_COLUMNS = ("duration_s", "f0_hz", "t60_s", "centroid_hz")


def _parquet(table: Any, columns: list[str], rows: list[dict[str, str]]) -> bytes:
    """The manifest as a Parquet file: each column typed (whole numbers, floats, bools, text,
    lists of floats for a list parameter), an empty value null."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ..parameters import BOOL, FLOATS, INT

    def typed(name: str) -> tuple[Any, Callable[[str], Any]]:
        kind = table[name].kind if name in table else None
        if name in _INTEGER_COLUMNS or kind == INT:
            return pa.int64(), int
        if name in _FLOAT_COLUMNS or kind == "float":
            return pa.float64(), float
        if kind == BOOL:
            return pa.bool_(), lambda text: text == "true"
        if kind == FLOATS:
            return pa.list_(pa.float64()), lambda text: [float(x) for x in text.split(",")]
        return pa.string(), str

    arrays, fields = [], []
    for name in columns:
        kind, parse = typed(name)
        values = [parse(r[name]) if r.get(name, "") != "" else None for r in rows]
        arrays.append(pa.array(values, type=kind))
        fields.append(pa.field(name, kind))
    sink = io.BytesIO()
    pq.write_table(pa.Table.from_arrays(arrays, schema=pa.schema(fields)), sink)
    return sink.getvalue()


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
