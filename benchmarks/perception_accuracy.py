"""Perception accuracy against the simulator's ground truth, over generated scenes and episode stages.

For every scene (all four task families, ``--seeds`` seeds each) the rope is driven through four stages
and perceived from rendered images (scene view + zoomed clip views) after each:

| stage     | how it is made                                                                    |
|-----------|-----------------------------------------------------------------------------------|
| straight  | the generated start, settled                                                      |
| one_clip  | heuristic insertion through the first clip of the order                           |
| two_clips | Pull towards the second clip, then heuristic insertion through it                 |
| crossed   | the head grasped and dragged sideways around the last clip and back across the rope |

Measured per stage: clip position error (mm), yaw error (deg), colour accuracy (every clip found, with
its colour, within 10 mm, nothing else found), rope particle error over the measured particles (mean and
95th percentile, mm, in the table plane), head error (mm), how many in-image particles were measured,
and whether the routed clips computed from the perceived state equal the true ones. A stage whose skill
fails is still measured: the rope is wherever the skill left it. A simulation error (the guard in
Physics) ends the scene: its remaining stages are skipped, not counted as perception failures.

    .venv/bin/python benchmarks/perception_accuracy.py            # 50 seeds x 4 families = 200 scenes
    .venv/bin/python benchmarks/perception_accuracy.py --seeds 5  # quick look
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import time
from pathlib import Path

import numpy as np

STAGES = ("straight", "one_clip", "two_clips", "crossed")
TARGETS = {"clip_mm": 3.0, "yaw_deg": 3.0, "colour": 1.0, "rope_mean_mm": 5.0, "head_mm": 5.0}
DRAG_REST = 1.0
"""Rest (s) after the sideways drag: 0.3 s after that release the head can still move at ~2 m/s."""
MATCH_MM = 10.0
"""A perceived clip within this distance (mm) of the true clip of its colour counts as a correct colour."""


def _drag_across(physics, clip, rng) -> None:
    """Grasp the head and drag it around ``clip``'s side and back across the rope in front of it."""
    from dloroute.sim.clip_frame import to_world_frame

    side = 1.0 if rng.random() < 0.5 else -1.0
    reach = float(rng.uniform(0.06, 0.09))
    via = np.array([[0.06, side * 0.07], [-0.05, side * 0.08], [-reach, side * 0.02], [-reach, -side * 0.05]])
    if physics.grasp(0) is None:
        pts = to_world_frame(clip, via)
        physics.move([(float(x), float(y), clip.yaw) for x, y in pts])
    physics.release()
    physics.settle(DRAG_REST)
    physics.park_gripper()


def _measure(physics, perceiver) -> dict:
    """One perception of the current state, compared with the ground truth."""
    from dloroute.perception import PerceptionError
    from dloroute.sim.clip_frame import routed_order, wrap_angle

    t0 = time.perf_counter()
    try:
        res = perceiver.analyse_physics(physics)
    except PerceptionError as err:
        return {"error": str(err)}
    ms = 1000 * (time.perf_counter() - t0)
    truth = physics.rope()
    obs = res.observation
    scene = physics.scene
    clip_mm, yaw_deg, scale_err = [], [], []
    colour_ok = len(obs.clips) == len(scene.clips)
    for c in scene.clips:
        try:
            p = obs.clip(c.name)
        except KeyError:
            colour_ok = False
            continue
        d = 1000 * math.hypot(p.x - c.x, p.y - c.y)
        colour_ok &= d < MATCH_MM
        clip_mm.append(d)
        yaw_deg.append(abs(math.degrees(float(wrap_angle(p.yaw - c.yaw)))))
        scale_err.append(abs(p.scale - c.scale))
    n = res.n_visible
    err = 1000 * np.linalg.norm(obs.rope[:n, :2] - truth[:n, :2], axis=1)
    cam = perceiver._renderer.camera(None)
    uv = cam.world_to_pixel(truth)
    in_image = int(((uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.rows)).sum())
    return {
        "clip_mm": clip_mm, "yaw_deg": yaw_deg, "scale_err": scale_err, "colour_ok": bool(colour_ok),
        "rope_mm": err.tolist(), "head_mm": float(err[0]), "n_visible": n, "in_image": in_image,
        "head_end": res.head_end, "max_speed": float(np.linalg.norm(physics.rope_velocities(), axis=1).max()),
        "routed_true": list(routed_order(scene.clips, truth)),
        "routed_perceived": list(routed_order(obs.clips, obs.rope)),
        "ms": ms,
    }


def stage_steps(physics, rng) -> dict:
    """Stage name -> the action that brings the rope there from the previous stage."""
    from dloroute.skills.heuristic import heuristic_insert
    from dloroute.skills.primitives import pull

    scene = physics.scene
    first, second = scene.clip(scene.order[0]), scene.clip(scene.order[1])
    return {
        "straight": lambda: physics.settle(0.3),
        "one_clip": lambda: heuristic_insert(physics, first),
        "two_clips": lambda: (pull(physics, second), heuristic_insert(physics, second)),
        "crossed": lambda: _drag_across(physics, second, rng),
    }


