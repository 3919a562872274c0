"""Experiment sweeps: plants x durations x seeds (x scenes x loop modes), one experiment run each.

    python -m hydrojet.sweep --plants A.yaml,B.yaml --durations 20,60 --seeds 1,2 \\
        [--path FILE] [--start on-path] [--controller FILE] [--ray-address auto|local|ADDRESS]

Prints one JSON line per run (the experiment's fields plus plant, duration, seed, scene), in grid
order, then one summary line. Without --ray-address the runs go to local processes; with it, to Ray
tasks (auto: the running cluster; local: start one here). Every run is deterministic for its seed,
so the same grid gives the same numbers either way. The files are read here and shipped with each
task as text: a cluster's workers need hydrojet installed, not this machine's files.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import socket
import sys
import tempfile
import time
from typing import Dict, List, Optional

import hydrojet

SHIPPED_SCENES = ["scenes/hydrojet_0deg.yaml", "scenes/hydrojet_30deg.yaml"]


def run_task(task: Dict) -> Dict:
    """One experiment run from the texts of its files (written to a private folder: the worker
    may be another machine)."""
    with tempfile.TemporaryDirectory(prefix="hydrojet_sweep_") as d:
        files = {}
        for key in ("scene", "plant", "controller", "path"):
            if task["texts"].get(key) is None:
                files[key] = None
                continue
            files[key] = os.path.join(d, key + os.path.splitext(task["names"][key])[1])
            with open(files[key], "w") as f:
                f.write(task["texts"][key])
        run = hydrojet.run_experiment(files["scene"], files["plant"], files["controller"], seed=task["seed"],
                                      mode=task["mode"], duration=task["duration"], path=files["path"],
                                      start=task["start"])
    run.update(plant=task["names"]["plant"], duration=task["duration_s"], seed=task["seed"],
               scene=task["names"]["scene"], path=task["names"]["path"])
    return run


def _read(path: Optional[str], what: str) -> Optional[str]:
    if path is None:
        return None
    try:
        with open(path) as f:
            return f.read()
    except OSError as e:
        raise ValueError(f"{what}: cannot read {path!r} ({e.strerror})") from None


def _numbers(text: str, what: str, kind=float) -> List:
    try:
        values = [kind(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{what}: expects a comma-separated list of {kind.__name__}s, got {text!r}") from None
    if not values:
        raise ValueError(f"{what}: empty")
    return values


def make_grid(args) -> List[Dict]:
    """The runs, in grid order: plant, duration, seed, scene, mode."""
    plants = [p for p in args.plants.split(",") if p]
    if not plants:
        raise ValueError("--plants: empty")
    seeds = _numbers(args.seeds, "--seeds", int)
    if any(not 0 <= s < 2**32 for s in seeds):
        raise ValueError("--seeds: each must be an integer in [0, 2^32)")
    scenes = [s for s in args.scenes.split(",") if s] if args.scenes else [hydrojet.data_path(s) for s in SHIPPED_SCENES]
    if not scenes:
        raise ValueError("--scenes: empty")
    modes = [m for m in args.modes.split(",") if m]
    if not modes:
        raise ValueError("--modes: empty")
    for m in modes:
        if m not in ("closed", "open"):
            raise ValueError(f"--modes: each must be 'closed' or 'open', got {m!r}")
    if args.start not in ("rest", "on-path"):
        raise ValueError(f"--start: must be 'rest' or 'on-path', got {args.start!r}")
    controller = args.controller or hydrojet.data_path("controller.yaml")
    if args.path:
        duration = hydrojet.load_path(args.path).duration  # the path's own duration sets the run's
        if args.durations:
            print(f"sweep: --durations ignored: the path file sets the duration ({duration:g} s)", file=sys.stderr)
        durations = [0.0]
    else:
        durations = _numbers(args.durations or "20", "--durations")
        if any(not (d > 0) for d in durations):
            raise ValueError("--durations: each must be positive")
    texts = {"controller": _read(controller, "--controller"), "path": _read(args.path, "--path")}
    plant_texts = {p: _read(p, "--plants") for p in plants}
    scene_texts = {s: _read(s, "--scenes") for s in scenes}
    for plant in plants:  # every file loads here (ValueError naming the file's key) before any run starts
        for scene in scenes:
            hydrojet._core._check_run(scene, plant, controller, args.path)
    grid = []
    for plant in plants:
        for d in durations:
            for seed in seeds:
                for scene in scenes:
                    for mode in modes:
                        grid.append({
                            "texts": dict(texts, plant=plant_texts[plant], scene=scene_texts[scene]),
                            "names": {"plant": plant, "scene": scene, "controller": controller, "path": args.path},
                            "seed": seed, "mode": mode, "duration": d, "start": args.start,
                            "duration_s": duration if args.path else d,
                        })
    return grid


def run_local(grid: List[Dict], workers: int):
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
        yield from pool.map(run_task, grid)


def _reachable(address: str, timeout: float = 5.0) -> None:
    """A HOST:PORT address answers within `timeout` seconds (Ray itself retries an unreachable head for
    minutes); auto, local and ray:// addresses are left to Ray."""
    host, sep, port = address.rpartition(":")
    if address in ("auto", "local") or "://" in address or not sep or not port.isdigit():
        return
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise ValueError(f"--ray-address {address}: no Ray head answers there ({e})") from None


