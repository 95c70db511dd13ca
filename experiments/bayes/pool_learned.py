"""The particle filter's posterior pooled with a learned model's Dirichlet, for a grid of powers.

After each push the filter's weighted particles are reweighed by the learned model's
Dirichlet density of their mass distributions, raised to a power (a logarithmic opinion
pool), and the estimate and 90 % intervals are taken from the reweighed particles. The pool
changes only what is reported, never the particles or the pushes, so one pass of the filter
scores every power. Power 0 is the filter alone; the last row is the learned model's own
estimate (its Dirichlet's mean) on the filter's pushes. The model needs a Dirichlet head
(TP+ ships one; for another, `masspush calibrate --setting S --model rp+` first).

    python experiments/bayes/pool_learned.py --setting 2link-0.1-10 --model tp+ --seed 1 --episodes
    40
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from masspush.bayes import (
    InfoSeekingPolicy,
    UnexplainedObservationWarning,
    filter_for,
    run_bayes_episode,
)
from masspush.data import EVAL, Episodes, episode_seed
from masspush.env import ChainEnv
from masspush.learn import LearnedPosterior
from masspush.metrics import percentage_error
from masspush.models import resolve_model
from masspush.settings import get_setting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", required=True)
    parser.add_argument("--model", default="tp+")
    parser.add_argument("--powers", type=float, nargs="+", default=[0.25, 0.5, 0.75, 1.0])
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    setting = get_setting(args.setting)
    env = ChainEnv.from_config(setting.env_config())
    pushes = setting.env_config().pushes
    learned = LearnedPosterior.load(resolve_model(args.model, setting.name), setting.name)
    filt = filter_for(setting, seed=args.seed)
    policy = InfoSeekingPolicy(filt, args.seed)
    powers = [0.0, *args.powers]
    episode: dict = {}
    update, posterior = filt.update, filt.posterior

    def recording_update(start, action, observed):
        if not episode["seen"]:
            episode["seen"].append(start)
        episode["seen"].append(observed)
        episode["pushed"].append(action)
        return update(start, action, observed)

    def pooled_posterior(w=None):
        # Called by the update on the weighted particles, before any resampling.
        history = Episodes.history(
            np.asarray(episode["seen"], np.float32)[None],
            np.asarray(episode["pushed"], np.float32)[None],
            np.asarray(filt.lengths, np.float32)[None],
        )
        log_w, log_q = filt.log_w, learned.log_density(history, filt.shares())
        for p in powers:
            pooled = np.exp(log_w + p * log_q - np.max(log_w + p * log_q))
            episode[p] = posterior(pooled / pooled.sum())
        alpha = learned.concentration(history)
        episode["learned"] = alpha / alpha.sum()
        return posterior(w)

    filt.update, filt.posterior = recording_update, pooled_posterior
    rows: dict = {p: ([], []) for p in powers}
    alone, truths = [], []
    start = time.perf_counter()
    for i in range(args.episodes):
        episode.update(seen=[], pushed=[])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnexplainedObservationWarning)
            result = run_bayes_episode(env, filt, policy, episode_seed(EVAL, args.seed, i), pushes)
        if result["failure"] is not None or len(result["posteriors"]) < pushes:
            continue
        truth = result["truth"]
        truths.append(truth)
        alone.append(episode["learned"])
        for p in powers:
            rows[p][0].append(episode[p].estimate)
            rows[p][1].append((episode[p].low <= truth) & (truth <= episode[p].high))
    filt.close()
    truth = np.array(truths)
    print(f"{args.setting}, seed {args.seed}, {len(truth)} episodes scored of {args.episodes}, "
          f"{(time.perf_counter() - start) / args.episodes:.1f} s per episode")  # fmt: skip
    print("| pool power | error | coverage |\n|---|---|---|")
    for p in powers:
        est, inside = rows[p]
        print(f"| {p:g} | {percentage_error(np.array(est), truth):.2f} | "
              f"{100 * np.mean(inside):.0f} % |")  # fmt: skip
    print(f"| {args.model} alone, on the filter's pushes | "
          f"{percentage_error(np.array(alone), truth):.2f} | - |")  # fmt: skip


if __name__ == "__main__":
    main()
