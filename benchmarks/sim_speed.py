"""Simulation speed: raw mj_step rate, one motion primitive's wall time, and dloroute's overhead.

Run: .venv/bin/python benchmarks/sim_speed.py [--repeats 5]
Prints a markdown table; record it with the machine in docs/benchmarks.md.

- raw mj_step: steps/s of the fixed_attribute seed-0 scene model (rope at rest, one thread).
- primitive: grasp particle 2, two via points, release, settle 0.3 s (about 2.5 s simulated), wall time.
- overhead: Physics.step (guards every CONTROL_STEPS steps) vs. raw mj_step for the same number of steps
  from the same state.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import mujoco
import numpy as np

from dloroute.sim.clip_frame import to_world_frame
from dloroute.sim.physics import Physics
from dloroute.sim.scene import generate_scene
from dloroute.skills.primitives import SETTLE_TIME


def primitive(physics: Physics) -> None:
    clip = physics.scene.clip(physics.scene.order[0])
    a, b = to_world_frame(clip, np.array([[-0.11, 0.0], [-0.016, 0.0]]))
    physics.grasp(2)
    physics.move([(a[0], a[1], clip.yaw), (b[0], b[1], clip.yaw)])
    physics.release()
    physics.settle(SETTLE_TIME + 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scene = generate_scene("fixed_attribute", 0)
    rows = []

    physics = Physics(scene)
    n = 5000
    best_raw = best_ours = float("inf")
    for _ in range(args.repeats):
        physics = Physics(scene)
        t = time.perf_counter()
        mujoco.mj_step(physics.model, physics.data, nstep=n)
        best_raw = min(best_raw, time.perf_counter() - t)
        physics = Physics(scene)
        t = time.perf_counter()
        physics.step(n)
        best_ours = min(best_ours, time.perf_counter() - t)
    rows.append(("raw mj_step rate", f"{n / best_raw:,.0f} steps/s ({1e6 * best_raw / n:.0f} us/step)"))
    rows.append(("Physics.step rate (guards on)", f"{n / best_ours:,.0f} steps/s"))
    rows.append(("dloroute overhead over raw mj_step", f"{100 * (best_ours / best_raw - 1):.1f} %"))

    walls, sims = [], []
    for _ in range(args.repeats):
        physics = Physics(scene)
        t0, s0 = time.perf_counter(), physics.time
        primitive(physics)
        walls.append(time.perf_counter() - t0)
        sims.append(physics.time - s0)
    rows.append(("one primitive (grasp, 2 via points, release, settle)",
                 f"{min(walls):.3f} s wall for {np.mean(sims):.2f} s simulated (median {np.median(walls):.3f} s)"))
    rows.append(("model", f"{scene.rope.n_particles} rope particles, nv = {physics.model.nv}, dt = {physics.timestep * 1e3:.0f} ms, {len(scene.clips)} clips"))
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, MuJoCo {mujoco.__version__}\n")
    print("| measure | result |\n|---|---|")
    for k, v in rows:
        print(f"| {k} | {v} |")


if __name__ == "__main__":
    main()
