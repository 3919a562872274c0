"""Solves the HydroJet rod model for a few jet-force combinations with rod_fk and prints a table.

Usage: fk_table.py ROD_FK SCENE.yaml
"""
import json
import math
import subprocess
import sys

# Jet forces q1 q2 q3 [N]; eq. (24) with Table 1's misalignments maps them to the tip-frame force.
JETS = [(0, 0, 0), (0.243, 0, 0), (0, 0.224, 0), (0, 0, 0.244), (0.12, 0.11, 0), (0.243, 0.224, 0.244)]
DA, DB, DG = 0.12, 0.06, -0.08


def jet_force(q1, q2, q3):
    p3 = math.pi / 3
    fx = math.sin(p3 - DB) * q1 + math.sin(DA) * q2 - math.sin(p3 - DG) * q3
    fy = math.cos(p3 - DB) * q1 - math.cos(DA) * q2 + math.cos(p3 - DG) * q3
    return fx, fy


def main():
    rod_fk, scene = sys.argv[1], sys.argv[2]
    batch = "".join("%r %r 0 0 0 0\n" % jet_force(*q) for q in JETS)
    out = subprocess.run([rod_fk, "--scene", scene, "--compliance", "--batch", "-"], input=batch,
                         capture_output=True, text=True)
    if out.returncode == 2:
        sys.exit(out.stderr.strip())
    head = ("jets q1 q2 q3 [N]", "tip x y z [mm]", "bend [deg]", "sigma_c", "eig_min", "solve [us]", "ok")
    print("%-20s | %-26s | %10s | %8s | %8s | %10s | %s" % head)
    for q, line in zip(JETS, out.stdout.splitlines()):
        d = json.loads(line)
        p = [1000 * v for v in d["tip_position"]]
        w, x, y, z = d["tip_quaternion_wxyz"]
        # angle between base z and tip z: the tip z-axis' z-component is 1 - 2(x^2 + y^2)
        bend = math.degrees(math.acos(max(-1.0, min(1.0, 1 - 2 * (x * x + y * y)))))
        print("%-20s | %8.2f %8.2f %8.2f | %10.1f | %8.3f | %8.3f | %10.1f | %s" % (
            " ".join("%.3f" % v for v in q), p[0], p[1], p[2], bend, d["stability_margin"],
            d["stability_eig_min"], d["solve_time_us"], d["converged"]))
    sys.exit(out.returncode)


if __name__ == "__main__":
    main()
