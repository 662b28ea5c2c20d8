"""The rope: a 1D MuJoCo flexcomp (MJCF builder) and its state read-out, head first.

Choice (measured in benchmarks/sim_speed.py, recorded in docs/benchmarks.md): a 1D ``flexcomp`` with
elasticity beats a capsule chain with ball joints on this task: it is a single MJCF element, its edges
collide as capsules (so the rope cannot slip between two particles through a post), and the edge
equality keeps it inextensible at a 3 ms step.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from dloroute.types import RopeSpec

ROPE_NAME = "rope"
ROPE_RGBA = "0.93 0.45 0.10 1"
"""Orange: distinct from every clip colour and from the table."""


def rope_element(spec: RopeSpec, head_xy: tuple[float, float], yaw: float) -> ET.Element:
    """MJCF ``flexcomp`` for a straight rope whose particle 0 (the head) sits at ``head_xy`` (m, world).

    ``yaw`` (rad, world) is the direction from the tail to the head. The flexcomp grid runs along its
    local +x from vertex 0, so it is rotated to point from the head towards the tail.
    """
    back = yaw + math.pi
    centre = (
        head_xy[0] + 0.5 * spec.length * math.cos(back),
        head_xy[1] + 0.5 * spec.length * math.sin(back),
        spec.radius,
    )
    s = spec.spacing
    el = ET.Element(
        "flexcomp",
        name=ROPE_NAME,
        type="grid",
        dim="1",
        count=f"{spec.n_particles} 1 1",
        spacing=f"{s} {s} {s}",
        pos=" ".join(f"{v:.6f}" for v in centre),
        euler=f"0 0 {back:.6f}",
        radius=str(spec.radius),
        mass=str(spec.mass),
        rgba=ROPE_RGBA,
    )
    ET.SubElement(el, "edge", equality="true", solref="-1e6 -1e3")
    ET.SubElement(el, "elasticity", young=str(spec.young), poisson="0", damping="0.0002")
    ET.SubElement(
        el, "contact", condim="3", friction="0.5 0.005 0.0001", margin="0.001", selfcollide="none",
        solref="0.004 1", solimp="0.99 0.999 0.0005",
    )
    return el


def particle_body_ids(model: mujoco.MjModel) -> np.ndarray:
    """Body id of each rope particle, head first."""
    flex = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, ROPE_NAME)
    adr, num = model.flex_vertadr[flex], model.flex_vertnum[flex]
    return np.array(model.flex_vertbodyid[adr : adr + num])


def particle_positions(data: mujoco.MjData, body_ids: np.ndarray) -> np.ndarray:
    """(n, 3) particle positions (m, world), head first."""
    return data.xpos[body_ids].copy()
