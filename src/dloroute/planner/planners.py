"""High-level planners behind one interface: the VLM planner and three offline planners.

Offline planners read the observed state (``ctx.observation`` and ``ctx.statuses``, computed with
:mod:`dloroute.sim.clip_frame`) and never issue a decision for a clip that is already routed:

- :class:`FixedOrderPlanner`: the ground-truth order; Pull then Insert on the first unrouted clip,
  repeated until it is routed (no Flatten), as the paper's "fixed order" baseline.
- :class:`SymbolicPlanner`: the paper's symbolic baseline: greedy next-closest order from the head,
  Insert when the head is in front of the target (else Pull), Flatten after three failed insertions.
- :class:`RuleBasedPlanner`: the project default: order from the instruction, Insert only when the head
  is in the insertion-feasible region and aligned, Flatten when insertions or pulls keep failing or the
  head is badly placed, done only when every clip is routed in the instructed order.

Geometry is measured in the target clip's frame (m, rad): +x is the insertion direction, the entry face
is at x = -CLIP_DEPTH/2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from dloroute.planner.instruction import greedy_order, parse_instruction
from dloroute.planner.vlm import VLMConfig, VLMPlanner
from dloroute.sim.clip_frame import front_heading, routed_order, to_clip_frame, yaw_to_clip_frame
from dloroute.types import ClipSpec, Decision, Observation, PlannerContext, SkillCall, SkillName

FRONT_SEGMENT_LENGTH = 0.05
"""Arc length (m) from the head over which the front segment's heading is measured."""
INSERT_REGION_X = (-0.15, -0.005)
"""Insertion-feasible region: clip-frame x range (m) of the head, in front of (up to just inside) the entry."""
INSERT_REGION_HALF_Y = 0.09
"""Insertion-feasible region: largest clip-frame |y| (m) of the head."""
INSERT_MAX_HEADING = math.radians(90)
"""Largest angle (rad) between the front segment's heading and the clip's +x for an aligned head."""
NEAR_RADIUS = 0.15
"""Distance (m) from the clip centre within which a head beside or behind the clip is badly placed."""
FRONT_CLEARANCE = 0.035
"""Rule-based planner: Insert only when the rope's front GRASP_SPAN metres keep this distance (m) from every
other clip's centre (the fingers could grasp it there without touching that clip); otherwise Pull."""
GRASP_SPAN = 0.05
"""Arc length (m) from the head where the Insert skill grasps to push (particles 0..2 at 2.5 cm)."""
RULE_FLATTEN_AFTER = 2
"""Rule-based planner: Flatten after this many failed insertions (or failed pulls) in a row."""
SYMBOLIC_FLATTEN_AFTER = 3
"""Symbolic planner: Flatten after this many failed insertions in a row (the paper's baseline)."""


class Planner(Protocol):
    """A high-level planner: one decision per step from a :class:`~dloroute.types.PlannerContext`."""

    name: str

    def reset(self, instruction: str, observation: Observation) -> None:
        """Start an episode; may raise ValueError (e.g. InstructionError) before any motion."""

    def decide(self, ctx: PlannerContext) -> Decision:
        """The next skill and target clip, done, or a failed decision."""


@dataclass(frozen=True)
class HeadPose:
    """The rope head in a clip's frame: position ``x``, ``y`` (m) and front-segment ``heading`` (rad)."""

    x: float
    y: float
    heading: float

    @property
    def in_region(self) -> bool:
        """The head lies in the insertion-feasible region in front of the entry face."""
        return INSERT_REGION_X[0] < self.x < INSERT_REGION_X[1] and abs(self.y) < INSERT_REGION_HALF_Y

    @property
    def aligned(self) -> bool:
        """The front segment points into the opening (within INSERT_MAX_HEADING of +x)."""
        return abs(self.heading) <= INSERT_MAX_HEADING

    @property
    def beside_or_behind(self) -> bool:
        """Near the clip but past the region's front edge: beside the posts or behind the clip."""
        return self.x >= INSERT_REGION_X[1] and math.hypot(self.x, self.y) < NEAR_RADIUS


def head_pose(clip: ClipSpec, rope: np.ndarray) -> HeadPose:
    """The head of ``rope`` ((n, 2 or 3) world positions (m), head first) in ``clip``'s frame.

    The heading is ``front_heading`` over FRONT_SEGMENT_LENGTH of arc.
    """
    local = to_clip_frame(clip, np.asarray(rope, dtype=float)[0, :2])
    heading = yaw_to_clip_frame(clip, front_heading(rope, FRONT_SEGMENT_LENGTH))
    return HeadPose(float(local[0]), float(local[1]), float(heading))


