"""What the policy sees and what it is paid: the push-history vector and the paper's reward.

Shared by the single-chain policy environment (`masspush.learn.policy.PushPolicyEnv`) and
the batch one (`masspush.learn.vec_env.BatchPushVecEnv`).
"""

from __future__ import annotations

import numpy as np

from masspush.data.rollout import Episodes
from masspush.learn.predictor import step_inputs

REWARD_SCALE, REWARD_BETA = 10.0, 2.0
"""The reward as coded: REWARD_SCALE * (1 - REWARD_BETA * mean_i |m_i - m_hat_i|) [code]."""


def paper_reward(predicted: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """The paper's per-push reward for predicted and true mass distributions (..., n)."""
    error = np.mean(np.abs(np.asarray(truth) - np.asarray(predicted)), axis=-1)
    return REWARD_SCALE * (1.0 - REWARD_BETA * error)


def history_dim(n_links: int, pushes: int) -> int:
    """Length of the policy's observation vector."""
    step = 2 + 3 + 2 * (n_links - 1) + n_links
    return (n_links - 1 + n_links) + pushes * step + pushes


def history_features(
    observations: np.ndarray, actions: np.ndarray, lengths: np.ndarray, step: int
) -> np.ndarray:
    """(E, history_dim) policy inputs before push `step`, from (E, K + 1, D) observations
    (q_0..q_step filled), (E, K, 2) actions (a_0..a_{step-1} filled) and (E, n) lengths."""
    e, k = actions.shape[:2]
    known_obs = np.full_like(observations, np.nan)
    known_obs[:, : step + 1] = observations[:, : step + 1]
    known_actions = np.zeros_like(actions)
    known_actions[:, :step] = actions[:, :step]
    history = Episodes.history(known_obs, np.nan_to_num(known_actions), lengths)
    q0, steps = step_inputs(history, "relative")
    onehot = np.zeros((e, k), np.float32)
    if step < k:
        onehot[:, step] = 1.0
    return np.concatenate([q0, steps.reshape(e, -1), onehot], axis=1).astype(np.float32)
