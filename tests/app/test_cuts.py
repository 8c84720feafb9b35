"""Cuts from the command line: the cut bar example separates (the result file carries
the split mesh from the cut step on, the free part falls, the cut faces appear in the
surface with their cut id, 2 ranks write the same file as 1, and a run stopped after
the cut continues with --restart to the same result), a static deck with a
piece the cut leaves unsupported stops with exit 3 naming the piece, and bad cut
entries give 'deck.yaml:LINE: message' and exit 2."""
import os
import re
import shutil
import sys

import h5py
import numpy as np

from cli_helpers import Checks, run, tempdir, write

SOURCE = os.environ["HEXCUT_SOURCE_DIR"]

BAR = """lattice: {h: 0.05, dims: [20, 2, 2]}
materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}
geometry: [{add: {box: {min: [0, 0, 0], max: [1, 0.1, 0.1]}}}]
boundary: {fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}], gravity: [0, 0, -9.81]}
solver: {type: gmg}
cuts:
%s
"""
PLANE = "  - blade: {polygon: [[0.6, -1, -1], [0.6, 1, -1], [0.6, 1, 1], [0.6, -1, 1]]}"
SURFACE = ("triangles", "cut_id", "owner_cell")  # the cut surface's canonical datasets


def step80_difference(path_a, path_b, names=("displacement",)):
    """Largest relative difference between two result files at step 80 over the datasets
    `names` (1.0 when their shapes differ)."""
    worst = 0.0
    with h5py.File(path_a, "r") as a, h5py.File(path_b, "r") as b:
        for name in names:
            x, y = a["steps/000080/" + name][:], b["steps/000080/" + name][:]
            if x.shape != y.shape:
                return 1.0
            worst = max(worst, np.abs(x - y).max() / np.abs(x).max())
    return worst


def same_step80_surface(path_a, path_b):
    """Whether two result files hold the same cut surface at step 80, entry for entry."""
    with h5py.File(path_a, "r") as a, h5py.File(path_b, "r") as b:
        return all(np.array_equal(a["steps/000080/surface/" + k][:], b["steps/000080/surface/" + k][:])
                   for k in SURFACE)


