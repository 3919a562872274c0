"""hydrojet's simulated plant side by side with PyElastica on the same rod and capsule.

Both simulate the HydroJet's bellows as a straight clamped Cosserat rod without gravity or damping:
L = 0.09 m, EI = 6.01e-4 N m^2 (both axes), GJ = 2.23e-4 N m^2, rho*A = 1.2e-3 kg/m (the rod's mass is 1.4 % of
the tip's), and the capsule at the tip: m_t = 3 x 0.00258 kg (water-filled), inertia
(8e-8, 8e-8, 6e-8) kg m^2. Each side is excited, released, and its tip swings freely for 3 s; the
first bending frequency (upward zero crossings of the lateral tip displacement about its mean,
sampled every 1 ms) is compared with the Rayleigh quotient of the static tip-load shape,
  omega^2 = (3 EI / L^3) / (m_t + 33/140 rho*A*L + J_t * 9 / (4 L^2)),
whose last term (the capsule's rotary inertia, -0.14 % on f) the point-mass formula leaves out.
  hydrojet: hydrojet.Plant (Till's BDF-alpha rod, 21 nodes) on a temporary scene and plant file with
    no mismatch, kelvin_voigt_time 0, exact sensors; jet 1 at duty 0.15 for 0.3 s, then all valves
    shut (a 5 mm swing; at duty 0.5 the swing is 49 mm and f rises by 0.8 %: geometric nonlinearity).
    Scene gravity [0, 0, 0] makes the plant's gravity 0 (config::nominal_plant takes its norm).
  PyElastica 1.0.0 (a peer, not a dependency; runs in its own venv via --peer elastica): CosseratRod
    of radius 3 mm (E, G chosen so E*I and G*J match exactly), OneEndFixedBC, tip mass on the last
    node and tip inertia on the last element, PositionVerlet at dt = 0.5 dl sqrt(rho / max(E, G))
    (the rule PyElastica's maintainers give for its explicit step), rounded down to divide 1 ms; a lateral tip
    force for half a period sets the same amplitude as hydrojet's, then it is released.
    Its discrete rod is not the closed form's: OneEndFixedBC holds the first element straight, so the
    rod acts as clamped at dl/2 (f higher by about 1.5 dl / (2 L)), and the section shears
    (alpha_c G A = 48 N: f lower by 0.23 %); "expected error" is the closed form of that rod.
Wall time per simulated second: hydrojet's advance_to (median of 5 runs); PyElastica's stepping
loop after a warm-up run has compiled numba. Both pinned to one core.

Reproduce (from the repository root; .venv is scripts/setup's):
  /usr/bin/python3 -m venv .venv-elastica
  .venv-elastica/bin/pip install pyelastica==1.0.0 matplotlib
  .venv/bin/python bench/compare_pyelastica.py [--elastica-python .venv-elastica/bin/python]
Prints one JSON object; the markdown table goes to stderr.
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

L, EI, GJ = 0.09, 6.01e-4, 2.23e-4
RHO_A = 1.2e-3                       # [kg/m] rod mass 1.08e-4 kg, 1.4 % of m_t
M_TIP = 3 * 0.00258                  # scene tip.mass x plant tip_mass_scale
J_TIP = (8e-8, 8e-8, 6e-8)           # plant default tip_inertia
RADIUS = 3e-3                        # PyElastica's solid section (the bellows is 8/6 mm)
SAMPLE, WINDOW, SETTLE = 1e-3, 3.0, 0.1  # sampling, free swing measured, skipped after release [s]


def closed_form_hz(tip_inertia=J_TIP[0], length=L, shear_stiffness=math.inf):
    """Rayleigh quotient of the static tip-load shape. A shorter free length or a finite shear stiffness
    (alpha G A) describe PyElastica's discrete rod, for the error it is expected to show."""
    m = M_TIP + 33.0 / 140.0 * RHO_A * length + tip_inertia * 9.0 / (4.0 * length**2)
    k = 1.0 / (length**3 / (3.0 * EI) + length / shear_stiffness)
    return math.sqrt(k / m) / (2.0 * math.pi)


def first_mode_hz(xy):
    """Frequency [Hz] and amplitude [m] of tip samples (n, 2) at SAMPLE spacing: the displacement along
    the swing's principal direction, about its mean; upward zero crossings, linearly interpolated."""
    xy = np.asarray(xy) - np.mean(xy, axis=0)
    y = xy @ np.linalg.svd(xy, full_matrices=False)[2][0]
    i = np.nonzero((y[:-1] < 0.0) & (y[1:] >= 0.0))[0]
    crossings = (i - y[i] / (y[i + 1] - y[i])) * SAMPLE
    return (len(crossings) - 1) / (crossings[-1] - crossings[0]), float(np.max(np.abs(y)))


