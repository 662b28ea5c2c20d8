"""MP4 of an episode: top-down frames sampled from the physics, each with the current step's caption."""

from __future__ import annotations

from pathlib import Path

import cv2
import imageio.v2 as imageio
import numpy as np

from dloroute.sim.physics import Physics
from dloroute.sim.render import SceneRenderer

FRAMES_PER_SIM_SECOND = 8
"""Frames sampled per simulated second."""
PLAYBACK_FPS = 16
"""Playback rate: twice real time."""


def caption(image: np.ndarray, text: str) -> np.ndarray:
    """Draw ``text`` in a dark band at the top of a copy of ``image``."""
    out = image.copy()
    cv2.rectangle(out, (0, 0), (out.shape[1], 28), (20, 20, 20), thickness=-1)
    cv2.putText(out, text, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return out


class EpisodeVideo:
    """Subscribes to the physics and writes a frame every 1/FRAMES_PER_SIM_SECOND s of simulated time."""

    def __init__(self, physics: Physics, renderer: SceneRenderer, path: str | Path):
        self.physics, self.renderer = physics, renderer
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.writer = imageio.get_writer(self.path, fps=PLAYBACK_FPS, macro_block_size=16)
        self.caption = "start"
        self._next = physics.time
        self._frame()
        physics.observers.append(self._observe)

    def _frame(self) -> np.ndarray:
        image = caption(self.renderer.render(None), self.caption)
        self.writer.append_data(image)
        return image

    def _observe(self, physics: Physics) -> None:
        if physics.time >= self._next:
            self._frame()
            self._next = physics.time + 1.0 / FRAMES_PER_SIM_SECOND

    def close(self, final_caption: str) -> None:
        self.physics.observers.remove(self._observe)
        self.caption = final_caption
        last = self._frame()
        for _ in range(PLAYBACK_FPS):  # hold the final frame for a second
            self.writer.append_data(last)
        self.writer.close()
