"""Speed of hydrojet.gym's HydroJet-v0 on one core (scripts/bench runs it; the median of many runs).

gym_steps_per_s: env.step with random actions (seeded), the resets their early terminations cause
included, as a learner meets them. gym_policy_steps_per_s: env.step with ModelBasedPolicy choosing
each action (the controller's cycle in the loop). The control period is 10 ms, so steps/s over 100
is the factor over real time. Prints one JSON object.
"""
import json
import os
import statistics
import sys
import time

import gymnasium
import numpy as np

import hydrojet.gym


def random_steps_per_s(env, steps: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - t0)


def policy_steps_per_s(env, steps: int, seed: int) -> float:
    policy = hydrojet.gym.ModelBasedPolicy(env)
    obs, info = env.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(policy(obs, info))
        if terminated or truncated:
            obs, info = env.reset()
    return steps / (time.perf_counter() - t0)


def main() -> int:
    repetitions = int(sys.argv[1]) if len(sys.argv) > 1 else 15
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    env = gymnasium.make("hydrojet/HydroJet-v0", seed=1, control_period=0.01)
    random_runs = [random_steps_per_s(env, 2000, seed) for seed in range(1, repetitions + 1)]
    policy_runs = [policy_steps_per_s(env, 2000, seed) for seed in range(1, repetitions + 1)]
    print(json.dumps({"gym_steps_per_s": statistics.median(random_runs),
                      "gym_policy_steps_per_s": statistics.median(policy_runs),
                      "gym_control_period_s": 0.01, "gym_repetitions": repetitions}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
