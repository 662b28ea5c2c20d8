import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import eval_fakes
import pytest

from dloroute.eval.runner import (
    PARENT_POLL_S,
    RoutingEpisode,
    RunInProgress,
    _exclusive,
    read_records,
    repair,
    resolve,
    run_suite,
)
from dloroute.eval.suites import Suite, record_key, row

SUITE = Suite("routing", rows=(row("fixed_order", "rl"), row("rule_based", "heuristic")),
              families=("implicit", "clips_4_5"), seeds=(0, 1, 2))


def keys(path: Path) -> Counter:
    return Counter(record_key(r) for r in read_records(path))


def test_one_record_per_job_and_rerun_skips_all(tmp_path):
    out = tmp_path / "routing.jsonl"
    stats = run_suite(SUITE.jobs(), out, workers=2, episode_fn=eval_fakes.fake_episode, progress=False)
    assert (stats.total, stats.skipped, stats.ran, stats.errors) == (12, 0, 12, 0)
    assert keys(out) == Counter(j.key for j in SUITE.jobs())
    first = next(r for r in read_records(out) if record_key(r) == ("fixed_order+rl", "implicit", 0))
    assert first["low_level"] == "rl" and first["length"] == 10 and "wall_time" in first
    before = out.read_bytes()
    again = run_suite(SUITE.jobs(), out, workers=2, episode_fn=eval_fakes.fake_episode, progress=False)
    assert (again.skipped, again.ran) == (12, 0) and out.read_bytes() == before


def test_raising_episode_becomes_an_error_record(tmp_path):
    out = tmp_path / "routing.jsonl"
    stats = run_suite(SUITE.jobs(), out, workers=2, episode_fn=eval_fakes.raising_episode, progress=False)
    assert stats.errors == 4 and keys(out) == Counter(j.key for j in SUITE.jobs())
    errors = [r for r in read_records(out) if r["termination"] == "error"]
    assert {r["seed"] for r in errors} == {1} and len(errors) == 4
    assert all(r["success"] is False and r["error"] == "RuntimeError: boom" for r in errors)
    assert "raise RuntimeError" in errors[0]["traceback"]
    kept = [r for r in read_records(out) if r["termination"] != "error"]

    retry = run_suite(SUITE.jobs(), out, workers=2, episode_fn=eval_fakes.fake_episode, progress=False,
                      retry_errors=True)
    assert (retry.skipped, retry.ran, retry.errors) == (8, 4, 0)
    assert keys(out) == Counter(j.key for j in SUITE.jobs())
    assert read_records(out)[:8] == kept


def test_worker_crash_is_pinned_on_its_job(tmp_path):
    out = tmp_path / "routing.jsonl"
    jobs = SUITE.jobs()[:3]  # seeds 0, 1, 2 of one row and family
    stats = run_suite(jobs, out, workers=2, episode_fn=eval_fakes.crashing_episode, progress=False)
    records = {r["seed"]: r for r in read_records(out)}
    assert keys(out) == Counter(j.key for j in jobs) and stats.errors == 1
    assert records[2]["termination"] == "error" and "worker process died" in records[2]["error"]
    assert records[0]["success"] and records[1]["termination"] == "timeout"


def test_killed_run_resumes_without_losing_or_repeating(tmp_path):
    out = tmp_path / "routing.jsonl"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(eval_fakes.__file__).parent),
                                                         os.environ.get("PYTHONPATH", "")])}
    code = f"import eval_fakes; eval_fakes.run_small({str(out)!r})"
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, start_new_session=True)
    deadline = time.monotonic() + 30
    while len(read_records(out)) < 4:
        assert proc.poll() is None and time.monotonic() < deadline, "runner ended before it was killed"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the runner and its workers, as a hard stop would
    proc.wait()
    survivors = read_records(out)
    assert 4 <= len(survivors) < len(eval_fakes.SMALL.jobs())
    with out.open("a") as f:
        f.write('{"row": "fixed_order+rl", "family": "impl')  # a torn write

    stats = run_suite(eval_fakes.SMALL.jobs(), out, workers=2, episode_fn=eval_fakes.fake_episode, progress=False)
    assert keys(out) == Counter(j.key for j in eval_fakes.SMALL.jobs())
    assert read_records(out)[: len(survivors)] == survivors
    assert stats.skipped == len(survivors) and stats.ran == len(eval_fakes.SMALL.jobs()) - len(survivors)


