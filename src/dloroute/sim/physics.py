"""MuJoCo model of a scene and the handful of operations skills need.

``Physics`` builds the MJCF from the base asset plus the scene's clips and rope, steps it, grasps and
releases rope particles with the gripper, drives the gripper through via points in the table plane, and
guards every step against instability (NaN, exploding velocities, rope through a clip's solid parts).
All positions are metres in the world frame; yaws are radians about +z.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources

import mujoco
import numpy as np

from dloroute.sim import rope as rope_model
from dloroute.sim.clip_frame import (
    CLIP_DEPTH,
    CLIP_HEIGHT,
    POST_WIDTH,
    opening_width,
)
from dloroute.types import ClipSpec, SceneSpec

ROOF_THICKNESS = 0.008
"""Roof thickness (m); the opening is CLIP_HEIGHT - ROOF_THICKNESS high."""
FINGER_HALF = (0.005, 0.013)
"""Half extents (m, gripper frame x, y) of the fingers' footprint on the table: 1 cm along the rope,
2.6 cm across it (wider than the clip's opening)."""
MAX_SPEED = 0.12
"""Gripper translation speed limit (m/s)."""
MAX_YAW_RATE = 2.0
"""Gripper rotation speed limit (rad/s)."""
MAX_PARTICLE_SPEED = 5.0
"""A rope particle faster than this (m/s) means the simulation blew up."""
MAX_TWIST_RATE = 500.0
"""A rope twist (hinge) degree of freedom faster than this (rad/s) means the simulation blew up."""
STALL_LAG = 0.004
"""Distance (m) between the gripper and the particle it holds at which the motion stops: the rope is
jammed (the head pushed into a post, the rope drawn taut around a clip) and a force-limited arm would
stall rather than force the rope through the clip. Free drags lag about 2.5 mm at 12 cm/s."""
CONTROL_STEPS = 4
"""Physics steps between two gripper set-points and guard checks."""


class SimulationError(RuntimeError):
    """The simulation became invalid; its numbers must not be used."""


class UnstableSimulation(SimulationError):
    """NaN / inf state or exploding velocities."""


class Penetration(SimulationError):
    """The rope passed through a clip's post or roof."""


@dataclass(frozen=True)
class MotionResult:
    """Outcome of a gripper motion: ``collision`` names the clip the fingers touched, if any;
    ``stalled`` says the rope jammed and the gripper stopped early (see STALL_LAG)."""

    collision: str | None
    sim_time: float
    stalled: bool = False


def clip_element(clip: ClipSpec) -> ET.Element:
    """MJCF body for one clip: two posts and a roof, placed in the clip frame (see clip_frame)."""
    w = opening_width(clip)
    h = CLIP_HEIGHT - ROOF_THICKNESS
    rgba = " ".join(str(v) for v in clip.rgba)
    body = ET.Element("body", name=f"clip_{clip.name}", pos=f"{clip.x} {clip.y} 0", euler=f"0 0 {clip.yaw}")
    for side, sign in (("left", 1), ("right", -1)):
        ET.SubElement(
            body, "geom", {"class": "clip"}, name=f"clip_{clip.name}_{side}", rgba=rgba,
            size=f"{CLIP_DEPTH / 2} {POST_WIDTH / 2} {h / 2}", pos=f"0 {sign * (w + POST_WIDTH) / 2} {h / 2}",
        )
    ET.SubElement(
        body, "geom", {"class": "clip"}, name=f"clip_{clip.name}_roof", rgba=rgba,
        size=f"{CLIP_DEPTH / 2} {w / 2 + POST_WIDTH} {ROOF_THICKNESS / 2}", pos=f"0 0 {h + ROOF_THICKNESS / 2}",
    )
    # A dark bar on the roof's exit edge shows the insertion direction in top-down images (visual only).
    ET.SubElement(
        body, "geom", name=f"clip_{clip.name}_arrow", type="box", contype="0", conaffinity="0",
        rgba="0.1 0.1 0.1 1", size=f"0.002 {w / 2 + POST_WIDTH} 0.0005",
        pos=f"{CLIP_DEPTH / 2 - 0.002} 0 {CLIP_HEIGHT + 0.0005}",
    )
    return body


def build_mjcf(scene: SceneSpec) -> str:
    """The scene's MJCF: base asset + one body per clip + the rope."""
    root = ET.fromstring(resources.files("dloroute.sim.assets").joinpath("base.xml").read_text())
    world = root.find("worldbody")
    for clip in scene.clips:
        world.append(clip_element(clip))
    world.append(rope_model.rope_element(scene.rope, scene.rope_head, scene.rope_yaw))
    equality = ET.SubElement(root, "equality")
    for k in range(2):
        ET.SubElement(
            equality, "connect", name=f"grasp{k}", body1="gripper", body2=f"{rope_model.ROPE_NAME}_0",
            anchor="0 0 0", active="false", solref="0.01 1",
        )
    return ET.tostring(root, encoding="unicode")


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


class Physics:
    """A scene's MuJoCo model and data, with the gripper's grasp and motion.

    The gripper is a mocap body whose fingers do not collide physically; touching a clip is detected from
    the fingers' footprint (a 2.6 cm x 1.8 cm rectangle reaching down to the table, taller than any clip)
    overlapping a clip's footprint, and reported as a collision.
    """

    def __init__(self, scene: SceneSpec, *, timestep: float | None = None):
        self.scene = scene
        self.model = mujoco.MjModel.from_xml_string(build_mjcf(scene))
        if timestep is not None:
            self.model.opt.timestep = timestep
        self.data = mujoco.MjData(self.model)
        self._particles = rope_model.particle_body_ids(self.model)
        self._mocap = int(self.model.body("gripper").mocapid[0])
        self._grasp_eq = [int(self.model.equality(f"grasp{k}").id) for k in range(2)]
        self.grasped: int | None = None
        self.stop_before_contact = False
        """When set, a motion whose next set-point would touch a clip stops short (``stalled``) instead of
        colliding: a contact-aware arm controller for deployment. Training and Table I leave it off, so the
        learned skill still meets the paper's collision penalty."""
        self.observers: list[Callable[[Physics], None]] = []
        """Called after every CONTROL_STEPS physics steps (e.g. a video recorder)."""
        slide = self.model.jnt_type[self.model.dof_jntid] == mujoco.mjtJoint.mjJNT_SLIDE
        self._slide_dofs, self._hinge_dofs = np.flatnonzero(slide), np.flatnonzero(~slide)
        # Clip footprints for the vectorised guards: centre, yaw, half extents (m, clip frame).
        clips = scene.clips
        self._clip_xy = np.array([[c.x, c.y] for c in clips]).reshape(-1, 2)
        self._clip_cs = np.array([[math.cos(c.yaw), math.sin(c.yaw)] for c in clips]).reshape(-1, 2)
        self._post_y = np.array([(opening_width(c) + POST_WIDTH) / 2 for c in clips])
        self._half_span = np.array([opening_width(c) / 2 + POST_WIDTH for c in clips])
        self.park_gripper()
        mujoco.mj_forward(self.model, self.data)

    # ----------------------------------------------------------------- state
    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def rope(self) -> np.ndarray:
        """(n, 3) rope particle positions (m, world), head first, at the current time (see ``step``)."""
        return rope_model.particle_positions(self.data, self._particles)

    def rope_velocities(self) -> np.ndarray:
        """(n, 3) particle linear velocities (m/s, world)."""
        return self.data.cvel[self._particles, 3:].copy()

    def gripper_pose(self) -> tuple[float, float, float]:
        """Gripper (x, y, yaw) in the world frame (m, rad)."""
        pos, quat = self.data.mocap_pos[self._mocap], self.data.mocap_quat[self._mocap]
        return float(pos[0]), float(pos[1]), float(2 * math.atan2(quat[3], quat[0]))

    def _set_gripper(self, x: float, y: float, yaw: float, z: float | None = None) -> None:
        pos = self.data.mocap_pos[self._mocap]
        pos[:2] = x, y
        if z is not None:
            pos[2] = z
        self.data.mocap_quat[self._mocap] = _yaw_quat(yaw)

    def park_gripper(self) -> None:
        """Lift the gripper out of the scene (and out of the top camera's view)."""
        self.release()
        self._set_gripper(0.0, 3.0, 0.0, z=0.5)

    # ----------------------------------------------------------------- stepping
    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps, checking stability every CONTROL_STEPS steps.

        ``mj_step`` leaves body positions from before its last integration; recomputing the kinematics
        (positions only) after it makes every read (guards, stall test, observers, ``rope()``) current, so
        an observer that renders (and recomputes them itself) cannot change a trajectory.
        """
        while n > 0:
            k = min(n, CONTROL_STEPS)
            mujoco.mj_step(self.model, self.data, nstep=k)
            mujoco.mj_kinematics(self.model, self.data)
            self.check()
            for observer in self.observers:
                observer(self)
            n -= k

    def settle(self, duration: float = 0.4) -> None:
        """Let the rope come to rest for ``duration`` seconds of simulated time."""
        self.step(max(1, round(duration / self.timestep)))

    def check(self) -> None:
        """Raise a SimulationError if the state is invalid (see the module docstring)."""
        d = self.data
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            raise UnstableSimulation(f"non-finite state at t = {d.time:.3f} s")
        for kind in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC):
            if d.warning[kind].number > 0:  # MuJoCo resets the state after these: the run is void
                raise UnstableSimulation(f"MuJoCo detected a non-finite or huge state ({kind.name}) at t = {d.time:.3f} s")
        speed = np.abs(d.qvel[self._slide_dofs]).max(initial=0.0)
        twist = np.abs(d.qvel[self._hinge_dofs]).max(initial=0.0)
        if speed > MAX_PARTICLE_SPEED or twist > MAX_TWIST_RATE:
            raise UnstableSimulation(
                f"rope velocity {speed:.1f} m/s or twist rate {twist:.0f} rad/s beyond the limits "
                f"({MAX_PARTICLE_SPEED} m/s, {MAX_TWIST_RATE} rad/s) at t = {d.time:.3f} s"
            )
        hit = self.penetrated_clip()
        if hit is not None:
            raise Penetration(f"the rope passed through the solid part of clip {hit!r} at t = {d.time:.3f} s")

    def _local(self, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (m) -> x, y in every clip's frame; arrays of shape (n_clips, n_points)."""
        rel = points_xy[None, :, :] - self._clip_xy[:, None, :]
        c, s = self._clip_cs[:, 0:1], self._clip_cs[:, 1:2]
        return c * rel[..., 0] + s * rel[..., 1], -s * rel[..., 0] + c * rel[..., 1]

    def penetrated_clip(self) -> str | None:
        """Name of a clip whose post or roof contains a rope centre-line point (1 mm tolerance), else None."""
        if not self.scene.clips:
            return None
        p = self.data.xpos[self._particles]
        dense = np.concatenate([p, 0.5 * (p[1:] + p[:-1]), 0.25 * p[1:] + 0.75 * p[:-1], 0.75 * p[1:] + 0.25 * p[:-1]])
        x, y = self._local(dense[:, :2])
        z = dense[:, 2][None, :]
        tol = 0.001
        in_x = np.abs(x) < CLIP_DEPTH / 2 - tol
        in_post = in_x & (np.abs(np.abs(y) - self._post_y[:, None]) < POST_WIDTH / 2 - tol)
        roof_low = CLIP_HEIGHT - ROOF_THICKNESS + tol
        in_roof = in_x & (np.abs(y) < self._half_span[:, None] - tol) & (z > roof_low) & (z < CLIP_HEIGHT - tol)
        bad = np.flatnonzero((in_post | in_roof).any(axis=1))
        return self.scene.clips[bad[0]].name if bad.size else None

    # ----------------------------------------------------------------- gripper
    def gripper_collision(self, x: float, y: float, yaw: float) -> str | None:
        """Name of the first clip whose footprint overlaps the fingers' footprint at (x, y, yaw), else None.

        Separating-axis test of two rectangles in the table plane (the fingers reach the table and are
        taller than every clip, so any overlap in the plane is a collision).
        """
        fx, fy = FINGER_HALF
        g_axes = np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]])
        for i, clip in enumerate(self.scene.clips):
            c_axes = np.array([self._clip_cs[i], [-self._clip_cs[i, 1], self._clip_cs[i, 0]]])
            c_half = np.array([CLIP_DEPTH / 2, self._half_span[i]])
            d = np.array([x, y]) - self._clip_xy[i]
            separated = False
            for axis in (*g_axes, *c_axes):
                r_g = fx * abs(axis @ g_axes[0]) + fy * abs(axis @ g_axes[1])
                r_c = c_half[0] * abs(axis @ c_axes[0]) + c_half[1] * abs(axis @ c_axes[1])
                if abs(axis @ d) > r_g + r_c:
                    separated = True
                    break
            if not separated:
                return clip.name
        return None

    def rope_yaw_at(self, index: int) -> float:
        """Direction (rad, world) of the rope at particle ``index``, pointing towards the head."""
        p = self.rope()
        a, b = (p[index - 1], p[index]) if index > 0 else (p[0], p[1])
        return math.atan2(a[1] - b[1], a[0] - b[0])

    def grasp(self, index: int) -> str | None:
        """Place the gripper on particle ``index`` (fingers across the rope) and attach it.

        Returns the name of a clip the fingers would collide with there (nothing is attached then).
        The particle and its head-side neighbour are both held, so the gripper also holds the yaw of the
        segment that leads towards the head.
        """
        n = len(self._particles)
        if not 0 <= index < n:
            raise ValueError(f"grasp index {index} outside the rope's particles 0..{n - 1}")
        self.release()
        p = self.rope()
        yaw = self.rope_yaw_at(index)
        hit = self.gripper_collision(p[index, 0], p[index, 1], yaw)
        if hit is not None:
            return hit
        self._set_gripper(p[index, 0], p[index, 1], yaw, z=p[index, 2])
        other = index - 1 if index > 0 else 1  # the head-side neighbour: it steers the free front segment
        c, s = math.cos(yaw), math.sin(yaw)
        for eq, vertex in zip(self._grasp_eq, (index, other)):
            rel = p[vertex] - p[index]
            self.model.eq_obj2id[eq] = self._particles[vertex]
            self.model.eq_data[eq, 0:3] = (c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1], rel[2])
            self.model.eq_data[eq, 3:6] = 0.0
            self.data.eq_active[eq] = 1
        self.grasped = index
        return None

    def grasp_lag(self) -> float:
        """Distance (m, table plane) from the gripper to the particle it holds; 0 when nothing is held."""
        if self.grasped is None:
            return 0.0
        pos = self.data.mocap_pos[self._mocap]
        held = self.data.xpos[self._particles[self.grasped]]
        return float(np.hypot(pos[0] - held[0], pos[1] - held[1]))

    def release(self) -> None:
        for eq in self._grasp_eq:
            self.data.eq_active[eq] = 0
        self.grasped = None

    def move(self, waypoints: list[tuple[float, float, float]]) -> MotionResult:
        """Drive the gripper through ``waypoints`` (x, y, yaw; m, rad, world) at bounded speed.

        Stops at the first set-point whose fingers touch a clip and reports it as a collision.
        """
        t0 = self.time
        ctrl_dt = CONTROL_STEPS * self.timestep
        x0, y0, a0 = self.gripper_pose()
        for x1, y1, a1 in waypoints:
            da = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
            duration = max(math.hypot(x1 - x0, y1 - y0) / MAX_SPEED, abs(da) / MAX_YAW_RATE, ctrl_dt)
            n = math.ceil(duration / ctrl_dt)
            for k in range(1, n + 1):
                f = k / n
                x, y, a = x0 + f * (x1 - x0), y0 + f * (y1 - y0), a0 + f * da
                hit = self.gripper_collision(x, y, a)
                if hit is not None:
                    if self.stop_before_contact:
                        return MotionResult(collision=None, sim_time=self.time - t0, stalled=True)
                    return MotionResult(collision=hit, sim_time=self.time - t0)
                self._set_gripper(x, y, a)
                self.step(CONTROL_STEPS)
                if self.grasp_lag() > STALL_LAG:
                    self._set_gripper(*self.rope()[self.grasped, :2], a)
                    return MotionResult(collision=None, sim_time=self.time - t0, stalled=True)
            x0, y0, a0 = x1, y1, a0 + da
        return MotionResult(collision=None, sim_time=self.time - t0)
