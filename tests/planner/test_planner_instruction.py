"""Instruction -> clip order: a table of colour, spatial, implicit and invalid instructions."""

from __future__ import annotations

import math

import pytest

from dloroute.planner.instruction import InstructionError, greedy_order, natural_order, parse_instruction
from dloroute.sim.scene import generate_scene
from dloroute.types import FAMILIES, ClipSpec

# Layout (m, rad, world): red on the left, green low in the middle, blue high on the right; the head
# sits just below green. Orders: left->right R G B; right->left B G R; top->bottom B R G; bottom->top
# G R B; nearest->farthest G R B; farthest->nearest B R G; natural G B R (green faces the head, blue
# lies ahead of green's exit, red does not).
CLIPS = (ClipSpec("red", -0.3, 0.1, 0.0), ClipSpec("green", 0.0, -0.2, 0.3), ClipSpec("blue", 0.3, 0.2, -0.2))
HEAD = (-0.05, -0.3)
R, G, B = "red", "green", "blue"

TABLE: list[tuple[str, tuple[str, ...] | str]] = [
    # colour orders
    ("red, then blue, then green", (R, B, G)),
    ("first the green clip, then red, finally blue", (G, R, B)),
    ("red -> blue -> green", (R, B, G)),
    ("RED → GREEN → BLUE", (R, G, B)),
    ("Route the rope through the blue clip, then the green clip, then the red clip.", (B, G, R)),
    ("Thread the cable through green, red and blue, in that order.", (G, R, B)),
    ("green; blue; red", (G, B, R)),
    ("Start with blue, next red, and finally green.", (B, R, G)),
    ("red first, then green, blue last", (R, G, B)),
    ("red, after that green, followed by blue", (R, G, B)),
    ("first blue, second green, third red", (B, G, R)),
    ("route through all the clips: green, red, blue", (G, R, B)),
    # spatial orders
    ("Route the rope through the clips from left to right.", (R, G, B)),
    ("Route the rope through the clips from right to left.", (B, G, R)),
    ("Thread the cable through the clips going from the top to the bottom.", (B, R, G)),
    ("Route the rope through the clips from bottom to top.", (G, R, B)),
    ("Route the rope through the clips from the nearest to the farthest.", (G, R, B)),
    ("Thread the cable through the clips from nearest to farthest from the rope end.", (G, R, B)),
    ("from the farthest to the nearest", (B, R, G)),
    ("closest to furthest", (G, R, B)),
    ("from the leftmost clip to the rightmost clip", (R, G, B)),
    ("route it left-to-right", (R, G, B)),
    # implicit orders
    ("Route the rope through all the clips.", (G, B, R)),
    ("Thread the cable through every clip along the natural path.", (G, B, R)),
    ("through each clip in the natural order", (G, B, R)),
    ("Route the rope through the clips.", (G, B, R)),
    # errors
    ("red, then orange, then blue", "no clip is orange"),
    ("red, yellow, blue", "no clip is yellow"),
    ("first red, second green, third blue, fourth purple", "no clip is purple"),
    ("red, blue, red, green", "names the red clip twice"),
    ("red then blue", "omits clip(s) green"),
    ("route the rope clockwise", "'clockwise'"),
    ("go up through the clips", "'up'"),
    ("red, then blue, then green, from left to right", "mixes a colour order with a spatial order"),
    ("from left to top", "direction word 'left'"),
    ("the left clip first", "direction word 'left'"),
    ("from left to right and from top to bottom", "more than one spatial order"),
    ("skip the red clip", "'skip'"),
    ("blue after red, then green", "'after'"),
    ("red before blue before green", "'before'"),
    ("green last, red first, blue second", "'last' is said of the green clip"),
    ("first red, then blue, then green, fourth", "'fourth'"),
    ("do a little dance", "gives no clip order"),
    ("", "gives no clip order"),
]


@pytest.mark.parametrize(("text", "expected"), TABLE, ids=[t or "<empty>" for t, _ in TABLE])
def test_instruction_table(text: str, expected: tuple[str, ...] | str) -> None:
    if isinstance(expected, tuple):
        assert parse_instruction(text, CLIPS, HEAD) == expected
    else:
        with pytest.raises(InstructionError, match=expected.replace("(", r"\(").replace(")", r"\)")):
            parse_instruction(text, CLIPS, HEAD)


def test_table_is_large_enough() -> None:
    assert len(TABLE) >= 30


def test_instruction_error_is_value_error() -> None:
    assert issubclass(InstructionError, ValueError)


def test_level_clips_make_a_spatial_order_ambiguous() -> None:
    clips = (
        ClipSpec("red", 0.0, 0.0, 0.0),
        ClipSpec("blue", 0.005, 0.3, 0.0),
        ClipSpec("green", 0.3, 0.0, 0.0),
    )
    with pytest.raises(InstructionError, match="ambiguous"):
        parse_instruction("from left to right", clips, (-0.2, 0.0))
    assert parse_instruction("from bottom to top", clips[:2], (-0.2, 0.0)) == ("red", "blue")


def test_natural_order_starts_at_the_clip_facing_the_head() -> None:
    # "purple" is nearer the head but faces away from it; the chain then follows the exits.
    clips = (
        ClipSpec("purple", -0.1, -0.09, math.pi),
        ClipSpec("red", 0.0, 0.0, 0.0),
        ClipSpec("blue", 0.18, 0.05, 0.5),
        ClipSpec("green", 0.25, 0.22, 1.6),
    )
    assert natural_order(clips, (-0.1, 0.0)) == ("red", "blue", "green", "purple")
    assert greedy_order(clips, (-0.1, 0.0), ahead_only=False)[0] == "purple"


@pytest.mark.parametrize("family", FAMILIES)
def test_generated_instructions_parse_to_the_scene_order(family: str) -> None:
    for seed in range(25):
        scene = generate_scene(family, seed)
        assert parse_instruction(scene.instruction, scene.clips, scene.rope_head) == scene.order, (
            scene.instruction
        )
