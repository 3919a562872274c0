"""The closed loop written by hand in Python (Controller, Plant) against the experiment tool's own run
of the same plant, path and seed: the same RMS, as both run the same deterministic loop."""
import json
import math
import subprocess

import numpy as np
import pytest

import hydrojet
from conftest import config, tool


def experiment(scene, duration, start, out, path=None):
    args = [tool("experiment"), "--scene", scene, "--plant", config("plant.yaml"), "--controller",
            config("controller.yaml"), "--seeds", "1", "--threads", "1", "--start", start, "--out", str(out)]
    args += ["--path", path] if path else ["--duration", str(duration)]
    out = subprocess.run(args, capture_output=True, text=True, check=True)
    runs = json.loads(out.stdout.strip().splitlines()[-1])["runs"]
    return next(r for r in runs if r["mode"] == "closed")


def hand_loop(scene_file, duration, start, path_file=None, seed=1, settle=1.0):
    """The experiment's loop (sim::run_path) in Python: at rest for `settle`, then the path."""
    scene = hydrojet.load_scene(scene_file)
    controller = hydrojet.Controller(scene, duration=duration)
    plant = hydrojet.Plant(scene, seed=seed)
    path = hydrojet.load_path(path_file) if path_file else controller.spiral()
    dt = controller.control_period
    settle_steps = round(settle / dt)
    bound = (math.pi / 0.3 + 10.0 + 1.0) if start == "on-path" else 0.0  # generous: the controller bounds it
    errors, path_start = [], None
    for k in range(settle_steps + round((bound + path.duration) / dt) + 1):
        t = k * dt
        assert plant.advance_to(t), plant.error
        if k == settle_steps:
            controller.follow(path, t, start)
            controller.start(t)
        out = controller.update(plant.sample(t))
        plant.command(out.valve_command, t)
        if k < settle_steps:
            continue
        assert out.state != "aborted", out.reason
        assert not out.path_failure
        if out.approaching:
            continue
        if path_start is None:
            path_start = t
        errors.append(out.error_geodesic)
        if out.state == "finished":
            break
    return math.sqrt(np.mean(np.square(errors))), out.state


@pytest.mark.parametrize("scene,start,path", [
    ("scenes/hydrojet_0deg.yaml", "rest", None),
    ("scenes/hydrojet_30deg.yaml", "on-path", None),
    ("scenes/hydrojet_0deg.yaml", "on-path", "paths/lissajous.csv"),
])
def test_hand_written_loop_reproduces_experiment(scene, start, path, tmp_path):
    duration = 10.0
    rms, state = hand_loop(config(scene), duration, start, config(path) if path else None)
    ref = experiment(config(scene), duration, start, tmp_path, config(path) if path else None)
    assert state == "finished" and ref["completed"]
    assert rms == pytest.approx(ref["rms_rad"], rel=1e-12, abs=0)
    # And run_experiment (the sweep's unit of work) is the experiment's run, field for field.
    run = hydrojet.run_experiment(config(scene), duration=duration, start=start, path=config(path) if path else None)
    for key in ("rms_rad", "rms_true_rad", "water_ml_per_min", "approach_time_s", "completed", "tilt_deg"):
        assert run[key] == pytest.approx(ref[key], rel=1e-12), key


def test_a_controller_file_with_a_moved_key_is_read_with_a_warning(tmp_path):
    """A controller file from before the option groups: gains/kp is read as pd/kp, with a FutureWarning
    naming both; given at both places it is refused, naming the old one."""
    scene = hydrojet.load_scene(config("scenes/hydrojet_0deg.yaml"))
    old = tmp_path / "old.yaml"
    old.write_text("gains: {kp: 2.5}\n")
    with pytest.warns(FutureWarning, match=r"gains/kp: deprecated, read as pd/kp"):
        hydrojet.Controller(scene, old)
    old.write_text("gains: {kp: 2.5}\npd: {kp: 3.0}\n")
    with pytest.raises(ValueError, match=r"gains/kp: moved to pd/kp"):
        hydrojet.Controller(scene, old)


def test_run_experiment_carries_the_experiments_contact_figures(tmp_path):
    """On the plant with a wall, run_experiment's contact fields are the experiment tool's."""
    args = [tool("experiment"), "--scene", config("scenes/hydrojet_0deg.yaml"), "--plant", config("plants/wall.yaml"),
            "--controller", config("controller.yaml"), "--seeds", "1", "--threads", "1", "--start", "on-path",
            "--duration", "20", "--out", str(tmp_path)]
    out = subprocess.run(args, capture_output=True, text=True, check=True)
    ref = next(r for r in json.loads(out.stdout.strip().splitlines()[-1])["runs"] if r["mode"] == "closed")
    run = hydrojet.run_experiment(config("scenes/hydrojet_0deg.yaml"), plant=config("plants/wall.yaml"), duration=20.0,
                                  start="on-path")
    assert ref["contact_onsets"] >= 1 and ref["max_contact_force_n"] > 0.02  # the spiral meets the wall
    for key in ("contact_onsets", "detection_delay_s", "missed_contact_s", "false_contact_s", "max_contact_force_n",
                "max_contact_force_after_detection_n", "external_force_rms_error_n", "min_clearance_m"):
        if ref[key] is None:
            assert run[key] is None, key
        else:
            assert run[key] == pytest.approx(ref[key], rel=1e-9, abs=1e-12), key
