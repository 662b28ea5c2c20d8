"""The paper's heuristic insertion baseline (Sec. IV-B), open loop, two pick-and-place primitives.

1. Grasp the head and place it on the clip's centreline in front of the entry face.
2. Regrasp the rope further back and push it straight along the centreline through the clip.
"""

from __future__ import annotations

from dloroute.sim.physics import Physics
from dloroute.skills.primitives import InsertParams, insert
from dloroute.types import ClipSpec, SkillResult

PLACE_X = -0.05
"""Clip-frame x (m) where the head is placed in step 1."""
REGRASP_INDEX = 4
"""Particle grasped in step 2 (10 cm behind the head at 2.5 cm spacing)."""
PUSH_TO_X = 0.045
"""Clip-frame x (m) the head should reach if the rope stays straight."""


def heuristic_insert(physics: Physics, clip: ClipSpec) -> SkillResult:
    """Run both steps; the result is the second step's, with ``primitives`` = 2 when both ran."""
    place = insert(physics, clip, InsertParams(0, ((PLACE_X - 0.03, 0.0, 0.0), (PLACE_X, 0.0, 0.0))))
    if place.collision:
        return place
    back = REGRASP_INDEX * physics.scene.rope.spacing
    x_end = PUSH_TO_X - back
    push = insert(physics, clip, InsertParams(REGRASP_INDEX, ((x_end - 0.04, 0.0, 0.0), (x_end, 0.0, 0.0))))
    return SkillResult(
        skill="insert", clip=clip.name, success=push.success, collision=push.collision, reason=push.reason,
        primitives=2, signed_distance=push.signed_distance, sim_time=place.sim_time + push.sim_time,
    )
