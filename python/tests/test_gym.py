"""hydrojet.gym: HydroJet-v0 passes Gymnasium's own checker, and ModelBasedPolicy in it is the
project's controller: its episode's RMS is the experiment's for the same plant, path and seed."""
import math

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hydrojet
import hydrojet.gym
from conftest import config


@pytest.mark.parametrize("kwargs", [
    {},
    {"scene": config("scenes/hydrojet_30deg.yaml"), "path": config("paths/figure_eight.csv"),
     "plant": config("plants/heavy_slow.yaml"), "control_period": 0.02},
    {"scene": config("scenes/two_segment_thrusters.yaml"), "duration": 5.0},
])
def test_check_env(kwargs):
    env = gymnasium.make("hydrojet/HydroJet-v0", seed=3, **kwargs)
    check_env(env.unwrapped)
    n = env.unwrapped.scene.actuator_count
    assert env.action_space.shape == (n,)
    assert env.observation_space.shape == (3 * 6 + n,)


def episode(env, policy, seed):
    obs, info = env.reset(seed=seed)
    errors, steps = [], 0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs, info))
        assert env.observation_space.contains(obs)
        errors.append(-reward)
        steps += 1
        if terminated or truncated:
            return math.sqrt(np.mean(np.square(errors))), terminated, truncated, steps


def test_model_based_policy_reproduces_the_experiment():
    duration = 10.0
    env = gymnasium.make("hydrojet/HydroJet-v0", seed=1, duration=duration)
    rms, terminated, truncated, steps = episode(env, hydrojet.gym.ModelBasedPolicy(env), seed=1)
    ref = hydrojet.run_experiment(hydrojet.data_path("scenes/hydrojet_0deg.yaml"), duration=duration, seed=1)
    print(f"ModelBasedPolicy, 10 s spiral, seed 1: RMS {rms:.5f} rad (experiment {ref['rms_rad']:.5f})")
    assert truncated and not terminated and steps == round(duration / 0.01)
    # The same loop: the reward's window starts one cycle later and the actions pass through float32.
    assert rms == pytest.approx(ref["rms_rad"], rel=2e-3)
    # And far better than doing nothing (valves shut): the spiral leaves the resting tip behind.
    idle, *_ = episode(env, lambda obs, info: -np.ones(env.action_space.shape, np.float32), seed=1)
    assert rms < 0.2 * idle


def test_termination_at_the_abort_angle():
    env = gymnasium.make("hydrojet/HydroJet-v0", seed=2, duration=3.0)
    env.reset(seed=2)
    full = np.array([1.0, -1.0, -1.0], np.float32)  # one jet at full duty: the tip swings off the path
    for _ in range(300):
        _, reward, terminated, truncated, info = env.step(full)
        assert terminated == (info["error"] > env.unwrapped.abort_angle == 0.5)
        if terminated or truncated:
            break
    assert terminated, "a full jet for 3 s should leave the path by more than 0.5 rad"


def test_reset_seeds():
    """reset(seed=s) repeats an episode; the constructor's seed serves the first reset, and the resets
    after it draw from np_random, so a run of episodes repeats too."""
    def first_observations(env, resets):
        return [env.reset(seed=s)[0] for s in resets]
    a = gymnasium.make("hydrojet/HydroJet-v0", seed=7, duration=2.0)
    b = gymnasium.make("hydrojet/HydroJet-v0", seed=7, duration=2.0)
    np.testing.assert_array_equal(first_observations(a, [None, None, 5, None]),
                                  first_observations(b, [None, None, 5, None]))
    c = gymnasium.make("hydrojet/HydroJet-v0", duration=2.0)
    assert not np.array_equal(a.reset(seed=7)[0], c.reset(seed=8)[0])  # the tracker's noise differs


def test_bad_arguments_raise_value_error():
    with pytest.raises(ValueError, match="control_period"):
        hydrojet.gym.HydroJetEnv(control_period=0.0)
    with pytest.raises(ValueError, match="scene"):
        hydrojet.gym.HydroJetEnv(scene="/nonexistent.yaml")
    env = hydrojet.gym.HydroJetEnv()
    env.reset(seed=1)
    with pytest.raises(ValueError, match="action"):
        env.step(np.zeros(2))
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=-1)
    with pytest.raises(ValueError, match="duration"):
        hydrojet.gym.HydroJetEnv(duration=float("inf"))
