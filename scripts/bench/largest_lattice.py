"""Largest lattice one process runs on this machine (issue 12; doc/benchmarks.md, "Memory per DOF and
the largest lattice").

Runs a deck on one rank at each --refine factor (-hexcut_refine: h / R, dims * R) into a
scratch folder and prints DOFs, peak resident memory, bytes per DOF, iterations and the time
per phase (scripts/study/scaling.py's run: PETSc events, the result file's solver history).
A run that fails (out of memory, a solver failure: exit 3) is reported, not hidden.

    /usr/bin/python3 scripts/bench/largest_lattice.py input/examples/cantilever.yaml \\
        --refine 4.5 13 [-- -gmg_precision single]
"""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "study"))
from scaling import parse_with_options, run  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("deck")
ap.add_argument("--refine", type=float, nargs="+", required=True)
a = parse_with_options(ap, instead="--refine")
if any(r <= 0 for r in a.refine):
    ap.error("--refine must be > 0")
print("| refine | cells | DOFs | peak MiB | bytes/DOF | its | voxelize | topology | setup | solve | "
      "output | total [s] |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
with tempfile.TemporaryDirectory(prefix="hexcut_largest_") as work:
    for r in a.refine:
        try:
            row = run(os.path.abspath(a.deck), 1, r, a.options,
                      os.environ.get("HEXCUT_MPIEXEC", "mpiexec"), work)
        except SystemExit as failure:
            print(f"| {r:g} | failed: {str(failure).splitlines()[0]} |")
            print(str(failure), file=sys.stderr)
            continue
        b = row["memory"] * 2**20 / row["dofs"]
        print(f"| {r:g} | {row['cells']} | {row['dofs']} | {row['memory']:.1f} | {b:.0f} | "
              f"{row['iterations']} | " + " | ".join(f"{row[k]:.2f}" for k in
                                                    ("voxelize", "topology", "setup", "solve", "output"))
              + f" | {row['total']:.1f} |", flush=True)
