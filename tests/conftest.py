"""Shared fixtures (tests/ is on sys.path, so test modules import ``scene_helpers`` directly)."""

import pytest
from scene_helpers import one_clip_scene

from dloroute.types import SceneSpec


@pytest.fixture
def clip_scene() -> SceneSpec:
    return one_clip_scene()
