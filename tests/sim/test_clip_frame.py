"""Clip-frame transforms and the rope's relation to a clip, on constructed ropes."""

import numpy as np
import pytest

from dloroute.sim.clip_frame import CLIP_DEPTH, clip_status, routed_order, to_clip_frame, to_world_frame
from dloroute.types import ClipSpec

CLIP = ClipSpec("red", 0.3, -0.2, 2.0)


def straight_rope(head_x: float, head_y: float = 0.0, n: int = 30, spacing: float = 0.025) -> np.ndarray:
    """A rope along the clip's axis in world coordinates, head at (head_x, head_y) in the clip frame."""
    local = np.stack([head_x - spacing * np.arange(n), np.full(n, head_y)], axis=1)
    return to_world_frame(CLIP, local)


def test_round_trip_and_axes():
    pts = np.random.default_rng(0).normal(size=(10, 2))
    assert np.allclose(to_clip_frame(CLIP, to_world_frame(CLIP, pts)), pts)
    ahead = to_world_frame(CLIP, np.array([1.0, 0.0]))
    assert np.allclose(ahead - [CLIP.x, CLIP.y], [np.cos(CLIP.yaw), np.sin(CLIP.yaw)])


def test_head_in_front_is_nothing():
    s = clip_status(CLIP, straight_rope(-0.05))
    assert not (s.rope_in or s.rope_out or s.routed)
    assert s.d_floor == pytest.approx(0.04) and s.signed_distance == pytest.approx(-0.06)


def test_head_inside_is_rope_in():
    s = clip_status(CLIP, straight_rope(0.0))
    assert s.rope_in and not s.rope_out and not s.routed


def test_through_is_routed_with_signed_distance():
    s = clip_status(CLIP, straight_rope(0.05))
    assert s.rope_in and s.rope_out and s.routed
    assert s.signed_distance == pytest.approx(0.05 - CLIP_DEPTH / 2)


def test_beside_the_clip_is_not_routed():
    s = clip_status(CLIP, straight_rope(0.08, head_y=0.03))  # passes beside the post, outside the opening
    assert not s.routed and not s.rope_in and s.signed_distance < 0


def test_backwards_is_not_routed():
    local = np.stack([-0.05 + 0.025 * np.arange(20), np.zeros(20)], axis=1)  # head in front, rope runs out the exit
    assert not clip_status(CLIP, to_world_frame(CLIP, local)).routed


def test_routed_order_follows_the_rope():
    a, b = ClipSpec("red", 0.0, 0.0, 0.0), ClipSpec("blue", 0.2, 0.0, 0.0)
    rope = np.stack([0.3 - 0.025 * np.arange(30), np.zeros(30)], axis=1)
    assert routed_order((b, a), rope) == ("red", "blue")
