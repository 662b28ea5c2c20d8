"""The command line: the main job writes a result and a video; bad input is a clear error."""

import json

import imageio.v2 as imageio
from typer.testing import CliRunner

from dloroute.cli import app

runner = CliRunner()


def test_route_writes_result_and_video(tmp_path):
    out = tmp_path / "run"
    res = runner.invoke(app, ["route", "--family", "implicit", "--seed", "1", "--low-level", "heuristic", "--out", str(out)])
    assert res.exit_code == 0, res.output
    result = json.loads((out / "result.json").read_text())
    assert result["success"] and result["clips_routed"] == 3
    frames = imageio.get_reader(out / "episode.mp4")
    assert frames.count_frames() > 20
    assert "success" in res.output


def test_route_reports_the_step_limit(tmp_path):
    res = runner.invoke(app, ["route", "--family", "implicit", "--seed", "1", "--low-level", "heuristic",
                              "--step-limit", "1", "--no-video", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["termination"] == "timeout" and result["length"] == 2  # one heuristic insertion: 2 primitives
    assert "step limit reached" in res.output


def test_unknown_colour_in_instruction_is_a_clear_error(tmp_path):
    res = runner.invoke(app, ["route", "--family", "fixed-attribute", "--seed", "0", "--low-level", "heuristic",
                              "--instruction", "Route the rope through the orange clip.", "--out", str(tmp_path)])
    assert res.exit_code == 2 and "orange" in res.output


def test_render_writes_images(tmp_path):
    res = runner.invoke(app, ["render", "--family", "clips-4-5", "--seed", "1", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "scene.png").exists() and len(list(tmp_path.glob("zoom_*.png"))) >= 4
