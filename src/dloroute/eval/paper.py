"""The paper's published numbers (Tables I and II), in the same stats types our runs aggregate to.

The numbers ship with the package as ``paper_tables.json`` (a copy of the paper's tables). The paper names
its high levels in words; ``PAPER_PLANNERS`` maps them to the episode loop's planner names.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

PAPER_PLANNERS = {
    "vlm_failure_reasoning": "vlm",
    "vlm_no_failure_reasoning": "vlm_no_fr",
    "fixed_order": "fixed_order",
    "symbolic": "symbolic",
}
"""The paper's high-level names -> planner names."""

PAPER_LOW_LEVELS = {"heuristic": "heuristic", "rl_sac": "rl"}
"""The paper's Table I row names -> low-level names."""

PAPER_ROUTING_TRIALS = 15
"""Episodes per family behind each Table II cell (the table's description)."""
PAPER_INSERTION_TRIALS = 100
"""Scenes behind each Table I row (the table's description)."""


@dataclass(frozen=True)
class RoutingStats:
    """One Table II cell group: success rate (%), average clips routed, average episode length (skills),
    over ``n`` episodes."""

    sr: float
    clips: float
    epi: float
    n: int


@dataclass(frozen=True)
class InsertionStats:
    """One Table I row: success rate (%), average signed endpoint distance (cm), average primitives, over
    ``n`` trials."""

    sr: float
    signed_distance_cm: float
    length: float
    n: int


@cache
def _tables() -> dict[str, Any]:
    return json.loads(resources.files("dloroute.eval").joinpath("paper_tables.json").read_text("utf-8"))


def paper_routing() -> dict[tuple[str, str], dict[str, RoutingStats]]:
    """Table II: (planner, low level) -> family -> stats."""
    table = _tables()["table_II_routing"]
    return {
        (PAPER_PLANNERS[r["high_level"]], r["low_level"]): {
            family: RoutingStats(r["sr"][i], r["clips"][i], r["epi"][i], PAPER_ROUTING_TRIALS)
            for i, family in enumerate(table["families"])
        }
        for r in table["rows"]
    }


def paper_insertion() -> dict[str, InsertionStats]:
    """Table I: low level -> stats."""
    table = _tables()["table_I_insertion"]
    return {
        PAPER_LOW_LEVELS[name]: InsertionStats(
            table[name]["success_rate_pct"], table[name]["avg_signed_distance_cm"], table[name]["episode_length"],
            PAPER_INSERTION_TRIALS,
        )
        for name in PAPER_LOW_LEVELS
    }