def main():
    d = tempdir()
    check = Checks()

    # The cut bar example: the cut at t = 0.1 s acts in step 20 (dt = 5 ms).
    rc, out, err = run([os.path.join(SOURCE, "input/examples/cut_bar.yaml"), "-log_view"], cwd=d)
    check(rc == 0 and "disconnected 16 links; 2 piece(s)" in out, f"cut_bar runs and cuts 16 links: {err.strip()}")
    # -log_view: one cut is one link test and one rebuild (topology, solver, hierarchy).
    counts = {e: re.search(rf"^{e}\s+(\d+)", out, re.M) for e in ("hexcutCutLinks", "hexcutRebuild")}
    counts = {e: int(m.group(1)) if m else None for e, m in counts.items()}
    check(counts == {"hexcutCutLinks": 1, "hexcutRebuild": 1}, f"events logged per cut: {counts}")
    if rc == 0:
        with h5py.File(f"{d}/results/cut_bar.h5", "r") as f:
            before = f["steps/000016"].attrs["mesh"].decode()
            after = f["steps/000020"].attrs["mesh"].decode()
            later = f["steps/000080"].attrs["mesh"].decode()
            n0 = f["mesh/points"].shape[0]
            p = f[after + "/points"][:]
            u = f["steps/000080/displacement"][:]
        check(before == "/mesh" and after == "/steps/000020/mesh" and later == after,
              f"meshes per step: {before}, {after}, {later}")
        # 5 x 5 lattice vertices on the cut face x = 0.15 get a second copy each.
        check(p.shape[0] == n0 + 25 and u.shape[0] == p.shape[0], f"points {n0} -> {p.shape[0]}")
        free = p[:, 0] > 0.2
        stub = p[:, 0] < 0.1
        fall = -u[free, 2].mean()
        check(fall > 0.3 and np.abs(u[stub]).max() < 0.05,
              f"free part fell {fall:.3f} m by t = 0.4 s; clamped stub moved {np.abs(u[stub]).max():.2e} m")
        with h5py.File(f"{d}/results/cut_bar.h5", "r") as f:
            ids0 = set(f["steps/000016/surface/cut_id"][:].tolist())
            ids1 = f["steps/000020/surface/cut_id"][:]
        # 4 x 4 cut links, one quad (2 triangles) on each side.
        check(ids0 == {0} and (ids1 == 1).sum() == 64, f"cut faces in the surface: {ids0}, {(ids1 == 1).sum()}")
        d2 = tempdir()
        rc2, _, err2 = run([os.path.join(SOURCE, "input/examples/cut_bar.yaml")], cwd=d2, ranks=2)
        worst, same = 1.0, False
        if rc2 == 0:
            one, two = f"{d}/results/cut_bar.h5", f"{d2}/results/cut_bar.h5"
            worst = step80_difference(one, two, ("displacement", "surface/points"))
            same = same_step80_surface(one, two)
        check(rc2 == 0 and same and worst < 1e-8, f"2 ranks write the same result (max rel. diff {worst:.1e}): {err2.strip()}")
        # The same on 2 ranks re-partitioned after the cut (-hexcut_repartition 1: whenever the
        # DOFs are not perfectly balanced; super-blocks of 2 cells, so cells do move): u, v and a
        # go to the cells' new ranks mid-run, and the result is still the 1-rank one.
        d5 = tempdir()
        rc5, out5, err5 = run([os.path.join(SOURCE, "input/examples/cut_bar.yaml"), "-hexcut_superblock", "2",
                               "-hexcut_repartition", "1"], cwd=d5, ranks=2)
        worst = step80_difference(f"{d}/results/cut_bar.h5", f"{d5}/results/cut_bar.h5") if rc5 == 0 else 1.0
        # An expectation of its own (the 1-rank run moves its state through the same code): the
        # cut splits copies but keeps every velocity, so the bar's energy goes on growing at the
        # pace of the steps before (gravity's work); lost velocities would drop it at step 20.
        energy = {int(n): float(e) for n, e in re.findall(r"^step (\d+)/80 .* E (\S+) J", out5, re.M)}
        gain = [energy.get(n, 0.0) - energy.get(n - 1, 0.0) for n in (19, 20)]
        check(gain[0] > 0 and 0.8 < gain[1] / gain[0] < 1.3,
              f"re-partitioned run: energy gain of the cut's step {gain[1]:.3g} J against {gain[0]:.3g} J before")
        check(rc5 == 0 and "re-partitioned" in out5 and worst < 1e-8,
              f"2 ranks re-partitioned after the cut write the 1-rank result (max rel. diff {worst:.1e}): "
              f"{err5.strip()[-300:]}")

        # Stop after the cut (step 40 of 80), restart from the checkpoint: the cut topology
        # is rebuilt from the checkpoint's links and the run ends where the full one did.
        # The example is corotational: the multigrid re-estimates its Chebyshev bounds every
        # 10th rotation update counted from the start of each invocation (-gmg_eig_every), so
        # the restarted run's preconditioner differs slightly and the two agree to far below
        # the solver's rtol (1e-8), not bit for bit (with -gmg_eig_every 1 they do).
        d3 = tempdir()
        deck = os.path.join(SOURCE, "input/examples/cut_bar.yaml")
        rc3, out3, err3 = run([deck, "-hexcut_max_steps", "40"], cwd=d3)
        d6 = tempdir()  # the same checkpoint, continued on 2 ranks below
        if rc3 == 0:
            shutil.copytree(f"{d3}/results", f"{d6}/results")
        rc4, out4, err4 = run(["--restart", f"{d3}/results/cut_bar.h5", deck], cwd=d3)
        diff = 1.0
        if rc3 == 0 and rc4 == 0:
            diff = step80_difference(f"{d}/results/cut_bar.h5", f"{d3}/results/cut_bar.h5")
        check(rc3 == 0 and rc4 == 0 and "16 cut links restored" in out4 and diff < 1e-10,
              f"restart after the cut: max rel. diff {diff:.1e}: {err3.strip()} {err4.strip()}")
        # Restart on another number of ranks (issue 12): the 1-rank checkpoint continued on 2
        # ranks gives the uninterrupted 1-rank result to solver tolerance and the same cut
        # surface (its triangles, cut ids and owner cells are canonical).
        rc6, out6, err6 = run(["--restart", f"{d6}/results/cut_bar.h5", deck], cwd=d6, ranks=2) \
            if rc3 == 0 else (1, "", "the 40-step run failed")
        diff, same = 1.0, False
        if rc3 == 0 and rc6 == 0:
            diff = step80_difference(f"{d}/results/cut_bar.h5", f"{d6}/results/cut_bar.h5")
            same = same_step80_surface(f"{d}/results/cut_bar.h5", f"{d6}/results/cut_bar.h5")
        check(rc6 == 0 and "16 cut links restored" in out6 and diff < 1e-8 and same,
              f"1-rank checkpoint after the cut restarted on 2 ranks: max rel. diff {diff:.1e}, "
              f"same surface {same}: {err6.strip()[-300:]}")

    # A static deck whose cut leaves the tip unsupported: exit 3 naming the piece.
    deck = write(d, "static_cut.yaml", BAR % PLANE)
    rc, out, err = run([deck], cwd=d)
    check(rc == 3 and "piece 2: 32 cells, box [0.6, 0, 0] - [1, 0.1, 0.1] m, unsupported" in err,
          f"unsupported piece: exit {rc}: {err.strip()}")

    # Bad cut entries: file:line and exit 2.
    bad = {
        "non-convex polygon": ("  - blade: {polygon: [[0.6, 0, 0], [0.6, 1, 1], [0.6, 1, 0], [0.6, 0, 1]]}",
                               "convex"),
        "window on a polygon": (PLANE + "\n    window: [0, 1]", "'window' applies to scalpel blades only"),
        "scalpel without path": ("  - blade: {scalpel: {edge: [[0, 0, 0], [0, 1, 0]]}}", "scalpel needs"),
        "unknown blade": ("  - blade: {disk: {radius: 1}}", "unknown key"),
        "negative time": (PLANE + "\n    time: -1", "cut.time must be >= 0"),
    }
    for name, (entry, message) in bad.items():
        deck = write(d, "bad.yaml", BAR % entry)
        rc, out, err = run([deck], cwd=d)
        check(rc == 2 and "bad.yaml:" in err and message in err, f"{name}: exit {rc}: {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