def front_clear(observation: Observation, target: str) -> bool:
    """True when no clip other than ``target`` lies within FRONT_CLEARANCE of the rope's front GRASP_SPAN."""
    xy = np.asarray(observation.rope, dtype=float)[:, :2]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    front = xy[arc <= GRASP_SPAN]
    return all(
        np.min(np.hypot(front[:, 0] - c.x, front[:, 1] - c.y)) >= FRONT_CLEARANCE
        for c in observation.clips
        if c.name != target
    )


def failures_since_recovery(ctx: PlannerContext) -> int:
    """Failed insertions in a row, not counting those before the latest Flatten.

    Capped by ``ctx.consecutive_failures`` (the episode loop's counter): a Flatten starts the count
    afresh here even when the loop's counter is not reset by it.
    """
    n = 0
    for rec in reversed(ctx.history):
        call = rec.decision.call
        if call is None or call.skill == "pull":
            continue
        if call.skill == "flatten" or (rec.result is not None and rec.result.success):
            break
        n += 1
    return min(n, ctx.consecutive_failures)


def failed_pulls_in_a_row(ctx: PlannerContext) -> int:
    """Pulls at the end of the history that did not leave the head in front of the target, aligned."""
    n = 0
    for rec in reversed(ctx.history):
        call = rec.decision.call
        if call is None or call.skill != "pull" or rec.result is None or rec.result.success:
            break
        n += 1
    return n


def _last_skill(ctx: PlannerContext) -> SkillName | None:
    for rec in reversed(ctx.history):
        if rec.decision.call is not None:
            return rec.decision.call.skill
    return None


def _call(skill: SkillName, clip: str, why: str) -> Decision:
    return Decision(call=SkillCall(skill=skill, clip=clip), reasoning=why)


def _pending(order: tuple[str, ...], ctx: PlannerContext) -> list[str]:
    """Clips of ``order`` the rope does not pass through yet, in order."""
    return [c for c in order if not ctx.status(c).routed]


def _describe(clip: str, pose: HeadPose) -> str:
    return (
        f"head at ({100 * pose.x:+.1f}, {100 * pose.y:+.1f}) cm, heading {math.degrees(pose.heading):+.0f} deg "
        f"in the {clip} clip's frame"
    )


def _check_order(order: tuple[str, ...], observation: Observation) -> None:
    names = sorted(c.name for c in observation.clips)
    if sorted(order) != names:
        raise ValueError(f"order {order} is not a permutation of the scene's clips {names}")


class FixedOrderPlanner:
    """The ground-truth order; Pull, then Insert, on the first unrouted clip until it is routed."""

    name = "fixed_order"

    def __init__(self, order: tuple[str, ...]):
        self.order = tuple(order)

    def reset(self, instruction: str, observation: Observation) -> None:
        _check_order(self.order, observation)

    def decide(self, ctx: PlannerContext) -> Decision:
        pending = _pending(self.order, ctx)
        if not pending:
            return Decision(call=None, done=True, reasoning="every clip is routed")
        target = pending[0]
        last = ctx.history[-1].decision.call if ctx.history else None
        if last == SkillCall("pull", target):
            return _call("insert", target, f"pulled toward {target}: insert")
        return _call("pull", target, f"{target} is the next clip of the order: pull toward it")


class SymbolicPlanner:
    """The paper's symbolic baseline on ground-truth poses.

    Order: greedy next-closest from the head (:func:`~dloroute.planner.instruction.greedy_order`), fixed
    at reset; the instruction is ignored. Target: the first clip of that order not routed (an insertion
    succeeded when the rope head passed through the opening). Insert when the head is in front of the
    target (in the insertion-feasible region, heading ignored) or inside its opening, else Pull; Flatten
    after SYMBOLIC_FLATTEN_AFTER failed insertions in a row. Done when every clip is routed.
    """

    name = "symbolic"

    def __init__(self) -> None:
        self.order: tuple[str, ...] = ()

    def reset(self, instruction: str, observation: Observation) -> None:
        self.order = greedy_order(observation.clips, observation.head[:2], ahead_only=False)

    def decide(self, ctx: PlannerContext) -> Decision:
        pending = _pending(self.order, ctx)
        if not pending:
            return Decision(call=None, done=True, reasoning="every clip is routed")
        target = pending[0]
        failures = failures_since_recovery(ctx)
        if failures >= SYMBOLIC_FLATTEN_AFTER:
            return _call("flatten", target, f"{failures} failed insertions into {target} in a row: flatten")
        pose = head_pose(ctx.observation.clip(target), ctx.observation.rope)
        if ctx.status(target).rope_in or pose.in_region:
            return _call("insert", target, f"{_describe(target, pose)}: in front of the clip, insert")
        return _call("pull", target, f"{_describe(target, pose)}: not in front of the clip, pull")


