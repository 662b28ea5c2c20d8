"""Clip pose from a clip's silhouette mask: roof fit in the world frame, yaw from the exit bar.

Seen from above, a clip shows its roof (a CLIP_DEPTH x (opening + 2 POST_WIDTH) rectangle at
z = CLIP_HEIGHT, coloured, with a 4 mm dark bar along its exit edge; see sim.physics.clip_element)
and, away from the image centre, some darker side faces. The roof's pixels (bright coloured + dark bar) are projected onto
the plane z = CLIP_HEIGHT; their centroid is the clip's (x, y), their principal axes its lateral (long)
and insertion (short) axes, and the bar's side of the centroid fixes the insertion direction (+x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from dloroute.sim.clip_frame import CLIP_HEIGHT, CLIP_OPENING, POST_WIDTH
from dloroute.sim.render import TopDownCamera
from dloroute.types import ClipSpec

COLOURED_SATURATION = 100
"""OpenCV saturation (0..255) above which a silhouette pixel belongs to a coloured face."""
ROOF_BRIGHTNESS = 0.8
"""Coloured pixels at least this fraction of the roof's brightness are roof; darker ones are side faces."""
BAR_BRIGHTNESS = 0.5
"""Unsaturated pixels darker than this fraction of the roof's brightness are the exit bar."""
MIN_PIXELS = 12
"""Fewest roof pixels (and bar pixels / 3) for a pose."""


@dataclass(frozen=True, eq=False)
class ClipMeasurement:
    """A clip found in one image: its pose (world), the silhouette and roof masks (pixels)."""

    clip: ClipSpec
    mask: np.ndarray
    roof: np.ndarray
    camera: TopDownCamera


def pixel_centres(mask: np.ndarray) -> np.ndarray:
    """(k, 2) continuous pixel coordinates (u, v) of the centres of ``mask``'s pixels."""
    rows, cols = np.nonzero(mask)
    return np.stack([cols + 0.5, rows + 0.5], axis=-1).astype(float)


def measure_clip(name: str, mask: np.ndarray, image: np.ndarray, camera: TopDownCamera) -> ClipMeasurement | None:
    """Pose of the clip ``name`` from its silhouette ``mask`` in ``image``; None if roof or bar is missing.

    ``scale`` is estimated from the roof's long side: its variance along the long axis is L^2 / 12 for a
    uniform rectangle of length L = CLIP_OPENING * scale + 2 * POST_WIDTH.
    """
    rows, cols = np.nonzero(mask)
    if rows.size < MIN_PIXELS:
        return None
    box = np.s_[rows.min(): rows.max() + 1, cols.min(): cols.max() + 1]  # work in the mask's bounding box
    offset = np.array([cols.min(), rows.min()], dtype=float)
    hsv = cv2.cvtColor(np.ascontiguousarray(image[box][..., :3]), cv2.COLOR_RGB2HSV)
    sat, val = hsv[..., 1], hsv[..., 2].astype(float)
    sil = mask[box]
    coloured = sil & (sat >= COLOURED_SATURATION)
    if coloured.sum() < MIN_PIXELS:
        return None
    bright = float(np.percentile(val[coloured], 90))
    top = coloured & (val >= ROOF_BRIGHTNESS * bright)
    bar = sil & ~coloured & (val < BAR_BRIGHTNESS * bright)
    roof = top | bar
    if top.sum() < MIN_PIXELS or bar.sum() < MIN_PIXELS / 3:
        return None
    pts = camera.pixel_to_world(pixel_centres(roof) + offset, z=CLIP_HEIGHT)[:, :2]
    centre = pts.mean(axis=0)
    evals, evecs = np.linalg.eigh(np.cov((pts - centre).T))
    x_axis = evecs[:, 0]  # the short axis: insertion direction up to sign
    bar_centre = camera.pixel_to_world(pixel_centres(bar) + offset, z=CLIP_HEIGHT)[:, :2].mean(axis=0)
    if (bar_centre - centre) @ x_axis < 0:
        x_axis = -x_axis
    span = math.sqrt(12.0 * max(float(evals[1]), 0.0))
    scale = max((span - 2 * POST_WIDTH) / CLIP_OPENING, 0.1)
    clip = ClipSpec(name=name, x=float(centre[0]), y=float(centre[1]),
                    yaw=math.atan2(float(x_axis[1]), float(x_axis[0])), scale=scale)
    full_roof = np.zeros(image.shape[:2], dtype=bool)
    full_roof[box] = roof
    return ClipMeasurement(clip=clip, mask=mask, roof=full_roof, camera=camera)
