"""The sweep on local processes and on a local Ray cluster with two workers: the same grid gives the
same runs, field for field (wall time aside), and the runs are the experiment's."""
import json
import subprocess
import sys

import pytest

import hydrojet
from conftest import config

WALL = {"wall_s"}


def sweep(*extra):
    args = [sys.executable, "-m", "hydrojet.sweep", "--plants", f"{config('plant.yaml')},{config('plants/heavy_slow.yaml')}",
            "--durations", "4,6", "--seeds", "1,2", "--modes", "closed", "--workers", "2", *extra]
    out = subprocess.run(args, capture_output=True, text=True, check=False)
    assert out.returncode == 0, out.stderr
    lines = [json.loads(line) for line in out.stdout.strip().splitlines()]
    return lines[:-1], lines[-1]["summary"]


def test_local_and_ray_give_the_same_runs():
    local, local_summary = sweep()
    ray_runs, ray_summary = sweep("--ray-address", "local")
    assert local_summary["backend"] == "local" and ray_summary["backend"] == "ray"
    assert len(local) == len(ray_runs) == 2 * 2 * 2 * 2  # plants x durations x seeds x scenes
    for a, b in zip(local, ray_runs):
        assert {k: v for k, v in a.items() if k not in WALL} == {k: v for k, v in b.items() if k not in WALL}
    assert local_summary["groups"] == ray_summary["groups"]
    # Each run is the experiment's run of its cell.
    first = local[0]
    assert (first["plant"], first["duration"], first["seed"]) == (config("plant.yaml"), 4.0, 1)
    ref = hydrojet.run_experiment(hydrojet.data_path("scenes/hydrojet_0deg.yaml"), config("plant.yaml"), seed=1,
                                  duration=4.0)
    assert first["rms_rad"] == ref["rms_rad"] and first["tilt_deg"] == 0


def test_bad_grid_is_refused_naming_the_flag():
    for args, flag in ((["--plants", "/nonexistent.yaml"], "--plants"),
                       (["--plants", config("plant.yaml"), "--seeds", "one"], "--seeds"),
                       (["--plants", config("plant.yaml"), "--durations", "-5"], "--durations"),
                       (["--plants", config("plant.yaml"), "--start", "later"], "--start"),
                       (["--plants", config("plant.yaml"), "--modes", ","], "--modes"),
                       (["--plants", config("plant.yaml"), "--durations", "2", "--ray-address", "127.0.0.1:1"],
                        "--ray-address")):
        out = subprocess.run([sys.executable, "-m", "hydrojet.sweep", *args], capture_output=True, text=True)
        assert out.returncode == 2 and flag in out.stderr, out.stderr
        assert out.stdout == ""
