"""hydrojet: tip follower actuated continuum robots (the HydroJet) from Python.

The ROS-free core of hydrojet_control: the rod solver (a static solve with its compliance in
microseconds), the paper's controller and the modal law, and the simulated plant. numpy in and out;
units SI, frames as in the scene files. Bad input raises ValueError naming the key or argument.

    import hydrojet
    scene = hydrojet.load_scene(hydrojet.data_path("scenes/hydrojet_0deg.yaml"))
    sol = hydrojet.solve(scene, [0.01, 0.0, 0.0])
    sol.tip_position, sol.compliance, sol.stability_margin
"""
from __future__ import annotations

import dataclasses
import os
from typing import Optional, Sequence

import numpy as np

from . import _core
from ._core import ControllerOutput, Path, PlantModel, Scene, Sensors, parse_scene

__all__ = [
    "Scene", "Solution", "Solver", "Controller", "Plant", "PlantModel", "Path", "Sensors", "ControllerOutput",
    "load_scene", "parse_scene", "load_plant", "solve", "load_path", "run_experiment", "data_path",
]

_HERE = os.path.dirname(os.path.abspath(__file__))


def data_path(name: str = "") -> str:
    """A shipped configuration file (scenes/, plants/, paths/, controller.yaml, plant.yaml).

    Installed: the copy inside the package; in the source tree: config/.
    """
    for root in (os.path.join(_HERE, "config"), os.path.join(_HERE, "..", "..", "config")):
        if os.path.isdir(root):
            path = os.path.normpath(os.path.join(root, name))
            if name and not os.path.exists(path):
                raise ValueError(f"data_path: no shipped file {name!r} (in {os.path.normpath(root)})")
            return path
    raise ValueError("data_path: the package's config folder is missing")


def load_path(file: str | os.PathLike) -> Path:
    """A path file (t, theta, phi rows; CSV or YAML), as follow_path and experiment --path read it.

    Raises ValueError naming the row and column.
    """
    return _core.load_path(os.fspath(file))


def _seed(seed) -> int:
    """A plant's seed: an integer in [0, 2^32)."""
    if isinstance(seed, bool) or int(seed) != seed or not 0 <= int(seed) < 2**32:
        raise ValueError(f"seed: must be an integer in [0, 2^32), got {seed!r}")
    return int(seed)


def load_plant(scene: Scene, path: str | os.PathLike | None = None) -> PlantModel:
    """The plant model of a scene under a plant YAML file (default: the shipped config/plant.yaml).

    Raises ValueError naming the key.
    """
    return _core.load_plant(scene, os.fspath(path) if path is not None else data_path("plant.yaml"))


def load_scene(path: str | os.PathLike) -> Scene:
    """Reads a scene YAML file (the same files as rod_fk, experiment and the nodes).

    Raises ValueError naming the key (``rod.length: must be positive``) or the file.
    """
    return _core.load_scene(os.fspath(path))


@dataclasses.dataclass(frozen=True)
class Solution:
    """One static solve, the numbers rod_fk prints (``--compliance --shape K``).

    compliance (6, 6): C^b, tip body twist (v, w) per tip body wrench (f, m).
    actuation_jacobian (6, N): J_q, tip body twist per unit input.
    shape (K + 1, 3): backbone points from base to tip [m], base frame.
    Those four and the stability fields are None when the solve did not converge.
    """

    converged: bool
    message: str
    warning: str
    iterations: int
    residual: float
    fold_crossings: int
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    tip_quaternion_wxyz: np.ndarray
    compliance: Optional[np.ndarray]
    actuation_jacobian: Optional[np.ndarray]
    stability_margin: Optional[float]
    stability_eig_min: Optional[float]
    shape: Optional[np.ndarray]


def _vector(v, n: int, name: str) -> np.ndarray:
    a = np.asarray(v if v is not None else np.zeros(n), dtype=float)
    if a.shape != (n,):
        raise ValueError(f"{name}: expects shape ({n},), got {a.shape}")
    return a