def row(side, setup, dt, hz, amplitude, wall):
    f0 = closed_form_hz()
    return {"side": side, "setup": setup, "dt_s": dt, "frequency_hz": hz, "closed_form_hz": f0,
            "error_pct": 100.0 * (hz / f0 - 1.0), "amplitude_m": amplitude, "wall_s_per_sim_s": wall}


# --- hydrojet: the plant in-process ---------------------------------------------------------------
SCENE = f"""rod:
  length: {L}
  bending_stiffness: [{EI}, {EI}]
  torsional_stiffness: {GJ}
  precurvature: [0.0, 0.0, 0.0]
  linear_density: {RHO_A}
tip:
  mass: 0.00258
gravity: [0.0, 0.0, 0.0]            # zero: the plant's gravity is this vector's norm
jets:                               # as config/scenes/hydrojet_0deg.yaml (they only excite the rod)
  misalignment: [0.12, 0.06, -0.08]
  max_force: [0.243, 0.224, 0.244]
  inlet_area: 1.13e-6
  outlet_area: 3.84e-7
  water_density: 998.0
"""
PLANT = """plant:
  mismatch: {{precurvature_offset: [0, 0, 0], bending_stiffness_scale: 1.0, torsional_stiffness_scale: 1.0,
             misalignment_offset: [0, 0, 0], tip_mass_scale: 3.0, base_tilt_offset: 0.0}}
  dynamics: {{kelvin_voigt_time: 0.0, tip_inertia: [{}, {}, {}], internal_dt: {}}}
  sensor_noise: false
"""


def hydrojet_run(hydrojet, scene, plant_file, duty, duration, push=0.3):
    """One excite-and-release run: tip samples of the free swing and the wall time in advance_to."""
    plant, tips, wall = hydrojet.Plant(scene, plant_file, seed=1), [], 0.0
    for k in range(1, int(round((push + SETTLE + duration) / SAMPLE)) + 1):
        t = k * SAMPLE
        plant.command(np.array([duty, 0.0, 0.0]) if t <= push + 1e-9 else np.zeros(3), t)
        t0 = time.perf_counter()
        if not plant.advance_to(t):
            raise RuntimeError(f"hydrojet: advance_to({t}) failed: {plant.error}")
        wall += time.perf_counter() - t0
        if t > push + SETTLE + 1e-9:
            tips.append(plant.tip_position[:2].copy())
    return tips, wall / t


def hydrojet_side(internal_dt, duty, duration, repeats):
    import hydrojet
    with tempfile.TemporaryDirectory() as tmp:
        scene_file, plant_file = os.path.join(tmp, "scene.yaml"), os.path.join(tmp, "plant.yaml")
        with open(scene_file, "w") as f:
            f.write(SCENE)
        with open(plant_file, "w") as f:
            f.write(PLANT.format(*J_TIP, internal_dt))
        scene = hydrojet.load_scene(scene_file)
        runs = [hydrojet_run(hydrojet, scene, plant_file, duty, duration) for _ in range(repeats)]
    hz, amplitude = first_mode_hz(runs[0][0])
    return row("hydrojet", "21 nodes", internal_dt, hz, amplitude, statistics.median(w for _, w in runs))


