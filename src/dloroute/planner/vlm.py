"""The in-context VLM planner on an OpenAI-compatible Chat Completions endpoint.

One ``openai.OpenAI`` client reaches GPT-5 (OpenAI cloud), vLLM, Ollama, llama.cpp, LM Studio or SGLang
through ``base_url``. The first decision of an episode asks for the routing :class:`~.schema.Plan` from
the scene image and the instruction; every decision then sends the system prompt, the two in-context
examples, a status report (step, history, failure counter and step limit), the whole-scene image and the
zoomed view of the current clip, all images as PNG data URLs, and asks for structured output through
``response_format`` json_schema. Answers are validated with pydantic (model output is data, never
executed); invalid answers, HTTP errors and timeouts are retried up to ``max_retries`` times, after which
the decision comes back failed instead of raising. Every attempt is recorded when a run folder is given,
and a recorded folder can be replayed offline.
"""

from __future__ import annotations

import base64
import dataclasses
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal, Protocol, TypeVar

import cv2
import numpy as np
import openai
from pydantic import BaseModel, ConfigDict, Field

from dloroute.planner.prompts import PromptBundle, load_prompt, render_template
from dloroute.planner.record import (
    CallRecord,
    CallRecorder,
    ChatAnswer,
    ChatError,
    ReplayClient,
)
from dloroute.planner.schema import (
    AnswerError,
    Plan,
    decision_response_format,
    parse_decision,
    parse_plan,
    plan_response_format,
)
from dloroute.types import Decision, Observation, PlannerContext, StepRecord

T = TypeVar("T")


class VLMConfig(BaseModel):
    """Where and how the VLM planner asks its model.

    ``base_url`` None means the OpenAI cloud. The API key is read from the environment variable named
    ``api_key_env`` and is never stored or recorded; local servers that need no key accept any value.
    ``max_retries`` counts attempts after the first; ``timeout_s`` bounds each attempt (s).
    ``temperature`` is sent only when set (GPT-5 rejects it); ``reasoning_effort`` only when set.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    model: str = "gpt-5"
    base_url: str | None = None
    api_key_env: str = "OPENAI_API_KEY"
    timeout_s: float = Field(default=120.0, gt=0)
    max_retries: int = Field(default=2, ge=0)
    retry_backoff_s: float = Field(default=1.0, ge=0, description="Sleep (s) before retry k: backoff * 2**k.")
    reasoning_effort: Literal["none", "minimal", "low", "medium", "high", "xhigh"] | None = None
    temperature: float | None = Field(default=None, ge=0, le=2)
    failure_reasoning: bool = True
    history_steps: int = Field(default=12, ge=1, description="Most recent steps listed in the status.")

    def api_key(self) -> str | None:
        """The key from the environment, or None when the variable is unset or empty."""
        return os.environ.get(self.api_key_env) or None


class ChatClient(Protocol):
    """Sends one Chat Completions request; raises :class:`~.record.ChatError` when no answer came back."""

    def complete(self, request: dict[str, Any]) -> ChatAnswer: ...


class OpenAIChatClient:
    """The official ``openai`` SDK client; SDK retries are off (the planner retries itself)."""

    def __init__(self, config: VLMConfig):
        key = config.api_key()
        if key is None and config.base_url is None:
            raise ValueError(
                f"the OpenAI cloud needs an API key: set the environment variable {config.api_key_env}"
            )
        kwargs: dict[str, Any] = {"base_url": config.base_url} if config.base_url else {}
        self._client = openai.OpenAI(
            api_key=key or "unused", timeout=config.timeout_s, max_retries=0, **kwargs
        )

    def complete(self, request: dict[str, Any]) -> ChatAnswer:
        try:
            response = self._client.chat.completions.create(**request)
        except openai.OpenAIError as e:
            raise ChatError(f"{type(e).__name__}: {e}") from e
        if not response.choices:
            return ChatAnswer(None, None)
        usage = response.usage.model_dump() if response.usage is not None else None
        return ChatAnswer(response.choices[0].message.content, usage)


class PlannerQueryError(RuntimeError):
    """A query whose every attempt failed; the message lists each attempt's error."""


def png_data_url(image: np.ndarray | bytes) -> str:
    """An RGB uint8 image (H, W, 3) or PNG bytes as a ``data:image/png;base64,...`` URL."""
    if isinstance(image, np.ndarray):
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"expected an RGB uint8 image (H, W, 3), got {image.dtype} {image.shape}")
        ok, buf = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
        if not ok:
            raise ValueError("PNG encoding failed")
        image = buf.tobytes()
    return "data:image/png;base64," + base64.b64encode(image).decode("ascii")