def _solution(d: dict) -> Solution:
    return Solution(**d)


def solve(scene: Scene, inputs: Sequence[float] | np.ndarray | None = None, force=None, moment=None,
          shape_segments: int = 32) -> Solution:
    """The equilibrium at actuator inputs [N] (scene order; None: all zero) and an extra tip wrench
    (tip frame; None: zero).

    Cold-started, as one rod_fk call: the same numbers. For many solves along a path, Solver keeps
    the warm start. inputs outside an actuator's [min_force, max_force] raise ValueError.
    """
    return Solver(scene, _cold=True).solve(inputs, force, moment, shape_segments)


class Solver:
    """Repeated solves of one scene, each warm-started from the last (rod_fk --batch)."""

    def __init__(self, scene: Scene, _cold: bool = False):
        if not isinstance(scene, Scene):
            raise ValueError("scene: expects a hydrojet.Scene (hydrojet.load_scene)")
        self.scene = scene
        self._warm = None if _cold else _core._WarmSolver(scene)

    def solve(self, inputs=None, force=None, moment=None, shape_segments: int = 32) -> Solution:
        n = self.scene.actuator_count
        q = _vector(inputs, n, "inputs")
        f, m = _vector(force, 3, "force"), _vector(moment, 3, "moment")
        if isinstance(shape_segments, bool) or int(shape_segments) != shape_segments:
            raise ValueError("shape_segments: must be an integer")
        if self._warm is None:
            return _solution(_core._solve(self.scene, q, f, m, int(shape_segments)))
        return _solution(self._warm.solve(q, f, m, int(shape_segments)))


class Controller(_core._Controller):
    """The project's controller (Algorithm 1 and the modal law) of a scene.

    options: a controller YAML file (config/controller.yaml's keys; default the shipped one);
    mode: 'closed' or 'open' (default: the file's); duration: the spiral's [s] (default: the file's).
    Drive it with follow(path, t, start) and start(t), then update(sensors) once per control_period.
    Not thread-safe: one thread per Controller (as per Plant and Solver).
    """

    def __init__(self, scene: Scene, options: str | os.PathLike | None = None, mode: str | None = None,
                 duration: float | None = None):
        super().__init__(scene, os.fspath(options) if options is not None else data_path("controller.yaml"),
                         mode, duration)


class Plant(_core._Plant):
    """The simulated robot (dynamic Cosserat rod, valves and flow loop, tracker) of a scene.

    plant: a plant YAML file (config/plant.yaml's keys; default the shipped one), or a PlantModel
    already loaded (load_plant: many seeds of one plant need not parse it again); seed: its noise.
    advance_to(t), then sample(t) for the sensors and command(valves, t).
    """

    def __init__(self, scene: Scene, plant: str | os.PathLike | PlantModel | None = None, seed: int = 1):
        if not isinstance(plant, PlantModel):
            plant = _core.load_plant(scene, os.fspath(plant) if plant is not None else data_path("plant.yaml"))
        super().__init__(plant, _seed(seed))


def run_experiment(scene: str | os.PathLike, plant: str | os.PathLike | None = None,
                   controller: str | os.PathLike | None = None, seed: int = 1, mode: str = "closed",
                   duration: float = 0.0, path: str | os.PathLike | None = None, start: str = "rest") -> dict:
    """One run of the experiment tool: its JSON fields (rms_rad, rms_true_rad, water_ml_per_min, ...).

    duration: the spiral's [s] (0: the controller file's); path: a path file instead of the spiral.
    """
    return _core._run_experiment(
        os.fspath(scene), os.fspath(plant) if plant is not None else data_path("plant.yaml"),
        os.fspath(controller) if controller is not None else data_path("controller.yaml"),
        _seed(seed), mode, float(duration), os.fspath(path) if path is not None else None, start)
