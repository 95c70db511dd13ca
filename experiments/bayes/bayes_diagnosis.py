"""What limits the particle filter in a setting: the probes behind docs/notebook's
"What limits the filter there", as commands.

on-pushes: a learned model's policy pushes simulated chains (`SimRobot`, seeds from
    10 000), its predictor estimates, and the filter estimates from the same pushes beside
    it; both scored on the same episodes. Variants of the filter: any BayesConfig field
    (--bayes particles=1024, motion_slack=0, tail_dof=2), a pseudo-marginal likelihood
    (--replicas R: each particle simulated R times from a start and action jittered by the
    sensing and actuation noise, its likelihood the replicas' mean under the observation's
    kernel), or the robust spread (--spread mad: the scaled median of the noise's effect
    instead of its root mean square).
fidelity: the filter's simulation of the true chain (true masses and friction) from the
    true start pose with the executed push, against the world's rest pose: how exactly the
    simulator can reproduce one push at all.
micro-state: the same pushes, the true chain started from the world's own state (its
    height, tilt and residual velocities at rest, which no observation gives) or from parts
    of it: what makes `fidelity`'s inexact pushes inexact.

    python experiments/bayes/bayes_diagnosis.py on-pushes --setting 2link-0.1-10 --model tp+
    --episodes 60
    python experiments/bayes/bayes_diagnosis.py fidelity --setting 2link-0.1-10 --pushes 60
    python experiments/bayes/bayes_diagnosis.py micro-state --setting 2link-0.1-10 --pushes 60
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import replace
from statistics import NormalDist

import numpy as np

import masspush.bayes as bayes
from masspush.bayes import (
    UnexplainedObservationWarning,
    bayes_overrides,
    config_difference,
    default_config,
)
from masspush.settings import get_setting


def on_pushes(args: argparse.Namespace) -> None:
    from masspush.metrics import percentage_error
    from masspush.models import model_and_policy
    from masspush.real import SimRobot, run_estimation

    setting = get_setting(args.setting)
    predictor, _, policy = model_and_policy(args.model, setting.name)
    config = replace(default_config(setting), **(bayes_overrides(args.bayes) or {}))
    filt = bayes.filter_for(setting, config=config, seed=1)
    if args.replicas:
        _pseudo_marginal(filt, args.replicas)
    if args.spread == "mad":
        _robust_spread(filt)
    if args.spread == "particle":
        _particle_spread(filt, args.jitters)
    robot = SimRobot(setting, seed=10_000)
    pushes = setting.env_config().pushes
    truths, learned, filtered, inside = [], [], [], []
    start = time.perf_counter()
    while len(truths) < args.episodes:
        rest = robot.start()
        filt.reset(rest.lengths)
        state = {"start": rest.config.astype(float), "posterior": None}

        def beside(k, action, report, estimate, state=state):
            if report.failure is None:
                observed = report.config.astype(float)
                state["posterior"] = filt.update(state["start"], np.asarray(action, float),
                                                 observed)  # fmt: skip
                state["start"] = observed

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnexplainedObservationWarning)
            episode = run_estimation(robot, predictor, policy, pushes, on_push=beside,
                                     start=rest, seed=robot.seed)  # fmt: skip
        if episode.failure is not None:
            continue
        truth, post = robot.truth["mass_distribution"], state["posterior"]
        truths.append(truth)
        learned.append(episode.estimates[-1])
        filtered.append(post.estimate)
        inside.append((post.low <= truth) & (truth <= post.high))
    filt.close()
    truth = np.array(truths)
    print(f"{setting.name}: {len(truth)} episodes of {args.model}'s pushes, "
          f"{(time.perf_counter() - start) / len(truth):.1f} s per episode")  # fmt: skip
    print(f"{args.model}'s predictor: {percentage_error(np.array(learned), truth):.2f}")
    print(f"filter: {percentage_error(np.array(filtered), truth):.2f}, "
          f"coverage {100 * np.mean(inside):.0f} %")  # fmt: skip


def fidelity(args: argparse.Namespace) -> None:
    from masspush.env import ChainEnv

    setting = get_setting(args.setting)
    env = ChainEnv.from_config(setting.env_config())
    filt = bayes.filter_for(setting, seed=0)
    diffs = []
    for info, _, after in _pushes_from_rest(env, args.pushes):
        filt.reset(info["lengths"])
        start = np.asarray(info["config"], float)
        executed = np.asarray(after["push"]["action"], float)[None]
        simulated, _ = filt.simulate(start, executed, np.array([info["masses"]]),
                                     np.array([info["friction"]]))  # fmt: skip
        diffs.append(config_difference(np.asarray(after["config"], float)[None], simulated)[0])
    filt.close()
    d = np.abs(np.array(diffs))
    print(
        f"{setting.name}: {len(d)} pushes; |world - simulation| per component (x, y, yaw, joints)"
    )
    for name, values in (
        ("median", np.median(d, 0)),
        ("90th percentile", np.quantile(d, 0.9, 0)),
        ("largest", d.max(0)),
        ("exact (< 1e-4)", np.mean(d < 1e-4, 0)),
    ):
        print(f"  {name}: {np.round(values, 4).tolist()}")


def _pushes_from_rest(env, pushes: int):
    """The fidelity probes' pushes: a fresh chain at rest (seeds from 1000), pushed once
    where TP+ pushes (a1 in 0.3-0.7, a2 in 0.3-0.6, a fixed stream); yields the info at
    rest, the world's state at rest (qpos, qvel) and the info after, for pushes that did
    not fail."""
    rng = np.random.default_rng(5)
    for i in range(pushes):
        _, info = env.reset(seed=1000 + i)
        if info["failure"]:
            continue
        state = {k: np.copy(getattr(env.sim.data, k)) for k in ("qpos", "qvel")}
        action = np.array([rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.6)], np.float32)
        _, _, _, _, after = env.step(action)
        if not after["failure"]:
            yield info, state, after


def micro_state(args: argparse.Namespace) -> None:
    import mujoco

    from masspush.env import ChainEnv
    from masspush.sim import ChainSim

    setting = get_setting(args.setting)
    if setting.pusher != "stiff":
        raise SystemExit(f"micro-state compares chain-only scenes: {setting.name} is pushed by "
                         f"an arm ({setting.pusher}); take a stiff-pusher setting")  # fmt: skip
    physics = setting.physics()
    env = ChainEnv.from_config(setting.env_config())
    rows: dict[str, list[float]] = {}
    for info, world_state, after in _pushes_from_rest(env, args.pushes):
        executed, world = np.asarray(after["push"]["action"], float), after["config"]
        start = np.asarray(info["config"], float)
        chain = replace(env.chain, joint_angles=tuple(float(v) for v in start[3:]),
                        root_pose=tuple(float(v) for v in start[:3]))  # fmt: skip
        # What the filter does: a chain built at the observed pose and let settle.
        variants = {"built at the pose (the filter)": {}, "the world's state": world_state,
                    "the world's qpos, own qvel": {"qpos": world_state["qpos"]},
                    "the world's qvel, own qpos": {"qvel": world_state["qvel"]},
                    "the world's state, 1 mm along x": {**world_state, "dx": 1e-3}}  # fmt: skip
        for name, state in variants.items():
            sim = ChainSim(chain, physics)
            for key in ("qpos", "qvel"):
                if key in state:
                    getattr(sim.data, key)[:] = state[key]
            sim.data.qpos[0] += state.get("dx", 0.0)
            mujoco.mj_forward(sim.model, sim.data)
            sim.push(executed)
            diff = config_difference(np.asarray(world, float), sim.config())
            diff[0] += state.get("dx", 0.0)  # the shift itself is not an error
            rows.setdefault(name, []).append(float(np.abs(diff).max()))
    print(f"{setting.name}: {len(rows[next(iter(rows))])} pushes from rest; the true chain "
          "pushed again by the executed push, from:")  # fmt: skip
    for name, d in rows.items():
        d = np.array(d)
        print(
            f"  {name}: exact (< 1e-4) {100 * np.mean(d < 1e-4):.0f} %, largest component "
            f"off by {np.quantile(d, 0.9):.4f} at the 90th percentile, {d.max():.4f} at most"
        )


def _pseudo_marginal(filt: bayes.ParticleFilter, replicas: int) -> None:
    """Replace the filter's update by the pseudo-marginal one (this script's variant)."""

    def update(start, action, observed):
        m = filt.config.particles
        rows = m * replicas
        starts = start[None] + filt.rng.normal(0, filt.obs_sigma, (rows, len(start)))
        actions = np.repeat(np.asarray(action, float)[None], rows, 0)
        actions = np.clip(actions + filt.rng.normal(0, filt.env.action_noise, actions.shape), -1, 1)
        predicted, failed = filt.simulate(starts, actions, np.repeat(filt.masses, replicas, 0),
                                          np.repeat(filt.friction, replicas))  # fmt: skip
        sigma = filt._sigma(start, predicted, failed, np.zeros(len(start)))
        log_lik = filt._log_lik(config_difference(observed[None], predicted) / sigma)
        log_lik = np.where(failed, -np.inf, log_lik).reshape(m, replicas)
        top = np.max(log_lik, axis=1, keepdims=True)
        top = np.where(np.isfinite(top), top, 0)
        mean = np.log(np.mean(np.exp(log_lik - top), axis=1) + 1e-300) + top[:, 0]
        finite = mean > -1e250
        mean = np.where(finite, mean, (mean[finite].min() if finite.any() else 0) - 25)
        return filt._weigh(mean)

    filt.update = update


def _robust_spread(filt: bayes.ParticleFilter) -> None:
    """The noise's effect as the scaled median absolute change, not the root mean square."""
    z = NormalDist().inv_cdf(0.75)

    def noise_spread(start, actions, masses, friction, nominal, failed):
        diff = filt.noise_effect(start, actions, masses, friction, nominal, failed)
        return np.median(np.abs(diff), axis=0) / z if len(diff) else np.full(len(start), np.inf)

    filt.noise_spread = noise_spread


