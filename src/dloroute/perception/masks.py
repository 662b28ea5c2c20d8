"""Segmentation back-ends: an RGB image -> one pixel mask per clip colour and one for the rope.

These are the first stage of the image perceiver (``segment.ImagePerceiver``).

Masks are (rows, width) bool arrays on the image's pixel grid (row 0 at the top). A clip's mask is its
whole visible silhouette: roof, the side faces that perspective shows, and the dark exit bar on the
roof. ``ColourSegmenter`` (OpenCV HSV thresholds) is the default for our renders; ``Sam2Segmenter`` is
the documented slot for a learned segmenter on real cameras (see docs/perception.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np

from dloroute.sim.rope import ROPE_RGBA
from dloroute.types import CLIP_COLOURS

ROPE_RGB: tuple[float, float, float] = tuple(float(v) for v in ROPE_RGBA.split()[:3])  # type: ignore[assignment]
"""The rope's colour (RGB in 0..1), as the simulator renders it."""


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Masks of one image: ``clips`` maps a colour name to that clip's silhouette; ``rope`` is the rope."""

    clips: Mapping[str, np.ndarray]
    rope: np.ndarray


class Segmenter(Protocol):
    """Image (rows, width, 3) uint8 RGB -> Segmentation. A colour missing from the image has no mask."""

    def segment(self, image: np.ndarray) -> Segmentation: ...


def opencv_hue(rgb: tuple[float, ...]) -> float:
    """OpenCV hue (0..180) of an RGB colour given in 0..1."""
    pixel = np.clip(np.round(np.asarray(rgb[:3]) * 255), 0, 255).astype(np.uint8)[None, None]
    return float(cv2.cvtColor(pixel, cv2.COLOR_RGB2HSV)[0, 0, 0])


def hue_distance(hue: np.ndarray, target: float) -> np.ndarray:
    """Circular distance between OpenCV hues (0..180)."""
    d = np.abs(np.asarray(hue, dtype=float) - target)
    return np.minimum(d, 180.0 - d)


def classify_colour(image: np.ndarray, mask: np.ndarray, colours: Mapping[str, tuple] = CLIP_COLOURS) -> str:
    """Name of the colour in ``colours`` nearest in hue to the saturated pixels of ``mask``.

    For learned segmenters, which return instance masks without a colour name.
    """
    hsv = cv2.cvtColor(np.ascontiguousarray(image[..., :3]), cv2.COLOR_RGB2HSV)
    sel = mask & (hsv[..., 1] >= 100)
    if not sel.any():
        raise ValueError("the mask holds no saturated pixel to classify")
    angle = np.deg2rad(hsv[..., 0][sel].astype(float) * 2.0)
    mean = np.rad2deg(np.arctan2(np.sin(angle).mean(), np.cos(angle).mean())) % 360.0 / 2.0
    return min(colours, key=lambda name: float(hue_distance(mean, opencv_hue(colours[name]))))


