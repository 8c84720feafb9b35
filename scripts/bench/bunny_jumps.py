"""Where the bunny's iterations go (issue 10; doc/benchmarks.md, "The bunny's stiff core and
nu = 0.45"). Runs input/examples/bunny.yaml (static, stiff core 1000x, tissue nu = 0.45) and
three variants of it - homogeneous nu = 0.3 (the core given the tissue's E), nu = 0.45 alone,
the jump alone (nu = 0.3 everywhere) - with the default multigrid and any option sets given,
one run each, side by side, and prints CG iterations to rtol 1e-8, set-up (hexcutAssembly) and
solve (KSPSolve) seconds.
  /usr/bin/python3 scripts/bench/bunny_jumps.py [--refine 2] [--variants full jump ...] \\
      [--options "" "-gmg_levels 2" "-gmg_cycle w" ...]"""
import argparse
import os
import re
import subprocess
import tempfile

from benchlib import ENV, HEXCUT, example_deck, log_events

TISSUE_NU = ("tissue: {E: 1.0e5, nu: 0.45", "tissue: {E: 1.0e5, nu: 0.3")
CORE = "core: {E: 1.0e8, nu: 0.3"
# Edits of bunny.yaml per variant (benchlib.example_deck checks that each one applies).
VARIANTS = {
    "homogeneous": [TISSUE_NU, (CORE, "core: {E: 1.0e5, nu: 0.3")],
    "nu 0.45": [(CORE, "core: {E: 1.0e5, nu: 0.45")],
    "jump": [TISSUE_NU],
    "full": [],
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--refine", default="2", help="-hexcut_refine (2: 194k cells, 631k DOFs)")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), help=", ".join(VARIANTS))
    ap.add_argument("--options", nargs="+", default=[""], help="option sets, one run each")
    a = ap.parse_args()
    print(f"{'variant':<12} {'options':<40} {'its':>4} {'setup':>7} {'solve':>7}")
    with tempfile.TemporaryDirectory() as work:
        for name in a.variants:
            deck = os.path.join(work, "bunny.yaml")
            with open(deck, "w") as f:
                f.write(example_deck("bunny.yaml", VARIANTS[name]))
            for k, opts in enumerate(a.options):
                out, log = os.path.join(work, f"out{name}{k}".replace(" ", "")), os.path.join(work, "log.txt")
                p = subprocess.run([HEXCUT, deck, "-hexcut_refine", a.refine, "-hexcut_output_directory", out,
                                    "-log_view", f":{log}", *opts.split()], env=ENV, capture_output=True,
                                   text=True)
                if p.returncode:
                    print(f"{name:<12} {opts:<40} exit {p.returncode}", flush=True)
                    continue
                its = re.search(r"its (\d+)", p.stdout).group(1)
                ev = log_events(open(log).read())
                print(f"{name:<12} {opts:<40} {its:>4} {ev['hexcutAssembly']:>7.3f} {ev['KSPSolve']:>7.3f}",
                      flush=True)


if __name__ == "__main__":
    main()