def _particle_spread(filt: bayes.ParticleFilter, jitters: int, pseudo: float = 1.0) -> None:
    """Each particle's own spread: its outcome simulated again `jitters` times from a start
    and action jittered by the sensing and actuation noise, the mean squared change shrunk
    towards all particles' mean with `pseudo` pseudo-samples; the likelihood then carries
    each particle's normalisation (a particle that makes the push unpredictable spreads
    its probability over more outcomes)."""

    def update(start, action, observed):
        m, d = filt.config.particles, len(start)
        actions = np.repeat(np.asarray(action, float)[None], m, 0)
        predicted, failed = filt.simulate(start, actions, filt.masses, filt.friction)
        sq, n = np.zeros((m, d)), np.zeros(m)
        for _ in range(jitters):
            starts = start[None] + filt.rng.normal(0, filt.obs_sigma, (m, d))
            noisy = np.clip(actions + filt.rng.normal(0, filt.env.action_noise, actions.shape),
                            -1, 1)  # fmt: skip
            perturbed, bad = filt.simulate(starts, noisy, filt.masses, filt.friction)
            ok = ~(bad | failed)
            sq[ok] += config_difference(perturbed[ok], predicted[ok]) ** 2
            n += ok
        seen = n > 0
        pooled = sq[seen].sum(0) / n[seen].sum() if seen.any() else np.full(d, 1.0)
        spread = np.sqrt((sq + pseudo * pooled) / (n + pseudo)[:, None])
        sigma = filt._sigma(start, predicted, failed, spread)
        log_lik = filt._log_lik(config_difference(observed[None], predicted) / sigma)
        log_lik = log_lik - filt.likelihood_power * np.log(sigma).sum(axis=1)
        return filt._weigh(bayes.failure_floor(log_lik, failed | ~np.isfinite(log_lik)))

    filt.update = update


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(required=True)
    one = sub.add_parser("on-pushes", help="the filter beside a learned model, on its pushes")
    one.add_argument("--setting", required=True)
    one.add_argument("--model", default="tp+")
    one.add_argument("--episodes", type=int, default=60)
    one.add_argument("--bayes", action="append", metavar="KEY=VALUE")
    one.add_argument("--replicas", type=int, default=0, help="pseudo-marginal replicas")
    one.add_argument("--spread", choices=("rms", "mad", "particle"), default="rms")
    one.add_argument("--jitters", type=int, default=2, help="with --spread particle")
    one.set_defaults(func=on_pushes)
    two = sub.add_parser("fidelity", help="the true chain simulated against the world")
    two.add_argument("--setting", required=True)
    two.add_argument("--pushes", type=int, default=60)
    two.set_defaults(func=fidelity)
    three = sub.add_parser("micro-state", help="how much the unobserved rest state matters")
    three.add_argument("--setting", required=True)
    three.add_argument("--pushes", type=int, default=60)
    three.set_defaults(func=micro_state)
    args = parser.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
