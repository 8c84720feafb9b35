"""Strong- and weak-scaling studies of one deck (issue 12; doc/benchmarks.md, "Scaling").

Shared by scripts/study/strong and scripts/study/weak: runs `hexcut DECK` under mpiexec for
each rank count, with -log_view, into a scratch output directory (-hexcut_output_directory,
so the deck's own result is never touched), and collects per run:

  voxelize   hexcutVoxelize: the body on the lattice (geometry, images, meshes)
  topology   hexcutTopology: vertex copies, partition, DOF layout, boundary data
  setup      hexcutAssembly: the operator and the preconditioner (multigrid hierarchy,
             Galerkin blocks, coarsest factorization; an assembled matrix for AMG)
  solve      hexcutSolve: the Krylov solves of every step
  output     hexcutOutput: stress recovery (hexcutStress, inside it) and the HDF5/XDMF files
  cuts       hexcutCutLinks + hexcutRebuild (0 without cuts)
  total      the run's wall time as hexcut reports it (start to the result file)

Times are PETSc's maximum over ranks (-log_view's "Max" column), so they are what the
slowest rank spent. Iterations are the sum over the run's solves (the result file's
/solver_history), memory the largest rank's peak resident set (VmHWM).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench"))
from benchlib import ENV, HEXCUT  # noqa: E402

PHASES = ["voxelize", "topology", "setup", "solve", "output", "cuts"]
EVENTS = {"voxelize": ["hexcutVoxelize"], "topology": ["hexcutTopology"], "setup": ["hexcutAssembly"],
          "solve": ["hexcutSolve"], "output": ["hexcutOutput"],
          "cuts": ["hexcutCutLinks", "hexcutRebuild"]}


def parse_with_options(ap, instead="--refine, --keep"):
    """Parses sys.argv with `ap`; the words after '--' become a.options, hexcut options for
    every run, less those run() sets itself (an error naming them and `instead`)."""
    ap.epilog = "Options after '--' go to every hexcut run (e.g. -- -pc_type gamg)."
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    a.options = extra
    owned = ("-hexcut_refine", "-hexcut_output_directory", "-log_view", "--check", "--restart", "--overwrite")
    for o in extra:
        if o.lower() in owned:
            ap.error(f"'{o}' after '--' is set by the study itself (use {instead})")
    return a


def arguments(description, weak):
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("deck", help="the hexcut deck (YAML)")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2], help="MPI rank counts (default 1 2)")
    ap.add_argument("--refine", type=float, default=1.0,
                    help="-hexcut_refine of the 1-rank run" +
                    (" (P ranks: about refine * P^(1/3), keeping integer dims)" if weak else ""))
    ap.add_argument("--repeats", type=int, default=1, help="runs per rank count; the fastest is kept")
    ap.add_argument("--mpiexec", default=os.environ.get("HEXCUT_MPIEXEC", "mpiexec"),
                    help="MPI launcher (default: $HEXCUT_MPIEXEC or mpiexec); '-n P' is appended")
    ap.add_argument("--png", default=None, help="plot file (default: <deck name>_<study>.png here)")
    ap.add_argument("--keep", default=None, help="keep the runs' result files and logs in this folder")
    a = parse_with_options(ap)
    if any(p < 1 for p in a.ranks):
        ap.error("--ranks must be >= 1")
    if a.repeats < 1:
        ap.error("--repeats must be >= 1")
    a.ranks = sorted(set(a.ranks))
    if a.refine <= 0:
        ap.error("--refine must be > 0")
    if not os.path.isfile(a.deck):
        ap.error(f"{a.deck}: no such deck")
    return a


def run(deck, ranks, refine, options, mpiexec, work):
    """One run; returns a dict of phases [s], total [s], iterations, DOFs, memory [MiB]."""
    out = os.path.join(work, f"p{ranks}_r{refine:.4f}")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    log = os.path.join(out, "log_view.txt")
    cmd = (mpiexec.split() + ["-n", str(ranks), HEXCUT, deck, "-hexcut_output_directory", out,
                              "-log_view", f":{log}"] + (["-hexcut_refine", repr(refine)] if refine != 1.0 else [])
           + list(options))
    p = subprocess.run(cmd, env=ENV, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"hexcut failed (exit {p.returncode}) on {ranks} rank(s):\n  {' '.join(cmd)}\n"
                         + p.stderr[-2000:])
    text = open(log).read()
    row = {"ranks": ranks, "refine": refine}
    for phase, names in EVENTS.items():
        row[phase] = 0.0
        for name in names:
            m = re.search(rf"^{name}\s+\d+\s+[\d.]+\s+([\d.e+-]+)", text, re.M)
            row[phase] += float(m.group(1)) if m else 0.0
    m = re.search(r"\(([\d.]+) s, peak memory ([\d.]+) MiB over all ranks(?:, ([\d.]+) MiB on the largest rank)?\)",
                  p.stdout)
    row["total"] = float(m.group(1))
    row["memory"] = float(m.group(3) or m.group(2))
    m = re.search(r"hexcut: (\d+) cells, \d+ vertex copies, (\d+) DOFs", p.stdout)
    row["cells"], row["dofs"] = int(m.group(1)), int(m.group(2))
    results = [f for f in os.listdir(out) if f.endswith(".h5")]
    with h5py.File(os.path.join(out, results[0]), "r") as f:
        row["iterations"] = int(np.sum(f["solver_history"]["iterations"][()]))
    return row


def study(a, refine_of, work):
    """Runs every rank count (fastest of a.repeats) and returns the rows."""
    rows = []
    cores = os.cpu_count() or 1
    for p in a.ranks:
        if p > cores:
            print(f"note: {p} ranks on {cores} cores are oversubscribed: their times are not "
                  "a scaling measurement (memory per rank is)", file=sys.stderr)
        best = None
        for _ in range(a.repeats):
            r = run(os.path.abspath(a.deck), p, refine_of(p), a.options, a.mpiexec, work)
            if best is None or r["total"] < best["total"]:
                best = r
        rows.append(best)
        print(f"  {p} rank(s): {best['dofs']} DOFs, {best['total']:.2f} s, {best['iterations']} its, "
              f"{best['memory']:.1f} MiB per rank", file=sys.stderr)
    return rows


def print_table(rows, efficiency, title):
    print(f"\n{title}\n")
    head = ["ranks", "refine", "DOFs", "DOFs/rank"] + PHASES + ["total", "efficiency", "its", "MiB/rank"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r, e in zip(rows, efficiency):
        cells = [str(r["ranks"]), f"{r['refine']:.4g}", str(r["dofs"]), str(r["dofs"] // r["ranks"])]
        cells += [f"{r[ph]:.3f}" for ph in PHASES]
        cells += [f"{r['total']:.2f}", f"{e:.2f}", str(r["iterations"]), f"{r['memory']:.1f}"]
        print("| " + " | ".join(cells) + " |")


def plot(rows, ideal_time, ideal_memory, title, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P = [r["ranks"] for r in rows]
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(15, 4.5))
    for ph in PHASES + ["total"]:
        t = [r[ph] for r in rows]
        if max(t) > 0:
            ax1.plot(P, t, "o-", label=ph, lw=2.5 if ph == "total" else 1.2)
    ax1.plot(P, ideal_time, "k--", label="ideal (total)")
    ax1.set_xscale("log", base=2)
    ax1.set_yscale("log")
    ax1.set_xlabel("MPI ranks")
    ax1.set_ylabel("time [s] (max over ranks)")
    ax1.legend(fontsize=8)
    ax2.plot(P, [r["iterations"] for r in rows], "o-")
    ax2.set_xscale("log", base=2)
    ax2.set_xlabel("MPI ranks")
    ax2.set_ylabel("Krylov iterations (all solves)")
    ax2.set_ylim(bottom=0)
    ax3.plot(P, [r["memory"] for r in rows], "o-", label="largest rank")
    ax3.plot(P, ideal_memory, "k--", label="ideal")
    ax3.set_xscale("log", base=2)
    ax3.set_xlabel("MPI ranks")
    ax3.set_ylabel("peak memory per rank [MiB]")
    ax3.legend(fontsize=8)
    for ax in (ax1, ax2, ax3):
        ax.set_xticks(P)
        ax.set_xticklabels([str(p) for p in P])
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    print(f"\nplot: {png}")


def weak_refinement(deck, refine):
    """For weak scaling: P -> the -hexcut_refine of the P-rank run, about refine P^(1/3), so
    the lattice of P ranks has about P times the cells. Where the dims allow it the ratio is
    m / g (g = the gcd of the 1-rank lattice's dims, m = round(g P^(1/3))): the dims stay
    integer multiples and the lattice box (origin + dims h) stays the deck's, so bodies and
    selectors on its faces (a plane at x = 1) keep their cells, which a refinement by P^(1/3)
    itself would shift by a fraction of a cell. Where g is too small for that to come within
    10 % of P^(1/3) (dims without a common factor, e.g. lattice.bounds decks), P^(1/3) itself,
    with a note."""
    import math

    import yaml

    try:
        lat = yaml.safe_load(open(deck))["lattice"]
        h = float(lat["h"])
        if "dims" in lat:
            dims = [int(d) for d in lat["dims"]]
        else:
            lo, hi = lat["bounds"]
            dims = [math.ceil((float(b) - float(a)) / h - 1e-9) for a, b in zip(lo, hi)]
    except Exception as e:  # hexcut itself reports a bad deck with its line; here: fall back
        print(f"note: could not read the lattice of {deck} ({e}); refining by P^(1/3)", file=sys.stderr)
        return lambda p: refine * p ** (1.0 / 3.0)
    base = [d * refine for d in dims]
    g = math.gcd(*[int(round(b)) for b in base]) if all(abs(b - round(b)) < 1e-9 for b in base) else 0

    def refine_of(p):
        ideal = p ** (1.0 / 3.0)
        if g > 0:
            m = max(1, round(g * ideal))
            if abs(m / g - ideal) <= 0.1 * ideal:
                return refine * m / g
        print(f"note: {p} ranks: dims {dims} x {refine:g} have no common factor that gives about "
              f"{ideal:.3f}; refining by it (the lattice's far faces move by up to a cell; a --refine "
              "that makes the dims multiples of 8 avoids this)", file=sys.stderr)
        return refine * ideal

    return refine_of


def main(kind):
    weak = kind == "weak"
    a = arguments(__doc__.splitlines()[0] + f" ({kind} scaling)", weak)
    refine_of = weak_refinement(a.deck, a.refine) if weak else (lambda p: a.refine)
    work = a.keep or tempfile.mkdtemp(prefix="hexcut_study_")
    os.makedirs(work, exist_ok=True)
    try:
        rows = study(a, refine_of, work)
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    base = rows[0]
    name = os.path.splitext(os.path.basename(a.deck))[0]
    opts = " ".join(a.options)
    if weak:
        # The work per rank is only about constant (integer dims: DOFs/rank in the table), so
        # the efficiency compares time per DOF per rank: T1 / N1 against TP / (NP / P).
        per_rank = lambda r: r["dofs"] / r["ranks"]  # noqa: E731
        eff = [(base["total"] / per_rank(base)) / (r["total"] / per_rank(r)) for r in rows]
        ideal_t = [base["total"] * per_rank(r) / per_rank(base) for r in rows]
        ideal_m = [base["memory"] * per_rank(r) / per_rank(base) for r in rows]
        title = f"weak scaling: {name} (refine {a.refine:g} x P^(1/3)) {opts}"
    else:
        eff = [base["total"] * base["ranks"] / (r["total"] * r["ranks"]) for r in rows]
        ideal_t = [base["total"] * base["ranks"] / r["ranks"] for r in rows]
        ideal_m = [base["memory"] * base["ranks"] / r["ranks"] for r in rows]
        title = f"strong scaling: {name}" + (f" (refine {a.refine:g})" if a.refine != 1 else "") + f" {opts}"
    print_table(rows, eff, title + "; times [s], max over ranks")
    plot(rows, ideal_t, ideal_m, title, a.png or f"{name}_{kind}.png")
