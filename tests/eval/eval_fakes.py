"""Fake job and episode functions for the evaluation tests: top-level, so spawned workers can import them."""

from __future__ import annotations

import os
import time
from pathlib import Path

from dloroute.eval.runner import run_suite
from dloroute.eval.suites import Job, Row, Suite, row
from dloroute.types import EpisodeResult

SMALL = Suite("routing", rows=(row("fixed_order", "rl"), row("rule_based", "rl")), families=("implicit",),
              seeds=tuple(range(8)))


def fake_episode(job: Job) -> dict:
    """A deterministic instant 'episode': even seeds succeed."""
    return {"success": job.seed % 2 == 0, "termination": "success" if job.seed % 2 == 0 else "timeout",
            "clips_routed": 3 - job.seed % 2, "length": 10 + job.seed}


def slow_episode(job: Job) -> dict:
    time.sleep(0.2)
    return fake_episode(job)


def pid_recording_episode(job: Job) -> dict:
    """A slow 'episode' that first leaves its worker's pid in the folder named by DLOROUTE_TEST_PID_DIR."""
    (Path(os.environ["DLOROUTE_TEST_PID_DIR"]) / str(os.getpid())).touch()
    time.sleep(0.5)
    return fake_episode(job)


def raising_episode(job: Job) -> dict:
    if job.seed == 1:
        raise RuntimeError("boom")
    return fake_episode(job)


def crashing_episode(job: Job) -> dict:
    """Kills its worker process outright for seed 2, as a native crash would."""
    if job.seed == 2:
        os._exit(3)
    return fake_episode(job)


def fake_make_config(row: Row, family: str, seed: int, run_dir: Path) -> dict:
    return {"planner": row.high_level, "low_level": row.low_level, "run_dir": str(run_dir)}


def fake_run_episode(scene, config: dict) -> EpisodeResult:
    return EpisodeResult(family=scene.family, seed=scene.seed, planner=config["planner"],
                         low_level=config["low_level"], success=True, termination="success",
                         clips_routed=len(scene.clips), n_clips=len(scene.clips), length=len(scene.clips),
                         wall_time=0.01, routed_order=scene.order)


def run_small(out_jsonl: str, episode: str = "slow_episode") -> None:
    """The run the kill tests start in a subprocess and kill; ``episode`` names a job function here."""
    run_suite(SMALL.jobs(), Path(out_jsonl), workers=2, episode_fn=globals()[episode], progress=False)
