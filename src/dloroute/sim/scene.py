"""Seeded scene generator for the paper's four task families.

A layout is a chain of clips: clip k+1 lies at the end of a circular arc that leaves clip k along its
insertion direction and turns by an angle Delta_k, and clip k+1 faces along the arc's end. The families
differ in the turns (the paper, Sec. IV-B):

| family          | clips | turn between clips        | instruction                          |
|-----------------|-------|---------------------------|--------------------------------------|
| implicit        | 3     | mild, |Delta| <= 35 deg   | "all the clips" (natural order)      |
| fixed_spatial   | 3     | |Delta| in 95-130 deg     | spatial words (left/right, top/bottom, nearest/farthest) |
| fixed_attribute | 3     | |Delta| in 95-130 deg     | colour order                         |
| clips_4_5       | 4-5   | |Delta| in 30-100 deg     | colour order                         |

The rope starts straight in front of the first clip: its head is drawn in a 5 cm (along the clip axis)
x 10 cm (lateral) rectangle 8-13 cm before the clip centre, its direction within +-10 deg of the axis.
All positions are metres in the world frame; angles are radians.
"""

from __future__ import annotations

import math

import numpy as np

from dloroute.sim.clip_frame import to_world_frame
from dloroute.types import CLIP_COLOURS, FAMILIES, ClipSpec, RopeSpec, SceneSpec

TABLE_HALF = (0.95, 0.65)
"""Usable table half extents (m, world x and y)."""
MIN_CLIP_SEPARATION = 0.11
"""Minimum distance (m) between two clip centres."""
ROPE_CLEARANCE = 0.06
"""Minimum distance (m) from a clip other than the first to the starting rope."""
HEAD_RECT = ((-0.13, -0.08), (-0.05, 0.05))
"""Rope head start (m, first clip's frame): x range (along the axis), y range (lateral)."""
HEAD_ANGLE = math.radians(10)
"""Rope start direction range (+-, rad) about the first clip's axis."""

_TURNS = {
    "implicit": (0.0, math.radians(35), 0.16, 0.20),
    "fixed_spatial": (math.radians(95), math.radians(130), 0.15, 0.18),
    "fixed_attribute": (math.radians(95), math.radians(130), 0.15, 0.18),
    "clips_4_5": (math.radians(30), math.radians(100), 0.14, 0.17),
}
"""Per family: |turn| range (rad) and chord length range (m) between consecutive clips."""

SPATIAL_RULES: dict[str, tuple[str, ...]] = {
    "left_to_right": ("Route the rope through the clips from left to right.",
                      "Thread the cable through the clips going from left to right."),
    "right_to_left": ("Route the rope through the clips from right to left.",
                      "Thread the cable through the clips going from right to left."),
    "bottom_to_top": ("Route the rope through the clips from bottom to top.",
                      "Thread the cable through the clips going from the bottom to the top."),
    "top_to_bottom": ("Route the rope through the clips from top to bottom.",
                      "Thread the cable through the clips going from the top to the bottom."),
    "nearest_to_farthest": ("Route the rope through the clips from the nearest to the farthest.",
                            "Thread the cable through the clips from nearest to farthest from the rope end."),
    "farthest_to_nearest": ("Route the rope through the clips from the farthest to the nearest.",
                            "Thread the cable through the clips from farthest to nearest from the rope end."),
}
"""Spatial orders and their instruction phrasings. Left/right are world -x/+x, bottom/top -y/+y (the
top-down image's axes); nearest/farthest are distances from the rope head at the start."""
SPATIAL_MARGIN = 0.03
"""Consecutive clips must differ by this much (m) along a spatial key for the phrase to be unambiguous."""

IMPLICIT_PHRASES = (
    "Route the rope through all the clips.",
    "Thread the cable through every clip along the natural path.",
)


def spatial_key(rule: str, clip: ClipSpec, head_xy: tuple[float, float]) -> float:
    """Sort key (m) of ``clip`` under a spatial rule: ascending key = routing order."""
    dist = math.hypot(clip.x - head_xy[0], clip.y - head_xy[1])
    return {
        "left_to_right": clip.x,
        "right_to_left": -clip.x,
        "bottom_to_top": clip.y,
        "top_to_bottom": -clip.y,
        "nearest_to_farthest": dist,
        "farthest_to_nearest": -dist,
    }[rule]


