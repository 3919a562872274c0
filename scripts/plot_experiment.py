"""Plots of the §7 experiment on the simulated plant, like the paper's Figs. 9–11.

Reads the CSVs that `experiment` writes (summary.csv, run_<mode>_<tilt>deg_seed<k>.csv) and saves
  experiment_path_<tilt>deg.png   3-D tip path (worst 10 % of errors in red), desired vs measured
                                  pitch and yaw, error norm over time, for open and closed loop
  experiment_boxplot.png          error distribution per configuration over all seeds (Fig. 11)
Usage: plot_experiment.py CSV_DIR OUT_DIR [SEED]
"""
import csv
import glob
import re
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def load(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else None


def pitch_yaw(x, y, z):
    # tip z-axis d = Ry(pitch) Rx(yaw) e_z (as in task_space.h)
    return np.arctan2(x, z), np.arcsin(np.clip(-y, -1, 1))


def path_figure(csv_dir, out_dir, tilt, seed):
    fig = plt.figure(figsize=(13, 8.5))
    for col, mode in enumerate(("open", "closed")):
        path = os.path.join(csv_dir, "run_%s_%ddeg_seed%d.csv" % (mode, tilt, seed))
        if not os.path.exists(path):
            continue
        d = load(path)
        if d is None:
            continue
        t, err = d["t"], d["err_geodesic"]
        thr = np.percentile(err, 90)
        bad = err > thr
        ax = fig.add_subplot(4, 2, 1 + col, projection="3d")
        ax.plot(1000 * d["tip_x"], 1000 * d["tip_y"], 1000 * d["tip_z"], lw=0.6, color="tab:blue")
        ax.scatter(1000 * d["tip_x"][bad], 1000 * d["tip_y"][bad], 1000 * d["tip_z"][bad], s=2, color="red")
        ax.set_title("%s loop, %d° base: tip path [mm] (red: error > 90th pct)" % (mode, tilt), fontsize=9)
        ax.invert_zaxis()
        pd_, yd = pitch_yaw(d["des_x"], d["des_y"], d["des_z"])
        pm, ym = pitch_yaw(d["meas_x"], d["meas_y"], d["meas_z"])
        for row, (des, mea, name) in enumerate(((pd_, pm, "pitch"), (yd, ym, "yaw"))):
            ax = fig.add_subplot(4, 2, 3 + 2 * row + col)
            ax.plot(t, des, color="black", lw=1.0, label="desired")
            ax.plot(t, mea, color="tab:orange", lw=0.6, label="measured")
            ax.set_ylabel(name + " [rad]")
            if row == 0:
                ax.legend(loc="upper left", fontsize=7)
        ax = fig.add_subplot(4, 2, 7 + col)
        ax.plot(t, err, lw=0.5, color="tab:blue")
        ax.axhline(thr, ls="--", color="gray", lw=0.8, label="90th percentile %.3f rad" % thr)
        ax.axhline(0.5, ls=":", color="red", lw=0.8, label="abort 0.5 rad")
        ax.set_ylabel("error [rad]")
        ax.set_xlabel("t [s]")
        ax.set_ylim(0, max(0.1, min(0.6, 1.2 * err.max())))
        ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    out = os.path.join(out_dir, "experiment_path_%ddeg.png" % tilt)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


def tilts_of(csv_dir):
    """The base tilts [deg] the runs were made at (0 and 30, or the one scene's)."""
    found = set()
    for p in glob.glob(os.path.join(csv_dir, "run_*_*deg_seed*.csv")):
        m = re.search(r"_(-?\d+)deg_seed", os.path.basename(p))
        if m:
            found.add(int(m.group(1)))
    return sorted(found)


def box_figure(csv_dir, out_dir):
    data, labels = [], []
    for tilt in tilts_of(csv_dir):
        for mode in ("open", "closed"):
            errs = []
            for p in sorted(glob.glob(os.path.join(csv_dir, "run_%s_%ddeg_seed*.csv" % (mode, tilt)))):
                d = load(p)
                if d is not None:
                    errs.append(d["err_geodesic"])
            if errs:
                data.append(np.concatenate(errs))
                labels.append("%s\n%d°" % (mode, tilt))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.boxplot(data, labels=labels, showfliers=False)
    ax.set_ylabel("geodesic tip-direction error [rad]")
    ax.set_title("error over all seeds (simulated plant), cf. paper Fig. 11", fontsize=9)
    fig.tight_layout()
    out = os.path.join(out_dir, "experiment_boxplot.png")
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


def main():
    csv_dir, out_dir = sys.argv[1], sys.argv[2]
    seed = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    os.makedirs(out_dir, exist_ok=True)
    for tilt in tilts_of(csv_dir):
        print("wrote", path_figure(csv_dir, out_dir, tilt, seed))
    print("wrote", box_figure(csv_dir, out_dir))


if __name__ == "__main__":
    main()
