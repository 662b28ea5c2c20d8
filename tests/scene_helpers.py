"""Hand-built test scenes (metres, radians, world frame)."""

from __future__ import annotations

import numpy as np

from dloroute.types import ClipSpec, RopeSpec, SceneSpec

SHORT_ROPE = RopeSpec(length=0.6, n_particles=25, mass=0.03)
"""The insertion env's rope: same spacing and section as the routing rope, half as long (faster)."""


def one_clip_scene(head_y: float = 0.0, head_x: float = -0.08, yaw: float = 0.0, scale: float = 1.0) -> SceneSpec:
    """A clip at the origin facing +x rotated by ``yaw``; a straight rope whose head is at (head_x, head_y)
    in the clip's frame, pointing along the clip's axis."""
    c, s = np.cos(yaw), np.sin(yaw)
    head = (head_x * c - head_y * s, head_x * s + head_y * c)
    return SceneSpec(
        family="test", seed=0, clips=(ClipSpec("red", 0.0, 0.0, yaw, scale),), order=("red",),
        instruction="insert", rope_head=(float(head[0]), float(head[1])), rope_yaw=yaw, rope=SHORT_ROPE,
    )

