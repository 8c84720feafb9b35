"""Composite elements after cuts: what re-assembling only the elements a cut changed saves
(issue 11; doc/theory.md, "Composite elements"). Runs the cut bunny on composite elements
(input/examples/bunny_composite.yaml: a scalpel swept from t = 0.02 s to 0.10 s and a stamp
at t = 0.12 s, corotational, 40 steps) at the given levels, each twice with the kept
elements (the default) and twice with -hexcut_composite_carry false (every element rebuilt
after each cut), alternating, and prints per level and mode the best of the two runs: total
seconds, gmgSetup seconds and count (hierarchy updates, the composite blocks included),
hexcutRebuild (topology after the cuts) and hexcutEnergy (mid-point forces, whose element
data are built once per topology), plus the displacement difference between the modes.

  /usr/bin/python3 scripts/bench/composite_cuts.py [--levels 1 2] [--repeats 2]
"""
import argparse
import re
import tempfile

import h5py
import numpy as np

from composite import deck_of, run

EVENTS = ("gmgSetup", "hexcutRebuild", "hexcutEnergy")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="hexcut-composite-cuts-")
    print("| level | mode | total s | gmgSetup s (count) | hexcutRebuild s | hexcutEnergy s |")
    print("|---|---|---|---|---|---|")
    for level in args.levels:
        best, last = {}, {}
        for _ in range(args.repeats):
            for mode, extra in (("kept", ()), ("all rebuilt", ("-hexcut_composite_carry", "false"))):
                name = f"l{level}_{'kept' if not extra else 'all'}"
                # The last step only is written: the benchmark times the steps, not the output.
                text = deck_of("bunny_composite.yaml", name, 0,
                               [("level: 2", f"level: {level}")], every=1000)
                out, ev, h5 = run(text, work, name, extra)
                total = float(re.search(r"Time \(sec\):\s+([\d.e+-]+)", out).group(1))
                count = re.search(r"^gmgSetup\s+(\d+)", out, re.M).group(1)
                row = (total, ev.get("gmgSetup", 0.0), count, *(ev.get(e, 0.0) for e in EVENTS[1:]))
                if mode not in best or row[0] < best[mode][0]:
                    best[mode] = row
                with h5py.File(h5) as f:
                    steps = sorted(f["steps"].keys(), key=lambda s: int(s.split("_")[-1]))
                    last[mode] = np.array(f["steps"][steps[-1]]["displacement"])
        for mode, r in best.items():
            print(f"| {level} | {mode} | {r[0]:.2f} | {r[1]:.2f} ({r[2]}) | {r[3]:.2f} | {r[4]:.2f} |")
        a, b = last["kept"], last["all rebuilt"]
        d = np.abs(a - b).max() / np.abs(b).max() if a.shape == b.shape else float("nan")
        print(f"|   | max \\|u_kept - u_all\\| / max \\|u\\| at the end: {d:.1e} | | | | |")


if __name__ == "__main__":
    main()