def run_scene(job: tuple[str, int]) -> list[dict]:
    """All stages of one scene; one record per stage."""
    from dloroute.perception import ImagePerceiver
    from dloroute.sim.physics import Physics, SimulationError
    from dloroute.sim.scene import generate_scene

    family, seed = job
    physics = Physics(generate_scene(family, seed))
    steps = stage_steps(physics, np.random.default_rng(seed))
    records = []
    with ImagePerceiver() as perceiver:
        for stage in STAGES:
            base = {"family": family, "seed": seed, "stage": stage}
            try:
                steps[stage]()
            except SimulationError as err:
                records.append({**base, "error": f"simulation: {err}"})
                break
            records.append({**base, **_measure(physics, perceiver)})
    return records


def _pct(values, q) -> float:
    return float(np.percentile(values, q)) if len(values) else float("nan")


def summarise(records: list[dict]) -> dict[str, dict]:
    """Per stage and overall: the table's numbers."""
    out = {}
    for stage in (*STAGES, "all"):
        rs = [r for r in records if stage in ("all", r["stage"])]
        skipped = [r for r in rs if r.get("error", "").startswith("simulation")]
        ok = [r for r in rs if "error" not in r]
        clip = [v for r in ok for v in r["clip_mm"]]
        yaw = [v for r in ok for v in r["yaw_deg"]]
        rope = [v for r in ok for v in r["rope_mm"]]
        head = [r["head_mm"] for r in ok]
        out[stage] = {
            "samples": len(rs) - len(skipped),
            "failed": len(rs) - len(skipped) - len(ok),
            "skipped": len(skipped),
            "clip_mm_mean": float(np.mean(clip)) if clip else float("nan"),
            "clip_mm_max": max(clip, default=float("nan")),
            "yaw_deg_mean": float(np.mean(yaw)) if yaw else float("nan"),
            "yaw_deg_max": max(yaw, default=float("nan")),
            "scale_err_max": max((v for r in ok for v in r["scale_err"]), default=float("nan")),
            "colour": float(np.mean([r["colour_ok"] for r in ok])) if ok else float("nan"),
            "rope_mm_mean": float(np.mean(rope)) if rope else float("nan"),
            "rope_mm_p95": _pct(rope, 95),
            "head_mm_mean": float(np.mean(head)) if head else float("nan"),
            "head_mm_p95": _pct(head, 95),
            "head_mm_max": max(head, default=float("nan")),
            "visible": sum(r["n_visible"] for r in ok) / max(sum(r["in_image"] for r in ok), 1),
            "routed_agree": float(np.mean([r["routed_true"] == r["routed_perceived"] for r in ok])) if ok else float("nan"),
            "ms_mean": float(np.mean([r["ms"] for r in ok])) if ok else float("nan"),
        }
    return out


def markdown(summary: dict[str, dict]) -> str:
    head = ("| stage | samples | perception failed | clip pos mm (mean / max) | yaw deg (mean / max) | colour | "
            "rope mm (mean / p95) | head mm (mean / p95 / max) | measured / in-image particles | "
            "routed clips agree | ms / perception |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for stage, s in summary.items():
        lines.append(
            f"| {stage} | {s['samples']} | {s['failed']} | {s['clip_mm_mean']:.2f} / {s['clip_mm_max']:.2f} | "
            f"{s['yaw_deg_mean']:.2f} / {s['yaw_deg_max']:.2f} | {100 * s['colour']:.1f}% | "
            f"{s['rope_mm_mean']:.2f} / {s['rope_mm_p95']:.2f} | "
            f"{s['head_mm_mean']:.2f} / {s['head_mm_p95']:.2f} / {s['head_mm_max']:.2f} | "
            f"{100 * s['visible']:.1f}% | {100 * s['routed_agree']:.1f}% | {s['ms_mean']:.0f} |"
        )
    return "\n".join(lines)


def main() -> None:
    from dloroute.types import FAMILIES

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=50, help="seeds per family (scenes = 4 x seeds)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes")
    ap.add_argument("--out", type=Path, default=Path("perception_accuracy.json"), help="JSON output")
    args = ap.parse_args()
    jobs = [(f, s) for f in FAMILIES for s in range(args.seeds)]
    t0 = time.perf_counter()
    with mp.get_context("spawn").Pool(args.workers) as pool:
        records = [r for rs in pool.imap_unordered(run_scene, jobs) for r in rs]
    records.sort(key=lambda r: (r["family"], r["seed"], STAGES.index(r["stage"])))
    summary = summarise(records)
    wall = time.perf_counter() - t0
    args.out.write_text(json.dumps({"scenes": len(jobs), "wall_s": wall, "targets": TARGETS,
                                    "summary": summary, "records": records}, indent=1))
    print(markdown(summary))
    skipped = summary["all"]["skipped"]
    print(f"\n{len(jobs)} scenes, {summary['all']['samples']} samples ({skipped} stages skipped after a simulation "
          f"error), {wall:.0f} s with {args.workers} workers; records in {args.out}")


if __name__ == "__main__":
    main()
