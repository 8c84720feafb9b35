"""The command line's changes to a deck and the scaling studies built on them (doc/user-guide.md,
"Command line"; doc/benchmarks.md, "Scaling"): -hexcut_refine R runs the deck's lattice with cells R
times smaller (the same result as a deck written with h / R and dims * R), -hexcut_output_directory
DIR writes the result into DIR and leaves the deck's own result alone; wrong values are input
errors (exit 2) before anything is written. scripts/study/strong and weak run a deck on 1 and 2
ranks and print their table and plot."""
import os
import re
import subprocess
import sys

import h5py
import numpy as np

from cli_helpers import BEAM, ENV, Checks, run, tempdir, write

SOURCE = os.environ["HEXCUT_SOURCE_DIR"]


def deck(d, name, text=BEAM, output=None):
    return write(d, name + ".yaml", text + f"output: {{directory: {output or d + '/' + name}, name: r}}\n")


def displacement(path):
    with h5py.File(path, "r") as f:
        return (f["steps/000001/displacement"][()], list(f["mesh"].attrs["lattice_dims"]),
                float(f["mesh"].attrs["lattice_h"]))


def main():
    check = Checks()
    d = tempdir()
    beam = deck(d, "beam")
    # -hexcut_refine 2 = the same deck written with h / 2 and dims * 2, bit for bit.
    rc, out, err = run([beam, "-hexcut_refine", "2"])
    check(rc == 0 and "-hexcut_refine 2: lattice h = 0.05 m, dims 20 x 4 x 4" in out,
          f"-hexcut_refine 2 runs and says what it ran (rc {rc}) {err[-300:]}")
    fine = deck(d, "fine", BEAM.replace("{h: 0.1, dims: [10, 2, 2]}", "{h: 0.05, dims: [20, 4, 4]}"))
    rc2, _, err2 = run([fine])
    if rc == 0 and rc2 == 0:
        u, dims, h = displacement(f"{d}/beam/r.h5")
        v, dims2, h2 = displacement(f"{d}/fine/r.h5")
        check(dims == [20, 4, 4] and h == 0.05 and u.shape == v.shape and np.array_equal(u, v),
              f"the refined run is the deck written at h / 2 (dims {dims}, h {h}; max difference "
              f"{np.max(np.abs(u - v)) if u.shape == v.shape else 'shapes differ'})")
    else:
        check(False, f"the deck at h / 2 runs {err2[-300:]}")
    # A factor that is not an integer: dims rounded up, so the lattice still covers the box.
    rc, out, err = run([beam, "--overwrite", "-hexcut_refine", "1.25"])
    check(rc == 0 and "dims 13 x 3 x 3" in out, f"-hexcut_refine 1.25: dims 10, 2, 2 -> 13, 3, 3 (rc {rc}) "
          f"{out[:300]} {err[-300:]}")

    # -hexcut_output_directory: the result goes there; the deck's own result stays as it was.
    rc, out, err = run([beam, "--overwrite"])
    before = open(f"{d}/beam/r.h5", "rb").read()
    elsewhere = os.path.join(d, "elsewhere")
    rc, out, err = run([beam, "-hexcut_output_directory", elsewhere, "-hexcut_refine", "2"])
    check(rc == 0 and os.path.isfile(f"{elsewhere}/r.h5") and open(f"{d}/beam/r.h5", "rb").read() == before,
          f"-hexcut_output_directory writes r.h5 there and leaves the deck's result untouched (rc {rc}) "
          f"{err[-300:]}")
    if rc == 0:
        check(displacement(f"{elsewhere}/r.h5")[1] == [20, 4, 4], "the result there is the refined run's")
    # Without --overwrite the result there is protected like any other.
    rc, out, err = run([beam, "-hexcut_output_directory", elsewhere])
    check(rc == 2 and "r.h5" in err, f"a second run into it without --overwrite is refused (rc {rc}) {err[-200:]}")

    # --restart continues its file in place: an output directory is refused, not ignored.
    rc, out, err = run([beam, "--restart", f"{d}/beam/r.h5", "-hexcut_output_directory", elsewhere])
    check(rc == 2 and "-hexcut_output_directory does not apply" in err,
          f"--restart with -hexcut_output_directory: exit 2 (rc {rc}) {err[-200:]}")

    # An output directory that cannot be made (a file is in the way): exit 2 from --check
    # and from the run, naming it.
    blocker = write(d, "a_file", "not a directory\n")
    for extra in (["--check"], []):
        rc, out, err = run([beam, *extra, "-hexcut_output_directory", blocker + "/sub"])
        check(rc == 2 and "cannot be used" in err and "is not a directory" in err,
              f"{' '.join(extra) or 'run'}: an output directory under a file exits 2 (rc {rc}) {err[-200:]}")

    # Wrong values: exit 2, nothing written.
    for args, message in ((["-hexcut_refine", "0"], "-hexcut_refine must be a number > 0, got '0'"),
                          (["-hexcut_refine", "-2"], "-hexcut_refine must be a number > 0"),
                          (["-hexcut_refine", "1e300"], "more than 2e9"),
                          (["-hexcut_refine", "abc"], "-hexcut_refine must be a number > 0, got 'abc'"),
                          (["-hexcut_refine", "3000"], "30000 x 6000 x 6000 cells, more than 2e9"),
                          (["-hexcut_refin", "2"], "did you mean -hexcut_refine"),
                          (["-hexcut_output_directory", ""], "-hexcut_output_directory needs a directory"),
                          (["-hexcut_io_buffer", "-1"], "-hexcut_io_buffer must be an integer number of MiB"),
                          (["-hexcut_io_buffer", "4.5"], "from 0 (the MPI library's default) to 4096, got '4.5'"),
                          (["-hexcut_io_buffer", "5000"], "to 4096, got '5000'")):
        target = os.path.join(d, "bad")
        rc, out, err = run([beam, *args] if args[0] == "-hexcut_output_directory" else
                           [beam, "-hexcut_output_directory", target, *args])
        check(rc == 2 and message in err and not os.path.exists(target),
              f"{' '.join(args)}: exit 2 with '{message}' and nothing written (rc {rc}) {err[-300:]}")

    # Two ranks: the largest rank's peak memory is reported too.
    rc, out, err = run([beam, "-hexcut_output_directory", os.path.join(d, "two")], ranks=2)
    m = re.search(r"peak memory ([\d.]+) MiB over all ranks, ([\d.]+) MiB on the largest rank", out)
    check(rc == 0 and m and 0 < float(m.group(2)) <= float(m.group(1)),
          f"2 ranks report the largest rank's peak memory ({m and m.groups()}) {err[-300:]}")
    # -hexcut_io_buffer (the MPI-IO collective buffer) changes memory, never the file's numbers:
    # 0 (the MPI library's default) and 1 MiB write what the default 4 MiB wrote.
    for mib in ("0", "1"):
        other = os.path.join(d, "two_io" + mib)
        rc, out, err = run([beam, "-hexcut_output_directory", other, "-hexcut_io_buffer", mib], ranks=2)
        same = rc == 0 and np.array_equal(displacement(os.path.join(other, "r.h5"))[0],
                                          displacement(os.path.join(d, "two", "r.h5"))[0])
        check(same, f"-hexcut_io_buffer {mib} on 2 ranks writes the same displacements (rc {rc}) {err[-300:]}")

    # The scaling studies: gmg on the beam refined 4x (40 x 8 x 8 cells), 1 and 2 ranks.
    gmg = deck(d, "gmg", BEAM.replace("solver: {type: direct}", "solver: {type: gmg, rtol: 1.0e-8}"))
    env = dict(ENV, HEXCUT_BUILD_DIR=os.path.dirname(os.path.dirname(os.path.dirname(os.environ["HEXCUT"]))))
    for kind in ("strong", "weak"):
        png = os.path.join(d, f"{kind}.png")
        p = subprocess.run([sys.executable, os.path.join(SOURCE, "scripts", "study", kind), gmg, "--ranks", "1", "2",
                            "--refine", "4", "--png", png, "--mpiexec", " ".join(os.environ.get(
                                "HEXCUT_MPIEXEC", "mpiexec").split())],
                           env=env, capture_output=True, text=True, timeout=600)
        rows = [line.split("|")[1:-1] for line in p.stdout.splitlines() if re.match(r"\| [12] \|", line)]
        ok = p.returncode == 0 and len(rows) == 2 and os.path.getsize(png) > 10000 if os.path.exists(png) else False
        check(ok, f"scripts/study/{kind} prints two rows and a plot (rc {p.returncode}) {p.stderr[-500:]}")
        if not ok:
            continue
        dofs = [int(r[2]) for r in rows]
        its = [int(r[-2]) for r in rows]
        if kind == "strong":
            check(dofs == [3 * 41 * 9 * 9] * 2 and its[0] == its[1],
                  f"strong: the same 10k DOFs and iterations on 1 and 2 ranks ({dofs}, {its})")
        else:
            # 2 ranks: the 40 x 8 x 8 lattice (gcd 8) refined by round(8 * 2^(1/3)) / 8 = 10 / 8.
            check(dofs[1] == 3 * 51 * 11 * 11 and [r[1].strip() for r in rows] == ["4", "5"],
                  f"weak: 2 ranks run refine 5 = 50 x 10 x 10 cells, about twice the DOFs ({dofs}, "
                  f"{[r[1] for r in rows]})")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
