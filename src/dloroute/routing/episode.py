"""The routing loop: observe -> planner decision -> skill -> termination checks.

An episode succeeds when the planner declares the task done and every clip is routed in the
instruction's order. It fails on a gripper-clip collision, when the planner asks for a skill once the
step limit's primitives are spent (timeout; declaring done then still succeeds), when it declares done
with clips unrouted or out of order (early termination), after ``MAX_FAILED_DECISIONS``
failed decisions in a row (planner failure), or when the simulation becomes unstable. ``length`` counts
pick-and-place primitives, as the paper's episode length. With image perception, a scene the perceiver
cannot measure ends the episode as ``perception_failure``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dloroute.sim.clip_frame import clip_status, routed_order
from dloroute.sim.physics import Physics, SimulationError
from dloroute.skills import primitives
from dloroute.skills.heuristic import heuristic_insert
from dloroute.types import (
    Decision,
    EpisodeResult,
    Observation,
    PlannerContext,
    SceneSpec,
    SkillResult,
    StepRecord,
)

MAX_FAILED_DECISIONS = 3
"""Failed planner decisions in a row that end the episode."""


def step_limit(n_clips: int) -> int:
    """Pick-and-place primitives allowed in an episode with ``n_clips`` clips (30 for 3, 46 for 5)."""
    return 8 * n_clips + 6


@dataclass(frozen=True)
class EpisodeConfig:
    """How to run an episode. ``planner``: vlm, vlm_no_fr, fixed_order, symbolic, rule_based;
    ``low_level``: rl or heuristic; ``perception``: oracle or image."""

    planner: str = "rule_based"
    low_level: str = "rl"
    perception: str = "oracle"
    policy_path: str | None = None
    """Insertion policy weights (.npz); None = the shipped policy."""
    vlm: Any = None
    """A ``dloroute.planner.vlm.VLMConfig`` for the VLM planners."""
    record_dir: str | None = None
    """Folder for the planner's recorded model calls."""
    replay_dir: str | None = None
    """Answer the VLM planner from a recorded run folder instead of the network."""
    video: str | None = None
    """Write an MP4 of the episode here."""
    step_limit: int | None = None
    """Override of ``step_limit(n_clips)``."""
    stop_before_contact: bool = True
    """Arm motions stop short of touching a clip (``Physics.stop_before_contact``); grasps on a clip still
    count as collisions. Off: every gripper-clip contact ends the episode as a collision."""


class LowLevel:
    """Executes planner skill calls on the physics with the chosen Insert implementation."""

    def __init__(self, kind: str, policy_path: str | None = None):
        if kind not in ("rl", "heuristic"):
            raise ValueError(f"unknown low-level policy {kind!r}; choose rl or heuristic")
        self.kind = kind
        self.policy = None
        if kind == "rl":
            from dloroute.skills.policy import InsertPolicy

            self.policy = InsertPolicy.load(policy_path)

    def __call__(self, physics: Physics, skill: str, clip_name: str) -> SkillResult:
        clip = physics.scene.clip(clip_name)
        if skill == "insert":
            return self.policy.insert(physics, clip) if self.policy else heuristic_insert(physics, clip)
        if skill == "pull":
            return primitives.pull(physics, clip)
        if skill == "flatten":
            return primitives.flatten(physics, clip)
        raise ValueError(f"unknown skill {skill!r}")


class PerceptionFailure(RuntimeError):
    """The perceiver could not measure the scene (e.g. the rope's head left the camera's view)."""


def _perceiver(kind: str) -> Callable[[Physics, Any], Observation]:
    if kind == "oracle":
        return lambda physics, _renderer: Observation(clips=physics.scene.clips, rope=physics.rope())
    if kind == "image":
        from dloroute.perception import PerceptionError, perceive_physics

        def perceive(physics: Physics, renderer) -> Observation:
            try:
                return perceive_physics(physics, renderer)
            except PerceptionError as err:
                raise PerceptionFailure(str(err)) from err

        return perceive
    raise ValueError(f"unknown perception {kind!r}; choose oracle or image")


