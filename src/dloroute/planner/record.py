"""Recording of every VLM call into a run folder, and offline replay of a recorded run.

A run folder holds ``calls.jsonl`` (one line per attempt: request with images replaced by file
references, raw answer, error, parsed result, latency, token usage) and ``images/<sha256>.png`` (each
distinct image once). API keys never reach the folder: the request carries none, keys named like
credentials are redacted, and every configured secret value and ``Bearer`` token is scrubbed from
every string before a line is written.

:class:`ReplayClient` answers the same requests from a recording, in order and without network, so a
planner fed the same contexts reproduces the recorded decisions exactly.
"""

from __future__ import annotations

import base64
import hashlib
import json
import re
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

CALLS_FILE = "calls.jsonl"
IMAGES_DIR = "images"
REDACTED = "[REDACTED]"
MIN_SECRET_LENGTH = 8
"""Secret values shorter than this (characters) are not scrubbed from text: they would mangle it."""

_PNG_PREFIX = "data:image/png;base64,"
_CREDENTIAL_KEY = re.compile(r"authorization|api[-_]?key|secret|token$", re.IGNORECASE)
_BEARER = re.compile(r"Bearer\s+[^\s\"',]+")


class ChatError(RuntimeError):
    """A call that returned no answer: HTTP error, timeout, connection failure (retryable)."""


class ReplayMismatch(RuntimeError):
    """The replayed run asks a different question than the recording holds (not retryable)."""


@dataclass(frozen=True)
class ChatAnswer:
    """A completion's answer text (None when the model gave none) and token usage as the server sent it."""

    text: str | None
    usage: dict[str, Any] | None = None


@dataclass(frozen=True)
class CallRecord:
    """One attempt of one planner query, as written to ``calls.jsonl``.

    ``kind`` is the query ("plan" or "decide"), ``step`` the episode step it was made at, ``attempt`` its
    index among the retries (0 first). ``error_kind`` is "transport" when no answer came back, "answer"
    when the answer failed validation, None on success; ``result`` is the parsed plan or decision.
    """

    kind: Literal["plan", "decide"]
    step: int
    attempt: int
    request: dict[str, Any]
    answer: str | None
    usage: dict[str, Any] | None
    latency_s: float
    error: str | None
    error_kind: Literal["transport", "answer"] | None
    result: dict[str, Any] | None


def fingerprint(request: dict[str, Any]) -> str:
    """Hash of a request's messages and response format with every image replaced by a marker.

    Images are left out so that a replay is not broken by renderer differences of a pixel.
    """

    def strip(node: Any) -> Any:
        if isinstance(node, dict):
            if node.get("type") in ("image_url", "image_file"):
                return "<image>"
            return {k: strip(v) for k, v in node.items()}
        if isinstance(node, list):
            return [strip(v) for v in node]
        return node

    key = {"messages": strip(request["messages"]), "response_format": request.get("response_format")}
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()


class CallRecorder:
    """Appends :class:`CallRecord` lines to ``run_dir/calls.jsonl``; images go to ``run_dir/images``.

    ``secrets`` are values (e.g. the API key) scrubbed from everything written.
    """

    def __init__(self, run_dir: Path, *, secrets: Sequence[str] = ()):
        self.run_dir = Path(run_dir)
        (self.run_dir / IMAGES_DIR).mkdir(parents=True, exist_ok=True)
        self._secrets = tuple(s for s in secrets if s and len(s) >= MIN_SECRET_LENGTH)

    def record(self, rec: CallRecord) -> None:
        line = asdict(rec)
        line["request"] = {**rec.request, "messages": self._externalise(rec.request["messages"])}
        line["fingerprint"] = fingerprint(rec.request)
        text = json.dumps(self._scrub(line), ensure_ascii=False)
        for s in self._secrets:
            text = text.replace(s, REDACTED)
        with open(self.run_dir / CALLS_FILE, "a", encoding="utf-8") as f:
            f.write(text + "\n")

    def _externalise(self, node: Any) -> Any:
        """Copy of ``node`` with PNG data URLs written to files and replaced by ``image_file`` refs."""
        if isinstance(node, dict):
            url = node.get("image_url", {}).get("url", "") if node.get("type") == "image_url" else ""
            if url.startswith(_PNG_PREFIX):
                png = base64.b64decode(url[len(_PNG_PREFIX) :])
                rel = f"{IMAGES_DIR}/{hashlib.sha256(png).hexdigest()[:20]}.png"
                path = self.run_dir / rel
                if not path.exists():
                    path.write_bytes(png)
                return {"type": "image_file", "path": rel}
            return {k: self._externalise(v) for k, v in node.items()}
        if isinstance(node, list):
            return [self._externalise(v) for v in node]
        return node

    def _scrub(self, node: Any) -> Any:
        if isinstance(node, dict):
            return {
                k: REDACTED if _CREDENTIAL_KEY.search(str(k)) else self._scrub(v) for k, v in node.items()
            }
        if isinstance(node, list):
            return [self._scrub(v) for v in node]
        if isinstance(node, str):
            node = _BEARER.sub(f"Bearer {REDACTED}", node)
            for s in self._secrets:
                node = node.replace(s, REDACTED)
        return node


def load_records(run_dir: Path) -> list[dict[str, Any]]:
    """The recorded attempts of a run folder, in call order."""
    path = Path(run_dir) / CALLS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"no recorded calls at {path}")
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


class ReplayClient:
    """A chat client that answers from a recorded run folder, attempt by attempt, with no network.

    Each request must match the next recorded one (same :func:`fingerprint`), else
    :class:`ReplayMismatch`. A recorded transport failure is raised again as :class:`ChatError`.
    """

    def __init__(self, run_dir: Path):
        self._records = load_records(run_dir)
        self._next = 0

    def complete(self, request: dict[str, Any]) -> ChatAnswer:
        if self._next >= len(self._records):
            raise ReplayMismatch(
                f"the recording has only {len(self._records)} calls; call #{self._next} asked"
            )
        rec = self._records[self._next]
        self._next += 1
        if rec["fingerprint"] != fingerprint(request):
            raise ReplayMismatch(
                f"call #{self._next - 1} ({rec['kind']}, step {rec['step']}, attempt {rec['attempt']}) "
                "differs from the recorded request"
            )
        if rec["error_kind"] == "transport":
            raise ChatError(rec["error"])
        return ChatAnswer(rec["answer"], rec["usage"])
