"""Runs the cantilever with each solver at several sizes and rank counts; prints a
table and writes CSV. See scripts/bench/solvers for usage."""
import argparse
import csv
import os
import re
import subprocess
import tempfile
import time

import h5py

from benchlib import ENV, HEXCUT, ROOT, cantilever

# Bar of aspect 8:1:1 (length 1 m); cells across the section -> DOFs 3 (8n+1)(n+1)^2.
SIZES = {"50k": 12, "400k": 24, "1.5M": 38}

def run_case(size, ranks, solver, timeout, workdir):
    n = SIZES[size]
    deck = os.path.join(workdir, f"{size}-{ranks}-{solver}.yaml")
    out = os.path.join(workdir, f"{size}-{ranks}-{solver}")
    with open(deck, "w") as f:
        f.write(cantilever(n, solver, out))
    cmd = (["mpiexec", "-n", str(ranks)] if ranks > 1 else []) + [HEXCUT, deck, "-log_view", f":{out}.log"]
    t0 = time.time()
    try:
        p = subprocess.run(cmd, env=ENV, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"status": f"timeout>{timeout}s"}
    wall = time.time() - t0
    if p.returncode != 0:
        return {"status": f"exit {p.returncode}: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ''}"}
    dofs = int(re.search(r"(\d+) DOFs", p.stdout).group(1))
    mem = float(re.search(r"peak memory ([\d.]+) MiB", p.stdout).group(1))
    with h5py.File(os.path.join(out, "bench.h5"), "r") as f:
        h = f["solver_history"]
        row = {"iterations": int(h["iterations"][-1]), "setup_s": float(h["setup_seconds"][-1]),
               "solve_s": float(h["solve_seconds"][-1]), "residual": float(h["relative_residual"][-1])}
    assembly = re.search(r"^hexcutAssembly\s+\d+\s+[\d.]+\s+([\d.e+-]+)", open(f"{out}.log").read(), re.M)
    row.update({"status": "ok", "dofs": dofs, "peak_mib": mem, "wall_s": wall,
                "assembly_s": float(assembly.group(1)) if assembly else float("nan")})
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="50k 400k 1.5M")
    ap.add_argument("--ranks", default="1 2")
    ap.add_argument("--solvers", default="gmg cg-jacobi hypre gamg direct")
    ap.add_argument("--timeout", type=int, default=900)
    ap.add_argument("--csv", default=os.path.join(ROOT, "bench-results", "solvers.csv"))
    a = ap.parse_args()
    os.makedirs(os.path.dirname(a.csv), exist_ok=True)
    fields = ["size", "ranks", "solver", "status", "dofs", "assembly_s", "setup_s", "solve_s", "iterations",
              "residual", "peak_mib", "wall_s"]
    print(f"{'size':>5} {'ranks':>5} {'solver':>10} {'DOFs':>9} {'asm s':>7} {'setup s':>8} {'solve s':>8} "
          f"{'its':>6} {'peak MiB':>9} {'wall s':>7}  status", flush=True)
    with open(a.csv, "w", newline="") as f, tempfile.TemporaryDirectory() as work:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for size in a.sizes.split():
            for ranks in map(int, a.ranks.split()):
                for solver in a.solvers.split():
                    r = run_case(size, ranks, solver, a.timeout, work)
                    r.update(size=size, ranks=ranks, solver=solver)
                    w.writerow({k: r.get(k, "") for k in fields})
                    f.flush()
                    if r["status"] == "ok":
                        print(f"{size:>5} {ranks:>5} {solver:>10} {r['dofs']:>9} {r['assembly_s']:>7.2f} "
                              f"{r['setup_s']:>8.2f} {r['solve_s']:>8.2f} {r['iterations']:>6} "
                              f"{r['peak_mib']:>9.0f} {r['wall_s']:>7.1f}  ok", flush=True)
                    else:
                        print(f"{size:>5} {ranks:>5} {solver:>10} {'':>9} {'':>7} {'':>8} {'':>8} {'':>6} "
                              f"{'':>9} {'':>7}  {r['status']}", flush=True)
    print(f"wrote {a.csv}")


if __name__ == "__main__":
    main()
