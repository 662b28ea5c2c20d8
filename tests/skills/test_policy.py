"""The shipped insertion policy: it loads, acts within bounds, carries its card, and inserts."""

import numpy as np

from dloroute.skills.insert_env import ClipInsertEnv
from dloroute.skills.policy import InsertPolicy
from dloroute.skills.trial import insertion_trial


def test_shipped_policy_loads_with_its_card():
    policy = InsertPolicy.load()
    card = policy.card
    assert card["command"].startswith("dloroute train-insert") and card["config"]["seed"] == 0
    assert card["evaluation"]["success_rate_pct"] >= 90


def test_shipped_policy_gives_valid_actions():
    policy = InsertPolicy.load()
    env = ClipInsertEnv()
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        action = policy.act(obs)
        assert action.shape == env.action_space.shape and env.action_space.contains(action.astype(np.float32))


def test_shipped_policy_inserts_on_table_one_scenes():
    results = [insertion_trial("rl", 10000 + s) for s in range(5)]
    assert all(r["success"] and not r["collision"] for r in results)
