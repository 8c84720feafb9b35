#!/usr/bin/env python3
"""Renders the surfaces of a hexcut result file to PNG: the outer boundary (grey) and
the cut faces (one colour per cut id), deformed, at chosen output steps, with simple
Lambert shading. Reads only the HDF5 file (doc/output-format.md), with h5py and
matplotlib.
  /usr/bin/python3 scripts/plot_surfaces.py RESULT.h5 OUT.png [--steps 0 -1] [--view 20 -60]
      [--up z] [--title TEXT]
Steps are indices into the written steps (-1 = last); one panel per step."""
import argparse

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

CUT_COLOURS = ["#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"]
AXES = {"x": 0, "y": 1, "z": 2}


def shaded(points, triangles, cut_id, light):
    v = points[triangles]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    lam = 0.35 + 0.65 * np.abs(n @ light)
    base = np.array([matplotlib.colors.to_rgb("#b0b0b0") if c == 0 else
                     matplotlib.colors.to_rgb(CUT_COLOURS[(c - 1) % len(CUT_COLOURS)]) for c in cut_id])
    return v, np.clip(base * lam[:, None], 0, 1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("result")
    ap.add_argument("out")
    ap.add_argument("--steps", type=int, nargs="+", default=[0, -1])
    ap.add_argument("--view", type=float, nargs=2, default=[20, -60], help="elevation, azimuth [deg]")
    ap.add_argument("--up", default="z", choices=["x", "y", "z"], help="axis drawn vertically")
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    with h5py.File(a.result, "r") as f:
        names = sorted(k for k in f["steps"] if f["steps"][k].attrs.get("complete", 0) and "surface" in f["steps"][k])
        chosen = [names[i] for i in a.steps]
        panels = []
        for name in chosen:
            g = f["steps"][name]
            s = g["surface"]
            panels.append((float(g.attrs["time"]), s["points"][:], s["triangles"][:], s["cut_id"][:]))
    # Draw with the chosen axis up: permute coordinates so it becomes matplotlib's z.
    up = AXES[a.up]
    perm = [i for i in range(3) if i != up] + [up]
    allp = np.vstack([p[:, perm] for _, p, _, _ in panels])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo).max()
    light = np.array([0.4, -0.5, 0.77])
    light /= np.linalg.norm(light)
    fig = plt.figure(figsize=(5 * len(panels), 5))
    for k, (t, p, tri, cut) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), k + 1, projection="3d")
        v, colours = shaded(p[:, perm], tri, cut, light)
        ax.add_collection3d(Poly3DCollection(v, facecolors=colours, edgecolors="none"))
        for i, setter in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            setter(centre[i] - half, centre[i] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(*a.view)
        ax.set_axis_off()
        cuts = sorted(set(int(c) for c in cut) - {0})
        label = f"t = {t:.3g} s" + (f"  (cut ids {', '.join(map(str, cuts))})" if cuts else "")
        ax.text2D(0.5, 0.92, label, transform=ax.transAxes, ha="center")
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}: steps {', '.join(chosen)}")


if __name__ == "__main__":
    main()
