"""Perception: the scene state (clip poses and colours, ordered rope particles) for planners and skills.

Two perceivers share one interface, ``perceive(physics) -> Observation``: ``OraclePerceiver`` reads
the simulator (oracle.py); ``ImagePerceiver`` renders top-down images and measures them (segment.py,
built on masks.py, clips.py, centreline.py and particles.py; see docs/perception.md).
``make_perceiver`` builds either from its name, for the episode loop's switch.
"""

from __future__ import annotations

from typing import Literal, Protocol

from dloroute.perception.masks import ColourSegmenter, Sam2Segmenter, Segmentation, Segmenter
from dloroute.perception.oracle import OraclePerceiver
from dloroute.perception.segment import ImagePerceiver, Perception, PerceptionError, View, perceive_physics
from dloroute.sim.physics import Physics
from dloroute.types import Observation

PerceiverName = Literal["oracle", "image"]


class Perceiver(Protocol):
    """Anything that observes a running simulation: the oracle, or the image pipeline."""

    def perceive(self, physics: Physics) -> Observation: ...


def make_perceiver(name: PerceiverName) -> Perceiver:
    """The perceiver called ``name``: "oracle" (simulator state) or "image" (rendered images)."""
    if name == "oracle":
        return OraclePerceiver()
    if name == "image":
        return ImagePerceiver()
    raise ValueError(f"unknown perceiver {name!r}; choose 'oracle' or 'image'")


__all__ = [
    "ColourSegmenter",
    "ImagePerceiver",
    "OraclePerceiver",
    "Perceiver",
    "PerceiverName",
    "Perception",
    "PerceptionError",
    "Sam2Segmenter",
    "Segmentation",
    "Segmenter",
    "View",
    "make_perceiver",
    "perceive_physics",
]
