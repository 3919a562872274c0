#!/usr/bin/python3
"""Heat maps of the stability measure over the HydroJet actuation space (paper Figs. 12–13).

    plot_stability_map.py OUT.png TITLE CSV

CSV from bench/stability_map.cpp (q1,q2,q3,fx,fy,converged,sigma_c,eig_min,...). Panels: the
smallest σ_c over q3 on the (q1, q2) grid; σ_c over the resulting tip force (f_x, f_y); the
smallest eigenvalue of S over q3 on the (q1, q2) grid (> 0: elastically stable).
"""
import csv
import math
import sys
from collections import defaultdict

import matplotlib
import matplotlib.colors

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main():
    if len(sys.argv) != 4:
        print(__doc__)
        return 2
    out, title, path = sys.argv[1:]
    rows = [r for r in csv.DictReader(open(path))]
    q1s = sorted({float(r["q1"]) for r in rows})
    q2s = sorted({float(r["q2"]) for r in rows})
    sig = defaultdict(lambda: math.inf)
    eig = defaultdict(lambda: math.inf)
    fx, fy, s_all = [], [], []
    failures = 0
    for r in rows:
        k = (float(r["q1"]), float(r["q2"]))
        s, e = float(r["sigma_c"]), float(r["eig_min"])
        if r["converged"] != "1" or not math.isfinite(s):
            failures += 1
            continue
        sig[k] = min(sig[k], s)
        eig[k] = min(eig[k], e)
        fx.append(float(r["fx"]))
        fy.append(float(r["fy"]))
        s_all.append(s)
    S = np.array([[sig[(a, b)] for a in q1s] for b in q2s])
    E = np.array([[eig[(a, b)] for a in q1s] for b in q2s])
    S[~np.isfinite(S)] = np.nan
    E[~np.isfinite(E)] = np.nan
    extent = (q1s[0], q1s[-1], q2s[0], q2s[-1])
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.4))
    im = ax[0].imshow(S, origin="lower", extent=extent, aspect="auto", cmap="viridis")
    ax[0].set_title("min over q3 of σ_c [N/m]")
    ax[0].set_xlabel("q1 [N]")
    ax[0].set_ylabel("q2 [N]")
    fig.colorbar(im, ax=ax[0])
    sc = ax[1].scatter(fx, fy, c=s_all, s=6, cmap="viridis")
    ax[1].set_title("σ_c over the tip force [N/m]")
    ax[1].set_xlabel("f_x [N]")
    ax[1].set_ylabel("f_y [N]")
    ax[1].set_aspect("equal")
    fig.colorbar(sc, ax=ax[1])
    norm = None
    if np.nanmin(E) <= 0.0:  # unstable points: a symmetric log scale keeps the sign visible
        norm = matplotlib.colors.SymLogNorm(linthresh=1.0, vmin=np.nanmin(E), vmax=np.nanmax(E))
    im = ax[2].imshow(E, origin="lower", extent=extent, aspect="auto", cmap="coolwarm_r" if norm else "magma",
                      norm=norm)
    ax[2].set_title("min over q3 of min Re λ(S) [N/m] (> 0: stable)")
    ax[2].set_xlabel("q1 [N]")
    ax[2].set_ylabel("q2 [N]")
    fig.colorbar(im, ax=ax[2])
    unstable = sum(1 for r in rows if r["converged"] == "1" and float(r["eig_min"]) <= 0.0)
    fig.suptitle(f"{title}: {len(rows)} jet-force combinations, {failures} not converged, {unstable} with "
                 f"min eigenvalue ≤ 0; min σ_c = {np.nanmin(S):.4g} N/m, min eigenvalue = {np.nanmin(E):.4g} N/m")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
