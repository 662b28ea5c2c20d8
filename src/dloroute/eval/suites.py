"""Benchmark suites as data: which configurations (rows) run on which task families and seeds.

A *job* is one episode: a row (high-level planner + low-level insertion skill) on one family's scene for one
seed. Its key ``(row label, family, seed)`` identifies its record in a run's JSONL file, so a run can be
resumed, and names its video.

- ``TABLE_II`` (routing, the paper's Table II): the paper's five configurations plus our offline rule-based
  planner with both low levels, on the four task families x seeds 0..14 (the paper's 15 trials per family).
- ``TABLE_I`` (insertion, the paper's Table I): the Insert skill alone, heuristic vs. RL, on 100 scenes at clip
  scale 1.0. Its seeds start at 10,000 to stay clear of the small seeds that training and tests use.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

from dloroute.types import FAMILIES

VLM_PLANNERS = frozenset({"vlm", "vlm_no_fr"})
"""Planner names that need a VLM endpoint."""


@dataclass(frozen=True)
class Row:
    """One configuration: the episode loop's planner name (``high_level``) and its insertion skill
    (``low_level``: ``"rl"`` or ``"heuristic"``). ``label`` is unique within a suite and file-name safe."""

    high_level: str
    low_level: str
    label: str
    needs_vlm: bool


def row(high_level: str, low_level: str) -> Row:
    """The row ``high_level+low_level``; it needs a VLM when its planner is one of ``VLM_PLANNERS``."""
    return Row(high_level, low_level, f"{high_level}+{low_level}", high_level in VLM_PLANNERS)


@dataclass(frozen=True)
class Job:
    """One episode to run: ``row`` on the scene of ``family`` and ``seed``."""

    row: Row
    family: str
    seed: int

    @property
    def key(self) -> tuple[str, str, int]:
        return (self.row.label, self.family, self.seed)

    def fields(self) -> dict[str, str | int]:
        """The job's identifying fields, as every record of it starts."""
        return {"row": self.row.label, "high_level": self.row.high_level, "low_level": self.row.low_level,
                "family": self.family, "seed": self.seed}


def record_key(record: dict) -> tuple[str, str, int]:
    """The key of the job a JSONL record belongs to (see ``Job.key``)."""
    return (record["row"], record["family"], int(record["seed"]))


@dataclass(frozen=True)
class Suite:
    """Rows x families x seeds. ``name`` names the suite's JSONL file in a run folder (``<name>.jsonl``)."""

    name: str
    rows: tuple[Row, ...]
    families: tuple[str, ...]
    seeds: tuple[int, ...]

    def jobs(self) -> tuple[Job, ...]:
        """Every job, row-major, so early results cover whole rows."""
        return tuple(Job(r, f, s) for r in self.rows for f in self.families for s in self.seeds)

    def jsonl(self, run_dir: Path) -> Path:
        return Path(run_dir) / f"{self.name}.jsonl"

    def select(
        self,
        *,
        vlm_configured: bool,
        labels: Iterable[str] | None = None,
        families: Iterable[str] | None = None,
        seeds: Iterable[int] | None = None,
    ) -> Suite:
        """The part of the suite to run: rows that need a VLM only when an endpoint is configured
        (``vlm_configured=False`` gives the offline rows), optionally narrowed to some row labels, families
        and seeds. Unknown labels or families raise ``ValueError``."""
        rows = self.rows if labels is None else tuple(_pick(self.rows, list(labels)))
        fams = self.families if families is None else tuple(families)
        unknown = sorted(set(fams) - set(self.families))
        if unknown:
            raise ValueError(f"unknown families {unknown}; suite {self.name!r} has {list(self.families)}")
        return replace(
            self,
            rows=tuple(r for r in rows if vlm_configured or not r.needs_vlm),
            families=fams,
            seeds=self.seeds if seeds is None else tuple(seeds),
        )


def _pick(rows: tuple[Row, ...], labels: list[str]) -> list[Row]:
    by_label = {r.label: r for r in rows}
    unknown = [lb for lb in labels if lb not in by_label]
    if unknown:
        raise ValueError(f"unknown rows {unknown}; choose from {list(by_label)}")
    return [by_label[lb] for lb in labels]


def video_path(run_dir: Path, label: str, family: str, seed: int) -> Path:
    """Where an episode's video lives in a run folder; the report links the videos it finds here."""
    return Path(run_dir) / "videos" / f"{label}_{family}_{seed}.mp4"


TABLE_II = Suite(
    name="routing",
    rows=(
        row("vlm", "heuristic"),
        row("vlm_no_fr", "rl"),
        row("fixed_order", "rl"),
        row("symbolic", "rl"),
        row("vlm", "rl"),
        row("rule_based", "rl"),
        row("rule_based", "heuristic"),
    ),
    families=FAMILIES,
    seeds=tuple(range(15)),
)

TABLE_I_CLIP_SCALE = 1.0
"""Clip scale of the Table I insertion scenes."""

TABLE_I = Suite(
    name="insertion",
    rows=(row("insert", "heuristic"), row("insert", "rl")),
    families=(f"scale_{TABLE_I_CLIP_SCALE}",),
    seeds=tuple(range(10_000, 10_100)),
)