class RuleBasedPlanner:
    """The default offline planner: instruction order, feasibility rules and failure recovery.

    Order: :func:`~dloroute.planner.instruction.parse_instruction` at reset (InstructionError before any
    motion). Target: the first clip of the order not routed. Rules, first match wins:

    1. every clip routed: done if the routed order is the instructed one, else a failed decision (no
       skill can undo a routing); never done while a clip is unrouted;
    2. RULE_FLATTEN_AFTER failed insertions, or failed pulls, in a row: Flatten;
    3. head inside the target's opening, or in its insertion-feasible region and aligned with the rope's
       front clear of the other clips (``front_clear``): Insert; aligned but not clear: Pull, or Insert
       when the last Pull failed (pulling does not free a front that lies in a clip just left);
    4. head badly placed near the target (in the region but misaligned, or beside/behind the clip) and
       the previous skill was not a Flatten: Flatten;
    5. otherwise Pull toward the target (after the previous clip of the order is routed, or for the
       first clip when the head is away from it).
    """

    name = "rule_based"

    def __init__(self) -> None:
        self.order: tuple[str, ...] = ()

    def reset(self, instruction: str, observation: Observation) -> None:
        self.order = parse_instruction(instruction, observation.clips, observation.head[:2])

    def decide(self, ctx: PlannerContext) -> Decision:
        obs = ctx.observation
        pending = _pending(self.order, ctx)
        if not pending:
            routed = routed_order(obs.clips, obs.rope)
            if routed == self.order:
                return Decision(call=None, done=True, reasoning=f"every clip is routed in order {routed}")
            return Decision(
                call=None, failed=True, error=f"every clip is routed but in order {routed}, not {self.order}"
            )
        target = pending[0]
        failures = failures_since_recovery(ctx)
        if failures >= RULE_FLATTEN_AFTER:
            return _call("flatten", target, f"{failures} failed insertions into {target} in a row: flatten")
        pulls = failed_pulls_in_a_row(ctx)
        if pulls >= RULE_FLATTEN_AFTER:
            return _call("flatten", target, f"{pulls} pulls in a row left the head misplaced: flatten")
        pose = head_pose(obs.clip(target), obs.rope)
        where = _describe(target, pose)
        if ctx.status(target).rope_in:
            return _call("insert", target, f"{where}: the head is inside the opening, insert")
        if pose.in_region and pose.aligned and front_clear(obs, target):
            return _call("insert", target, f"{where}: in the feasible region and aligned, insert")
        if pose.in_region and pose.aligned and pulls:
            return _call("insert", target, f"{where}: aligned, and the last pull did not clear the front, insert")
        if pose.in_region and pose.aligned:
            return _call("pull", target, f"{where}: aligned, but the front still lies in another clip, pull")
        if (pose.in_region or pose.beside_or_behind) and _last_skill(ctx) != "flatten":
            problem = "misaligned" if pose.in_region else "beside or behind the clip"
            return _call("flatten", target, f"{where}: {problem}, flatten")
        return _call("pull", target, f"{where}: away from the opening, pull")


PLANNER_NAMES = ("vlm", "vlm_no_fr", "fixed_order", "symbolic", "rule_based")


def make_planner(
    name: str,
    *,
    scene_order: tuple[str, ...],
    vlm_config: VLMConfig | None = None,
    run_dir: Path | None = None,
    replay_dir: Path | None = None,
) -> Planner:
    """A planner by name (PLANNER_NAMES). ``scene_order`` is the ground truth the fixed-order planner uses.

    The VLM planners take ``vlm_config`` (default: GPT-5 on the OpenAI cloud) with ``failure_reasoning``
    set by the name, record their calls in ``run_dir`` and replay from ``replay_dir`` when given.
    """
    if name in ("vlm", "vlm_no_fr"):
        config = (vlm_config or VLMConfig()).model_copy(update={"failure_reasoning": name == "vlm"})
        return VLMPlanner(config, run_dir=run_dir, replay_dir=replay_dir)
    if name == "fixed_order":
        return FixedOrderPlanner(scene_order)
    if name == "symbolic":
        return SymbolicPlanner()
    if name == "rule_based":
        return RuleBasedPlanner()
    raise ValueError(f"unknown planner {name!r}; choose one of {', '.join(PLANNER_NAMES)}")
