"""Pydantic schemas of the VLM planner's answers, their JSON schemas and their validation against a scene.

Two answers exist: the initial :class:`Plan` (clip order and insertion direction per clip) and the per-step
:class:`DecisionModel` (reasoning, skill, target clip, task-done flag). ``parse_plan`` / ``parse_decision``
turn a raw answer text into validated objects or raise :class:`AnswerError` whose message says what was
wrong, in words the model can act on when the message is fed back on a retry. Model output is data: it is
parsed and checked, never executed.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from dloroute.types import Decision, SkillCall, SkillName

Direction = Literal["along_clip_axis", "against_clip_axis"]


class AnswerError(ValueError):
    """A model answer that does not fit the schema or the scene; the message says what was wrong."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class DecisionModel(_Strict):
    """One step's decision as the model writes it."""

    reasoning: str = Field(description="Step-by-step analysis of both images before choosing.")
    skill: SkillName | None = Field(description="Skill to execute next; null only when task_done is true.")
    target_clip: str | None = Field(description="Clip the skill acts on; null only when task_done is true.")
    task_done: bool = Field(description="True only when the rope runs through every clip in the order.")


class PlanStep(_Strict):
    """One clip of the routing plan and the direction the rope passes through it."""

    clip: str = Field(description="Clip name (its colour).")
    direction: Direction = Field(description="Pass the rope along the clip's insertion axis or against it.")


class Plan(_Strict):
    """The initial routing plan: every clip once, in routing order."""

    reasoning: str = Field(description="How the instruction and the image give this order.")
    steps: list[PlanStep] = Field(description="Every clip exactly once, first clip first.")

    @property
    def order(self) -> tuple[str, ...]:
        """Clip names in routing order."""
        return tuple(s.clip for s in self.steps)


def decision_response_format(clip_names: Sequence[str], allowed_skills: Sequence[SkillName]) -> dict:
    """``response_format`` for a decision: the strict JSON schema with the scene's clips and skills as enums."""
    schema = _strict_schema(DecisionModel)
    _restrict_enum(schema, "skill", allowed_skills)
    _restrict_enum(schema, "target_clip", clip_names)
    return _response_format("routing_decision", schema)


def plan_response_format(clip_names: Sequence[str]) -> dict:
    """``response_format`` for the initial plan, with the scene's clip names as an enum."""
    schema = _strict_schema(Plan)
    _restrict_enum(schema["properties"]["steps"]["items"], "clip", clip_names)
    return _response_format("routing_plan", schema)


def parse_decision(text: str, clip_names: Sequence[str], allowed_skills: Sequence[SkillName]) -> Decision:
    """Raw answer text -> :class:`~dloroute.types.Decision`; raises :class:`AnswerError` saying what was wrong.

    Clip and skill names are matched case-insensitively. ``task_done`` true gives a done decision and
    requires ``skill`` and ``target_clip`` to be null; otherwise both must be given and known.
    """
    model = _validate(DecisionModel, text)
    if model.task_done:
        if model.skill is not None or model.target_clip is not None:
            raise AnswerError(
                "task_done is true but skill/target_clip are not null: set both to null when the task is "
                "done, or set task_done to false"
            )
        return Decision(call=None, done=True, reasoning=model.reasoning)
    if model.skill is None or model.target_clip is None:
        raise AnswerError("task_done is false, so skill and target_clip must both be given (not null)")
    if model.skill not in allowed_skills:
        raise AnswerError(
            f"skill {model.skill!r} is not allowed; allowed skills: {', '.join(allowed_skills)}"
        )
    clip = _known_clip(model.target_clip, clip_names)
    return Decision(call=SkillCall(skill=model.skill, clip=clip), reasoning=model.reasoning)


