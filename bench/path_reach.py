"""Does a path stay where a plant's jets can hold the tip? A quasi-static check, independent of any
controller. It drives the simulated plant (hydrojet.Plant, the truth of a plant file) through a grid
of valve duties, lets each point settle, and keeps the tip directions held with every jet force
within the scene's bounds (max_force: the q_max every law must respect). The grid covers the faces
of the duty box where one jet is off: three jets at 120° reach their lateral force polygon there (a
common flow on every jet adds no lateral force). The held region is taken star-shaped about the
rest direction, as the controller's ReachableSet takes it; for each second of the path the check
prints how far the path (as written, base frame) goes beyond it, at most. Above zero, the path asks
for more force than the jets are allowed there, whatever the law.

The check raises the plant's material damping to at least Kelvin–Voigt 0.05 s so that each point
settles fast: damping does not move an equilibrium, and it only widens what the tip can hold (a
lightly damped rod flutters under the larger follower forces), so what it reports beyond is a lower
bound.

Usage (from the repository, after scripts/setup):
  .venv/bin/python bench/path_reach.py --scene config/scenes/hydrojet_30deg.yaml \
      --plant config/plants/heavy_slow.yaml --duration 20
  .venv/bin/python bench/path_reach.py --scene ... --plant ... --path config/paths/lissajous.csv
Prints one JSON object: per second the largest angle beyond the held region [rad], and its RMS over
the path (a quasi-static floor under any law's true RMS error).
"""
import argparse
import json
import math
import os
import tempfile

import numpy as np
import yaml

import hydrojet

SETTLING_DAMPING = 0.05  # [s] Kelvin–Voigt time of the check's plant, at least


def duty_at_bound(scene, model, jet, upper, period=0.01):
    """The largest duty of one jet (the others off) whose steady force stays within max_force
    (bisection; each valve's force depends on its own duty only)."""
    lo, hi = 0.0, 1.0
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        plant = hydrojet.Plant(scene, model, seed=1)
        duty = np.zeros(scene.actuator_count)
        duty[jet] = mid
        t = 0.0
        for _ in range(60):  # 0.6 s: several valve time constants
            t += period
            plant.command(duty, t)
            plant.advance_to(t)
        lo, hi = (mid, hi) if plant.jet_forces[jet] <= upper[jet] else (lo, mid)
    return lo


def held_directions(scene, plant_file, steps, settle, period=0.01):
    """Tip directions held with one jet off and every jet force within max_force, along a serpentine
    over the other two jets' duties up to their bounds (each point starts from the last one's
    equilibrium); the points not held; and the rest direction (every jet off)."""
    with open(plant_file) as f:
        text = yaml.safe_load(f) or {}
    dynamics = text.setdefault("plant", {}).setdefault("dynamics", {})
    dynamics["kelvin_voigt_time"] = max(float(dynamics.get("kelvin_voigt_time", 0.03)), SETTLING_DAMPING)
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        yaml.safe_dump(text, f)
    try:
        model = hydrojet.load_plant(scene, f.name)
    finally:
        os.unlink(f.name)
    upper = np.asarray(scene.input_upper)
    if scene.actuator_count != 3 or not all(scene.actuator_is_jet):
        raise SystemExit("path_reach: the check is for three jets (the HydroJet's)")
    top = [duty_at_bound(scene, model, i, upper) for i in range(3)]
    rest = np.array(hydrojet.Plant(scene, model, seed=1).tip_rotation)[:, 2].copy()  # starts at rest, jets off
    held, skipped = [], 0
    for off in range(3):
        on = [i for i in range(3) if i != off]
        plant = hydrojet.Plant(scene, model, seed=1)
        t = 0.0
        for row, a in enumerate(np.linspace(0.0, top[on[0]], steps)):
            column = np.linspace(0.0, top[on[1]], steps)
            for b in column if row % 2 == 0 else column[::-1]:
                duty = np.zeros(3)
                duty[on[0]], duty[on[1]] = a, b
                z, moved, waited = None, math.inf, 0.0
                while moved > 1e-3 and waited < settle:  # settled: < 1 mrad over 0.1 s
                    last = z
                    for _ in range(10):
                        t += period
                        plant.command(duty, t)
                        if not plant.advance_to(t):
                            raise SystemExit(f"path_reach: the plant failed: {plant.error}")
                    waited += 10 * period
                    z = np.array(plant.tip_rotation)[:, 2].copy()
                    if last is not None:
                        moved = math.acos(min(1.0, float(z @ last)))
                if moved <= 1e-3 and np.all(np.asarray(plant.jet_forces) <= upper * 1.005):
                    held.append(z)
                else:
                    skipped += 1
    return np.array(held), skipped, rest


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", required=True)
    ap.add_argument("--plant", required=True)
    ap.add_argument("--duration", type=float, help="the spiral of config/controller.yaml over this time [s]")
    ap.add_argument("--path", help="a path file instead of the spiral")
    ap.add_argument("--grid", type=int, default=41, help="duties per jet on each face")
    ap.add_argument("--settle", type=float, default=4.0, help="[s] at most per grid point")
    a = ap.parse_args()
    if (a.duration is None) == (a.path is None):
        raise SystemExit("path_reach: give --duration or --path")
    scene = hydrojet.load_scene(a.scene)
    path = hydrojet.load_path(a.path) if a.path else hydrojet.Controller(scene, duration=a.duration).spiral()
    held, skipped, centre = held_directions(scene, a.plant, a.grid, a.settle)
    if len(held) == 0:
        raise SystemExit("path_reach: no direction held within the bounds")
    # The held region, star-shaped about the rest direction (the jets off) as the controller's
    # ReachableSet: its largest angle from there per azimuth bin. A path direction beyond it by e
    # is e from anything held (to within the bins' width).
    e1 = np.cross(centre, [1.0, 0.0, 0.0] if abs(centre[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(centre, e1)
    polar = lambda d: (np.arccos(np.clip(d @ centre, -1.0, 1.0)), np.arctan2(d @ e2, d @ e1))
    rho, alpha = polar(held)
    bins = 72
    index = ((alpha + np.pi) / (2 * np.pi) * bins).astype(int) % bins
    reach = np.zeros(bins)
    np.maximum.at(reach, index, rho)
    times = np.arange(0.0, path.duration, 0.01)
    rho_p, alpha_p = polar(np.array([path.direction_at(t) for t in times]))
    centres = (np.arange(bins) + 0.5) / bins * 2 * np.pi - np.pi
    edge = np.interp(alpha_p, centres, reach, period=2 * np.pi)
    beyond = np.maximum(0.0, rho_p - edge)
    per_second = [round(float(beyond[(times >= s) & (times < s + 1)].max()), 4)
                  for s in range(int(math.ceil(path.duration)))]
    print(json.dumps({"scene": a.scene, "plant": a.plant, "path": a.path or f"spiral {a.duration:g} s",
                      "held_directions": len(held), "points_not_held": skipped,
                      "largest_held_angle_rad": round(float(reach.max()), 4),
                      "max_beyond_per_second_rad": per_second,
                      "rms_beyond_rad": round(float(np.sqrt(np.mean(beyond ** 2))), 4)}))


if __name__ == "__main__":
    main()
