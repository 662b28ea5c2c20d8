"""Runs a suite's jobs in parallel worker processes and appends one JSON line per finished episode.

The parent process alone writes the JSONL file: each record is appended, flushed and fsynced as soon as its
episode finishes, so a killed run loses at most the episodes still in flight. ``run_suite`` resumes: jobs
whose key is already in the file are skipped, and a torn last line (a write cut by a kill) is cut off first.
A run holds an exclusive lock on ``<file>.lock`` (released by the OS however the run ends), so a second run
on the same file stops with ``RunInProgress`` instead of interleaving records; workers exit on their own
when the process that started them is gone (e.g. killed with SIGKILL), so no orphan keeps computing.

Workers call a *job function* ``fn(job) -> Mapping`` that returns the episode's record fields.
``RoutingEpisode`` (Table II) and ``InsertionTrial`` (Table I) adapt the episode functions to it; any
picklable top-level callable works. An exception inside a job becomes a failed record with termination
``"error"``; a worker that dies (native crash, out of memory) gets its in-flight jobs rerun one at a time, and
the job that kills a worker alone is recorded as an error too.
"""

from __future__ import annotations

import fcntl
import importlib
import json
import multiprocessing
import os
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from dloroute.eval.suites import TABLE_I_CLIP_SCALE, Job, Row, record_key
from dloroute.sim.scene import generate_scene

JobFn = Callable[[Job], Mapping[str, Any]]
DEFAULT_EPISODE_FN = "dloroute.routing.episode:run_episode"
_CONTEXT = multiprocessing.get_context("spawn")


PARENT_POLL_S = 1.0
"""How often (s) a worker checks that the process that started it is still alive."""


class RunInProgress(RuntimeError):
    """Another process is running an evaluation into the same JSONL file."""


@contextmanager
def _exclusive(out_jsonl: Path) -> Iterator[None]:
    """Hold an exclusive advisory lock on ``<out_jsonl>.lock`` (holding the owner's pid) for the block."""
    lock_path = out_jsonl.with_name(out_jsonl.name + ".lock")
    with lock_path.open("a+", encoding="utf-8") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.seek(0)
            owner = lock.read().strip() or "unknown"
            raise RunInProgress(
                f"another run (pid {owner}) is writing {out_jsonl}; wait for it to end or stop it, then rerun "
                "to resume"
            ) from None
        lock.truncate(0)
        lock.write(str(os.getpid()))
        lock.flush()
        yield