def parse_plan(text: str, clip_names: Sequence[str]) -> Plan:
    """Raw answer text -> :class:`Plan` naming every scene clip exactly once; raises :class:`AnswerError`."""
    model = _validate(Plan, text)
    steps = [s.model_copy(update={"clip": _known_clip(s.clip, clip_names)}) for s in model.steps]
    names = [s.clip for s in steps]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise AnswerError(f"the plan names clip(s) {', '.join(twice)} more than once; name every clip once")
    missing = [n for n in clip_names if n not in names]
    if missing:
        raise AnswerError(f"the plan omits clip(s) {', '.join(missing)}; the rope must pass every clip")
    return model.model_copy(update={"steps": steps})


def _known_clip(name: str, clip_names: Sequence[str]) -> str:
    key = name.strip().lower()
    if key not in clip_names:
        raise AnswerError(f"unknown clip {name!r}; the scene's clips are: {', '.join(clip_names)}")
    return key


_FENCE = re.compile(r"^\s*```(?:json)?\s*(.*?)\s*```\s*$", re.DOTALL)


def _validate(model: type[_Strict], text: str | None) -> Any:
    if text is None or not text.strip():
        raise AnswerError("the answer is empty; answer with one JSON object")
    fenced = _FENCE.match(text)
    body = fenced.group(1) if fenced else text
    try:
        raw = json.loads(body)
    except json.JSONDecodeError as e:
        raise AnswerError(
            f"the answer is not valid JSON ({e.msg} at line {e.lineno} column {e.colno})"
        ) from e
    if not isinstance(raw, dict):
        raise AnswerError(f"the answer must be a JSON object, not {type(raw).__name__}")
    try:
        return model.model_validate(raw)
    except ValidationError as e:
        raise AnswerError("; ".join(_describe(err) for err in e.errors())) from e


def _describe(err: Any) -> str:
    field = ".".join(str(p) for p in err["loc"]) or "answer"
    if err["type"] == "missing":
        return f"missing field {field!r}"
    if err["type"] == "extra_forbidden":
        return f"unexpected field {field!r}"
    return f"field {field!r}: {err['msg']} (got {err.get('input')!r})"


def _strict_schema(model: type[_Strict]) -> dict:
    """The model's JSON schema, ``$ref`` inlined and titles dropped, checked to be strict-compatible.

    Strict structured output requires ``additionalProperties: false`` and every property in ``required``
    on every object; the models forbid extras and give no defaults, so pydantic already emits both.
    """
    schema = model.model_json_schema()
    defs = schema.pop("$defs", {})

    def inline(node: Any) -> Any:
        if isinstance(node, dict):
            if "$ref" in node:
                return inline(defs[node["$ref"].rsplit("/", 1)[-1]])
            return {k: inline(v) for k, v in node.items() if k != "title"}
        if isinstance(node, list):
            return [inline(v) for v in node]
        return node

    out = inline(schema)
    check_strict(out)
    return out


def check_strict(schema: Any) -> None:
    """Raise ValueError unless every object in ``schema`` forbids extra keys and requires all its keys."""
    if isinstance(schema, dict):
        if schema.get("type") == "object":
            props = set(schema.get("properties", {}))
            if schema.get("additionalProperties") is not False or set(schema.get("required", [])) != props:
                raise ValueError(f"schema object is not strict-compatible: {sorted(props)}")
        for v in schema.values():
            check_strict(v)
    elif isinstance(schema, list):
        for v in schema:
            check_strict(v)


def _restrict_enum(obj_schema: dict, field: str, values: Sequence[str]) -> None:
    """Give the string branch of property ``field`` (possibly nullable) the enum ``values``."""
    prop = obj_schema["properties"][field]
    branches = prop.get("anyOf", [prop])
    for b in branches:
        if b.get("type") == "string":
            b["enum"] = list(values)
            return
    raise ValueError(f"property {field!r} has no string branch to restrict")


def _response_format(name: str, schema: dict) -> dict:
    return {"type": "json_schema", "json_schema": {"name": name, "schema": schema, "strict": True}}


__all__ = [
    "AnswerError",
    "DecisionModel",
    "Direction",
    "Plan",
    "PlanStep",
    "check_strict",
    "decision_response_format",
    "parse_decision",
    "parse_plan",
    "plan_response_format",
]
