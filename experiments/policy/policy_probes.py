"""Probes behind the pushing policy's training choices (docs/training.md).

landscape: the paper's reward, summed over an episode, when every push is the same fixed
    action, under a frozen predictor (the one PPO starts against). Shows where the good
    pushes are and why the zero action is a bad place to start.
fixed: a fixed push sequence, and a predictor fine-tuned on 8k episodes of it, evaluated on
    800 fresh episodes: what consistent pushes alone are worth.

    python experiments/policy/policy_probes.py landscape --setting 2link-1-10 \
        --predictor runs/2link-1-10-stiff-train/predictor-0/predictor.pt
    python experiments/policy/policy_probes.py fixed --setting 2link-1-10 \
        --predictor runs/2link-1-10-stiff-train/predictor-0/predictor.pt \
        --sequence "1,-0.9;1,0.9"
"""

from __future__ import annotations

import argparse
import tempfile

import numpy as np

from masspush.config import EnvConfig
from masspush.data import EVAL, collect, load_dataset, run_episodes
from masspush.learn import FINETUNE, load_model, train_predictor
from masspush.metrics import percentage_error
from masspush.settings import get_setting


class FixedPolicy:
    """The same push sequence in every episode."""

    def __init__(self, sequence: np.ndarray):
        self.sequence = np.asarray(sequence, np.float32)
        self.name = "fixed:" + ";".join(",".join(f"{v:g}" for v in a) for a in self.sequence)

    def reset(self, seeds: np.ndarray) -> None:
        pass

    def act(self, observations, actions, step, lengths) -> np.ndarray:
        return np.repeat(self.sequence[step][None], len(observations), axis=0)


def landscape(setting: str, predictor: str, envs: int) -> None:
    from masspush.learn import BatchPushVecEnv

    spec = get_setting(setting)
    env = BatchPushVecEnv(EnvConfig(physics=spec.physics(), pusher="stiff"), predictor, envs, 3)
    env.seed(3)
    print("a1    a2    episode reward (mean +- s.e.)  failed episodes")
    for a1 in (0.1, 0.3, 0.5, 0.7, 0.9, 1.0):
        for a2 in (-0.9, -0.5, 0.0, 0.5, 0.9):
            env.reset()
            total, failed = np.zeros(envs), 0
            for _ in range(env.k):
                _, reward, _, infos = env.step(np.tile([a1, a2], (envs, 1)).astype(np.float32))
                total += reward
                failed += sum(info["failure"] is not None for info in infos)
            se = total.std() / np.sqrt(envs)
            print(f"{a1:4.1f}  {a2:+4.1f}  {total.mean():7.2f} +- {se:4.2f}  {failed:4d}/{envs}")


def fixed(setting: str, predictor: str, sequence: str, episodes: int) -> None:
    spec = get_setting(setting)
    steps = np.array([[float(v) for v in a.split(",")] for a in sequence.split(";")])
    if steps.shape != (spec.n_links, 2):
        raise SystemExit(f"--sequence needs {spec.n_links} pushes 'a1,a2;a1,a2...'")
    policy = FixedPolicy(steps)
    start, meta = load_model(predictor, spec.name)
    with tempfile.TemporaryDirectory() as tmp:
        collect(spec, f"{tmp}/data", episodes=episodes, pusher=spec.pusher, policy=policy,
                base_seed=77, progress=True)  # fmt: skip
        _, data = load_dataset(f"{tmp}/data")
        train_predictor(data, f"{tmp}/model", FINETUNE, {**meta, "policy": policy.name},
                        init=start)  # fmt: skip
        tuned, _ = load_model(f"{tmp}/model/predictor.pt")
    config = EnvConfig(physics=spec.physics(), pusher=spec.pusher)
    run = run_episodes(config, policy, np.arange(800), EVAL, 0)
    good = run.select(run.ok)
    truth = good.mass_distribution
    print(
        f"{policy.name}: {len(run) - len(good)} failed of 800; percentage error with the "
        f"starting predictor {percentage_error(start.predict(good)[:, -1], truth):.2f}, "
        f"fine-tuned on it {percentage_error(tuned.predict(good)[:, -1], truth):.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("probe", choices=("landscape", "fixed"))
    parser.add_argument("--setting", default="2link-1-10")
    parser.add_argument("--predictor", required=True, help="a random-policy predictor (.pt)")
    parser.add_argument("--sequence", default="1,-0.9;1,0.9", help="fixed: 'a1,a2;a1,a2'")
    parser.add_argument("--episodes", type=int, default=8000, help="fixed: training episodes")
    parser.add_argument("--envs", type=int, default=512, help="landscape: chains per action")
    args = parser.parse_args()
    if args.probe == "landscape":
        landscape(args.setting, args.predictor, args.envs)
    else:
        fixed(args.setting, args.predictor, args.sequence, args.episodes)


if __name__ == "__main__":
    main()
