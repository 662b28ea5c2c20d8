import json
from pathlib import Path

from dloroute.eval.report import insertion_table, routing_table, termination_table, write_report
from dloroute.eval.suites import TABLE_I, TABLE_II, Suite, row, video_path

SMALL = Suite("routing", rows=(row("vlm", "heuristic"), row("fixed_order", "rl"), row("rule_based", "rl")),
              families=("implicit", "clips_4_5"), seeds=(0, 1, 2))


def rec(label, family, seed, success, clips, length, termination):
    high, low = label.split("+")
    return {"row": label, "high_level": high, "low_level": low, "family": family, "seed": seed,
            "success": success, "clips_routed": clips, "length": length, "termination": termination,
            "wall_time": 20.0}


ROUTING = [
    rec("rule_based+rl", "implicit", 0, True, 3, 10, "success"),
    rec("rule_based+rl", "implicit", 1, True, 3, 12, "success"),
    rec("rule_based+rl", "implicit", 2, False, 1, 20, "timeout"),
    rec("rule_based+rl", "clips_4_5", 0, True, 5, 21, "success"),
    rec("fixed_order+rl", "implicit", 0, False, 2, 9, "collision"),
    {"row": "fixed_order+rl", "high_level": "fixed_order", "low_level": "rl", "family": "implicit", "seed": 1,
     "success": False, "termination": "error", "error": "RuntimeError: boom", "wall_time": 1.0},
]
INSERTION = [
    {"row": "insert+rl", "high_level": "insert", "low_level": "rl", "family": "scale_1.0", "seed": 10_000,
     "success": True, "signed_distance_cm": 3.0, "length": 3, "wall_time": 2.0},
    {"row": "insert+rl", "high_level": "insert", "low_level": "rl", "family": "scale_1.0", "seed": 10_001,
     "success": False, "signed_distance_cm": 1.0, "length": 5, "wall_time": 2.0},
]

# Made by hand from the records above and the paper's Table II (fixed order + RL: SR 53/60, Clips 2.1/3.4,
# Epi 9.7/14.6; VLM + heuristic: 13/7, 1.3/1.3, 8.0/9.1).
EXPECTED_TABLE_II = """\
| High Level | Low Level | Episodes | Implicit SR | Implicit Clips | Implicit Epi | 4-5 clips SR | 4-5 clips Clips | 4-5 clips Epi |
|---|---|---|---|---|---|---|---|---|
| VLM w/ failure reasoning | Heuristic | not run | - (13) | - (1.3) | - (8.0) | - (7) | - (1.3) | - (9.1) |
| Fixed order | RL (SAC) | 2 (1 error) | 0 (53) | 1.0 (2.1) | 9.0 (9.7) | - (60) | - (3.4) | - (14.6) |
| Rule-based w/ failure reasoning (ours) | RL (SAC) | 4 | 67 (-) | 2.3 (-) | 14.0 (-) | 100 (-) | 5.0 (-) | 21.0 (-) |"""

EXPECTED_TABLE_I = """\
| Low Level | Episodes | Success % | Avg signed distance (cm) | Episode length |
|---|---|---|---|---|
| Heuristic | not run | - (45) | - (1.24) | - (2.00) |
| RL (SAC) | 2 | 50 (87) | 2.00 (2.59) | 4.00 (3.86) |"""

EXPECTED_TERMINATIONS = """\
| High Level | Low Level | success | collision | timeout | error |
|---|---|---|---|---|---|
| Fixed order | RL (SAC) | 0 | 1 | 0 | 1 |
| Rule-based w/ failure reasoning (ours) | RL (SAC) | 3 | 0 | 1 | 0 |"""


def test_routing_table_reproduces_the_hand_made_table():
    assert routing_table(ROUTING, SMALL) == EXPECTED_TABLE_II


def test_insertion_and_termination_tables():
    assert insertion_table(INSERTION) == EXPECTED_TABLE_I
    assert termination_table(ROUTING, SMALL) == EXPECTED_TERMINATIONS


def write_jsonl(path: Path, records: list[dict]) -> None:
    path.write_text("".join(json.dumps(r) + "\n" for r in records))


def test_write_report_from_a_run_folder(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    write_jsonl(TABLE_II.jsonl(run), ROUTING)
    write_jsonl(TABLE_I.jsonl(run), INSERTION)
    video = video_path(run, "rule_based+rl", "implicit", 2)
    video.parent.mkdir()
    video.write_bytes(b"")
    out = write_report(run, tmp_path / "docs" / "results.md")
    text = out.read_text()
    assert EXPECTED_TABLE_I in text
    assert "| Symbolic | RL (SAC) | not run | - (68) |" in text
    assert "| Rule-based w/ failure reasoning (ours) | RL (SAC) | 4 | 67 (-) | 2.3 (-) | 14.0 (-) | - (-) |" in text
    assert "[seed 2 timeout](../run/videos/rule_based+rl_implicit_2.mp4)" in text
    assert "![Success rate per family: ours solid, paper hatched](results_sr.png)" in text
    assert (tmp_path / "docs" / "results_sr.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_report_of_an_empty_run_says_not_run(tmp_path):
    text = write_report(tmp_path, tmp_path / "report.md").read_text()
    assert text.count("not run") == len(TABLE_II.rows) + len(TABLE_I.rows)
    assert "No episodes recorded." in text and "Episode videos" not in text
