"""Answer schemas, their validation messages, and the prompt files."""

from __future__ import annotations

import json

import pytest
from planner_helpers import decision_json, plan_json

from dloroute.planner.prompts import VARIANT_PARTS, load_prompt, prompts_dir, render_template
from dloroute.planner.schema import (
    AnswerError,
    check_strict,
    decision_response_format,
    parse_decision,
    parse_plan,
    plan_response_format,
)
from dloroute.types import Decision, SkillCall

CLIPS = ("red", "green", "blue")
ALL = ("insert", "pull", "flatten")


def test_valid_decisions() -> None:
    assert parse_decision(decision_json("insert", " Red "), CLIPS, ALL) == Decision(
        SkillCall("insert", "red"), reasoning="ok"
    )
    assert parse_decision(decision_json(None, None, done=True), CLIPS, ALL) == Decision(
        None, done=True, reasoning="ok"
    )
    fenced = "```json\n" + decision_json("pull", "blue") + "\n```"
    assert parse_decision(fenced, CLIPS, ALL).call == SkillCall("pull", "blue")


INVALID = [
    ("{not json", ALL, "not valid JSON"),
    ("[1, 2]", ALL, "must be a JSON object"),
    ("", ALL, "empty"),
    ('{"reasoning": "x"}', ALL, "missing field 'skill'"),
    (
        json.dumps({"reasoning": "", "skill": "pull", "target_clip": "red", "task_done": False, "x": 1}),
        ALL,
        "unexpected field 'x'",
    ),
    (
        decision_json("insert", "orange"),
        ALL,
        "unknown clip 'orange'; the scene's clips are: red, green, blue",
    ),
    (decision_json("jump", "red"), ALL, "field 'skill'"),
    (decision_json("flatten", "red"), ("insert", "pull"), "skill 'flatten' is not allowed"),
    (decision_json("insert", None), ALL, "must both be given"),
    (decision_json("insert", "red", done=True), ALL, "task_done is true"),
    (
        json.dumps({"reasoning": "", "skill": "pull", "target_clip": "red", "task_done": "maybe"}),
        ALL,
        "field 'task_done'",
    ),
]


@pytest.mark.parametrize(("text", "skills", "message"), INVALID)
def test_invalid_decisions_say_what_was_wrong(text: str, skills: tuple, message: str) -> None:
    with pytest.raises(AnswerError) as err:
        parse_decision(text, CLIPS, skills)
    assert message in str(err.value)


def test_plans() -> None:
    assert parse_plan(plan_json(["Blue", "red", "green"]), CLIPS).order == ("blue", "red", "green")
    for order, message in [
        (["red", "red", "blue"], "more than once"),
        (["red", "blue"], r"omits clip\(s\) green"),
        (["red", "blue", "green", "pink"], "unknown clip 'pink'"),
    ]:
        with pytest.raises(AnswerError, match=message):
            parse_plan(plan_json(order), CLIPS)


def test_response_formats_are_strict_with_scene_enums() -> None:
    fmt = decision_response_format(CLIPS, ("insert", "pull"))
    assert fmt["type"] == "json_schema" and fmt["json_schema"]["strict"] is True
    schema = fmt["json_schema"]["schema"]
    check_strict(schema)
    assert schema["properties"]["skill"]["anyOf"] == [
        {"enum": ["insert", "pull"], "type": "string"},
        {"type": "null"},
    ]
    plan = plan_response_format(CLIPS)["json_schema"]["schema"]
    check_strict(plan)
    assert "$defs" not in json.dumps(plan) and "$ref" not in json.dumps(plan)
    assert plan["properties"]["steps"]["items"]["properties"]["clip"]["enum"] == list(CLIPS)
    with pytest.raises(ValueError):
        check_strict(
            {"type": "object", "properties": {"a": {}}, "required": [], "additionalProperties": False}
        )


def test_prompt_variants() -> None:
    fr, no_fr = load_prompt("failure_reasoning"), load_prompt("no_failure_reasoning")
    assert fr.skills == ("insert", "pull", "flatten") and no_fr.skills == ("insert", "pull")
    for needle in ("head", "occlu", "zoomed", "2 cm", "Do not use", "task_done"):
        assert needle in fr.system and needle in no_fr.system, needle
    assert "flatten" in fr.system and "Step limit" in fr.system and "counter" in fr.system
    assert "flatten" not in no_fr.system.lower() and "step limit" not in no_fr.system.lower()
    assert [e.skill for e in fr.examples] == ["insert", "pull"]
    assert all(e.image_png.startswith(b"\x89PNG") for e in fr.examples)
    for bundle in (fr, no_fr):  # every template placeholder is one the planner fills
        assert "{" not in bundle.system
    with pytest.raises(ValueError, match="unknown prompt variant"):
        load_prompt("chatty")  # type: ignore[arg-type]


def test_every_prompt_file_is_used() -> None:
    used = {p for parts in VARIANT_PARTS.values() for p in parts} | {
        "plan",
        "status",
        "failure_status",
        "examples",
    }
    assert {p.stem for p in prompts_dir().glob("*.md")} == used


def test_render_template() -> None:
    assert render_template('{a} and {"json": 1} {b_c}', a=1, b_c="x") == '1 and {"json": 1} x'
    with pytest.raises(KeyError, match="b_c"):
        render_template("{a} {b_c}", a=1)


def test_missing_example_image_is_a_clear_error(tmp_path) -> None:
    with pytest.raises(FileNotFoundError, match="render_examples"):
        load_prompt("failure_reasoning", examples_dir=tmp_path)
