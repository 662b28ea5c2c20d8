"""Test helpers: a scripted OpenAI-compatible server on 127.0.0.1, synthetic ropes and planner contexts."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from dloroute.sim.clip_frame import clip_status, to_world_frame
from dloroute.types import (
    ClipSpec,
    Decision,
    Observation,
    PlannerContext,
    SkillCall,
    SkillResult,
    StepRecord,
)

SPACING = 0.025
"""Particle spacing (m) of synthetic ropes (1 m, 41 particles)."""


# --------------------------------------------------------------------------- scripted server
@dataclass
class Reply:
    """One scripted server reply: ``content`` as the assistant message, or an HTTP ``status`` error body,
    after sleeping ``delay`` seconds."""

    content: str | None = None
    status: int = 200
    delay: float = 0.0


@dataclass
class FakeOpenAI:
    """Records every request (path, headers, JSON body) and answers from ``script`` in order."""

    script: list[Reply] = field(default_factory=list)
    requests: list[dict[str, Any]] = field(default_factory=list)
    url: str = ""

    def answer(self, *replies: Reply | str) -> None:
        self.script.extend(r if isinstance(r, Reply) else Reply(content=r) for r in replies)


def serve(fake: FakeOpenAI) -> ThreadingHTTPServer:
    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:  # noqa: N802 (http.server API)
            body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
            fake.requests.append(
                {"path": self.path, "headers": {k.lower(): v for k, v in self.headers.items()}, "body": body}
            )
            reply = fake.script.pop(0) if fake.script else Reply(status=500)
            time.sleep(reply.delay)
            if reply.status == 200:
                payload = {
                    "id": f"chatcmpl-{len(fake.requests)}",
                    "object": "chat.completion",
                    "created": 0,
                    "model": body["model"],
                    "choices": [
                        {
                            "index": 0,
                            "message": {"role": "assistant", "content": reply.content},
                            "finish_reason": "stop",
                        }
                    ],
                    "usage": {"prompt_tokens": 100, "completion_tokens": 20, "total_tokens": 120},
                }
            else:
                payload = {"error": {"message": "scripted failure", "type": "server_error"}}
            data = json.dumps(payload).encode()
            try:
                self.send_response(reply.status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the client gave up (timeout test)

        def log_message(self, *args: object) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True).start()
    fake.url = f"http://127.0.0.1:{server.server_address[1]}/v1"
    return server


def decision_json(skill: str | None, clip: str | None, done: bool = False, reasoning: str = "ok") -> str:
    return json.dumps({"reasoning": reasoning, "skill": skill, "target_clip": clip, "task_done": done})


def plan_json(order: Sequence[str]) -> str:
    steps = [{"clip": c, "direction": "along_clip_axis"} for c in order]
    return json.dumps({"reasoning": "colours in order", "steps": steps})


# --------------------------------------------------------------------------- ropes and contexts
def polyline_rope(points: Sequence[Sequence[float]], n: int = 41) -> np.ndarray:
    """(n, 3) particles (m, world), head first, SPACING apart along the polyline from points[0] onward."""
    pts = np.asarray(points, dtype=float)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.arange(n) * SPACING
    last = pts[-1] - pts[-2]
    extra = np.clip(s - arc[-1], 0, None)
    xy = np.stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])], axis=1)
    xy += extra[:, None] * last / np.linalg.norm(last)
    return np.concatenate([xy, np.full((n, 1), 0.0035)], axis=1)


def straight_rope(clip: ClipSpec, head_local: tuple[float, float], heading_local: float = 0.0) -> np.ndarray:
    """A straight rope whose head sits at ``head_local`` (m, clip frame) pointing along ``heading_local``."""
    hx, hy = head_local
    back = np.array([-np.cos(heading_local), -np.sin(heading_local)])
    local = np.array([[hx, hy], [hx + back[0], hy + back[1]]])
    return polyline_rope(to_world_frame(clip, local))


def step(i: int, skill: str, clip: str, success: bool) -> StepRecord:
    return StepRecord(
        step=i,
        decision=Decision(call=SkillCall(skill, clip)),  # type: ignore[arg-type]
        result=SkillResult(skill=skill, clip=clip, success=success),  # type: ignore[arg-type]
    )


def context(
    clips: Sequence[ClipSpec],
    rope: np.ndarray,
    *,
    history: Sequence[StepRecord] = (),
    consecutive_failures: int = 0,
    instruction: str = "",
    views: Any = None,
    step_limit: int = 30,
) -> PlannerContext:
    obs = Observation(clips=tuple(clips), rope=rope)
    return PlannerContext(
        instruction=instruction,
        observation=obs,
        statuses=tuple(clip_status(c, rope) for c in clips),
        history=tuple(history),
        consecutive_failures=consecutive_failures,
        step=len(history),
        step_limit=step_limit,
        views=views,
    )


def fake_views(clip_name: str | None) -> np.ndarray:
    """A small distinct RGB image per view: the scene for None, else one per clip name."""
    seed = 0 if clip_name is None else sum(map(ord, clip_name))
    return np.random.default_rng(seed).integers(0, 256, size=(24, 32, 3), dtype=np.uint8)