def _text(text: str) -> dict[str, Any]:
    return {"type": "text", "text": text}


def _image(url: str) -> dict[str, Any]:
    return {"type": "image_url", "image_url": {"url": url}}


class VLMPlanner:
    """High-level planner asking a VLM for a plan, then one skill and target clip per step.

    ``name`` is "vlm" with failure reasoning, "vlm_no_fr" without (no failure text, no Flatten).
    ``run_dir``: record every call there. ``replay_dir``: answer from that recording, no network.
    ``prompt`` / ``client`` replace the packaged prompt and the SDK client (tests, other transports).
    """

    def __init__(
        self,
        config: VLMConfig | None = None,
        *,
        run_dir: Path | None = None,
        replay_dir: Path | None = None,
        prompt: PromptBundle | None = None,
        client: ChatClient | None = None,
    ):
        self.config = config or VLMConfig()
        variant = "failure_reasoning" if self.config.failure_reasoning else "no_failure_reasoning"
        self.name = "vlm" if self.config.failure_reasoning else "vlm_no_fr"
        self.prompt = prompt or load_prompt(variant)
        if self.prompt.variant != variant:
            raise ValueError(
                f"prompt variant {self.prompt.variant!r} does not match the config ({variant!r})"
            )
        if replay_dir is not None:
            self._client: ChatClient = ReplayClient(Path(replay_dir))
            self._backoff = 0.0
        else:
            self._client = client or OpenAIChatClient(self.config)
            self._backoff = self.config.retry_backoff_s
        secrets = [self.config.api_key() or ""]
        self._recorder = CallRecorder(Path(run_dir), secrets=secrets) if run_dir is not None else None
        self._instruction = ""
        self._clips: tuple[str, ...] = ()
        self.routing_plan: Plan | None = None

    def reset(self, instruction: str, observation: Observation) -> None:
        """Start an episode: the instruction and the scene's clip names; the plan is asked at step one."""
        self._instruction = instruction
        self._clips = tuple(c.name for c in observation.clips)
        self.routing_plan = None

    def plan(self, scene: np.ndarray, step: int = 0) -> Plan:
        """Ask for the routing plan from the scene image (RGB uint8); raises PlannerQueryError on failure."""
        text = render_template(
            self.prompt.plan_template,
            instruction=self._instruction,
            n_clips=len(self._clips),
            clip_names=", ".join(self._clips),
        )
        messages = [
            {"role": "system", "content": self.prompt.system},
            {"role": "user", "content": [_text(text), _image(png_data_url(scene))]},
        ]
        self.routing_plan = self._ask(
            "plan", step, messages, plan_response_format(self._clips), lambda t: parse_plan(t, self._clips)
        )
        return self.routing_plan

    def decide(self, ctx: PlannerContext) -> Decision:
        """The next skill and clip, or done; a failed decision (never an exception) when the model fails.

        Only a replay whose recording does not fit the run raises (:class:`~.record.ReplayMismatch`).
        """
        if ctx.views is None:
            return Decision(call=None, failed=True, error="the VLM planner needs rendered views (ctx.views)")
        scene = ctx.views(None)
        try:
            plan = self.routing_plan or self.plan(scene, ctx.step)
            clip = current_clip(plan, ctx.history)
            messages = self._decide_messages(ctx, plan, clip, scene, ctx.views(clip))
            skills = self.prompt.skills
            return self._ask(
                "decide",
                ctx.step,
                messages,
                decision_response_format(self._clips, skills),
                lambda t: parse_decision(t, self._clips, skills),
            )
        except PlannerQueryError as e:
            return Decision(call=None, failed=True, error=str(e))

    def _decide_messages(
        self, ctx: PlannerContext, plan: Plan, clip: str, scene: np.ndarray, zoom: np.ndarray
    ) -> list[dict[str, Any]]:
        content = [_text(self.prompt.examples_intro)]
        for i, ex in enumerate(self.prompt.examples, 1):
            content += [
                _text(f"Example {i} (correct skill: {ex.skill}). {ex.caption}"),
                _image(png_data_url(ex.image_png)),
            ]
        content += [
            _text(self._status(ctx, plan, clip)),
            _image(png_data_url(scene)),
            _image(png_data_url(zoom)),
        ]
        return [{"role": "system", "content": self.prompt.system}, {"role": "user", "content": content}]

    def _status(self, ctx: PlannerContext, plan: Plan, clip: str) -> str:
        failure_status = ""
        if self.prompt.failure_reasoning:
            failure_status = " " + render_template(
                self.prompt.failure_status_template,
                step_limit=ctx.step_limit,
                steps_left=max(ctx.step_limit - ctx.step, 0),
                consecutive_failures=ctx.consecutive_failures,
            )
        return render_template(
            self.prompt.status_template,
            instruction=self._instruction,
            clip_names=", ".join(self._clips),
            plan=" -> ".join(f"{s.clip} ({s.direction})" for s in plan.steps),
            step=ctx.step,
            failure_status=failure_status,
            inserted=", ".join(sorted(inserted_clips(ctx.history))) or "none",
            history=history_summary(ctx.history, self.config.history_steps),
            current_clip=clip,
        )

    def _ask(
        self,
        kind: Literal["plan", "decide"],
        step: int,
        messages: list[dict[str, Any]],
        response_format: dict[str, Any],
        parse: Callable[[str | None], T],
    ) -> T:
        """One query with bounded retries. An invalid answer is fed back with what was wrong."""
        errors = []
        for attempt in range(self.config.max_retries + 1):
            request = {"model": self.config.model, "messages": messages, "response_format": response_format}
            if self.config.reasoning_effort is not None:
                request["reasoning_effort"] = self.config.reasoning_effort
            if self.config.temperature is not None:
                request["temperature"] = self.config.temperature
            answer, result, error, error_kind = None, None, None, None
            start = time.monotonic()
            try:
                answer = self._client.complete(request)
            except ChatError as e:
                error, error_kind = str(e), "transport"
            latency = time.monotonic() - start
            if answer is not None:
                try:
                    result = parse(answer.text)
                except AnswerError as e:
                    error, error_kind = str(e), "answer"
            if self._recorder is not None:
                self._recorder.record(
                    CallRecord(
                        kind=kind,
                        step=step,
                        attempt=attempt,
                        request=request,
                        answer=None if answer is None else answer.text,
                        usage=None if answer is None else answer.usage,
                        latency_s=round(latency, 4),
                        error=error,
                        error_kind=error_kind,
                        result=_as_dict(result),
                    )
                )
            if error is None:
                return result  # type: ignore[return-value]
            errors.append(f"attempt {attempt + 1}: {error}")
            if error_kind == "answer":
                messages = [
                    *messages,
                    {"role": "assistant", "content": answer.text or ""},
                    {
                        "role": "user",
                        "content": f"That answer was invalid: {error}. Answer again with one "
                        "JSON object that follows the schema.",
                    },
                ]
            elif attempt < self.config.max_retries and self._backoff > 0:
                time.sleep(self._backoff * 2**attempt)
        raise PlannerQueryError(f"{kind}: no valid answer after {len(errors)} attempts ({'; '.join(errors)})")


