"""Image perception: top-down RGB images -> clip poses and colours, ordered rope particles, the head.

``ImagePerceiver`` turns a top-down RGB image and its camera into an Observation:

1. segment the image (``masks.Segmenter``; ``ColourSegmenter`` by default) into clip silhouettes and a
   rope mask;
2. fit each clip's pose on its roof (``clips.measure_clip``), refined in the clip's zoomed view if given;
3. trace the rope's centre-line (``centreline.Tracer``), bridging under clips, and pick the head end;
4. back-project the centre-line onto the plane z = rope radius and walk it with the particle spacing
   (``particles.compass_walk``). Particles past the image border continue straight along the last
   measured direction; ``Perception.n_visible`` says how many were measured.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from dloroute.perception.centreline import Centreline, EndKind, Occluder, Tracer
from dloroute.perception.clips import ClipMeasurement, measure_clip
from dloroute.perception.masks import ColourSegmenter, Segmentation, Segmenter
from dloroute.perception.particles import compass_walk
from dloroute.sim.clip_frame import opening_width
from dloroute.sim.physics import Physics
from dloroute.sim.render import SceneRenderer, TopDownCamera
from dloroute.types import ClipSpec, Observation, RopeSpec

TUNNEL_MARGIN = 0.003
"""Slack (m) beyond the opening's half width plus the rope's radius for a rope that goes through a clip."""
MIN_ROPE_PX = 3.5
"""Narrowest rope image (px across) the tracer handles; the 640 x 480 scene view shows it 4.4-7 px wide."""


class PerceptionError(RuntimeError):
    """The image does not show what an observation needs (no rope, no visible rope end, too coarse)."""


@dataclass(frozen=True, eq=False)
class View:
    """An RGB image (rows, width, 3, uint8) and the top-down camera that took it."""

    image: np.ndarray
    camera: TopDownCamera


@dataclass(frozen=True, eq=False)
class Perception:
    """The image pipeline's full result, for debugging and evaluation.

    ``segmentation`` holds the scene image's masks; ``clips`` each clip's measurement (its ``mask`` is
    in the image it was measured in: the zoomed view when one was given). ``centreline`` (k, 3) is the
    traced rope (m, world, head first); ``bridged`` (k,) marks its points bridged under a clip rather
    than seen. Particles 0..``n_visible``-1 of ``observation.rope`` were measured; the rest extend the
    last measured direction. ``head_end`` is "free" for a head seen in the open, "occluded" for a head
    lost at a clip (placed where it disappears; under a roof it may lie up to a roof's depth further in).
    """

    observation: Observation
    segmentation: Segmentation
    clips: tuple[ClipMeasurement, ...]
    centreline: np.ndarray
    bridged: np.ndarray
    n_visible: int
    head_end: EndKind

    def clip_mask(self, name: str) -> np.ndarray:
        """Silhouette mask (rows, width) bool of clip ``name`` in the scene image."""
        return self.segmentation.clips[name]


def _occluders(seg: Segmentation, clips: tuple[ClipSpec, ...], cam: TopDownCamera, rope: RopeSpec
               ) -> list[Occluder]:
    """The found clips as occluders in the image; silhouettes grown by a pixel (anti-aliased edges)."""
    grow = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    out = []
    for c in clips:
        ends = cam.world_to_pixel(np.array([[c.x, c.y, rope.radius], [c.x + math.cos(c.yaw), c.y + math.sin(c.yaw),
                                                                      rope.radius]]))
        axis = (ends[1] - ends[0]) / np.linalg.norm(ends[1] - ends[0])
        half = (opening_width(c) / 2 + rope.radius + TUNNEL_MARGIN) / cam.metres_per_pixel(rope.radius)
        mask = cv2.dilate(seg.clips[c.name].astype(np.uint8), grow).astype(bool)
        out.append(Occluder(mask, ends[0], axis, half))
    return out


def _measure_clips(view: View, seg: Segmentation, zooms: Mapping[str, View], segmenter: Segmenter
                   ) -> tuple[ClipMeasurement, ...]:
    """Every clip found in the scene view, re-measured in its zoomed view when that one shows it whole."""
    out = []
    for name, mask in seg.clips.items():
        m = measure_clip(name, mask, view.image, view.camera)
        if m is None:
            continue
        zoom = zooms.get(name)
        if zoom is not None:
            zmask = segmenter.segment(zoom.image).clips.get(name)
            if zmask is not None and not (zmask[0].any() or zmask[-1].any() or zmask[:, 0].any() or zmask[:, -1].any()):
                m = measure_clip(name, zmask, zoom.image, zoom.camera) or m
        out.append(m)
    return tuple(out)


END_RANK = {"free": 2, "occluded": 1, "border": 0}
"""Which rope end is the head: one in the open before one lost at a clip; never one leaving the image."""


def _choose_head(line: Centreline, world: np.ndarray, clips: tuple[ClipSpec, ...],
                 head_hint: np.ndarray | None) -> bool:
    """True when ``line``'s start is the head (else its stop). World points ``world`` (k, 2), m.

    The end of higher END_RANK; between equals, the one nearest ``head_hint``, else nearest a clip.
    """
    rank = [END_RANK[kind] for kind in (line.start, line.stop)]
    if max(rank) == 0:
        raise PerceptionError("both rope ends leave the image (or none was found): the head is not visible")
    if rank[0] != rank[1]:
        return rank[0] > rank[1]
    ends = (world[0], world[-1])
    if head_hint is not None:
        dist = [float(np.linalg.norm(e - head_hint[:2])) for e in ends]
    elif clips:
        dist = [min(math.hypot(e[0] - c.x, e[1] - c.y) for c in clips) for e in ends]
    else:
        return True
    return dist[0] <= dist[1]


class ImagePerceiver:
    """Observation from top-down images; ``perceive(physics)`` renders them with a SceneRenderer.

    ``zoom`` also renders each clip's zoomed view to refine its pose. ``renderer`` lends a renderer of
    the physics to be perceived (e.g. the episode's); without one the perceiver makes its own, which
    ``close()`` frees (or use ``with``).
    """

    def __init__(self, segmenter: Segmenter | None = None, *, zoom: bool = True,
                 renderer: SceneRenderer | None = None):
        self.segmenter: Segmenter = segmenter or ColourSegmenter()
        self.zoom = zoom
        self._renderer = renderer
        self._owned = renderer is None

    def perceive(self, physics: Physics) -> Observation:
        return self.analyse_physics(physics).observation

    def analyse_physics(self, physics: Physics) -> Perception:
        """Render ``physics`` (scene view, and a zoomed view per clip) and analyse it."""
        if self._renderer is None or self._renderer.physics is not physics:
            if not self._owned:
                raise ValueError("the renderer lent to this ImagePerceiver renders another Physics")
            self.close()
            self._renderer = SceneRenderer(physics)
        r = self._renderer
        view = View(r.render(None), r.camera(None))
        # The zoomed cameras point at the scene's clips; only their images and poses are used.
        names = [c.name for c in physics.scene.clips] if self.zoom else []
        zooms = {name: View(r.render(name), r.camera(name)) for name in names}
        return self.analyse(view, zooms, rope=physics.scene.rope)

    def analyse(self, view: View, zooms: Mapping[str, View] | None = None, *, rope: RopeSpec = RopeSpec(),
                head_hint: np.ndarray | None = None) -> Perception:
        """Perceive from a scene ``view`` and optional zoomed ``zooms`` {clip name: view}.

        ``head_hint`` (m, world) picks the head when both rope ends are free (default: the end nearest
        a clip). Raises PerceptionError without a rope or a visible rope end, or when the rope is under
        MIN_ROPE_PX wide.
        """
        seg = self.segmenter.segment(view.image)
        measured = _measure_clips(view, seg, zooms or {}, self.segmenter)
        clips = tuple(m.clip for m in measured)
        cam = view.camera
        width = 2 * rope.radius / cam.metres_per_pixel(rope.radius)
        if width < MIN_ROPE_PX:
            raise PerceptionError(f"the rope is {width:.1f} px wide in this image; tracing needs {MIN_ROPE_PX} px: "
                                  "use a closer or higher-resolution camera")
        tracer = Tracer(seg.rope, _occluders(seg, clips, cam, rope), width)
        line = tracer.trace(max_length=1.5 * rope.length / cam.metres_per_pixel(rope.radius))
        if line is None or len(line.points) < 2:
            raise PerceptionError("no rope found in the image")
        world = cam.pixel_to_world(line.points, z=rope.radius)[:, :2]
        if not _choose_head(line, world, clips, head_hint):
            line, world = line.reversed(), world[::-1].copy()
        xy, n_visible = compass_walk(world, rope.n_particles, rope.spacing)
        particles = np.column_stack([xy, np.full(len(xy), rope.radius)])
        obs = Observation(clips=clips, rope=particles, source="perception")
        centreline = np.column_stack([world, np.full(len(world), rope.radius)])
        return Perception(obs, seg, measured, centreline, ~line.visible, n_visible, line.start)

    def close(self) -> None:
        """Free the renderer this perceiver made (a lent one stays open)."""
        if self._owned and self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> ImagePerceiver:
        return self

    def __exit__(self, *exc) -> None:
        self.close()



def perceive_physics(physics: Physics, renderer: SceneRenderer | None = None) -> Observation:
    """One image observation of ``physics``, rendered with ``renderer`` (or a temporary one)."""
    with ImagePerceiver(renderer=renderer) as perceiver:
        return perceiver.perceive(physics)