# --- PyElastica: this file under --peer elastica, in the peer's venv ------------------------------
def elastica_side(n_elem, amplitude, duration):
    import elastica as ea

    area, inertia = math.pi * RADIUS**2, math.pi * RADIUS**4 / 4.0
    density, youngs, shear = RHO_A / area, EI / inertia, GJ / (2.0 * inertia)  # J = 2 I
    dl = L / n_elem
    dt_max = dl * math.sqrt(density / max(youngs, shear))
    per_sample = math.ceil(SAMPLE / (0.5 * dt_max))   # dt <= 0.5 dt_max, dividing the sample period
    dt = SAMPLE / per_sample
    omega = 2.0 * math.pi * closed_form_hz()
    push = math.pi / omega                            # half a period: released at rest, swing = 2 x static
    force = 0.5 * amplitude * 3.0 * EI / L**3

    class TipPush(ea.NoForces):
        def apply_forces(self, system, time=0.0):
            if time < push:
                system.external_forces[0, -1] += force

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing):
        pass

    def build():
        sim = Sim()
        rod = ea.CosseratRod.straight_rod(n_elem, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]),
                                          L, RADIUS, density, youngs_modulus=youngs, shear_modulus=shear)
        rod.mass[-1] += M_TIP                         # the capsule: mass on the last node,
        rod.mass_second_moment_of_inertia[..., -1] += np.diag(J_TIP)   # inertia on the last element
        rod.inv_mass_second_moment_of_inertia[..., -1] = np.linalg.inv(rod.mass_second_moment_of_inertia[..., -1])
        sim.append(rod)
        sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
        sim.add_forcing_to(rod).using(TipPush)
        sim.finalize()
        return sim, rod

    def run(samples):
        sim, rod = build()
        stepper, t, tips = ea.PositionVerlet(), np.float64(0.0), []
        t0 = time.perf_counter()
        for k in range(1, samples + 1):
            for _ in range(per_sample):
                t = stepper.step(sim, t, dt)
            if k * SAMPLE > push + SETTLE:
                tips.append(rod.position_collection[:2, -1].copy())
        wall = time.perf_counter() - t0
        if not np.all(np.isfinite(rod.position_collection)):
            raise RuntimeError(f"PyElastica: NaN at n_elem {n_elem}, dt {dt:g}")
        return tips, wall / (samples * SAMPLE)

    run(20)                                           # warm-up: numba compiles here
    tips, wall = run(int(round((push + SETTLE + duration) / SAMPLE)))
    hz, swing = first_mode_hz(tips)
    out = row("PyElastica", f"n_elem {n_elem}", dt, hz, swing, wall)
    out["dt_over_rule"] = dt / dt_max
    # OneEndFixedBC holds element 0's director and the first curvature sits at node 1: the rod acts as
    # clamped at dl/2 (free length L - dl/2); and its section shears (alpha_c = 27/28). That rod's f1:
    expected = closed_form_hz(length=L - 0.5 * dl, shear_stiffness=27.0 / 28.0 * shear * area)
    out["expected_error_pct"] = 100.0 * (expected / closed_form_hz() - 1.0)
    return out


def markdown(result):
    lines = ["| side | discretisation | dt [s] | f1 [Hz] | error vs closed form [%] | expected error [%] "
             "| tip swing [mm] | wall s per simulated s |", "|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        expected = f"{r['expected_error_pct']:+.2f}" if "expected_error_pct" in r else "0.00"
        lines.append(f"| {r['side']} | {r['setup']} | {r['dt_s']:.3g} | {r['frequency_hz']:.4f} | "
                     f"{r['error_pct']:+.3f} | {expected} | {1e3 * r['amplitude_m']:.1f} | "
                     f"{r['wall_s_per_sim_s']:.3g} |")
    return "\n".join(lines) + f"\n\nClosed form f1 = {result['closed_form_hz']:.4f} Hz " \
        f"({result['closed_form_point_mass_hz']:.4f} Hz without the capsule's rotary inertia).\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--elastica-python", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..",
                                                               ".venv-elastica", "bin", "python"))
    ap.add_argument("--n-elem", type=int, nargs="+", default=[20, 50])
    ap.add_argument("--duty", type=float, default=0.15, help="jet 1's duty while exciting (0.15: ~5 mm swing)")
    ap.add_argument("--repeats", type=int, default=5, help="hydrojet runs timed (median)")
    ap.add_argument("--duration", type=float, default=WINDOW, help="free swing measured [s]")
    ap.add_argument("--peer", choices=["elastica"], help=argparse.SUPPRESS)
    ap.add_argument("--amplitude", type=float, default=5e-3, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core, both sides
    if a.peer:
        print(json.dumps(elastica_side(a.n_elem[0], a.amplitude, a.duration)))
        return 0
    if not os.path.exists(a.elastica_python):
        raise SystemExit(f"no {a.elastica_python}: make the peer's venv (see this file's docstring)")
    rows = [hydrojet_side(dt, a.duty, a.duration, a.repeats) for dt in (0.0005, 0.002)]
    for n in a.n_elem:  # one peer process at a time, at hydrojet's swing
        out = subprocess.run([a.elastica_python, os.path.abspath(__file__), "--peer", "elastica", "--n-elem", str(n),
                              "--amplitude", repr(rows[0]["amplitude_m"]), "--duration", repr(a.duration)],
                             capture_output=True, text=True)
        if out.returncode != 0:
            sys.stderr.write(out.stderr)
            raise SystemExit(f"PyElastica peer (n_elem {n}) failed with exit code {out.returncode}")
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    result = {"closed_form_hz": closed_form_hz(), "closed_form_point_mass_hz": closed_form_hz(0.0),
              "rod": {"length_m": L, "EI_Nm2": EI, "GJ_Nm2": GJ, "linear_density_kg_per_m": RHO_A,
                      "tip_mass_kg": M_TIP, "tip_inertia_kgm2": J_TIP, "elastica_radius_m": RADIUS,
                      "gravity": 0.0, "damping": 0.0}, "rows": rows}
    print(json.dumps(result, indent=1))
    sys.stderr.write(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
