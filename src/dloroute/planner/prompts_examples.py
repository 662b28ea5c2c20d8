"""Renders the VLM prompt's two in-context example images with the simulator.

Each example is a hand-placed scene with a straight rope (no physics step is needed): ``insert`` has the
head 6 cm in front of the red clip, pointing into it; ``pull`` has the rope already through the red clip
with the head 5 cm past its exit, far from the blue clip and pointing away from its opening. The image is
the whole scene (left) beside the zoomed view of the target clip (right), as the planner sees them.
File names, labels and captions come from ``prompts/examples/manifest.json``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np

from dloroute.planner.prompts import prompts_dir
from dloroute.types import ClipSpec, SceneSpec

EXAMPLE_SCENES: dict[str, SceneSpec] = {
    "insert": SceneSpec(
        family="example",
        seed=0,
        clips=(
            ClipSpec("red", 0.35, 0.0, 0.0),
            ClipSpec("blue", 0.55, 0.14, 0.6),
            ClipSpec("green", 0.74, 0.06, -0.4),
        ),
        order=("red", "blue", "green"),
        instruction="Route the rope through the red clip, then the blue clip, then the green clip.",
        rope_head=(0.29, 0.0),
        rope_yaw=0.0,
    ),
    "pull": SceneSpec(
        family="example",
        seed=0,
        clips=(
            ClipSpec("red", 0.0, 0.0, 0.0),
            ClipSpec("blue", 0.12, 0.22, math.pi / 2),
            ClipSpec("green", 0.32, 0.34, 0.3),
        ),
        order=("red", "blue", "green"),
        instruction="Route the rope through the red clip, then the blue clip, then the green clip.",
        rope_head=(0.06, 0.0),
        rope_yaw=0.0,
    ),
}
"""Example scenes by skill label (m, rad, world frame)."""


def compose(scene: np.ndarray, zoom: np.ndarray) -> np.ndarray:
    """The scene image with the zoomed view to its right, vertically centred on a white band (RGB uint8)."""
    rows = max(scene.shape[0], zoom.shape[0])
    out = np.full((rows, scene.shape[1] + zoom.shape[1], 3), 255, dtype=np.uint8)
    out[: scene.shape[0], : scene.shape[1]] = scene
    top = (rows - zoom.shape[0]) // 2
    out[top : top + zoom.shape[0], scene.shape[1] :] = zoom
    return out


def render_examples(out_dir: Path | None = None) -> list[Path]:
    """Render every manifest example into ``out_dir`` (default: the package's prompts/examples folder)."""
    from dloroute.sim.physics import Physics
    from dloroute.sim.render import SceneRenderer

    out = Path(out_dir) if out_dir is not None else prompts_dir() / "examples"
    out.mkdir(parents=True, exist_ok=True)
    manifest = json.loads((prompts_dir() / "examples" / "manifest.json").read_text(encoding="utf-8"))
    written = []
    for ex in manifest["examples"]:
        with SceneRenderer(Physics(EXAMPLE_SCENES[ex["skill"]])) as renderer:
            image = compose(renderer.render(None), renderer.render(ex["clip"]))
        path = out / ex["image"]
        ok, png = cv2.imencode(".png", image[..., ::-1])
        if not ok:
            raise RuntimeError(f"PNG encoding failed for {path}")
        path.write_bytes(png.tobytes())
        written.append(path)
    return written