def run_ray(grid: List[Dict], address: str, workers: int):
    try:
        import ray
    except ImportError:
        raise ValueError("--ray-address: Ray is not installed (pip install 'hydrojet[ray]')") from None
    _reachable(address)
    try:
        if address == "local":
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    except Exception as e:  # Ray raises ConnectionError, RuntimeError, ... : say which address failed
        raise ValueError(f"--ray-address {address}: Ray did not start or connect ({e})") from None
    try:
        task = ray.remote(num_cpus=1)(run_task)
        refs = [task.remote(t) for t in grid]
        for ref in refs:  # in grid order, each as soon as it and those before it are done
            yield ray.get(ref)
    finally:
        ray.shutdown()


def summarise(runs: List[Dict]) -> List[Dict]:
    """Per plant, duration, scene and mode: the seeds' mean RMS (measured and true) and the aborts."""
    groups: Dict = {}
    for r in runs:
        key = (r["plant"], r["duration"], r["scene"], r["mode"])
        groups.setdefault(key, []).append(r)
    out = []
    for (plant, duration, scene, mode), rs in groups.items():
        out.append({"plant": plant, "duration": duration, "scene": scene, "tilt_deg": rs[0]["tilt_deg"], "mode": mode,
                    "seeds": [r["seed"] for r in rs],
                    "rms_rad_mean": sum(r["rms_rad"] for r in rs) / len(rs),
                    "rms_true_rad_mean": sum(r["rms_true_rad"] for r in rs) / len(rs),
                    "aborted": sum(1 for r in rs if not r["completed"])})
    return out


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m hydrojet.sweep", description=__doc__.split("\n\n")[0])
    p.add_argument("--plants", required=True, help="plant YAML files, comma-separated")
    p.add_argument("--durations", help="spiral durations [s], comma-separated (default 20)")
    p.add_argument("--seeds", default="1", help="seeds, comma-separated (default 1)")
    p.add_argument("--path", help="a path file (t, theta, phi rows) instead of the spiral")
    p.add_argument("--start", default="rest", help="rest (the paper's protocol) or on-path")
    p.add_argument("--controller", help="controller YAML (default: the shipped config/controller.yaml)")
    p.add_argument("--scenes", help="scene YAML files, comma-separated (default: the shipped 0 and 30 degree)")
    p.add_argument("--modes", default="closed,open", help="loop modes, comma-separated (default closed,open)")
    p.add_argument("--ray-address", help="run on Ray: auto (a running cluster), local (start one here), or an address")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="local processes, or the CPUs of a local Ray (default: this machine's cores)")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        if args.workers < 1:
            raise ValueError("--workers: must be at least 1")
        grid = make_grid(args)
    except ValueError as e:
        print(f"sweep: {e}", file=sys.stderr)
        return 2
    t0 = time.monotonic()
    backend = "ray" if args.ray_address else "local"
    try:
        results = run_ray(grid, args.ray_address, args.workers) if args.ray_address else run_local(grid, args.workers)
        runs = []
        for run in results:
            runs.append(run)
            print(json.dumps(run), flush=True)
    except ValueError as e:  # a file a run could not load (named by the core), or Ray missing
        print(f"sweep: {e}", file=sys.stderr)
        return 2
    print(json.dumps({"summary": {"runs": len(runs), "backend": backend, "wall_s": time.monotonic() - t0,
                                  "aborted": sum(1 for r in runs if not r["completed"]),
                                  "groups": summarise(runs)}}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
