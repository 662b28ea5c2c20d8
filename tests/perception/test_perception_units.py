"""Unit tests of the perception pieces on synthetic data (no rendering): pixels, metres, world frame."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from dloroute.perception import ColourSegmenter, Sam2Segmenter, make_perceiver
from dloroute.perception.centreline import Tracer, cross_section
from dloroute.perception.masks import ROPE_RGB, classify_colour
from dloroute.perception.oracle import OraclePerceiver
from dloroute.perception.particles import compass_walk
from dloroute.perception.segment import ImagePerceiver
from dloroute.types import CLIP_COLOURS


def _rgb255(rgb) -> tuple[int, int, int]:
    return tuple(int(round(255 * v)) for v in rgb[:3])


def test_compass_walk_keeps_spacing_and_pads_past_the_line():
    line = np.array([[0.0, 0.0], [0.1, 0.0], [0.1, 0.1]])  # an L, 0.2 m long
    pts, found = compass_walk(line, 12, 0.025)
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    np.testing.assert_allclose(steps, 0.025, atol=1e-9)
    assert found == 9  # 0.2 m of line hold particles 0..8 (the corner is cut by the chord)
    np.testing.assert_allclose(pts[found:, 0], pts[found - 1, 0], atol=1e-9)  # padded straight along +y


def test_cross_section_centres_on_the_rope_and_treats_wide_runs_as_crossings():
    mask = np.zeros((40, 40), dtype=bool)
    mask[17:24, :] = True  # horizontal band 7 px wide centred on v = 20.5
    layers = np.stack([mask, np.zeros_like(mask)], axis=-1).astype(np.float32)
    offset, wide = cross_section(layers, np.array([20.0, 19.0]), np.array([1.0, 0.0]), width=7.0)
    assert not wide and offset == pytest.approx(1.5, abs=0.3)
    mask[:, 15:25] = True  # a crossing strand
    layers[..., 0] = mask
    offset, wide = cross_section(layers, np.array([20.0, 20.5]), np.array([0.0, 1.0]), width=7.0)
    assert wide and offset == 0.0


def test_tracer_orders_a_polyline_and_finds_both_kinds_of_end():
    mask = np.zeros((120, 200), dtype=np.uint8)
    cv2.polylines(mask, [np.array([[40, 60], [120, 60], [199, 100]], np.int32)], False, 1, thickness=7)
    line = Tracer(mask.astype(bool), [], width=7.0).trace(max_length=500)
    ends = {line.start, line.stop}
    assert ends == {"free", "border"}
    pts = line.points if line.start == "free" else line.points[::-1]
    assert pts[0][0] == pytest.approx(37.0, abs=2.0)  # the free end, a half width beyond the vertex
    assert pts[-1][0] > 195


def test_colour_segmenter_separates_clips_rope_and_exit_bar():
    img = np.full((120, 160, 3), 215, np.uint8)
    cv2.rectangle(img, (20, 20), (34, 60), _rgb255(CLIP_COLOURS["red"]), -1)
    cv2.rectangle(img, (35, 20), (37, 60), (26, 26, 26), -1)  # exit bar on the red clip
    cv2.rectangle(img, (100, 30), (114, 70), _rgb255(CLIP_COLOURS["yellow"]), -1)
    cv2.line(img, (0, 100), (159, 90), _rgb255(ROPE_RGB), 6)
    seg = ColourSegmenter().segment(img)
    assert set(seg.clips) == {"red", "yellow"}
    assert seg.clips["red"][40, 36]  # the bar belongs to the red clip's silhouette
    assert seg.rope[97, 50] and not seg.rope[40, 25] and not seg.rope[50, 105]
    assert classify_colour(img, seg.clips["yellow"]) == "yellow"


def test_learned_segmenter_slot_explains_how_to_plug_one_in():
    with pytest.raises(NotImplementedError, match="Segmenter protocol"):
        Sam2Segmenter("sam2_hiera_large.pt")


def test_make_perceiver_switch():
    assert isinstance(make_perceiver("oracle"), OraclePerceiver)
    assert isinstance(make_perceiver("image"), ImagePerceiver)
    with pytest.raises(ValueError, match="oracle"):
        make_perceiver("camera")  # type: ignore[arg-type]


def test_compass_walk_of_a_circle_arc_matches_chord_spacing():
    t = np.linspace(0, math.pi, 2000)
    arc = 0.1 * np.stack([np.cos(t), np.sin(t)], axis=-1)
    pts, found = compass_walk(arc, 5, 0.025)
    assert found == 5
    np.testing.assert_allclose(np.linalg.norm(np.diff(pts, axis=0), axis=1), 0.025, atol=1e-4)


def test_tracer_goes_straight_through_a_self_crossing():
    """A rope drawn as a loop that crosses itself (a nodal cubic): one trace from end to end."""
    t = np.linspace(-1.8, 1.8, 400)
    path = np.stack([70 + 50 * (t**2 - 1), 100 + 20 * t * (t**2 - 1)], axis=-1)  # crosses at t = +-1
    mask = np.zeros((200, 240), dtype=np.uint8)
    cv2.polylines(mask, [np.round(path).astype(np.int32)], False, 1, thickness=7)
    line = Tracer(mask.astype(bool), [], width=7.0).trace(max_length=1000)
    assert (line.start, line.stop) == ("free", "free")
    ends = sorted([line.points[0], line.points[-1]], key=lambda e: e[1])
    np.testing.assert_allclose(ends, [path[0], path[-1]], atol=5.0)
    drawn = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    traced = np.linalg.norm(np.diff(line.points, axis=0), axis=1).sum()
    assert traced == pytest.approx(drawn + 7.0, rel=0.05)  # + the round caps at both ends