def run_episode(
    scene: SceneSpec,
    config: EpisodeConfig,
    *,
    planner=None,
    on_step: Callable[[StepRecord, Observation], None] | None = None,
) -> EpisodeResult:
    """Run one routing episode and return its result (see the module docstring)."""
    from dloroute.planner.planners import make_planner
    from dloroute.routing.video import EpisodeVideo

    start = time.time()
    physics = Physics(scene)
    physics.stop_before_contact = config.stop_before_contact
    physics.settle(0.3)
    low_level = LowLevel(config.low_level, config.policy_path)
    perceive = _perceiver(config.perception)
    limit = config.step_limit or step_limit(len(scene.clips))
    needs_images = config.planner.startswith("vlm") or config.perception == "image" or config.video
    renderer = None
    if needs_images:
        from dloroute.sim.render import SceneRenderer

        renderer = SceneRenderer(physics)
    video = EpisodeVideo(physics, renderer, config.video) if config.video else None
    if planner is None:
        planner = make_planner(
            config.planner, scene_order=scene.order, vlm_config=config.vlm,
            run_dir=Path(config.record_dir) if config.record_dir else None,
            replay_dir=Path(config.replay_dir) if config.replay_dir else None,
        )
    history: list[StepRecord] = []
    length = failures = failed_decisions = 0
    termination = None
    try:
        observation = perceive(physics, renderer)
        planner.reset(scene.instruction, observation)
        while termination is None:
            statuses = tuple(clip_status(c, observation.rope) for c in observation.clips)
            ctx = PlannerContext(
                instruction=scene.instruction, observation=observation, statuses=statuses,
                history=tuple(history), consecutive_failures=failures, step=length, step_limit=limit,
                views=renderer.render if renderer else None,
            )
            decision: Decision = planner.decide(ctx)
            result = None
            if decision.failed:
                failed_decisions += 1
                if failed_decisions >= MAX_FAILED_DECISIONS:
                    termination = "planner_failure"
            elif decision.done or decision.call is None:
                done = routed_order(scene.clips, physics.rope())
                termination = "success" if done == scene.order else "early_termination"
            elif length >= limit:
                termination = "timeout"  # the planner asked for one more primitive than the limit allows
            else:
                failed_decisions = 0
                if video:
                    video.caption = f"step {length + 1}: {decision.call.skill} {decision.call.clip}"
                result = low_level(physics, decision.call.skill, decision.call.clip)
                length += result.primitives
                if decision.call.skill == "insert":
                    failures = 0 if result.success else failures + 1
                elif decision.call.skill == "flatten":
                    failures = 0
                if result.collision:
                    termination = "collision"
            record = StepRecord(step=len(history), decision=decision, result=result)
            history.append(record)
            observation = perceive(physics, renderer)
            if on_step:
                on_step(record, observation)
    except (SimulationError, PerceptionFailure) as err:
        termination = "unstable" if isinstance(err, SimulationError) else "perception_failure"
        history.append(StepRecord(step=len(history), decision=Decision(call=None, failed=True, error=str(err)), result=None))
    finally:
        done = routed_order(scene.clips, physics.rope())
        if video:
            video.close(final_caption=f"{termination}: routed {', '.join(done) or 'none'}")
        if renderer:
            renderer.close()
    return EpisodeResult(
        family=scene.family, seed=scene.seed, planner=config.planner, low_level=config.low_level,
        success=termination == "success", termination=termination, clips_routed=_correct_prefix(done, scene.order),
        n_clips=len(scene.clips), length=length, wall_time=round(time.time() - start, 3), routed_order=done,
        steps=tuple(_step_dict(r) for r in history),
    )


def _correct_prefix(done: tuple[str, ...], order: tuple[str, ...]) -> int:
    """Clips routed in agreement with the instruction: the length of the common prefix."""
    n = 0
    for a, b in zip(done, order):
        if a != b:
            break
        n += 1
    return n


def _step_dict(record: StepRecord) -> dict:
    d = record.decision
    out = {
        "step": record.step,
        "skill": d.call.skill if d.call else None,
        "clip": d.call.clip if d.call else None,
        "done": d.done,
        "failed": d.failed,
        "reasoning": d.reasoning,
        "error": d.error,
    }
    if record.result:
        r = record.result
        out.update(success=r.success, collision=r.collision, primitives=r.primitives,
                   signed_distance=r.signed_distance, reason=r.reason)
    return out


def write_result(result: EpisodeResult, path: Path) -> None:
    import json

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result.to_dict(), indent=2) + "\n")
