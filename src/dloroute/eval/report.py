"""Run folder -> markdown report: Tables I and II beside the paper's numbers, an SR plot, episode videos.

A run folder holds ``routing.jsonl`` (Table II) and/or ``insertion.jsonl`` (Table I), as ``run_suite`` writes
them, and optionally ``videos/`` named by ``suites.video_path``. Every table cell reads "ours (paper)"; "-"
marks a number that does not exist. Error episodes (termination ``"error"``) count as failures with 0 clips
routed; their length is unknown and left out of the average length.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Iterable, Sequence
from pathlib import Path
from statistics import fmean
from typing import Any, get_args

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from dloroute.eval.paper import InsertionStats, RoutingStats, paper_insertion, paper_routing
from dloroute.eval.runner import read_records
from dloroute.eval.suites import TABLE_I, TABLE_I_CLIP_SCALE, TABLE_II, VLM_PLANNERS, Row, Suite, video_path
from dloroute.types import Termination

HIGH_LEVEL_TITLES = {
    "vlm": "VLM w/ failure reasoning",
    "vlm_no_fr": "VLM w/o failure reasoning",
    "fixed_order": "Fixed order",
    "symbolic": "Symbolic",
    "rule_based": "Rule-based w/ failure reasoning (ours)",
    "insert": "Insert skill",
}
LOW_LEVEL_TITLES = {"rl": "RL (SAC)", "heuristic": "Heuristic"}
FAMILY_TITLES = {
    "implicit": "Implicit",
    "fixed_spatial": "Fixed spatial",
    "fixed_attribute": "Fixed attribute",
    "clips_4_5": "4-5 clips",
}
TERMINATIONS = (*get_args(Termination), "error")
"""Column order of the terminations table; unknown reasons follow, sorted."""


def aggregate_routing(records: Iterable[dict[str, Any]]) -> dict[tuple[str, str], RoutingStats]:
    """(row label, family) -> Table II stats of those records."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in records:
        groups.setdefault((r["row"], r["family"]), []).append(r)
    return {
        key: RoutingStats(
            sr=100.0 * fmean(bool(r["success"]) for r in group),
            clips=fmean(r.get("clips_routed", 0) for r in group),
            epi=_mean(r["length"] for r in group if "length" in r),
            n=len(group),
        )
        for key, group in groups.items()
    }


def aggregate_insertion(records: Iterable[dict[str, Any]]) -> dict[str, InsertionStats]:
    """Row label -> Table I stats of those records."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        groups.setdefault(r["row"], []).append(r)
    return {
        label: InsertionStats(
            sr=100.0 * fmean(bool(r["success"]) for r in group),
            signed_distance_cm=_mean(r["signed_distance_cm"] for r in group if "signed_distance_cm" in r),
            length=_mean(r["length"] for r in group if "length" in r),
            n=len(group),
        )
        for label, group in groups.items()
    }


def _mean(values: Iterable[float]) -> float:
    values = list(values)
    return fmean(values) if values else float("nan")


def _num(value: float | None, digits: int) -> str:
    return "-" if value is None or math.isnan(value) else f"{value:.{digits}f}"


def _cell(ours: float | None, paper: float | None, digits: int) -> str:
    return f"{_num(ours, digits)} ({_num(paper, digits)})"


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _titles(row: Row) -> list[str]:
    return [HIGH_LEVEL_TITLES.get(row.high_level, row.high_level), LOW_LEVEL_TITLES.get(row.low_level, row.low_level)]


def _episodes(records: list[dict[str, Any]], label: str) -> str:
    """The Episodes cell: how many records the row has, and how many of them are errors."""
    mine = [r for r in records if r["row"] == label]
    errors = sum(r.get("termination") == "error" for r in mine)
    if not mine:
        return "not run"
    return f"{len(mine)} ({errors} error{'s' * (errors > 1)})" if errors else str(len(mine))


def report_rows(suite: Suite, records: list[dict[str, Any]]) -> tuple[Row, ...]:
    """The suite's rows, then any other rows the records hold (so no record is left out of a report)."""
    known = {r.label for r in suite.rows}
    extra = {r["row"]: Row(r["high_level"], r["low_level"], r["row"], r["high_level"] in VLM_PLANNERS)
             for r in records if r["row"] not in known}
    return suite.rows + tuple(extra.values())