def _as_dict(result: Any) -> dict[str, Any] | None:
    if result is None:
        return None
    if isinstance(result, BaseModel):
        return result.model_dump()
    return dataclasses.asdict(result)


def inserted_clips(history: Sequence[StepRecord]) -> set[str]:
    """Clips whose Insert reported success at some step of ``history``."""
    return {
        r.decision.call.clip
        for r in history
        if r.decision.call is not None
        and r.decision.call.skill == "insert"
        and r.result is not None
        and r.result.success
    }


def current_clip(plan: Plan, history: Sequence[StepRecord]) -> str:
    """The clip the zoomed view shows: the first planned clip without a successful Insert (else the last)."""
    done = inserted_clips(history)
    return next((c for c in plan.order if c not in done), plan.order[-1])


def history_summary(history: Sequence[StepRecord], max_steps: int) -> str:
    """One line per executed skill, the most recent ``max_steps`` of them, with each skill's result."""
    lines = []
    for rec in history[-max_steps:]:
        call, res = rec.decision.call, rec.result
        if call is None:
            continue
        if res is None:
            outcome = "no result"
        else:
            outcome = "succeeded" if res.success else "failed"
            if res.collision:
                outcome += ", collided with a clip"
            if call.skill == "insert" and res.signed_distance is not None:
                outcome += f" (head {100 * res.signed_distance:+.1f} cm from the exit face)"
        lines.append(f"- step {rec.step}: {call.skill} {call.clip}: {outcome}")
    omitted = len(history) - min(len(history), max_steps)
    if omitted:
        lines.insert(0, f"- ({omitted} earlier steps not shown)")
    return "\n".join(lines) or "- none yet"
