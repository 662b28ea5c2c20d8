"""A tiny SAC run completes, exports weights that load, and can be resumed."""

import json

import numpy as np
import pytest

from dloroute.skills.insert_env import ClipInsertEnv
from dloroute.skills.policy import InsertPolicy
from dloroute.skills.train_sac import TrainConfig, train


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("train")
    config = TrainConfig(steps=24, n_envs=1, learning_starts=8, demo_steps=4, batch_size=8, net_arch=(16, 16), out=str(out))
    return train(config, progress=False), config


def test_tiny_training_writes_weights_that_load(tiny_run):
    path, config = tiny_run
    policy = InsertPolicy.load(path)
    card = json.loads(path.with_suffix(".json").read_text())
    assert card["config"]["steps"] == 24 and card["total_steps"] >= 24 and card["wall_time_s"] > 0
    env = ClipInsertEnv()
    obs, _ = env.reset(seed=0)
    a = policy.act(obs)
    assert a.shape == (7,) and np.all(np.abs(a) <= 1.0)
    assert path.stat().st_size < 50_000  # the actor only


def test_training_resumes(tiny_run, tmp_path):
    path, config = tiny_run
    resumed = train(TrainConfig(steps=8, n_envs=1, out=str(tmp_path), resume=config.out), progress=False)
    card = json.loads(resumed.with_suffix(".json").read_text())
    assert card["resumed_from"]["total_steps"] >= 24 and card["total_steps"] >= 32
