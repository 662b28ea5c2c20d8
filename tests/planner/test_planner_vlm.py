"""The VLM planner against a scripted OpenAI-compatible server on 127.0.0.1 (no network)."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from planner_helpers import (
    FakeOpenAI,
    Reply,
    context,
    decision_json,
    fake_views,
    plan_json,
    step,
    straight_rope,
)

from dloroute.planner.planners import make_planner
from dloroute.planner.record import CALLS_FILE, ReplayMismatch, load_records
from dloroute.planner.vlm import VLMConfig, VLMPlanner, history_summary
from dloroute.types import ClipSpec, Decision, SkillCall

KEY_ENV = "DLOROUTE_TEST_VLM_KEY"
KEY = "sk-test-DO-NOT-LEAK-7f3a9c2e51d84b6b"
CLIPS = (ClipSpec("red", 0.0, 0.0, 0.0), ClipSpec("blue", 0.25, 0.1, 0.5), ClipSpec("green", 0.45, 0.0, 0.0))
ORDER = ("red", "blue", "green")
TIMEOUT = 0.15


@pytest.fixture(autouse=True)
def api_key(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(KEY_ENV, KEY)


def config(fake: FakeOpenAI, **kw) -> VLMConfig:
    base = dict(
        model="test-vlm",
        base_url=fake.url,
        api_key_env=KEY_ENV,
        timeout_s=TIMEOUT,
        max_retries=2,
        retry_backoff_s=0.0,
    )
    return VLMConfig(**{**base, **kw})


def ctx(history=(), failures: int = 0):
    rope = straight_rope(CLIPS[0], (-0.06, 0.0))
    return context(
        CLIPS,
        rope,
        history=history,
        consecutive_failures=failures,
        instruction="red, then blue, then green",
        views=fake_views,
    )


def started(planner: VLMPlanner) -> VLMPlanner:
    c = ctx()
    planner.reset(c.instruction, c.observation)
    return planner


def image_urls(body: dict) -> list[str]:
    return [
        part["image_url"]["url"]
        for msg in body["messages"]
        if isinstance(msg["content"], list)
        for part in msg["content"]
        if part["type"] == "image_url"
    ]


def decode(url: str) -> np.ndarray:
    assert url.startswith("data:image/png;base64,")
    png = np.frombuffer(base64.b64decode(url.split(",", 1)[1]), np.uint8)
    return cv2.imdecode(png, cv2.IMREAD_COLOR)[..., ::-1]


def all_text(body: dict) -> str:
    return json.dumps(body["messages"])


def test_plan_then_decision_carry_images_and_json_schema(fake_openai: FakeOpenAI) -> None:
    fake_openai.answer(plan_json(ORDER), decision_json("insert", "Red", reasoning="head aligned"))
    planner = started(VLMPlanner(config(fake_openai)))
    decision = planner.decide(ctx())
    assert decision == Decision(call=SkillCall("insert", "red"), reasoning="head aligned")
    assert planner.routing_plan is not None and planner.routing_plan.order == ORDER

    plan_req, decide_req = (r["body"] for r in fake_openai.requests)
    assert all(r["path"] == "/v1/chat/completions" for r in fake_openai.requests)
    assert [decode(u).tolist() for u in image_urls(plan_req)] == [fake_views(None).tolist()]
    assert plan_req["response_format"]["json_schema"]["name"] == "routing_plan"

    urls = image_urls(decide_req)
    assert len(urls) == 4  # two in-context examples, the scene, the zoomed view of the current clip
    assert np.array_equal(decode(urls[2]), fake_views(None))
    assert np.array_equal(decode(urls[3]), fake_views("red"))
    fmt = decide_req["response_format"]
    assert fmt["type"] == "json_schema" and fmt["json_schema"]["strict"] is True
    schema = fmt["json_schema"]["schema"]
    assert schema["additionalProperties"] is False
    assert set(schema["required"]) == {"reasoning", "skill", "target_clip", "task_done"}
    assert schema["properties"]["target_clip"]["anyOf"][0]["enum"] == ["red", "blue", "green"]
    assert schema["properties"]["skill"]["anyOf"][0]["enum"] == ["insert", "pull", "flatten"]
    assert "temperature" not in decide_req and "reasoning_effort" not in decide_req
    assert decide_req["messages"][0]["role"] == "system"
    assert "Consecutive failed insertions: 0" in all_text(decide_req)


def test_optional_parameters_only_when_configured(fake_openai: FakeOpenAI) -> None:
    fake_openai.answer(plan_json(ORDER), decision_json("pull", "red"))
    planner = started(VLMPlanner(config(fake_openai, reasoning_effort="low", temperature=0.2)))
    planner.decide(ctx())
    body = fake_openai.requests[-1]["body"]
    assert body["reasoning_effort"] == "low" and body["temperature"] == 0.2


def test_done_answer_and_zoom_follows_progress(fake_openai: FakeOpenAI) -> None:
    history = [step(0, "pull", "red", True), step(1, "insert", "red", True)]
    fake_openai.answer(plan_json(ORDER), decision_json(None, None, done=True))
    planner = started(VLMPlanner(config(fake_openai)))
    assert planner.decide(ctx(history)) == Decision(call=None, done=True, reasoning="ok")
    body = fake_openai.requests[-1]["body"]
    assert np.array_equal(decode(image_urls(body)[3]), fake_views("blue"))
    assert "step 1: insert red: succeeded" in all_text(body)


BAD_ANSWERS = {
    "malformed json": (Reply(content='{"reasoning": "x", "skill": '), "not valid JSON"),
    "wrong fields": (Reply(content='{"thought": "x", "action": "insert"}'), "missing field 'reasoning'"),
    "unknown clip": (Reply(content=decision_json("insert", "orange")), "unknown clip 'orange'"),
    "unknown skill": (Reply(content=decision_json("jump", "red")), "field 'skill'"),
    "empty answer": (Reply(content=None), "empty"),
    "http 500": (Reply(status=500), "InternalServerError"),
    "timeout": (Reply(content=decision_json("pull", "red"), delay=3 * TIMEOUT), "Timeout"),
}


@pytest.mark.parametrize("case", list(BAD_ANSWERS))
def test_bad_answers_are_retried_then_fail_without_exception(
    fake_openai: FakeOpenAI, case: str, tmp_path: Path
) -> None:
    reply, message = BAD_ANSWERS[case]
    fake_openai.answer(plan_json(ORDER), reply, reply, reply)
    planner = started(VLMPlanner(config(fake_openai), run_dir=tmp_path))
    decision = planner.decide(ctx())
    assert decision.failed and decision.call is None and not decision.done
    assert message in decision.error and "after 3 attempts" in decision.error
    assert len(fake_openai.requests) == 1 + 3
    records = load_records(tmp_path)
    assert [r["attempt"] for r in records if r["kind"] == "decide"] == [0, 1, 2]
    kind = "transport" if case in ("http 500", "timeout") else "answer"
    assert all(r["error_kind"] == kind for r in records if r["kind"] == "decide")


def test_invalid_answer_is_fed_back_and_retry_succeeds(fake_openai: FakeOpenAI) -> None:
    fake_openai.answer(plan_json(ORDER), decision_json("insert", "orange"), decision_json("insert", "red"))
    planner = started(VLMPlanner(config(fake_openai)))
    assert planner.decide(ctx()).call == SkillCall("insert", "red")
    retry = fake_openai.requests[-1]["body"]["messages"]
    assert retry[-2] == {"role": "assistant", "content": decision_json("insert", "orange")}
    assert "unknown clip 'orange'" in retry[-1]["content"]


def test_failed_plan_gives_failed_decision(fake_openai: FakeOpenAI) -> None:
    fake_openai.answer(plan_json(["red", "red", "blue"]), plan_json(["red", "blue"]), Reply(status=500))
    decision = started(VLMPlanner(config(fake_openai))).decide(ctx())
    assert decision.failed and decision.error.startswith("plan:")
    assert "more than once" in decision.error and "omits clip(s) green" in decision.error


def test_without_failure_reasoning_no_flatten_no_failure_text(fake_openai: FakeOpenAI) -> None:
    fake_openai.answer(plan_json(ORDER), decision_json("flatten", "red"), decision_json("pull", "red"))
    planner = started(make_planner("vlm_no_fr", scene_order=ORDER, vlm_config=config(fake_openai)))
    assert planner.name == "vlm_no_fr"
    assert planner.decide(ctx(failures=3)).call == SkillCall("pull", "red")
    body = fake_openai.requests[1]["body"]
    assert body["response_format"]["json_schema"]["schema"]["properties"]["skill"]["anyOf"][0]["enum"] == [
        "insert",
        "pull",
    ]
    text = all_text(body).lower()
    assert "flatten" not in text and "consecutive failed" not in text and "step limit" not in text
    assert "skill 'flatten' is not allowed" in fake_openai.requests[2]["body"]["messages"][-1]["content"]


def test_missing_views_fail_cleanly(fake_openai: FakeOpenAI) -> None:
    planner = started(VLMPlanner(config(fake_openai)))
    c = context(CLIPS, straight_rope(CLIPS[0], (-0.06, 0.0)))
    assert planner.decide(c).failed and not fake_openai.requests


def test_api_key_never_recorded(fake_openai: FakeOpenAI, tmp_path: Path) -> None:
    leak = decision_json("insert", "red", reasoning=f"my key is {KEY}, header Bearer {KEY}")
    fake_openai.answer(plan_json(ORDER), Reply(status=500), leak)
    planner = started(VLMPlanner(config(fake_openai), run_dir=tmp_path))
    assert planner.decide(ctx()).call == SkillCall("insert", "red")
    assert fake_openai.requests[0]["headers"]["authorization"] == f"Bearer {KEY}"  # the key was used
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert any(p.suffix == ".png" for p in files)
    for p in files:
        data = p.read_bytes()
        assert KEY.encode() not in data and KEY[8:].encode() not in data, p
    assert "[REDACTED]" in (tmp_path / CALLS_FILE).read_text()


def test_recording_contents(fake_openai: FakeOpenAI, tmp_path: Path) -> None:
    fake_openai.answer(plan_json(ORDER), decision_json("pull", "red"))
    started(VLMPlanner(config(fake_openai), run_dir=tmp_path)).decide(ctx())
    plan_rec, decide_rec = load_records(tmp_path)
    assert plan_rec["kind"] == "plan" and plan_rec["result"]["steps"][0]["clip"] == "red"
    assert decide_rec["result"]["call"] == {"skill": "pull", "clip": "red"}
    assert decide_rec["usage"]["total_tokens"] == 120 and decide_rec["latency_s"] >= 0
    assert decide_rec["answer"] == decision_json("pull", "red")
    refs = [
        p for m in decide_rec["request"]["messages"] if isinstance(m["content"], list) for p in m["content"]
    ]
    images = [p["path"] for p in refs if p["type"] == "image_file"]
    assert len(images) == 4 and all((tmp_path / p).is_file() for p in images)
    assert "data:image" not in (tmp_path / CALLS_FILE).read_text()
    assert np.array_equal(cv2.imread(str(tmp_path / images[3]))[..., ::-1], fake_views("red"))


def test_recorded_run_replays_to_identical_decisions(fake_openai: FakeOpenAI, tmp_path: Path) -> None:
    contexts = [
        ctx(),
        ctx([step(0, "pull", "red", True)]),
        ctx([step(0, "pull", "red", True), step(1, "insert", "red", False)], failures=1),
        ctx([step(0, "pull", "red", True), step(1, "insert", "red", True)]),
    ]
    fake_openai.answer(
        plan_json(ORDER),
        decision_json("pull", "red"),
        Reply(status=500),
        "not json",
        decision_json("insert", "red"),
        decision_json("flatten", "red", reasoning="twisted"),
        decision_json("insert", "green"),
    )
    live = started(VLMPlanner(config(fake_openai), run_dir=tmp_path))
    recorded = [live.decide(c) for c in contexts]
    assert [d.call.skill for d in recorded] == ["pull", "insert", "flatten", "insert"]

    offline = VLMConfig(model="test-vlm", base_url="http://127.0.0.1:9/v1", api_key_env=KEY_ENV)
    replay = started(VLMPlanner(offline, replay_dir=tmp_path))
    assert [replay.decide(c) for c in contexts] == recorded
    assert len(fake_openai.requests) == 7  # the replay asked no server

    diverging = started(VLMPlanner(offline, replay_dir=tmp_path))
    with pytest.raises(ReplayMismatch):
        diverging.decide(ctx([step(0, "flatten", "blue", True)]))


def test_history_summary_is_bounded() -> None:
    history = [step(i, "insert", "red", False) for i in range(20)]
    text = history_summary(history, 5)
    assert text.count("\n") == 5 and "15 earlier steps" in text and "step 19" in text
    assert history_summary([], 5) == "- none yet"