def routing_table(records: list[dict[str, Any]], suite: Suite = TABLE_II) -> str:
    """Table II in the paper's layout: High Level | Low Level | Episodes | SR, Clips, Epi per family."""
    ours, paper = aggregate_routing(records), paper_routing()
    header = ["High Level", "Low Level", "Episodes"]
    header += [f"{FAMILY_TITLES.get(f, f)} {m}" for f in suite.families for m in ("SR", "Clips", "Epi")]
    body = []
    for row in report_rows(suite, records):
        cells = [*_titles(row), _episodes(records, row.label)]
        for family in suite.families:
            o, p = ours.get((row.label, family)), paper.get((row.high_level, row.low_level), {}).get(family)
            cells += [_cell(o and o.sr, p and p.sr, 0), _cell(o and o.clips, p and p.clips, 1),
                      _cell(o and o.epi, p and p.epi, 1)]
        body.append(cells)
    return _table(header, body)


def insertion_table(records: list[dict[str, Any]], suite: Suite = TABLE_I) -> str:
    """Table I: success %, average signed endpoint distance (cm), episode length (primitives)."""
    ours, paper = aggregate_insertion(records), paper_insertion()
    body = []
    for row in report_rows(suite, records):
        o, p = ours.get(row.label), paper.get(row.low_level)
        body.append([LOW_LEVEL_TITLES.get(row.low_level, row.low_level), _episodes(records, row.label),
                     _cell(o and o.sr, p and p.sr, 0), _cell(o and o.signed_distance_cm, p and p.signed_distance_cm, 2),
                     _cell(o and o.length, p and p.length, 2)])
    header = ["Low Level", "Episodes", "Success %", "Avg signed distance (cm)", "Episode length"]
    return _table(header, body)


def termination_table(records: list[dict[str, Any]], suite: Suite = TABLE_II) -> str:
    """Episodes per termination reason, per row that has records."""
    counts = {row: Counter(r["termination"] for r in records if r["row"] == row.label)
              for row in report_rows(suite, records)}
    seen = set().union(*counts.values())
    reasons = [t for t in TERMINATIONS if t in seen] + sorted(seen - set(TERMINATIONS))
    body = [[*_titles(row), *(str(c[t]) for t in reasons)] for row, c in counts.items() if c]
    return _table(["High Level", "Low Level", *reasons], body)


def plot_routing(records: list[dict[str, Any]], out_png: Path, suite: Suite = TABLE_II) -> Path:
    """Bar chart of SR per family: one solid bar (ours) and one hatched bar (paper) per row."""
    ours, paper = aggregate_routing(records), paper_routing()
    rows = report_rows(suite, records)
    fig = Figure(figsize=(3.2 * len(suite.families), 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(suite.families), sharey=True, squeeze=False)[0]
    for ax, family in zip(axes, suite.families):
        for i, row in enumerate(rows):
            colour = f"C{i % 10}"
            o, p = ours.get((row.label, family)), paper.get((row.high_level, row.low_level), {}).get(family)
            if o:
                ax.bar(i - 0.2, o.sr, 0.4, color=colour)
            else:
                ax.text(i - 0.2, 2, "not run", rotation=90, ha="center", va="bottom", fontsize=7)
            if p:
                ax.bar(i + 0.2, p.sr, 0.4, facecolor="white", edgecolor=colour, hatch="///")
        ax.set_title(FAMILY_TITLES.get(family, family))
        ax.set_xticks(range(len(rows)), [r.label for r in rows], rotation=60, ha="right", fontsize=8)
        ax.set_ylim(0, 105)
    axes[0].set_ylabel("success rate (%)")
    fig.legend(handles=[Patch(color="grey", label="ours"),
                        Patch(facecolor="white", edgecolor="grey", hatch="///", label="paper")],
               loc="outside upper right", ncols=2)
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=120)
    return out_png


