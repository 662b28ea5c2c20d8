"""World <-> clip-frame transforms and the rope's relation to a clip (pure numpy, no MuJoCo).

Clip frame (DESIGN): origin at the tunnel centre on the table, +x along the insertion direction, +y
lateral, +z up. The entry face ("floor") is at x = -depth/2, the exit face ("ceiling") at x = +depth/2;
the opening spans |y| < width/2 where width = 0.022 m x scale.
"""

from __future__ import annotations

import numpy as np

from dloroute.types import ClipSpec, ClipStatus

CLIP_OPENING = 0.022
"""Opening width (m) at scale 1.0 (the paper's clip)."""
CLIP_DEPTH = 0.02
"""Tunnel length along the clip's x axis (m)."""
POST_WIDTH = 0.012
"""Width of each post along the clip's y axis (m)."""
CLIP_HEIGHT = 0.03
"""Height of the roof's top above the table (m); the opening is 0.022 m high."""
SUCCESS_DISTANCE = 0.02
"""Insertion success: signed endpoint distance past the exit face above this (m)."""


def opening_width(clip: ClipSpec) -> float:
    return CLIP_OPENING * clip.scale


def to_clip_frame(clip: ClipSpec, points: np.ndarray) -> np.ndarray:
    """World points (..., 2 or 3) -> clip-frame points of the same shape (m)."""
    pts = np.asarray(points, dtype=float)
    c, s = np.cos(clip.yaw), np.sin(clip.yaw)
    out = pts.copy()
    dx, dy = pts[..., 0] - clip.x, pts[..., 1] - clip.y
    out[..., 0] = c * dx + s * dy
    out[..., 1] = -s * dx + c * dy
    return out


def to_world_frame(clip: ClipSpec, points: np.ndarray) -> np.ndarray:
    """Clip-frame points (..., 2 or 3) -> world points of the same shape (m)."""
    pts = np.asarray(points, dtype=float)
    c, s = np.cos(clip.yaw), np.sin(clip.yaw)
    out = pts.copy()
    out[..., 0] = clip.x + c * pts[..., 0] - s * pts[..., 1]
    out[..., 1] = clip.y + s * pts[..., 0] + c * pts[..., 1]
    return out


def yaw_to_clip_frame(clip: ClipSpec, yaw: float) -> float:
    """World yaw -> clip-frame yaw, wrapped to (-pi, pi]."""
    return wrap_angle(yaw - clip.yaw)


def wrap_angle(a):
    """Angle(s) (rad) wrapped to [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def front_heading(rope: np.ndarray, span: float = 0.05) -> float:
    """World yaw (rad) of the rope's front: the direction from the first particle at least ``span`` metres
    of arc behind the head (or the tail) to the head. ``rope``: (n, 2 or 3) world positions (m), head first."""
    xy = np.asarray(rope, dtype=float)[:, :2]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    k = int(min(np.searchsorted(arc, span), len(xy) - 1))
    d = xy[0] - xy[k]
    return float(np.arctan2(d[1], d[0]))


def _face_crossings(local: np.ndarray, x_face: float, half_width: float) -> list[tuple[float, int]]:
    """Rope segments crossing the line x = x_face within |y| < half_width (clip frame).

    Returns (fractional particle index of the crossing, direction) with direction +1 when the rope,
    walked from head to tail, goes from +x to -x (i.e. the head side lies at larger x).
    """
    x, y = local[:, 0], local[:, 1]
    out = []
    for k in range(len(local) - 1):
        a, b = x[k] - x_face, x[k + 1] - x_face
        if a == b or (a > 0) == (b > 0):
            continue
        t = a / (a - b)
        yc = y[k] + t * (y[k + 1] - y[k])
        if abs(yc) < half_width:
            out.append((k + t, 1 if a > 0 else -1))
    return out


def clip_status(clip: ClipSpec, rope: np.ndarray) -> ClipStatus:
    """The rope's relation to ``clip``; ``rope`` is (n, 2 or 3) world positions (m), head first.

    Walking the rope from the head towards the tail, the first face crossing decides: an exit-face
    crossing followed by an entry-face crossing means the rope runs through the tunnel in the insertion
    direction (routed). A head inside the tunnel whose rope leaves through the entry face is ``rope_in``.
    """
    local = to_clip_frame(clip, np.asarray(rope)[:, :2])
    half_w = opening_width(clip) / 2
    head = local[0]
    entry, exit_ = np.array([-CLIP_DEPTH / 2, 0.0]), np.array([CLIP_DEPTH / 2, 0.0])
    events = sorted(
        [(i, "entry", d) for i, d in _face_crossings(local, -CLIP_DEPTH / 2, half_w)]
        + [(i, "exit", d) for i, d in _face_crossings(local, CLIP_DEPTH / 2, half_w)]
    )
    head_inside = abs(head[0]) <= CLIP_DEPTH / 2 and abs(head[1]) < half_w
    routed = False
    rope_in = False
    crossing = None
    if events:
        first = events[0]
        if head_inside and first[1] == "entry" and first[2] == 1:
            rope_in, crossing = True, first[0]
        elif (
            not head_inside
            and len(events) >= 2
            and first[1] == "exit"
            and first[2] == 1
            and events[1][1] == "entry"
            and events[1][2] == 1
        ):
            routed = rope_in = True
            crossing = 0.5 * (first[0] + events[1][0])
    rope_out = bool(routed and head[0] > CLIP_DEPTH / 2)
    d_ceil = float(np.linalg.norm(head - exit_))
    return ClipStatus(
        name=clip.name,
        rope_in=rope_in,
        rope_out=rope_out,
        routed=routed,
        d_floor=float(np.linalg.norm(head - entry)),
        d_ceil=d_ceil,
        signed_distance=d_ceil if rope_out else -d_ceil,
        crossing_index=None if crossing is None else float(crossing),
    )


def routed_order(clips: tuple[ClipSpec, ...], rope: np.ndarray) -> tuple[str, ...]:
    """Names of the clips the rope runs through, in threading order (the clip nearest the tail first)."""
    statuses = [clip_status(c, rope) for c in clips]
    routed = [s for s in statuses if s.routed]
    return tuple(s.name for s in sorted(routed, key=lambda s: -(s.crossing_index or 0.0)))