def _exit_with_parent(parent: int) -> None:
    """Worker initializer: end this worker once ``parent`` (the evaluation process) is gone."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def resolve(ref: str | Callable) -> Callable:
    """A callable, or the one a dotted ``"package.module:attribute"`` name points to (imported now)."""
    if callable(ref):
        return ref
    module, _, attr = ref.partition(":")
    if not attr:
        raise ValueError(f"expected 'package.module:attribute', got {ref!r}")
    return getattr(importlib.import_module(module), attr)


@dataclass(frozen=True)
class RoutingEpisode:
    """Job function for routing: ``episode_fn(generate_scene(family, seed), make_config(row, family, seed,
    run_dir)).to_dict()``. Both callables may be dotted names, resolved in the worker; callables must be
    picklable (top-level functions)."""

    make_config: str | Callable[[Row, str, int, Path], Any]
    run_dir: Path
    episode_fn: str | Callable[[Any, Any], Any] = DEFAULT_EPISODE_FN

    def __call__(self, job: Job) -> Mapping[str, Any]:
        scene = generate_scene(job.family, job.seed)
        config = resolve(self.make_config)(job.row, job.family, job.seed, self.run_dir)
        return resolve(self.episode_fn)(scene, config).to_dict()


@dataclass(frozen=True)
class InsertionTrial:
    """Job function for Table I: ``trial_fn(low_level, seed, scale)`` returns a mapping with ``success``,
    ``signed_distance_cm`` and ``length`` (primitives used). ``trial_fn`` may be a dotted name."""

    trial_fn: str | Callable[[str, int, float], Mapping[str, Any]]
    scale: float = TABLE_I_CLIP_SCALE

    def __call__(self, job: Job) -> Mapping[str, Any]:
        return resolve(self.trial_fn)(job.row.low_level, job.seed, self.scale)


@dataclass(frozen=True)
class RunStats:
    """What one ``run_suite`` call did. ``elapsed_s`` is wall time; ``errors`` counts error records."""

    total: int
    skipped: int
    ran: int
    errors: int
    elapsed_s: float

    @property
    def episodes_per_minute(self) -> float:
        return 60.0 * self.ran / self.elapsed_s if self.elapsed_s > 0 else 0.0


def read_records(path: Path) -> list[dict[str, Any]]:
    """The records of a JSONL run file (none if it is missing), ignoring a torn last line."""
    return _scan(Path(path))[0]


def repair(path: Path) -> int:
    """Cut a torn last line off a JSONL run file; returns the number of bytes removed."""
    path = Path(path)
    good = _scan(path)[1]
    torn = path.stat().st_size - good if path.exists() else 0
    if torn:
        os.truncate(path, good)
    return torn


def drop_errors(path: Path) -> int:
    """Rewrite a JSONL run file without its error records (atomically); returns how many were dropped."""
    path = Path(path)
    records = read_records(path)
    kept = [r for r in records if r.get("termination") != "error"]
    if len(kept) < len(records):
        tmp = path.with_name(path.name + ".tmp")
        with tmp.open("w", encoding="utf-8") as f:
            f.writelines(json.dumps(r) + "\n" for r in kept)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    return len(records) - len(kept)


def _scan(path: Path) -> tuple[list[dict[str, Any]], int]:
    """Parse ``path``: its complete records and the byte length they span. Text after the final newline and a
    last line that is not valid JSON are a torn write; a bad line before the last raises ``ValueError``."""
    if not path.exists():
        return [], 0
    lines = path.read_bytes().split(b"\n")[:-1]  # drops what follows the final newline
    records, length = [], 0
    for number, line in enumerate(lines, start=1):
        try:
            record = json.loads(line) if line.strip() else None
        except json.JSONDecodeError:
            if number == len(lines):
                break
            raise ValueError(f"{path}:{number}: corrupt record before the last line") from None
        if record is not None:
            records.append(record)
        length += len(line) + 1
    return records, length


def run_suite(
    jobs: Iterable[Job],
    out_jsonl: Path,
    *,
    workers: int,
    episode_fn: JobFn,
    progress: bool = True,
    retry_errors: bool = False,
) -> RunStats:
    """Run every job not yet recorded in ``out_jsonl`` on ``workers`` processes, appending one record per
    episode. ``episode_fn`` is a job function (see the module docstring). ``retry_errors`` first removes the
    file's error records, so their jobs run again (e.g. after fixing a missing policy file). Raises
    ``RunInProgress`` when another run holds the file."""
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    out_jsonl = Path(out_jsonl)
    out_jsonl.parent.mkdir(parents=True, exist_ok=True)
    with _exclusive(out_jsonl):
        return _run_locked(jobs, out_jsonl, workers, episode_fn, progress, retry_errors)


def _run_locked(
    jobs: Iterable[Job], out_jsonl: Path, workers: int, episode_fn: JobFn, progress: bool, retry_errors: bool
) -> RunStats:
    repair(out_jsonl)
    if retry_errors:
        drop_errors(out_jsonl)
    jobs = list({j.key: j for j in jobs}.values())  # a job listed twice still runs once
    keys = {j.key for j in jobs}
    done = {record_key(r): bool(r.get("success")) for r in read_records(out_jsonl)}
    queue = deque(j for j in jobs if j.key not in done)
    skipped = len(jobs) - len(queue)
    successes = sum(ok for key, ok in done.items() if key in keys)
    counts = {"ran": 0, "ok": successes, "errors": 0}
    start = time.perf_counter()
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[ok]}"),
               TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn())
    with Progress(*columns, disable=not progress, speed_estimate_period=600) as bar, \
            out_jsonl.open("a", encoding="utf-8") as out:
        task = bar.add_task(out_jsonl.stem, total=len(jobs), completed=skipped, ok=_ok_text(successes, skipped))

        def write(line: str, success: bool, error: str | None) -> None:
            out.write(line + "\n")
            out.flush()
            os.fsync(out.fileno())
            counts["ran"] += 1
            counts["ok"] += success
            if error:
                counts["errors"] += 1
                bar.console.log(f"[red]error[/red] {escape(error)}")
            bar.update(task, advance=1, ok=_ok_text(counts["ok"], skipped + counts["ran"]))

        while queue:
            for job in _execute(queue, episode_fn, workers, write):
                # A worker died with this job in flight: rerun it alone to tell whether it is the culprit.
                if _execute(deque([job]), episode_fn, 1, write):
                    write(*_error_record(job, "worker process died (native crash or out of memory)", 0.0))
    return RunStats(len(jobs), skipped, counts["ran"], counts["errors"], time.perf_counter() - start)


def _ok_text(ok: int, n: int) -> str:
    return f"success {ok}/{n} ({100 * ok / n:.0f}%)" if n else "success -"


def _execute(queue: deque[Job], episode_fn: JobFn, workers: int, write: Callable[..., None]) -> list[Job]:
    """Run jobs from ``queue`` with at most ``workers`` in flight, passing each result to ``write``. If the pool
    breaks, return the jobs that were in flight (unstarted ones stay in ``queue``); else return []."""
    broken: list[Job] = []
    with ProcessPoolExecutor(workers, mp_context=_CONTEXT, initializer=_exit_with_parent,
                             initargs=(os.getpid(),)) as pool:
        running: dict = {}
        while (queue or running) and not broken:
            while queue and len(running) < workers:
                job = queue.popleft()
                running[pool.submit(_run_job, episode_fn, job)] = job
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            if any(isinstance(f.exception(), BrokenProcessPool) for f in finished):
                finished, _ = wait(running)  # a broken pool fails every other future promptly
            for future in finished:
                job = running.pop(future)
                if isinstance(future.exception(), BrokenProcessPool):
                    broken.append(job)
                else:
                    write(*future.result())
    return broken


def _run_job(episode_fn: JobFn, job: Job) -> tuple[str, bool, str | None]:
    """Worker side: run one job and serialise its record; any exception becomes an error record."""
    start = time.perf_counter()
    try:
        result = dict(episode_fn(job))
        record = {**result, **job.fields(), "wall_time": result.get("wall_time", time.perf_counter() - start)}
        return json.dumps(record, default=_to_json), bool(record.get("success")), None
    except Exception as exc:  # an episode's failure must not stop the suite
        return _error_record(job, f"{type(exc).__name__}: {exc}", time.perf_counter() - start,
                             traceback.format_exc())


def _error_record(job: Job, message: str, wall_time: float, trace: str = "") -> tuple[str, bool, str]:
    record = {**job.fields(), "success": False, "termination": "error", "error": message, "traceback": trace,
              "wall_time": wall_time}
    return json.dumps(record), False, f"{job.row.label} {job.family} seed {job.seed}: {message}"


def _to_json(value: Any) -> Any:
    """JSON fallback for numpy scalars and arrays and paths in episode results."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot write {type(value).__name__} to JSON")
