"""The oracle perceiver: the scene state straight from the simulator (ground truth)."""

from __future__ import annotations

from dloroute.sim.physics import Physics
from dloroute.types import Observation


class OraclePerceiver:
    """Clip poses from the scene spec, rope particles (m, world, head first) from the physics state."""

    def perceive(self, physics: Physics) -> Observation:
        return Observation(clips=physics.scene.clips, rope=physics.rope(), source="oracle")
