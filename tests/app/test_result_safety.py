"""A run never destroys a user's data (doc/user-guide.md, "Result files"):

- a rerun over an existing result is refused (exit 2, nothing touched) unless told to
  replace it (--overwrite or output.overwrite); a replacing run writes NAME.new.h5 and
  renames it over NAME.h5 only when it succeeds, so a failed rerun leaves the old result;
- a second run on a result that another run is writing is refused at start and does not
  touch the first run's file;
- --restart with a deck whose physics differs from the checkpoint's is refused, naming
  the keys; solver and output settings and the end time may change;
- typos on the command line are errors before anything is written, and unused PETSc
  options get PETSc's warning."""
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py

from cli_helpers import BEAM, ENV, HEXCUT, Checks, run, tempdir, write

STATIC = BEAM.replace("type: direct", "type: cg-jacobi") + "output: {directory: OUT, name: beam}\n"

CUTS = """\
cuts:
  - blade: {polygon: [[0.61, -1, -1], [0.61, 1, -1], [0.61, 1, 1], [0.61, -1, 1]]}
    time: 0.5"""

# The bar of the issue's concurrent-writer case (40x4x4 cells).
DYNAMIC = """\
lattice: {h: 0.025, dims: [40, 4, 4]}
materials:
  rubber: {E: 2.0e6, nu: 0.3, rho: 1000}
geometry:
  - add: {box: {min: [0, 0, 0], max: [1.0, 0.1, 0.1]}}
boundary:
  fixed:
    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
  gravity: [0, 0, -9.81]
CUTS
analysis: {type: dynamic, dt: 0.01, steps: STEPS}
solver: {type: gmg}
output: {directory: OUT, name: bar, every: 10, checkpoint_every: 25}
""".replace("CUTS", CUTS)


def info(path):
    """(last complete step, command line, deck, solver_history rows) of a result file."""
    with h5py.File(path, "r") as f:
        return (int(f["steps"].attrs["last_complete_step"]), f["input/command_line"][()].decode(),
                f["input/deck"][()].decode(), len(f["solver_history/step"]) if "solver_history" in f else 0)


def xdmf_files(path):
    """The HDF5 files an XDMF index refers to (it must parse as XML)."""
    root = ET.parse(path).getroot()
    return {item.text.strip().split(":")[0] for item in root.iter("DataItem") if item.get("Format") == "HDF"}