def test_a_second_run_on_the_same_file_is_refused(tmp_path):
    out = tmp_path / "routing.jsonl"
    with _exclusive(out):  # as a run in another process would hold it
        with pytest.raises(RunInProgress, match=f"pid {os.getpid()}"):
            run_suite(SUITE.jobs(), out, workers=1, episode_fn=eval_fakes.fake_episode, progress=False)
    assert read_records(out) == []
    stats = run_suite(SUITE.jobs(), out, workers=1, episode_fn=eval_fakes.fake_episode, progress=False)
    assert stats.ran == len(SUITE.jobs())


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return not Path(f"/proc/{pid}/stat").exists() or Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"


def test_workers_exit_when_the_runner_is_killed(tmp_path):
    pids = tmp_path / "pids"
    pids.mkdir()
    env = {**os.environ, "DLOROUTE_TEST_PID_DIR": str(pids),
           "PYTHONPATH": os.pathsep.join([str(Path(eval_fakes.__file__).parent), os.environ.get("PYTHONPATH", "")])}
    code = f"import eval_fakes; eval_fakes.run_small({str(tmp_path / 'routing.jsonl')!r}, 'pid_recording_episode')"
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, start_new_session=True)
    try:
        deadline = time.monotonic() + 30
        while len(list(pids.iterdir())) < 2:
            assert proc.poll() is None and time.monotonic() < deadline, "runner ended before it was killed"
            time.sleep(0.05)
        workers = [int(p.name) for p in pids.iterdir()]
        assert all(_alive(w) for w in workers)
        os.kill(proc.pid, signal.SIGKILL)  # the runner only: its workers are orphaned
        proc.wait()
        deadline = time.monotonic() + 10 * PARENT_POLL_S
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(w) for w in workers), "orphaned workers kept running"
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def test_routing_episode_builds_scene_and_config(tmp_path):
    fn = RoutingEpisode(make_config="eval_fakes:fake_make_config", run_dir=tmp_path,
                        episode_fn=eval_fakes.fake_run_episode)
    out = tmp_path / "routing.jsonl"
    run_suite(SUITE.jobs()[:2], out, workers=1, episode_fn=fn, progress=False)
    first = read_records(out)[0]
    assert first["planner"] == "fixed_order" and first["success"] and first["n_clips"] == 3
    assert first["routed_order"] and first["wall_time"] == 0.01


def test_resolve_dotted_names():
    assert resolve("eval_fakes:fake_episode") is eval_fakes.fake_episode
    with pytest.raises(ValueError, match="package.module:attribute"):
        resolve("eval_fakes.fake_episode")


def test_torn_tail_is_cut_and_a_corrupt_middle_line_raises(tmp_path):
    path = tmp_path / "x.jsonl"
    good = json.dumps({"row": "a", "family": "f", "seed": 0}) + "\n"
    path.write_text(good + '{"row": "a", "fam')
    assert read_records(path) == [{"row": "a", "family": "f", "seed": 0}]
    assert repair(path) > 0 and path.read_text() == good
    path.write_text(good + "{not json\n")  # a complete but corrupt last line is torn too
    assert repair(path) == len("{not json\n")
    path.write_text("{not json\n" + good)
    with pytest.raises(ValueError, match="corrupt"):
        read_records(path)
    assert read_records(tmp_path / "missing.jsonl") == []
