"""hydrojet.solve against rod_fk on the shipped scenes: the same numbers, digit for digit (rod_fk
prints %.17g, which round-trips a double), and bad input raised as ValueError naming the key."""
import glob
import json
import os
import subprocess

import numpy as np
import pytest

import hydrojet
from conftest import config, tool

SCENES = sorted(glob.glob(config("scenes/*.yaml")))


def rod_fk(*args):
    out = subprocess.run([tool("rod_fk"), *args], capture_output=True, text=True, check=False)
    assert out.returncode in (0, 1), out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def input_cases(scene):
    """Zero, and a mixed load within every actuator's box (negative for reversible ones)."""
    lo, hi = scene.input_lower, scene.input_upper
    mixed = np.where(np.arange(scene.actuator_count) % 2 == 0, 0.6 * hi, 0.3 * hi + 0.4 * lo)
    return [np.zeros(scene.actuator_count), mixed]


def assert_same(sol, ref):
    assert sol.converged == ref["converged"]
    np.testing.assert_array_equal(sol.tip_position, ref["tip_position"])
    np.testing.assert_array_equal(sol.tip_quaternion_wxyz, ref["tip_quaternion_wxyz"])
    np.testing.assert_array_equal(sol.compliance, np.array(ref["compliance"]))
    assert sol.stability_margin == ref["stability_margin"]
    assert sol.stability_eig_min == ref["stability_eig_min"]
    np.testing.assert_array_equal(sol.shape, np.array(ref["shape"]))
    if "actuation_jacobian" in ref:
        np.testing.assert_array_equal(sol.actuation_jacobian, np.array(ref["actuation_jacobian"]).reshape(6, -1))


@pytest.mark.parametrize("path", SCENES, ids=os.path.basename)
def test_solve_matches_rod_fk_on_actuator_inputs(path):
    scene = hydrojet.load_scene(path)
    for q in input_cases(scene):
        sol = hydrojet.solve(scene, q, shape_segments=16)
        args = ["--scene", path, "--compliance", "--shape", "16"]
        if scene.actuator_count:
            args += ["--actuators", *[repr(float(x)) for x in q]]
        assert_same(sol, rod_fk(*args))
        # The tip rotation is the quaternion's, orthonormal.
        np.testing.assert_allclose(sol.tip_rotation @ sol.tip_rotation.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("path", SCENES, ids=os.path.basename)
def test_solve_matches_rod_fk_on_a_tip_wrench(path):
    scene = hydrojet.load_scene(path)
    f, m = np.array([0.02, -0.01, 0.005]), np.array([1e-4, 2e-4, 0.0])
    sol = hydrojet.solve(scene, None, force=f, moment=m, shape_segments=8)
    ref = rod_fk("--scene", path, "--force", *[repr(float(x)) for x in f], "--moment", *[repr(float(x)) for x in m], "--compliance", "--shape", "8")
    assert_same(sol, ref)


def test_warm_solver_follows_the_cold_solve():
    scene = hydrojet.load_scene(config("scenes/hydrojet_30deg.yaml"))
    solver = hydrojet.Solver(scene)
    for k in range(5):
        q = scene.input_upper * np.array([0.1 * k, 0.05, 0.2])
        warm, cold = solver.solve(q), hydrojet.solve(scene, q)
        assert warm.converged and cold.converged
        # Two converged solves of the same equilibrium agree to the solver's tolerance, not bitwise.
        np.testing.assert_allclose(warm.tip_position, cold.tip_position, atol=1e-9)


def test_scene_facts():
    scene = hydrojet.load_scene(config("scenes/hydrojet_0deg.yaml"))
    assert scene.actuator_names == ["jet1", "jet2", "jet3"]
    assert scene.actuator_count == 3
    assert np.all(scene.input_lower == 0.0) and np.all(scene.input_upper > 0.0)


def test_bad_input_raises_value_error_naming_the_key(tmp_path):
    text = open(config("scenes/hydrojet_0deg.yaml")).read()
    assert "length: 0.09 " in text
    with pytest.raises(ValueError, match="rod.length"):
        hydrojet.parse_scene(text.replace("length: 0.09 ", "length: -0.09", 1))
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("rod:", "rod:\n  colour: red", 1))
    with pytest.raises(ValueError, match="colour"):
        hydrojet.load_scene(bad)
    with pytest.raises(ValueError, match="scene"):
        hydrojet.load_scene(tmp_path / "missing.yaml")
    scene = hydrojet.load_scene(config("scenes/hydrojet_0deg.yaml"))
    with pytest.raises(ValueError, match="inputs"):
        hydrojet.solve(scene, [0.01, 0.0])
    with pytest.raises(ValueError, match=r"inputs\[1\]"):
        hydrojet.solve(scene, [0.01, float("nan"), 0.0])
    with pytest.raises(ValueError, match="jet1"):
        hydrojet.solve(scene, [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="force"):
        hydrojet.solve(scene, None, force=[float("inf"), 0, 0])
