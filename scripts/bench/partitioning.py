"""Partitioning methods compared (issue 12; doc/benchmarks.md, "Partitioning"): METIS k-way on the
super-block graph (hexcut's default), PT-Scotch on the same graph through PETSc's MatPartitioning
(distributed over the ranks), and a Hilbert curve through the super-blocks cut into runs of equal
cell count (-hexcut_partition metis|ptscotch|sfc). For the bunny (input/examples/bunny.yaml) and a
48^3 cube cut from the top by a grid of blades every 3 cells rotated 20 degrees (static: the cuts
act before the solve), on 2, 4, 8 and 16 ranks (hexcut --check, oversubscribed: the partition does
not depend on the cores), it prints the balance (cells and DOFs, max over mean; DOFs again after
the cuts, which add vertex copies but move no cell), the face links between ranks and the ghost
DOFs (what the halo exchanges move). Then the time of the whole run on 2 ranks per method (best of
--repeats), the only rank count this 2-core machine times honestly. --repartition X ... runs the
cut case again with -hexcut_repartition X (re-partition after the cuts when the DOFs' max/mean
exceeds X; 0 = never, hexcut's default).
  /usr/bin/python3 scripts/bench/partitioning.py [--ranks 2 4 8 16] [--repeats 2] [--repartition 0 1.05]"""
import argparse
import os
import re
import shutil
import subprocess
import tempfile

from benchlib import ENV, HEXCUT, ROOT
import coarse_spaces

METHODS = ["metis", "ptscotch", "sfc"]
MPIEXEC = os.environ.get("HEXCUT_MPIEXEC", "mpiexec").split()


def cases(work):
    cube = coarse_spaces.deck_text(dict(geometry=coarse_spaces.BOX, cuts=coarse_spaces.blade_grid(3, 20, n=48)),
                                   "gmg", os.path.join(work, "out_cube"), 48)
    path = os.path.join(work, "blade_grid48.yaml")
    with open(path, "w") as f:
        f.write(cube)
    return {"bunny": os.path.join(ROOT, "input", "examples", "bunny.yaml"), "blade grid 48^3": path}


def check(deck, ranks, method, repartition):
    p = subprocess.run([*MPIEXEC, "-n", str(ranks), HEXCUT, deck, "--check", "-hexcut_partition", method,
                        "-hexcut_repartition", repartition],
                       env=ENV, capture_output=True, text=True)
    m = re.search(r"partition \S+, super-blocks of (\d+): cells max/mean ([\d.]+), DOFs max/mean ([\d.]+), "
                  r"(\d+) links between ranks, ghost DOFs ([\d.]+)% of all \((\d+) on the rank with most\)", p.stdout)
    if p.returncode != 0 or not m:
        raise SystemExit(f"hexcut --check failed ({ranks} ranks, {method}):\n{p.stdout[-800:]}\n{p.stderr[-800:]}")
    cut = re.search(r"DOFs max/mean over ranks ([\d.]+)", p.stdout)
    return dict(sb=int(m.group(1)), cells=float(m.group(2)), dofs=float(m.group(3)), links=int(m.group(4)),
                ghosts=float(m.group(5)), max_ghosts=int(m.group(6)), after=float(cut.group(1)) if cut else None)


def timed(deck, method, work, repeats, repartition):
    best = None
    for _ in range(repeats):
        out = os.path.join(work, "run")
        log = os.path.join(work, "log.txt")
        p = subprocess.run([*MPIEXEC, "-n", "2", HEXCUT, deck, "-hexcut_partition", method,
                            "-hexcut_repartition", repartition,
                            "-hexcut_output_directory", out, "--overwrite", "-log_view", f":{log}"],
                           env=ENV, capture_output=True, text=True)
        if p.returncode != 0:
            raise SystemExit(f"hexcut failed ({method}):\n{p.stderr[-800:]}")
        total = float(re.search(r"\(([\d.]+) s, peak memory", p.stdout).group(1))
        solve = float(re.search(r"^hexcutSolve\s+\d+\s+[\d.]+\s+([\d.e+-]+)", open(log).read(), re.M).group(1))
        if best is None or total < best[0]:
            best = (total, solve)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ranks", type=int, nargs="+", default=[2, 4, 8, 16])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--repartition", nargs="+", default=["0"])
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="hexcut_partitioning_")
    decks = cases(work)
    # The bunny has no cuts: re-partitioning never applies to it.
    runs = [(name, deck, x) for name, deck in decks.items()
            for x in (a.repartition if name != "bunny" else a.repartition[:1])]
    print("| case | -hexcut_repartition | ranks | method | super-block | cells max/mean | DOFs max/mean | "
          "after cuts | links between ranks | ghost DOFs % | ghost DOFs on the rank with most |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, deck, x in runs:
        for P in a.ranks:
            for m in METHODS:
                r = check(deck, P, m, x)
                after = f"{r['after']:.3f}" if r["after"] is not None else "–"
                print(f"| {name} | {x} | {P} | {m} | {r['sb']} | {r['cells']:.3f} | {r['dofs']:.3f} | {after} | "
                      f"{r['links']} | {r['ghosts']:.2f} | {r['max_ghosts']} |", flush=True)
    print("\n2 ranks, whole run (best of %d per method):\n" % a.repeats)
    print("| case | -hexcut_repartition | method | total [s] | solve [s] |")
    print("|---|---|---|---|---|")
    for name, deck, x in runs:
        for m in METHODS:
            total, solve = timed(deck, m, work, a.repeats, x)
            print(f"| {name} | {x} | {m} | {total:.2f} | {solve:.2f} |", flush=True)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
