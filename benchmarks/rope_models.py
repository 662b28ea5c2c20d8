"""Rope model choice: 1D flexcomp (dloroute's) vs. a capsule chain with ball joints, same rope.

Run: .venv/bin/python benchmarks/rope_models.py
Both ropes: 1.2 m, 49 particles, 3.5 mm radius, 60 g, E = 0.2 MPa, friction 0.5, the same clip, table and
gripper (two connect constraints on particles 2 and 1). Measured: mj_step rate with the rope at rest, wall
time of pushing the head through the clip (gripper from 11 cm to 1.6 cm before the clip centre at
0.12 m/s, then 0.3 s settling), whether the head came out past the exit face, and the rope's largest
stretch. The capsule chain has body k at particle k (head first), a free joint on the head, ball joints
with stiffness EI / segment length, damping 2e-4 and armature 1e-6 (DESIGN.md's fallback), implicitfast.
"""

from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from dloroute.sim.physics import build_mjcf
from dloroute.types import ClipSpec, RopeSpec, SceneSpec

ROPE = RopeSpec()
CLIP = ClipSpec("red", 0.0, 0.0, 0.0)
HEAD_X = -0.06
GRASP = 2


def _base(rope: RopeSpec) -> ET.Element:
    return ET.fromstring(build_mjcf(SceneSpec("bench", 0, (CLIP,), ("red",), "", (HEAD_X, 0.0), 0.0, rope)))


def _grasp(root: ET.Element, bodies: tuple[str, str]) -> None:
    """Gripper at the grasped particle, holding it and its head-side neighbour."""
    root.find("worldbody").find("body[@name='gripper']").set("pos", f"{HEAD_X - GRASP * ROPE.spacing} 0 {ROPE.radius}")
    eq = root.find("equality")
    for el in list(eq):
        eq.remove(el)
    for name in bodies:
        ET.SubElement(eq, "connect", body1="gripper", body2=name, anchor="0 0 0", solref="0.01 1")
    for name, off in zip(bodies, (0.0, ROPE.spacing)):
        eq.find(f"connect[@body2='{name}']").set("anchor", f"{off} 0 0")


def flex_model() -> tuple[mujoco.MjModel, list[str]]:
    root = _base(ROPE)
    _grasp(root, (f"rope_{GRASP}", f"rope_{GRASP - 1}"))
    return mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode")), [f"rope_{i}" for i in range(ROPE.n_particles)]


def capsule_model() -> tuple[mujoco.MjModel, list[str]]:
    root = _base(RopeSpec(n_particles=2, length=0.01))
    world = root.find("worldbody")
    world.remove(world.find("flexcomp"))
    root.find("option").set("integrator", "implicitfast")
    n, seg = ROPE.n_particles, ROPE.spacing
    ei = ROPE.young * math.pi * ROPE.radius**4 / 4
    parent = world
    for k in range(n):
        body = ET.SubElement(parent, "body", name=f"c{k}", pos=f"{HEAD_X} 0 {ROPE.radius}" if k == 0 else f"{-seg} 0 0")
        if k == 0:
            ET.SubElement(body, "freejoint")
        else:
            ET.SubElement(body, "joint", type="ball", stiffness=str(ei / seg), damping="2e-4", armature="1e-6")
        if k < n - 1:
            ET.SubElement(body, "geom", type="capsule", fromto=f"0 0 0 {-seg} 0 0", size=str(ROPE.radius),
                          mass=str(ROPE.mass / (n - 1)), rgba="0.93 0.45 0.1 1", margin="0.001",
                          solimp="0.99 0.999 0.0005")
        else:  # the tail particle: a sphere of the rope's radius
            ET.SubElement(body, "geom", type="sphere", size=str(ROPE.radius), mass=str(ROPE.mass / (n - 1) / 10),
                          rgba="0.93 0.45 0.1 1")
        parent = body
    root.append(ET.fromstring('<contact><exclude body1="c0" body2="c1"/></contact>'))
    _grasp(root, (f"c{GRASP}", f"c{GRASP - 1}"))
    return mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode")), [f"c{k}" for k in range(n)]


def measure(name: str, build) -> str:
    model, names = build()
    ids = [model.body(nm).id for nm in names]
    data = mujoco.MjData(model)
    data.eq_active[:] = 0
    n = 3000
    t = time.perf_counter()
    mujoco.mj_step(model, data, nstep=n)
    rate = n / (time.perf_counter() - t)
    mujoco.mj_resetData(model, data)
    mocap = model.body("gripper").mocapid[0]
    x1 = -0.016
    data.mocap_pos[mocap, 0] = HEAD_X - GRASP * ROPE.spacing
    steps_move = int(abs(x1 - data.mocap_pos[mocap, 0]) / 0.12 / model.opt.timestep)
    start = float(data.mocap_pos[mocap, 0])
    t = time.perf_counter()
    ok = True
    for k in range(steps_move + int(0.3 / model.opt.timestep)):
        f = min(1.0, k / steps_move)
        data.mocap_pos[mocap, 0] = start + f * (x1 - start)
        if k == steps_move:
            data.eq_active[:] = 0
        mujoco.mj_step(model, data)
        ok = ok and bool(np.isfinite(data.qpos).all())
    wall = time.perf_counter() - t
    pts = data.xpos[ids]
    stretch = float(np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1)) / ROPE.spacing - 1)
    through = bool(pts[0, 0] > 0.01 and abs(pts[0, 1]) < 0.011)
    return f"| {name} | {rate:,.0f} steps/s | {wall:.3f} s | {through} | {100 * stretch:.2f} % | {ok} |"


def main() -> None:
    print("| rope model | mj_step rate (rest) | push through the clip, wall | head past exit | max stretch | finite |")
    print("|---|---|---|---|---|---|")
    print(measure("1D flexcomp (dloroute)", flex_model))
    print(measure("capsule chain, ball joints", capsule_model))


if __name__ == "__main__":
    main()