def main():
    d = tempdir()
    check = Checks()
    out = f"{d}/out"
    deck = write(d, "beam.yaml", STATIC.replace("OUT", out))
    h5 = f"{out}/beam.h5"

    rc, _, err = run([deck])
    check(rc == 0, f"first run exits 0 ({rc}) {err.strip()}")
    first = info(h5)
    mtime = os.stat(h5).st_mtime_ns

    # 1. A plain rerun is refused before anything happens.
    rc, _, err = run([deck, "-ksp_max_it", "1"])
    check(rc == 2 and f"{deck}:13: " in err and "exists" in err and "--overwrite" in err,
          f"rerun without --overwrite: exit {rc}: {err.strip()}")
    check(os.stat(h5).st_mtime_ns == mtime and info(h5) == first, "the earlier result is untouched")

    # 2. A replacing rerun that fails leaves the earlier result as it was.
    rc, _, err = run([deck, "--overwrite", "-ksp_max_it", "1"])
    check(rc == 3 and "unchanged" in err, f"failing rerun with --overwrite: exit {rc}: {err.strip()}")
    check(info(h5) == first and os.stat(h5).st_mtime_ns == mtime,
          f"after the failed rerun the earlier result is intact: {info(h5)[:2]}")
    check(os.path.exists(f"{out}/beam.new.h5") and "-ksp_max_it 1" in info(f"{out}/beam.new.h5")[1],
          "the failed rerun's own output is in beam.new.h5")

    # 3. A replacing rerun that succeeds replaces it, with the index pointing at beam.h5.
    rc, _, err = run([deck, "--overwrite", "-ksp_rtol", "1e-10"])
    now = info(h5)
    check(rc == 0 and now[0] == 1 and "-ksp_rtol 1e-10" in now[1], f"successful rerun replaces: exit {rc}, {now[:2]}")
    leftovers = [n for n in os.listdir(out) if n.startswith("beam.new")]
    check(not leftovers, f"no temporary files left: {leftovers}")
    check(xdmf_files(f"{out}/beam.xmf") == {"beam.h5"}, f"the index refers to beam.h5: {xdmf_files(f'{out}/beam.xmf')}")
    check(xdmf_files(f"{out}/beam_surface.xmf") == {"beam.h5"},
          f"the surface index refers to beam.h5: {xdmf_files(f'{out}/beam_surface.xmf')}")

    # 4. output.overwrite: true does the same from the deck.
    deck2 = write(d, "beam2.yaml", STATIC.replace("OUT", out).replace("name: beam}", "name: beam, overwrite: true}"))
    rc, _, err = run([deck2])
    check(rc == 0 and info(h5)[1].endswith("beam2.yaml"), f"output.overwrite: true replaces: exit {rc} {err.strip()}")

    # 5. Command-line typos: errors before anything is written.
    for args, message in [(["--restrat", h5], "unknown argument '--restrat'"),
                          (["-hexcut_max_step", "10"], "did you mean -hexcut_max_steps?"),
                          (["-hexcut_max_steps", "-3"], "-hexcut_max_steps must be an integer >= 1, got '-3'"),
                          (["-hexcut_max_steps", "0"], "-hexcut_max_steps must be an integer >= 1, got '0'"),
                          (["-hexcut_max_steps", "abc"], "-hexcut_max_steps must be an integer >= 1, got 'abc'"),
                          (["-hexcut_superblock", "6"], "-hexcut_superblock must be a power of two"),
                          (["--overwrite", "-ksp_type", "nonsense"], "invalid PETSc option: Unable to find requested KSP type nonsense")]:
        before = info(h5)
        rc, _, err = run([deck2, *args])
        check(rc == 2 and message in err and "PETSC ERROR" not in err and info(h5) == before,
              f"{' '.join(args)}: exit {rc}, file untouched: {err.strip()[:200]}")
    rc, stdout, err = run([deck, "--overwrite", "-ksp_monitr"])
    check(rc == 0 and "WARNING! There are options you set that were not used!" in stdout and "-ksp_monitr" in stdout,
          f"an unused PETSc option gets PETSc's warning: exit {rc}")
    check("There are options you set" not in run([deck, "--overwrite"])[1], "no warning without unused options")

    # 6. Two runs on one result: the second is refused at start, the first is not disturbed.
    bar_out = f"{d}/bars"
    bar = write(d, "bar.yaml", DYNAMIC.replace("OUT", bar_out).replace("STEPS", "300"))
    bar_b = write(d, "bar_b.yaml", DYNAMIC.replace("OUT", bar_out).replace("STEPS", "300").replace("2.0e6", "3.0e6"))
    first_run = subprocess.Popen([HEXCUT, bar], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in first_run.stdout:
        if line.startswith("step 3/"):
            break
    results = []
    for args in ([bar_b], [bar_b, "--overwrite"], [bar, "--restart", f"{bar_out}/bar.h5"]):
        rc, _, err = run(args)
        results.append((rc, "being written by another hexcut run" in err, err.strip()[:300]))
    first_run.stdout.read()
    first_run.wait()
    check(all(rc == 2 and said for rc, said, _ in results), f"a second run on a busy result is refused: {results}")
    last, _, stored_deck, rows = info(f"{bar_out}/bar.h5")
    check(first_run.returncode == 0 and last == 300 and "2.0e6" in stored_deck and "3.0e6" not in stored_deck
          and rows == 300, f"the first run ends 0 with its own deck and 300 history rows: {first_run.returncode}, {last}, {rows}")

    # 7. Restart with a changed deck: refused with the keys; allowed changes continue.
    chunk_out = f"{d}/chunk"
    chunk = DYNAMIC.replace("OUT", chunk_out).replace("STEPS", "60")
    path = write(d, "chunk.yaml", chunk)
    rc, _, err = run([path, "-hexcut_max_steps", "30"])
    check(rc == 0, f"a chunk of 30 steps: {rc} {err.strip()}")
    partial = f"{chunk_out}/bar.h5"
    before = info(partial)
    changed = [
        ("E", chunk.replace("2.0e6", "3.0e6"), "materials.rubber.E"),
        ("dt", chunk.replace("dt: 0.01", "dt: 0.005"), "analysis.dt"),
        ("formulation", chunk.replace("type: dynamic,", "type: dynamic, formulation: corotational,"),
         "analysis.formulation"),
        ("cut moved", chunk.replace("0.61", "0.41"), "cuts[0].blade.polygon[0][0]"),
        ("cut removed", chunk.replace(CUTS + "\n", ""), "cuts"),
        ("h and box doubled", chunk.replace("h: 0.025", "h: 0.05").replace("max: [1.0, 0.1, 0.1]", "max: [2.0, 0.2, 0.2]"),
         "lattice.h"),
        ("mesh of the body", chunk.replace("max: [1.0, 0.1, 0.1]", "max: [1.0, 0.1, 0.075]"), "geometry[0].add.box.max[2]"),
    ]
    for name, text, key in changed:
        p = write(d, "changed.yaml", text)
        rc, _, err = run([p, "--restart", partial])
        check(rc == 2 and key in err and "physics differs" in err and info(partial) == before,
              f"restart with {name} changed: exit {rc}, names {key}: {err.strip()[:300]}")
    allowed = chunk.replace("steps: 60", "steps: 50").replace("type: gmg", "type: cg-jacobi, rtol: 1.0e-9") \
                   .replace("every: 10", "every: 5")
    p = write(d, "allowed.yaml", allowed)
    rc, out_text, err = run([p, "--restart", partial])
    check(rc == 0 and info(partial)[0] == 50, f"restart with another end, solver and output interval: exit {rc} {err.strip()[:300]}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
