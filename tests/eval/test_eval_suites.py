import pytest

from dloroute.eval.paper import paper_insertion, paper_routing
from dloroute.eval.suites import TABLE_I, TABLE_II, video_path
from dloroute.types import FAMILIES


def test_table_ii_is_the_papers_design_plus_ours():
    assert TABLE_II.families == FAMILIES and TABLE_II.seeds == tuple(range(15))
    labels = [r.label for r in TABLE_II.rows]
    assert len(set(labels)) == len(labels) == 7
    assert len(TABLE_II.jobs()) == 7 * 4 * 15
    configs = {(r.high_level, r.low_level) for r in TABLE_II.rows}
    assert set(paper_routing()) <= configs
    assert {("rule_based", "rl"), ("rule_based", "heuristic")} <= configs


def test_table_i_has_100_scenes_per_low_level():
    assert len(TABLE_I.jobs()) == 200
    assert {r.low_level for r in TABLE_I.rows} == set(paper_insertion()) == {"heuristic", "rl"}


def test_select_drops_vlm_rows_without_an_endpoint():
    offline = TABLE_II.select(vlm_configured=False)
    assert [r.label for r in offline.rows] == ["fixed_order+rl", "symbolic+rl", "rule_based+rl",
                                               "rule_based+heuristic"]
    assert TABLE_II.select(vlm_configured=True).rows == TABLE_II.rows
    narrow = TABLE_II.select(vlm_configured=False, labels=["vlm+rl", "symbolic+rl"], families=["implicit"],
                             seeds=[3])
    assert [j.key for j in narrow.jobs()] == [("symbolic+rl", "implicit", 3)]


@pytest.mark.parametrize("kwargs", [{"labels": ["nope+rl"]}, {"families": ["nope"]}])
def test_select_rejects_unknown_names(kwargs):
    with pytest.raises(ValueError, match="unknown"):
        TABLE_II.select(vlm_configured=True, **kwargs)


def test_video_path_naming(tmp_path):
    assert video_path(tmp_path, "rule_based+rl", "clips_4_5", 7) == tmp_path / "videos/rule_based+rl_clips_4_5_7.mp4"