def video_table(records: list[dict[str, Any]], run_dir: Path, link_from: Path, suite: Suite = TABLE_II) -> str:
    """Links to one successful and one failed episode video per row and family, where videos exist; "" if
    the run folder has none. Links are relative to the folder ``link_from``."""
    body = []
    for row in report_rows(suite, records):
        cells, found = [], False
        for family in suite.families:
            mine = sorted((r for r in records if r["row"] == row.label and r["family"] == family),
                          key=lambda r: r["seed"])
            links = []
            for success in (True, False):
                for r in mine:
                    path = video_path(run_dir, row.label, family, r["seed"])
                    if bool(r["success"]) == success and path.exists():
                        mark = "success" if success else r.get("termination", "failed")
                        links.append(f"[seed {r['seed']} {mark}]({_rel(path, link_from)})")
                        break
            found |= bool(links)
            cells.append(" ".join(links) or "-")
        if found:
            body.append([*_titles(row), *cells])
    return _table(["High Level", "Low Level", *(FAMILY_TITLES.get(f, f) for f in suite.families)], body) if body else ""


def _rel(path: Path, start: Path) -> str:
    return Path(os.path.relpath(Path(path).resolve(), Path(start).resolve())).as_posix()


def write_report(run_dir: Path, out_md: Path) -> Path:
    """Write the markdown report of ``run_dir`` to ``out_md`` and its SR plot beside it
    (``<out_md stem>_sr.png``); returns ``out_md``. Files ``<run_dir>/*.section.md`` are appended as they are."""
    run_dir, out_md = Path(run_dir), Path(out_md)
    routing, insertion = read_records(TABLE_II.jsonl(run_dir)), read_records(TABLE_I.jsonl(run_dir))
    plot = plot_routing(routing, out_md.with_name(f"{out_md.stem}_sr.png"))
    parts = [
        "# Results",
        (f"Run folder: `{_rel(run_dir, out_md.parent)}`. Each cell: ours (paper); `-`: no number. "
         "Error episodes count as failures with 0 clips; their length is left out of the averages."),
        "## Table I: insertion primitive",
        (f"{len(TABLE_I.seeds)} scenes at clip scale {TABLE_I_CLIP_SCALE}; success = signed endpoint distance "
         "past the exit face > +2 cm. Episode length = Insert primitives used."),
        insertion_table(insertion),
        "## Table II: long-horizon routing",
        (f"{len(TABLE_II.seeds)} seeds per family. SR = success rate (%), Clips = average clips routed, "
         "Epi = average episode length (pick-and-place skills)."),
        routing_table(routing),
        f"![Success rate per family: ours solid, paper hatched]({_rel(plot, out_md.parent)})",
        "### Terminations",
        termination_table(routing) if routing else "No routing episodes recorded.",
        _timing(routing + insertion),
    ]
    videos = video_table(routing, run_dir, out_md.parent)
    if videos:
        parts += ["### Episode videos", videos]
    # Other measurements kept beside the runs (e.g. perception accuracy), as written by their commands.
    parts += [section.read_text(encoding="utf-8").strip() for section in sorted(run_dir.glob("*.section.md"))]
    out_md.parent.mkdir(parents=True, exist_ok=True)
    out_md.write_text("\n\n".join(parts) + "\n", encoding="utf-8")
    return out_md


def _timing(records: list[dict[str, Any]]) -> str:
    times = [r["wall_time"] for r in records if "wall_time" in r]
    if not times:
        return "No episodes recorded."
    return (f"{len(times)} episodes; episode wall time: mean {fmean(times):.1f} s, "
            f"total {sum(times) / 60:.1f} min (summed over workers).")
