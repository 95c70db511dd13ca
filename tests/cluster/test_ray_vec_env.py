"""PPO's environments as Ray actors: the transitions of the local vectorised environment."""

from __future__ import annotations

import numpy as np
import pytest

from masspush.settings import get_setting


@pytest.mark.slow
def test_ray_actors_give_the_transitions_of_the_local_environments(ray_cluster, predictor_file):
    from masspush.cluster.pool import open_pool
    from masspush.learn.policy import make_vec_env

    env_config = get_setting("2link-0.1-1").env_config("kuka")
    actions = np.random.default_rng(0).uniform(-1, 1, (5, 3, 2)).astype(np.float32)

    def rollout(vec):
        out = [vec.reset()]
        for a in actions:  # 5 steps of 2-push episodes: each environment resets twice
            obs, rewards, dones, infos = vec.step(a)
            ends = [i.get("terminal_observation") for i in infos]
            out += [obs, rewards, dones, *[e for e in ends if e is not None]]
        assert vec.get_attr("render_mode") == [None] * 3
        vec.close()
        return out

    # An arm's environments as processes (--no-lockstep-arms): the lockstep runs in the
    # learner's process whatever the pool.
    here = rollout(make_vec_env(env_config, predictor_file, 3, seed=11, lockstep_arms=False))
    with open_pool(ray_cluster) as pool:
        vec = make_vec_env(env_config, predictor_file, 3, seed=11, workers=pool,
                           lockstep_arms=False)  # fmt: skip
        assert type(vec).__name__ == "RayVecEnv"
        on_ray = rollout(vec)
    assert len(on_ray) == len(here)
    for a, b in zip(on_ray, here, strict=True):
        np.testing.assert_array_equal(a, b)