def colour_instruction(order: tuple[str, ...], rng: np.random.Generator) -> str:
    """An explicit colour-order instruction such as 'red clip, then the blue clip, then ...'."""
    if rng.random() < 0.5:
        return "Route the rope through the " + ", then the ".join(f"{c} clip" for c in order) + "."
    return "Thread the cable through " + ", ".join(order[:-1]) + f" and {order[-1]}, in that order."


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def _sample_chain(family: str, rng: np.random.Generator) -> tuple[list[tuple[float, float, float]], float]:
    """Clip poses (x, y, yaw) with the first clip at the origin, and the first clip's yaw."""
    lo, hi, c_lo, c_hi = _TURNS[family]
    n = int(rng.integers(4, 6)) if family == "clips_4_5" else 3
    yaw = float(rng.uniform(-math.radians(30), math.radians(30)))
    poses = [(0.0, 0.0, yaw)]
    sign = 1.0 if rng.random() < 0.5 else -1.0
    for _ in range(n - 1):
        turn = float(rng.uniform(lo, hi))
        if family == "implicit":
            sign = 1.0 if rng.random() < 0.5 else -1.0
        else:
            sign = -sign  # zig-zag: alternate turns keep the chain moving forward
        delta = sign * turn
        chord = float(rng.uniform(c_lo, c_hi))
        x, y, a = poses[-1]
        poses.append((x + chord * math.cos(a + delta / 2), y + chord * math.sin(a + delta / 2), a + delta))
    return poses, yaw


def _valid(clips: list[ClipSpec], head: np.ndarray, tail: np.ndarray) -> bool:
    pts = np.array([[c.x, c.y] for c in clips])
    for i in range(len(clips)):
        for j in range(i + 1, len(clips)):
            if np.linalg.norm(pts[i] - pts[j]) < MIN_CLIP_SEPARATION:
                return False
        if i > 0 and _point_segment_distance(pts[i], head, tail) < ROPE_CLEARANCE:
            return False
        # The approach lane in front of each clip (12 cm along -x, +-4 cm lateral) is free of other clips.
        lane = to_world_frame(clips[i], np.array([[-0.12, 0.0], [-0.02, 0.0]]))
        for j in range(len(clips)):
            if j != i and _point_segment_distance(pts[j], lane[0], lane[1]) < 0.05:
                return False
    return bool(
        (np.abs(pts[:, 0]) < TABLE_HALF[0] - 0.1).all()
        and (np.abs(pts[:, 1]) < TABLE_HALF[1] - 0.1).all()
        and (np.abs(tail) < np.array(TABLE_HALF)).all()
    )


def generate_scene(family: str, seed: int, *, rope: RopeSpec | None = None) -> SceneSpec:
    """The scene of ``family`` for ``seed``: the same arguments always give the same scene."""
    if family not in FAMILIES:
        raise ValueError(f"unknown task family {family!r}; choose one of {', '.join(FAMILIES)}")
    rope = rope or RopeSpec()
    rng = np.random.default_rng([seed, FAMILIES.index(family)])
    for _ in range(1000):
        poses, yaw0 = _sample_chain(family, rng)
        names = [str(c) for c in rng.permutation(list(CLIP_COLOURS))[: len(poses)]]
        # Rope start in the first clip's frame, then the whole layout is centred on the table.
        hx, hy = rng.uniform(*HEAD_RECT[0]), rng.uniform(*HEAD_RECT[1])
        rope_yaw = yaw0 + float(rng.uniform(-HEAD_ANGLE, HEAD_ANGLE))
        head = np.array([hx * math.cos(yaw0) - hy * math.sin(yaw0), hx * math.sin(yaw0) + hy * math.cos(yaw0)])
        tail = head - rope.length * np.array([math.cos(rope_yaw), math.sin(rope_yaw)])
        pts = np.array([p[:2] for p in poses] + [tail])
        shift = -0.5 * (pts.min(axis=0) + pts.max(axis=0))
        clips = [
            ClipSpec(name=nm, x=round(float(x + shift[0]), 5), y=round(float(y + shift[1]), 5), yaw=round(a, 5))
            for nm, (x, y, a) in zip(names, poses)
        ]
        head, tail = head + shift, tail + shift
        if not _valid(clips, head, tail):
            continue
        order = tuple(names)
        head_xy = (round(float(head[0]), 5), round(float(head[1]), 5))
        instruction = _instruction(family, clips, order, head_xy, rng)
        if instruction is None:
            continue
        return SceneSpec(
            family=family, seed=seed, clips=tuple(clips), order=order, instruction=instruction,
            rope_head=head_xy, rope_yaw=round(rope_yaw, 5), rope=rope,
        )
    raise RuntimeError(f"could not generate a valid {family} scene for seed {seed}")


def _instruction(family: str, clips: list[ClipSpec], order: tuple[str, ...], head_xy, rng) -> str | None:
    """The instruction for the path ``order``, or None if the family's phrasing cannot express it."""
    if family == "implicit":
        return str(rng.choice(IMPLICIT_PHRASES))
    if family in ("fixed_attribute", "clips_4_5"):
        return colour_instruction(order, rng)
    by_name = {c.name: c for c in clips}
    fitting = []
    for rule in SPATIAL_RULES:
        keys = [spatial_key(rule, by_name[n], head_xy) for n in order]
        if all(b - a >= SPATIAL_MARGIN for a, b in zip(keys, keys[1:])):
            fitting.append(rule)
    if not fitting:
        return None
    rule = str(rng.choice(fitting))
    return str(rng.choice(SPATIAL_RULES[rule]))
