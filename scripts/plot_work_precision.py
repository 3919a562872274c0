#!/usr/bin/python3
"""Work-precision plots from the CSV of bench/work_precision.cpp (scripts/work_precision runs it).

    plot_work_precision.py CSV OUTDIR

Writes OUTDIR/work_precision_solve.png (tip error against the median warm-solve time) and
OUTDIR/work_precision_compliance.png (against warm solve + C^b), log-log, one panel per scene and one
line per method, and OUTDIR/work_precision_summary.md: per scene, the fastest configuration of each
method that reaches a tip error <= 1e-6·L/0.09 m.
"""
import csv
import math
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STYLE = {
    "rk4": ("tab:blue", "o", "-"),
    "rk8": ("tab:orange", "s", "-"),
    "dopri5": ("tab:green", "^", "-"),
    "cvode-adams": ("tab:red", "v", "-"),
    "cvode-bdf": ("tab:purple", "D", "-"),
    "cvode-adams+cvodes-sens": ("tab:red", "v", ":"),
    "cvode-bdf+cvodes-sens": ("tab:purple", "D", ":"),
    "rk8+kinsol": ("tab:brown", "s", ":"),
}
LENGTH = {"soft_long": 0.45}


def num(x):
    try:
        v = float(x)
        return v if math.isfinite(v) else None
    except ValueError:
        return None


def load(path):
    rows = list(csv.DictReader(open(path)))
    by_scene = defaultdict(lambda: defaultdict(list))
    for r in rows:
        by_scene[r["scene"]][r["method"]].append(r)
    return rows, by_scene


def plot(by_scene, key, xlabel, out):
    scenes = list(by_scene)
    n = len(scenes)
    cols = min(4, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), squeeze=False)
    for ax, scene in zip(axes.flat, scenes):
        for method, pts in by_scene[scene].items():
            xy = [(num(p[key]), num(p["pos_err_m"])) for p in pts if p["converged"] == "1"]
            xy = [(x, max(y, 1e-16)) for x, y in xy if x is not None and y is not None]
            if not xy:
                continue
            # in the order of the parameter (steps up, tolerance down), as the CSV lists them
            color, marker, ls = STYLE.get(method, ("gray", ".", "-"))
            ax.loglog([p[0] for p in xy], [p[1] for p in xy], ls, color=color, marker=marker, ms=4, lw=1.2,
                      label=method)
        tol = 1e-6 * LENGTH.get(scene, 0.09) / 0.09
        ax.axhline(tol, color="k", lw=0.6, ls="--")
        ax.set_title(scene, fontsize=10)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("tip position error [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="major", lw=0.3)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=min(8, len(labels)), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(out, dpi=110)
    plt.close(fig)


def summary(by_scene, out):
    lines = ["| scene | method | fastest setting with tip error ≤ 1e-6·L/9 cm | error [m] | warm [µs] | "
             "warm + C^b [µs] | RHS/solve | Newton/solve |", "|---|---|---|---|---|---|---|---|"]
    for scene, methods in by_scene.items():
        tol = 1e-6 * LENGTH.get(scene, 0.09) / 0.09
        for method, pts in methods.items():
            ok = [p for p in pts if p["converged"] == "1" and num(p["pos_err_m"]) is not None
                  and num(p["pos_err_m"]) <= tol and num(p["warm_cb_us"]) is not None]
            if not ok:
                lines.append(f"| {scene} | {method} | — (none reached it) | | | | | |")
                continue
            best = min(ok, key=lambda p: num(p["warm_cb_us"]))
            lines.append(f"| {scene} | {method} | {best['param']} | {num(best['pos_err_m']):.1e} | "
                         f"{num(best['warm_us']):.1f} | {num(best['warm_cb_us']):.1f} | "
                         f"{num(best['rhs_per_warm_solve']):.0f} | {num(best['newton_per_warm_solve']):.2f} |")
    open(out, "w").write("\n".join(lines) + "\n")


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    _, by_scene = load(sys.argv[1])
    outdir = sys.argv[2]
    plot(by_scene, "warm_us", "median warm solve [µs]", f"{outdir}/work_precision_solve.png")
    plot(by_scene, "warm_cb_us", "median warm solve + C^b [µs]", f"{outdir}/work_precision_compliance.png")
    summary(by_scene, f"{outdir}/work_precision_summary.md")
    print(f"wrote {outdir}/work_precision_solve.png, work_precision_compliance.png, work_precision_summary.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
