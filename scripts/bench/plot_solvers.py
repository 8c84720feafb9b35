"""Plots time to solution (setup + solve) against DOFs per solver and rank count from
the CSV written by scripts/bench/solvers.
  /usr/bin/python3 scripts/bench/plot_solvers.py bench-results/solvers.csv doc/solvers.png"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(src, dst):
    rows = [r for r in csv.DictReader(open(src)) if r["status"] == "ok"]
    fig, ax = plt.subplots(figsize=(7, 5))
    for key in sorted({(r["solver"], r["ranks"]) for r in rows}):
        pts = sorted((int(r["dofs"]), float(r["setup_s"]) + float(r["solve_s"])) for r in rows
                     if (r["solver"], r["ranks"]) == key)
        ax.loglog(*zip(*pts), marker="o", linestyle="-" if key[1] == "1" else "--",
                  label=f"{key[0]}, {key[1]} rank(s)")
    ax.set_xlabel("DOFs")
    ax.set_ylabel("setup + solve time [s]")
    ax.set_title("Clamped cantilever, rtol 1e-8")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(dst, dpi=120)
    print(f"wrote {dst}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
