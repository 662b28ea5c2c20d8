"""Instruction text -> clip order, for the offline planners (no model involved).

Three kinds of instruction are understood; mixing them is an error:

- **Colour order**: the clips' colours in routing order, e.g. "red, then blue, then green", "first the
  green clip, then red, finally blue", "red -> blue -> green". Every clip must be named exactly once.
  Position words (first ... fifth, last, finally, lastly) must agree with the position of the colour in
  their clause (clauses are split at commas, semicolons, arrows, "then", "next", "and", "after that",
  "followed by"), so "blue last, red first, green second" is refused instead of misread.
- **Spatial order**: "<A> to <B>" with A, B opposite ends of one axis: left/right (world x; left is -x),
  top/bottom (world y; top is +y), nearest/farthest (distance from the rope head at ``head_xy``). Clips
  are sorted along that key; two clips closer than ``SPATIAL_TIE`` along it make the order ambiguous.
- **Implicit order** ("through all the clips", "every clip in the natural order"): the natural path of
  the layout, see :func:`natural_order`.

:class:`InstructionError` (a ValueError) is raised, before any motion, for colour words no clip has
(the palette's and common others such as "orange"), direction words outside an understood phrase
("clockwise", "up", a lone "left"), negations and relative words ("skip", "except", "before", a lone
"after"), an order naming a clip twice or omitting one, and text with no order at all. Other words are
fillers and ignored. Positions are metres in the world frame.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from dloroute.sim.clip_frame import CLIP_DEPTH, to_clip_frame, to_world_frame
from dloroute.types import CLIP_COLOURS, ClipSpec

SPATIAL_TIE = 0.01
"""Two clips closer than this (m) along a spatial key cannot be ordered by that key."""

OTHER_COLOURS = frozenset(
    "orange pink black white brown grey gray cyan magenta violet teal turquoise gold golden silver maroon "
    "navy lime beige indigo crimson scarlet amber olive".split()
)
"""Colour words that are not clip colours: naming one is an error, not a filler."""

_DIRECTION_WORDS = {
    "left": "left",
    "leftmost": "left",
    "right": "right",
    "rightmost": "right",
    "top": "top",
    "topmost": "top",
    "uppermost": "top",
    "bottom": "bottom",
    "bottommost": "bottom",
    "nearest": "near",
    "closest": "near",
    "near": "near",
    "close": "near",
    "farthest": "far",
    "furthest": "far",
    "far": "far",
}
_OPPOSITE = {"left": "right", "right": "left", "top": "bottom", "bottom": "top", "near": "far", "far": "near"}
_UNSUPPORTED = frozenset(
    "up down upward upwards downward downwards above below upper lower higher lowest highest north south east "
    "west clockwise counterclockwise anticlockwise diagonal diagonally centre center middle inner outer "
    "inward inwards outward outwards front behind back backward backwards forward forwards reverse reversed "
    "opposite horizontal horizontally vertical vertically ascending descending before skip except without "
    "avoid ignore excluding not never don dont".split()
)
"""Direction-, negation- and relation-like words the parser does not understand: naming one is an error."""
_FILLERS_IN_PHRASE = frozenset("the a most clip clips one ones side".split())
_ORDINALS = {
    "first": 0,
    "second": 1,
    "third": 2,
    "fourth": 3,
    "fifth": 4,
    "last": -1,
    "lastly": -1,
    "finally": -1,
}
_SEPARATORS = frozenset(", ; . -> then next and afterwards".split())
_IMPLICIT = frozenset("all every each natural clips".split())
_TOKEN = re.compile(r"->|→|=>|[a-z]+|[,;.]")


class InstructionError(ValueError):
    """An instruction the offline planners cannot turn into a clip order; the message says why."""


def parse_instruction(text: str, clips: tuple[ClipSpec, ...], head_xy: Sequence[float]) -> tuple[str, ...]:
    """The clip names in routing order for ``text``; ``head_xy`` is the rope head (m, world)."""
    names = [c.name for c in clips]
    tokens = _tokens(text)
    _refuse_unknown_words(tokens, names, text)
    colours = [t for t in tokens if t in names]
    spatial = _spatial_phrases(tokens, text)
    if colours and spatial:
        raise InstructionError(f"{text!r} mixes a colour order with a spatial order; give one of them")
    if colours:
        return _colour_order(tokens, names, text)
    if len(spatial) > 1:
        raise InstructionError(f"{text!r} gives more than one spatial order: {', '.join(spatial)}")
    if spatial:
        return _spatial_order(spatial[0], clips, head_xy, text)
    if any(t in _IMPLICIT for t in tokens):
        return natural_order(clips, head_xy)
    raise InstructionError(
        f"{text!r} gives no clip order: name the colours, a spatial order, or 'all the clips'"
    )


def natural_order(clips: tuple[ClipSpec, ...], head_xy: Sequence[float]) -> tuple[str, ...]:
    """The layout's natural routing path: a greedy chain that follows the clips' insertion directions.

    First clip: the nearest to the head among the clips whose entry side faces the head (head at
    clip-frame x < -depth/2); the nearest overall if none does. Each next clip: the nearest to the
    previous clip's exit point (clip frame (+depth/2, 0)) among the remaining clips lying ahead of that
    exit (their centre at x > +depth/2 in the previous clip's frame); the nearest overall if none does.
    """
    return greedy_order(clips, head_xy, ahead_only=True)


def greedy_order(
    clips: tuple[ClipSpec, ...], head_xy: Sequence[float], *, ahead_only: bool
) -> tuple[str, ...]:
    """Greedy nearest-next chain from the head (m, world); ``ahead_only`` as in :func:`natural_order`.

    With ``ahead_only`` False it is the symbolic planner's "next closest clip": the clip nearest the
    head, then repeatedly the remaining clip nearest the previous clip's exit point.
    """
    point = np.asarray(head_xy, dtype=float)[:2]
    remaining = list(clips)
    order: list[ClipSpec] = []
    while remaining:
        pool = remaining
        if ahead_only:
            if order:
                prev = order[-1]
                ahead = [
                    c for c in remaining if to_clip_frame(prev, np.array([c.x, c.y]))[0] > CLIP_DEPTH / 2
                ]
            else:
                ahead = [c for c in remaining if to_clip_frame(c, point)[0] < -CLIP_DEPTH / 2]
            pool = ahead or remaining
        nxt = min(pool, key=lambda c: float(np.hypot(c.x - point[0], c.y - point[1])))
        order.append(nxt)
        remaining.remove(nxt)
        point = to_world_frame(nxt, np.array([CLIP_DEPTH / 2, 0.0]))
    return tuple(c.name for c in order)


def _tokens(text: str) -> list[str]:
    return ["->" if t in ("→", "=>") else t for t in _TOKEN.findall(text.lower())]


def _refuse_unknown_words(tokens: list[str], names: list[str], text: str) -> None:
    for i, t in enumerate(tokens):
        if (t in CLIP_COLOURS or t in OTHER_COLOURS) and t not in names:
            raise InstructionError(f"no clip is {t} in {text!r}; the scene's clips are: {', '.join(names)}")
        if t == "after" and (i + 1 >= len(tokens) or tokens[i + 1] not in ("that", "this", "which")):
            raise InstructionError(
                f"relative word 'after' in {text!r} is not understood; list clips in order"
            )
        if t in _UNSUPPORTED:
            raise InstructionError(f"word {t!r} in {text!r} is not understood (no such direction or rule)")


def _spatial_phrases(tokens: list[str], text: str) -> list[str]:
    """The "<A> to <B>" phrases as "A_to_B" (canonical ends); a direction word outside one is an error."""
    phrases, used = [], set()
    for i, t in enumerate(tokens):
        a = _DIRECTION_WORDS.get(t)
        if a is None or i in used:
            continue
        j = _skip(tokens, i + 1)
        if j < len(tokens) and tokens[j] in ("to", "toward", "towards"):
            k = _skip(tokens, j + 1)
            if k < len(tokens) and _DIRECTION_WORDS.get(tokens[k]) == _OPPOSITE[a]:
                phrases.append(f"{a}_to_{_OPPOSITE[a]}")
                used.update((i, k))
                continue
        raise InstructionError(
            f"direction word {t!r} in {text!r} is not understood; say e.g. 'from left to right', "
            "'from top to bottom' or 'from the nearest to the farthest'"
        )
    return phrases


def _skip(tokens: list[str], i: int) -> int:
    while i < len(tokens) and tokens[i] in _FILLERS_IN_PHRASE:
        i += 1
    return i


def _colour_order(tokens: list[str], names: list[str], text: str) -> tuple[str, ...]:
    order: list[str] = []
    pending: list[str] = []  # position words waiting for their clause's colour
    for clause in _clauses(tokens):
        colours = [t for t in clause if t in names]
        pending += [t for t in clause if t in _ORDINALS]
        if not colours:
            continue
        for c in colours:
            if c in order:
                raise InstructionError(f"{text!r} names the {c} clip twice")
            order.append(c)
        if pending and len(colours) > 1:
            raise InstructionError(f"position word {pending[0]!r} in {text!r} fits more than one colour")
        for word in pending:
            want = len(names) - 1 if _ORDINALS[word] < 0 else _ORDINALS[word]
            if want != len(order) - 1:
                raise InstructionError(
                    f"in {text!r}, {word!r} is said of the {colours[0]} clip, which is named at position "
                    f"{len(order)}: list the clips in routing order"
                )
        pending = []
    if pending:
        raise InstructionError(f"position word {pending[0]!r} in {text!r} is not said of any clip")
    missing = [n for n in names if n not in order]
    if missing:
        raise InstructionError(f"{text!r} omits clip(s) {', '.join(missing)}; every clip must be routed")
    return tuple(order)


def _clauses(tokens: list[str]) -> list[list[str]]:
    clauses: list[list[str]] = [[]]
    for i, t in enumerate(tokens):
        after_that = t == "after" or (t in ("that", "this") and i > 0 and tokens[i - 1] == "after")
        followed_by = t == "followed" or (t == "by" and i > 0 and tokens[i - 1] == "followed")
        if t in _SEPARATORS or after_that or followed_by:
            clauses.append([])
        else:
            clauses[-1].append(t)
    return [c for c in clauses if c]


def _spatial_order(
    phrase: str, clips: tuple[ClipSpec, ...], head_xy: Sequence[float], text: str
) -> tuple[str, ...]:
    hx, hy = float(head_xy[0]), float(head_xy[1])
    key = {
        "left_to_right": lambda c: c.x,
        "right_to_left": lambda c: -c.x,
        "bottom_to_top": lambda c: c.y,
        "top_to_bottom": lambda c: -c.y,
        "near_to_far": lambda c: float(np.hypot(c.x - hx, c.y - hy)),
        "far_to_near": lambda c: -float(np.hypot(c.x - hx, c.y - hy)),
    }[phrase]
    ranked = sorted(clips, key=key)
    for a, b in zip(ranked, ranked[1:]):
        if key(b) - key(a) < SPATIAL_TIE:
            raise InstructionError(
                f"{text!r} is ambiguous here: the {a.name} and {b.name} clips are level ({phrase.replace('_', ' ')})"
            )
    return tuple(c.name for c in ranked)
