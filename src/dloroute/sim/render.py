"""Headless top-down images: the whole scene and a zoomed view centred on one clip.

Both views come from the model's ``top`` camera looking straight down (image right = world +x, image up
= world +y); only its position changes. ``TopDownCamera`` carries the intrinsics and pose so that
perception can map pixels back to the table plane. Rendering uses MuJoCo's offscreen renderer with
``MUJOCO_GL=egl`` (default, set in ``dloroute/__init__.py``) or ``osmesa``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from dloroute.sim.physics import Physics

SCENE_SIZE = (640, 480)
"""Scene image width, height (px)."""
ZOOM_SIZE = (320, 320)
"""Zoomed clip view width, height (px)."""
ZOOM_SPAN = 0.22
"""Table extent (m) shown across the zoomed view's height."""
SCENE_MARGIN = 0.12
"""Margin (m) around the clips and the rope head in the scene image."""


@dataclass(frozen=True)
class TopDownCamera:
    """A pinhole camera looking straight down from ``height`` (m) above the world point (cx, cy, 0).

    ``fovy`` is the vertical field of view (rad). Image right is world +x, image down is world -y.
    """

    cx: float
    cy: float
    height: float
    fovy: float
    width: int
    rows: int

    @property
    def focal(self) -> float:
        """Focal length (px)."""
        return 0.5 * self.rows / math.tan(self.fovy / 2)

    def intrinsics(self) -> np.ndarray:
        """3x3 intrinsic matrix K (px)."""
        f = self.focal
        return np.array([[f, 0, self.width / 2], [0, f, self.rows / 2], [0, 0, 1.0]])

    def metres_per_pixel(self, z: float = 0.0) -> float:
        """Size (m) of one pixel on the plane at height ``z``."""
        return (self.height - z) / self.focal

    def world_to_pixel(self, xyz: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> pixel (u, v) (..., 2); u to the right, v downwards."""
        p = np.asarray(xyz, dtype=float)
        depth = self.height - p[..., 2]
        u = self.width / 2 + self.focal * (p[..., 0] - self.cx) / depth
        v = self.rows / 2 - self.focal * (p[..., 1] - self.cy) / depth
        return np.stack([u, v], axis=-1)

    def pixel_to_world(self, uv: np.ndarray, z: float = 0.0) -> np.ndarray:
        """Pixels (..., 2) -> world points (..., 3) on the plane at height ``z`` (m)."""
        q = np.asarray(uv, dtype=float)
        depth = self.height - z
        x = self.cx + (q[..., 0] - self.width / 2) * depth / self.focal
        y = self.cy - (q[..., 1] - self.rows / 2) * depth / self.focal
        return np.stack([x, y, np.full_like(x, z)], axis=-1)


class SceneRenderer:
    """Renders a Physics' current state; close it (or use ``with``) to free the GL context."""

    def __init__(self, physics: Physics):
        self.physics = physics
        self._cam = int(physics.model.camera("top").id)
        self._fovy = math.radians(float(physics.model.cam_fovy[self._cam]))
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        clips = physics.scene.clips
        pts = np.array([[c.x, c.y] for c in clips] + [list(physics.scene.rope_head)])
        lo, hi = pts.min(axis=0) - SCENE_MARGIN, pts.max(axis=0) + SCENE_MARGIN
        w, h = SCENE_SIZE
        span_y = max(hi[1] - lo[1], (hi[0] - lo[0]) * h / w)
        centre = 0.5 * (lo + hi)
        self.scene_camera = TopDownCamera(
            float(centre[0]), float(centre[1]), span_y / 2 / math.tan(self._fovy / 2), self._fovy, w, h
        )

    def zoom_camera(self, clip_name: str) -> TopDownCamera:
        clip = self.physics.scene.clip(clip_name)
        w, h = ZOOM_SIZE
        return TopDownCamera(clip.x, clip.y, ZOOM_SPAN / 2 / math.tan(self._fovy / 2), self._fovy, w, h)

    def camera(self, clip_name: str | None) -> TopDownCamera:
        return self.scene_camera if clip_name is None else self.zoom_camera(clip_name)

    def render(self, clip_name: str | None = None) -> np.ndarray:
        """RGB image (rows, width, 3, uint8): the scene, or the zoomed view of ``clip_name``."""
        cam = self.camera(clip_name)
        key = (cam.rows, cam.width)
        if key not in self._renderers:
            self._renderers[key] = mujoco.Renderer(self.physics.model, height=cam.rows, width=cam.width)
        r = self._renderers[key]
        self.physics.model.cam_pos[self._cam] = (cam.cx, cam.cy, cam.height)
        mujoco.mj_kinematics(self.physics.model, self.physics.data)  # positions only: stepping is unaffected
        mujoco.mj_camlight(self.physics.model, self.physics.data)
        r.update_scene(self.physics.data, camera=self._cam)
        return r.render().copy()

    def close(self) -> None:
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
