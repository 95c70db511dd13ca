"""What the policy sees and what it is paid: the push-history vector and the paper's reward.

Shared by the single-chain policy environment (`masspush.learn.policy.PushPolicyEnv`) and
the batch one (`masspush.learn.vec_env.BatchPushVecEnv`).
"""

from __future__ import annotations

import numpy as np

from masspush.data.rollout import Episodes
from masspush.learn.predictor import step_inputs
from masspush.sim.simulate import REACH_FAILURES
from masspush.sim.workspace import ROBOT_FRAME_DIM, Workspace

REWARD_SCALE, REWARD_BETA = 10.0, 2.0
"""The reward as coded: REWARD_SCALE * (1 - REWARD_BETA * mean_i |m_i - m_hat_i|) [code]."""


def paper_reward(predicted: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """The paper's per-push reward for predicted and true mass distributions (..., n)."""
    error = np.mean(np.abs(np.asarray(truth) - np.asarray(predicted)), axis=-1)
    return REWARD_SCALE * (1.0 - REWARD_BETA * error)


LOSS_REWARD = -REWARD_SCALE
"""The reward of a push after which a stationary robot has lost the chain (it could not
reach the push, or the chain came to rest out of its reach; `REACH_FAILURES`) [ours]: as
far below a perfect estimate's reward as a perfect estimate is above zero, on top of the
rewards of the pushes the episode no longer has, so that no estimate's gain pays for a
throw out of reach (docs/real-robot.md)."""


REWARDS = ("paper", "gain")
"""The per-push rewards a policy can be trained on: the paper's, or its gain over the prior
(`push_reward`)."""


def push_reward(
    predicted: np.ndarray, truth: np.ndarray, failure: str | None, reward: str = "paper",
    loss: float = LOSS_REWARD,
) -> float:  # fmt: skip
    """One push's reward: the paper's for a push that succeeded, `loss` (`LOSS_REWARD`) for
    one that lost the chain to a stationary robot, 0 for another failure (the chain's own).

    `reward` "gain": a successful push earns the paper's reward minus that of the prior's
    guess (every link 1/n of the mass), so a push that teaches nothing earns about 0. With
    episodes of many runs the paper's reward pays ~6 a push for any push the chain survives,
    and a loss then forfeits far more than any estimate gains: the policy learns to push
    timidly (docs/notebook 2026-12-02-runs-of-the-policy) [ours]."""
    if failure is None:
        earned = float(paper_reward(predicted, truth))
        if reward == "gain":
            earned -= float(paper_reward(np.full_like(truth, 1.0 / len(truth)), truth))
        return earned
    return loss if failure in REACH_FAILURES else 0.0


def history_dim(n_links: int, pushes: int, workspace: Workspace | None = None) -> int:
    """Length of the policy's observation vector."""
    step = 2 + 3 + 2 * (n_links - 1) + n_links
    where = 0 if workspace is None else ROBOT_FRAME_DIM
    return (n_links - 1 + n_links) + pushes * step + pushes + where


def history_features(
    observations: np.ndarray,
    actions: np.ndarray,
    lengths: np.ndarray,
    step: int,
    workspace: Workspace | None = None,
) -> np.ndarray:
    """(E, history_dim) policy inputs before push `step`, from (E, K + 1, D) observations
    (q_0..q_step filled), (E, K, 2) actions (a_0..a_{step-1} filled) and (E, n) lengths.

    The history is relative to the first pose (where the chain lies does not change how
    it moves); for a stationary robot (`workspace`) the latest pose in the robot's frame
    follows, so that the policy knows where the chain lies from the robot."""
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
    parts = [q0, steps.reshape(e, -1), onehot]
    if workspace is not None:
        parts.append(np.nan_to_num(workspace.robot_frame(observations[:, step, :3])))
    return np.concatenate(parts, axis=1).astype(np.float32)
