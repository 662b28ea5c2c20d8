from __future__ import annotations

from collections.abc import Iterator

import pytest
from planner_helpers import FakeOpenAI, serve


@pytest.fixture
def fake_openai() -> Iterator[FakeOpenAI]:
    """A scripted OpenAI-compatible server on 127.0.0.1 (random free port), stopped after the test."""
    fake = FakeOpenAI()
    server = serve(fake)
    yield fake
    server.shutdown()
    server.server_close()
