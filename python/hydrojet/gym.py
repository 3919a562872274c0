"""A Gymnasium environment of the HydroJet (or any robot a scene describes) following a path, and the
project's controller as the baseline policy a learned one is measured against.

    import gymnasium, hydrojet.gym
    env = gymnasium.make("hydrojet/HydroJet-v0", seed=1)
    policy = hydrojet.gym.ModelBasedPolicy(env)
    obs, info = env.reset(seed=1)
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs, info))
        if terminated or truncated:
            break

Observation (float32): the measured tip direction (3, base frame), the path's next `preview_steps`
directions `preview_dt` apart (3 each), and per actuator its measured state: a jet's flow over its
flow at max_force, a force actuator's force over its largest. Action: per actuator in [-1, 1], the
command box scaled: a jet's valve duty (a + 1) / 2, a force actuator's drive a. Reward: minus the
geodesic angle [rad] between the measured direction and the path's. Terminated when that angle
exceeds the controller's abort (safety/max_oscillation, 0.5 rad) or the plant fails; truncated at the
path's end. Not thread-safe: one thread per environment.
"""
from __future__ import annotations

import os
from typing import Optional

import gymnasium
import numpy as np

import hydrojet

ENV_ID = "hydrojet/HydroJet-v0"


class HydroJetEnv(gymnasium.Env):
    """The simulated plant (dynamic Cosserat rod, valves, flow sensors, tracker) following a path.

    scene, plant: YAML files (default: the shipped 0 degree HydroJet and config/plant.yaml); path: a
    path file (t, theta, phi rows) or None for the controller file's spiral over `duration` seconds;
    seed: seeds the first reset (the plant's noise, then np_random for the resets after it);
    control_period [s]; controller: the options file of the spiral, the abort angle and the baseline.
    """

    metadata = {"render_modes": []}

    def __init__(self, scene: Optional[str] = None, plant: Optional[str] = None, path: Optional[str] = None,
                 seed: Optional[int] = None, control_period: float = 0.01, duration: float = 20.0,
                 controller: Optional[str] = None, preview_steps: int = 5, preview_dt: float = 0.05):
        super().__init__()
        if not (1e-4 <= control_period <= 1.0):
            raise ValueError(f"control_period: must lie in [1e-4, 1] s, got {control_period!r}")
        if int(preview_steps) != preview_steps or preview_steps < 0:
            raise ValueError(f"preview_steps: must be a non-negative integer, got {preview_steps!r}")
        if not (preview_dt > 0.0):
            raise ValueError(f"preview_dt: must be positive, got {preview_dt!r}")
        self.scene_file = os.fspath(scene) if scene is not None else hydrojet.data_path("scenes/hydrojet_0deg.yaml")
        self.plant_file = os.fspath(plant) if plant is not None else hydrojet.data_path("plant.yaml")
        self.controller_file = (os.fspath(controller) if controller is not None
                                else hydrojet.data_path("controller.yaml"))
        self.scene = hydrojet.load_scene(self.scene_file)
        spiral, self.abort_angle = hydrojet._core._spiral_and_abort_angle(self.controller_file, float(duration))
        self.path = hydrojet.load_path(path) if path is not None else spiral
        self.control_period = float(control_period)
        self.preview = [(k + 1) * preview_dt for k in range(int(preview_steps))]
        self._seed = None if seed is None else hydrojet._seed(seed)
        n = self.scene.actuator_count
        self._jet = np.array(self.scene.actuator_is_jet, dtype=bool)
        lo, hi = self.scene.input_lower, self.scene.input_upper
        # A measured actuator state over its scale: flow at max_force (jets), largest force (others).
        self._state_scale = np.where(self._jet, self.scene.max_flow, np.maximum(np.abs(lo), np.abs(hi)))
        self._state_scale[self._state_scale <= 0.0] = 1.0
        size = 3 * (1 + len(self.preview)) + n
        self.observation_space = gymnasium.spaces.Box(-2.0, 2.0, shape=(size,), dtype=np.float32)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        self._core = hydrojet._core._EnvCore(hydrojet.load_plant(self.scene, self.plant_file), self.path,
                                             self.control_period, self.preview, self._state_scale,
                                             hydrojet._core._DEFAULT_SETTLE)

    def action_from_command(self, command) -> np.ndarray:
        """A command (a jet's duty in [0, 1], a force actuator's drive in [-1, 1]) as an action."""
        c = np.asarray(command, dtype=float)
        return np.clip(np.where(self._jet, 2.0 * c - 1.0, c), -1.0, 1.0).astype(np.float32)

    def reset(self, *, seed: Optional[int] = None, options=None):
        if seed is None:  # the constructor's seed serves the first reset only
            seed = self._seed
        self._seed = None
        if seed is not None:
            seed = hydrojet._seed(seed)
        super().reset(seed=seed)  # seeds np_random when a seed is given
        plant_seed = seed if seed is not None else int(self.np_random.integers(0, 2**32 - 1))
        if not self._core.reset(plant_seed):
            raise RuntimeError(f"plant: {self._core.error}")
        return self._core.observation(), self._info(0.0)

    def step(self, action):
        ok, error = self._core.step(np.asarray(action, dtype=float))
        terminated = (not ok) or error > self.abort_angle
        truncated = (not terminated) and self._core.path_time >= self.path.duration - 1e-9
        info = self._info(error)
        if not ok:
            info["plant_error"] = self._core.error
        return self._core.observation(), -error, terminated, truncated, info

    def _info(self, error: float) -> dict:
        s = self._core.sensors  # as plain values: what the controller reads (ModelBasedPolicy)
        sensors = {"t": s.t, "tip_valid": s.tip_valid, "tip_stamp": s.tip_stamp, "tip_rotation": s.tip_rotation,
                   "flow_valid": s.flow_valid, "flow_stamp": s.flow_stamp, "flows": s.flows, "forces": s.forces}
        return {"t": self._core.t, "path_time": self._core.path_time, "error": error, "sensors": sensors}


class ModelBasedPolicy:
    """The project's controller (Algorithm 1 with the modal law, closed loop) as a policy of
    HydroJet-v0: the baseline a learned policy is measured against.

    policy(obs, info) reads the sensors in info (what the controller reads on the rig) and returns
    the controller's command as an action. A new episode (info["path_time"] == 0) restarts it.
    """

    def __init__(self, env: gymnasium.Env, options: Optional[str] = None):
        self.env = env.unwrapped
        if not isinstance(self.env, HydroJetEnv):
            raise ValueError("env: expects a HydroJet-v0 environment")
        self.options = os.fspath(options) if options is not None else self.env.controller_file
        self.controller = None

    def __call__(self, obs, info) -> np.ndarray:
        if self.controller is None or info["path_time"] <= 0.0:
            self.controller = hydrojet.Controller(self.env.scene, self.options, mode="closed")
            self.controller.follow(self.env.path, info["t"], "rest")
            self.controller.start(info["t"])
        sensors = hydrojet.Sensors()
        for key, value in info["sensors"].items():
            setattr(sensors, key, value)
        out = self.controller.update(sensors)
        self.last_output = out
        return self.env.action_from_command(out.valve_command)


if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="hydrojet.gym:HydroJetEnv")