def drop_small(mask: np.ndarray, min_area: int) -> np.ndarray:
    """``mask`` without its 8-connected components smaller than ``min_area`` pixels."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    keep = np.zeros(n, dtype=bool)
    keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= min_area
    return keep[labels]


def _disk(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


@dataclass(frozen=True)
class ColourSegmenter:
    """HSV thresholds for the simulator's renders (flat colours, white head light, no shadows).

    Each saturated pixel takes the clip colour (or the rope's) within ``hue_tolerance`` of its hue. A
    clip is the largest component of its colour, grown by the dark, unsaturated exit bar next to it.
    The rope is every component of rope pixels of at least ``min_rope_area`` px, after a small closing.
    Saturation and value thresholds are on OpenCV's 0..255 scale; hues on 0..180 (red 0, rope orange
    13, yellow 27: a tolerance of 6 keeps them apart).
    """

    clip_colours: Mapping[str, tuple[float, float, float, float]] = field(default_factory=lambda: dict(CLIP_COLOURS))
    rope_rgb: tuple[float, float, float] = ROPE_RGB
    hue_tolerance: float = 6.0
    min_saturation: int = 128
    min_value: int = 40
    dark_value: int = 110
    dark_saturation: int = 80
    min_clip_area: int = 30
    min_rope_area: int = 3

    def segment(self, image: np.ndarray) -> Segmentation:
        hsv = cv2.cvtColor(np.ascontiguousarray(image[..., :3]), cv2.COLOR_RGB2HSV)
        hue, sat, val = hsv[..., 0], hsv[..., 1], hsv[..., 2]
        vivid = (sat >= self.min_saturation) & (val >= self.min_value)
        names = list(self.clip_colours)
        # Label per hue: 1..K for the clip colours, K + 1 for the rope, 0 for none.
        lut = np.zeros(256, dtype=np.int32)
        for k, rgb in enumerate([*self.clip_colours.values(), self.rope_rgb], start=1):
            lut[:180][hue_distance(np.arange(180), opencv_hue(rgb)) <= self.hue_tolerance] = k
        label = np.where(vivid, lut[hue], 0)
        n, comp, stats, _ = cv2.connectedComponentsWithStats(((label >= 1) & (label <= len(names))).astype(np.uint8),
                                                             connectivity=8)
        colour_of = np.bincount(comp[comp > 0] * (len(names) + 2) + label[comp > 0],
                                minlength=n * (len(names) + 2)).reshape(n, -1).argmax(axis=1)
        dark = (val < self.dark_value) & (sat < self.dark_saturation)
        clips = {}
        for k, name in enumerate(names, start=1):
            mine = [j for j in range(1, n) if colour_of[j] == k and stats[j, cv2.CC_STAT_AREA] >= self.min_clip_area]
            if mine:
                j = max(mine, key=lambda j: stats[j, cv2.CC_STAT_AREA])
                clips[name] = self._with_exit_bar(comp == j, dark, stats[j])
        rope = (label == len(names) + 1).astype(np.uint8)
        # The renderer draws the rope as one cylinder per edge: bends leave wedge-shaped cracks on their
        # outer side, which a closing fills.
        rope = cv2.morphologyEx(rope, cv2.MORPH_CLOSE, _disk(2)).astype(bool)
        return Segmentation(clips=clips, rope=drop_small(rope, self.min_rope_area))

    @staticmethod
    def _with_exit_bar(body: np.ndarray, dark: np.ndarray, box: np.ndarray) -> np.ndarray:
        """``body`` plus the dark pixels next to it; ``box`` is its connected-component stats row.

        The exit bar is a fifth of the roof's depth; the reach scales with the body's thickness,
        estimated as twice its area over its perimeter (exact for a long thin rectangle).
        """
        x, y, w, h, area = (int(v) for v in box[:5])
        pad = max(w, h) // 2 + 2
        r0, c0 = max(y - pad, 0), max(x - pad, 0)
        roi = np.s_[r0: y + h + pad, c0: x + w + pad]
        part = body[roi].astype(np.uint8)
        contours, _ = cv2.findContours(part, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        perimeter = max(sum(cv2.arcLength(c, True) for c in contours), 1.0)
        reach = int(np.ceil(0.4 * 2.0 * area / perimeter)) + 1
        near = cv2.dilate(part, _disk(reach)).astype(bool)
        silhouette = part.astype(bool) | (dark[roi] & near)
        out = np.zeros_like(body)
        out[roi] = cv2.morphologyEx(silhouette.astype(np.uint8), cv2.MORPH_CLOSE, _disk(1)).astype(bool)
        return out


class Sam2Segmenter:
    """Slot for a learned segmenter (SAM2) on real camera images: not bundled, so it refuses to start.

    To plug one in, write a class with ``segment(image) -> Segmentation``:

    1. run the model on the top-down RGB image (prompted with points/boxes, or automatic masks);
    2. keep the instances that are clips (e.g. by size and rectangularity) and name each with
       ``classify_colour(image, mask)``; the mask should cover the whole visible clip, exit bar included;
    3. return ``Segmentation(clips={colour: mask}, rope=rope_mask)``;

    then pass it as ``ImagePerceiver(segmenter=YourSegmenter())``. Pose fitting, rope tracing and
    occlusion handling stay the same.
    """

    def __init__(self, *args, **kwargs):
        raise NotImplementedError(
            "no learned segmenter is bundled with dloroute. Implement the Segmenter protocol "
            "(segment(image) -> Segmentation(clips={colour: mask}, rope=mask)) around SAM2 or another model, "
            "name clip instances with dloroute.perception.masks.classify_colour, and pass it as "
            "ImagePerceiver(segmenter=...); see docs/perception.md, 'Plugging in a learned segmenter'."
        )
