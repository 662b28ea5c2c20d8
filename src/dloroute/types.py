"""Frozen dataclasses shared by every layer (scene, physics, skills, planners, evaluation).

Units are metres, radians and seconds. Poses are in the world frame unless a field says otherwise:
the world frame has its origin at the table centre, +z up, the table top at z = 0.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

SkillName = Literal["insert", "pull", "flatten"]
SKILLS: tuple[SkillName, ...] = ("insert", "pull", "flatten")

FamilyName = Literal["implicit", "fixed_spatial", "fixed_attribute", "clips_4_5"]
FAMILIES: tuple[FamilyName, ...] = ("implicit", "fixed_spatial", "fixed_attribute", "clips_4_5")

# Clip colours: name -> RGBA. Chosen to be far apart in hue so both people and the colour segmenter
# tell them apart in a top-down render.
CLIP_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "red": (0.85, 0.10, 0.10, 1.0),
    "green": (0.10, 0.70, 0.15, 1.0),
    "blue": (0.10, 0.25, 0.90, 1.0),
    "yellow": (0.95, 0.85, 0.10, 1.0),
    "purple": (0.60, 0.15, 0.75, 1.0),
}


@dataclass(frozen=True)
class ClipSpec:
    """One rigid clip on the table.

    ``x``, ``y`` (m) and ``yaw`` (rad) are the clip frame's pose in the world frame: the origin is the
    tunnel centre on the table and +x (``yaw``) is the insertion direction. ``scale`` widens the opening
    (2.2 cm at 1.0). ``name`` is the clip's label in instructions and decisions; it is its colour.
    """

    name: str
    x: float
    y: float
    yaw: float
    scale: float = 1.0

    @property
    def colour(self) -> str:
        return self.name

    @property
    def rgba(self) -> tuple[float, float, float, float]:
        return CLIP_COLOURS[self.name]


def clip_named(clips: tuple[ClipSpec, ...], name: str) -> ClipSpec:
    """The clip called ``name``; a KeyError that lists the clips otherwise."""
    for c in clips:
        if c.name == name:
            return c
    raise KeyError(f"no clip named {name!r}; clips: {[c.name for c in clips]}")


@dataclass(frozen=True)
class RopeSpec:
    """Rope model parameters: length (m), radius (m), mass (kg), Young's modulus (Pa), particle count."""

    length: float = 1.2
    radius: float = 0.0035
    mass: float = 0.06
    young: float = 2.0e5
    n_particles: int = 49

    @property
    def spacing(self) -> float:
        """Rest distance between neighbouring particles (m)."""
        return self.length / (self.n_particles - 1)


@dataclass(frozen=True)
class SceneSpec:
    """A generated task: clip layout, rope start, instruction and its ground-truth order.

    ``rope_head`` is the head particle's (x, y) in the world frame (m); ``rope_yaw`` is the direction
    from tail to head (rad, world); the rope starts straight. ``order`` lists clip names in the order the
    rope must pass through them.
    """

    family: str
    seed: int
    clips: tuple[ClipSpec, ...]
    order: tuple[str, ...]
    instruction: str
    rope_head: tuple[float, float]
    rope_yaw: float
    rope: RopeSpec = field(default_factory=RopeSpec)

    def clip(self, name: str) -> ClipSpec:
        return clip_named(self.clips, name)

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), indent=2)

    @classmethod
    def from_json(cls, text: str) -> SceneSpec:
        raw = json.loads(text)
        return cls(
            family=raw["family"],
            seed=raw["seed"],
            clips=tuple(ClipSpec(**c) for c in raw["clips"]),
            order=tuple(raw["order"]),
            instruction=raw["instruction"],
            rope_head=tuple(raw["rope_head"]),
            rope_yaw=raw["rope_yaw"],
            rope=RopeSpec(**raw["rope"]),
        )


@dataclass(frozen=True)
class ClipStatus:
    """The rope's relation to one clip, measured in that clip's frame (DESIGN's conventions).

    ``rope_in``: the head entered the tunnel through the entry face (it is inside, or went on through).
    ``rope_out``: the rope passes through the tunnel entry-to-exit and the head is past the exit face.
    ``routed``: the rope passes through the tunnel entry-to-exit (the head may be far beyond).
    ``d_floor`` / ``d_ceil``: distance (m) from the head to the centre of the entry / exit face.
    ``signed_distance``: the paper's signed endpoint distance (m): +d_ceil when ``rope_out``, else
    -d_ceil; above +0.02 after an insertion primitive = success.
    ``crossing_index``: arc position (in particles, fractional) where the rope crosses the tunnel, or None.
    """

    name: str
    rope_in: bool
    rope_out: bool
    routed: bool
    d_floor: float
    d_ceil: float
    signed_distance: float
    crossing_index: float | None = None


@dataclass(frozen=True)
class SkillCall:
    """A skill and its target clip, as a planner chooses them."""

    skill: SkillName
    clip: str


@dataclass(frozen=True)
class Decision:
    """A planner's decision for one step.

    ``call`` is None when the planner declares the task done (``done``) or failed to decide (``failed``;
    e.g. a VLM answer that stayed invalid after the retries; ``error`` then says why).
    """

    call: SkillCall | None
    done: bool = False
    reasoning: str = ""
    failed: bool = False
    error: str | None = None


@dataclass(frozen=True)
class SkillResult:
    """What a skill did. ``success`` is the skill's own criterion (Insert: signed distance > +2 cm)."""

    skill: SkillName
    clip: str
    success: bool
    collision: bool = False
    reason: str = ""
    primitives: int = 1
    signed_distance: float | None = None
    sim_time: float = 0.0


@dataclass(frozen=True, eq=False)
class Observation:
    """What a planner or policy sees: clip poses and the rope's particles, from the oracle or perception.

    ``rope`` is an (n, 3) array of particle positions (m, world), head first.
    """

    clips: tuple[ClipSpec, ...]
    rope: np.ndarray
    source: Literal["oracle", "perception"] = "oracle"

    @property
    def head(self) -> np.ndarray:
        return self.rope[0]

    def clip(self, name: str) -> ClipSpec:
        return clip_named(self.clips, name)


@dataclass(frozen=True)
class StepRecord:
    """One executed step of an episode: the decision and what its skill did."""

    step: int
    decision: Decision
    result: SkillResult | None


@dataclass(frozen=True, eq=False)
class PlannerContext:
    """Everything a high-level planner may use for one decision.

    ``views`` renders an RGB image (H, W, 3, uint8): the whole scene for ``None``, else the zoomed view
    centred on the named clip. ``consecutive_failures`` counts insertion attempts in a row that did not
    succeed; ``step`` counts executed skills so far, ``step_limit`` is the episode's cap.
    """

    instruction: str
    observation: Observation
    statuses: tuple[ClipStatus, ...]
    history: tuple[StepRecord, ...]
    consecutive_failures: int
    step: int
    step_limit: int
    views: Callable[[str | None], np.ndarray] | None = None

    def status(self, name: str) -> ClipStatus:
        for s in self.statuses:
            if s.name == name:
                return s
        raise KeyError(name)


Termination = Literal[
    "success", "collision", "timeout", "early_termination", "planner_failure", "unstable", "perception_failure"
]


@dataclass(frozen=True)
class EpisodeResult:
    """One routing episode's outcome. ``length`` counts executed pick-and-place skills."""

    family: str
    seed: int
    planner: str
    low_level: str
    success: bool
    termination: Termination
    clips_routed: int
    n_clips: int
    length: int
    wall_time: float
    routed_order: tuple[str, ...] = ()
    steps: tuple[dict[str, Any], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
