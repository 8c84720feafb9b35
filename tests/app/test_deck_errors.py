"""Each class of deck error gives 'deck.yaml:LINE: message' and exit code 2, before any
heavy work; --version and --check work; a non-converging solve gives exit 3 and keeps
the steps written so far readable."""
import os
import sys

import h5py

from cli_helpers import BEAM, Checks, run, tempdir, write

GOOD = BEAM

# (description, text to replace, replacement, expected line, expected message part)
CASES = [
    ("unknown key", "solver: {type: direct}", "solver: {type: direct, tolerance: 1}", 12, "unknown key 'tolerance'"),
    ("wrong type", "h: 0.1", "h: fast", 1, "lattice.h must be a number"),
    ("nu >= 0.5", "nu: 0.3", "nu: 0.5", 3, "nu must be in (-1, 0.5)"),
    ("h <= 0", "h: 0.1", "h: -0.1", 1, "lattice.h must be > 0"),
    ("unknown material", "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}",
     "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}\n    material: wood", 6, "unknown material 'wood'"),
    ("empty geometry", "max: [1.0, 0.2, 0.2]", "max: [-5.0, -4.0, -4.0]", 5, "box.max must exceed box.min"),
    ("geometry outside the lattice", "min: [0, 0, 0], max: [1.0, 0.2, 0.2]", "min: [5, 5, 5], max: [6, 6, 6]", 5,
     "the geometry is empty"),
    ("selector selects nothing", "point: [1.0, 0, 0]", "point: [3.0, 0, 0]", 10,
     "this traction selects no boundary face"),
    ("support selects nothing", "point: [0, 0, 0], normal: [1, 0, 0]}}\n  traction",
     "point: [-1, 0, 0], normal: [1, 0, 0]}}\n  traction", 8, "this support selects no vertex"),
    ("bad solver", "type: direct", "type: superlu", 12, "solver.type must be one of"),
    ("composite level out of range", "solver: {type: direct}",
     "solver: {type: direct}\ndiscretization: {type: composite, level: 5}", 13,
     "discretization.level must be 1, 2 or 3"),
    ("composite_element without composite elements", "solver: {type: direct}",
     "solver: {type: direct}\noutput:\n  fields: [displacement,\n           composite_element]", 15,
     "output field 'composite_element' needs discretization: {type: composite}"),
    ("composite without a level", "solver: {type: direct}",
     "solver: {type: direct}\ndiscretization: {type: composite}", 13,
     "discretization type composite needs 'level'"),
    ("YAML syntax", "dims: [10, 2, 2]}", "dims: [10, 2, 2]", 2, "YAML syntax error"),
    ("missing mesh file", "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}", "add: {mesh: {file: nowhere.obj}}", 5,
     "nowhere.obj' does not exist"),
    ("mesh file is a directory", "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}", "add: {mesh: {file: .}}", 5,
     "is a directory, not a file"),
    ("raw image file is a directory", "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}",
     "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}\n  - image: {file: ., format: raw, dims: [1, 1, 1], "
     "dtype: uint8, spacing: [1, 1, 1], youngs_scale: 1}", 6, "is a directory, not a file"),
    ("a folder is a DICOM series: no spacing", "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}",
     "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}\n  - image: {file: ., spacing: [1, 1, 1], "
     "youngs_scale: 1}", 6, "image.spacing is not used for a DICOM series"),
    ("a folder without DICOM files", "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}",
     "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}\n  - image: {file: ., youngs_scale: 1}", 6,
     "cannot load image"),
    ("duplicate key in a map", "h: 0.1, dims", "h: 0.1, h: 0.2, dims", 1, "duplicate key 'h' (first given on line 1)"),
    ("duplicate section", "solver: {type: direct}", "solver: {type: direct}\nsolver: {type: gmg}", 13,
     "duplicate key 'solver' (first given on line 12)"),
    ("second YAML document", "solver: {type: direct}", "solver: {type: direct}\n---\nsolver: {type: gmg}", 14,
     "more than one YAML document"),
    ("petsc_options value is a list", "solver: {type: direct}", "solver: {type: direct, petsc_options: {ksp_type: [cg]}}",
     12, "the value of '-ksp_type' must be a single value"),
    ("petsc_options key is a map", "solver: {type: direct}", "solver: {type: direct, petsc_options: {{a: 1}: 2}}",
     12, "petsc_options name must be a string"),
    ("output name with a colon", "solver: {type: direct}", 'solver: {type: direct}\noutput: {name: "job_12:30"}', 13,
     "output.name 'job_12:30' must be a plain file name"),
    ("output name with a space", "solver: {type: direct}", 'solver: {type: direct}\noutput: {name: "my run"}', 13,
     "must be a plain file name"),
    ("step count overflows", "solver: {type: direct}",
     "analysis: {type: dynamic, dt: 2.0e-10, end_time: 1.0}\nsolver: {type: direct}", 12,
     "end_time / dt = 5e+09 steps, more than the limit of 2147483647"),
    ("steps beyond int", "solver: {type: direct}", "analysis: {type: dynamic, dt: 0.1, steps: 3000000000}\nsolver: {type: direct}",
     12, "analysis.steps must be an integer"),
    ("dynamic without dt", "solver: {type: direct}", "analysis: {type: dynamic, steps: 3}\nsolver: {type: direct}", 12,
     "dynamic analysis needs 'dt'"),
]


def main():
    d = tempdir()
    check = Checks()
    rc, out, err = run(["--version"])
    check(rc == 0 and out.startswith("hexcut "), f"--version: {out.strip()} {err.strip()}")
    good = write(d, "good.yaml", GOOD)
    rc, out, err = run(["--check", good])
    check(rc == 0 and "deck is valid" in out, f"a valid deck passes --check: {out.strip()} {err.strip()}")
    for name, old, new, line, message in CASES:
        assert old in GOOD, name
        path = write(d, "deck.yaml", GOOD.replace(old, new, 1))
        rc, out, err = run(["--check", path])
        expected_prefix = f"{path}:{line}: "
        check(rc == 2 and expected_prefix in err and message in err, f"{name}: exit {rc}: {err.strip()}")
    # Errors found after parsing, with their own decks or options.
    big = write(d, "big.yaml", GOOD.replace("dims: [10, 2, 2]", "dims: [2000, 1000, 999]"))
    rc, out, err = run(["--check", big, "-hexcut_memory_available", "16"])
    check(rc == 2 and f"{big}:1: the lattice of 1998000000 cells needs about 26.1 GiB per rank" in err,
          f"a lattice too large for the memory is refused before voxelization: exit {rc}: {err.strip()}")
    solid = write(d, "solid.yaml", GOOD.replace("h: 0.1, dims: [10, 2, 2]", "h: 0.025, dims: [40, 8, 8]"))
    rc, out, err = run(["--check", solid, "-hexcut_memory_available", "0.1"])
    check(rc == 2 and f"{solid}:1: this job (2560 cells, solver direct, 1 rank(s)) needs about" in err,
          f"a job too large for the memory is refused after voxelization: exit {rc}: {err.strip()}")
    # The direct solver's estimate against measured peaks (VmHWM, doc/benchmarks.md: the
    # 8:1:1 bar of 192 x 24 x 24 cells peaked at 3.96 GiB, a 1280 x 16 x 16 bar at 8.96 GiB),
    # within the 30% the user guide promises; a bar's fill is that of its cross-section's
    # cube (the estimate of a cube of the same cells, 6.6 and 25.7 GiB, refused them).
    import re
    for dims, h, box, measured in [("[192, 24, 24]", "0.005208333333333333", "[1.0, 0.125, 0.125]", 3.96),
                                   ("[1280, 16, 16]", "0.00625", "[8.0, 0.1, 0.1]", 8.96)]:
        bar = write(d, "bar.yaml", GOOD.replace("h: 0.1, dims: [10, 2, 2]", f"h: {h}, dims: {dims}")
                    .replace("max: [1.0, 0.2, 0.2]", f"max: {box}").replace("point: [1.0, 0, 0]", f"point: [{box[1:4]}, 0, 0]"))
        rc, out, err = run(["--check", bar, "-hexcut_memory_available", "0.5"])
        m = re.search(r"solver direct, 1 rank\(s\)\) needs about ([0-9.]+) GiB per rank", err)
        check(rc == 2 and m and abs(float(m.group(1)) / measured - 1) < 0.3,
              f"direct solver's estimate for a {dims} bar within 30% of the measured {measured} GiB: {err.strip()[-200:]}")
    # gmg's estimate against the largest-lattice runs (doc/benchmarks.md, "Memory per DOF"),
    # with the coarse blocks shared (the default: the cantilever at 1.48M DOFs peaked at
    # 576 MiB, at 52.8M DOFs at 18790 MiB) and without (728 MiB, and 20221 MiB at 42.9M
    # DOFs): above the measured peak, so that a job the check lets through fits, and by less
    # than 30%.
    cantilever = os.path.join(os.environ["HEXCUT_SOURCE_DIR"], "input/examples/cantilever.yaml")
    for refine, measured, extra in [("4.5", 575.8 / 1024, []), ("15", 18789.9 / 1024, []),
                                    ("4.5", 728.4 / 1024, ["-gmg_shared_blocks", "false"]),
                                    ("14", 20221.3 / 1024, ["-gmg_shared_blocks", "0"])]:
        rc, out, err = run(["--check", cantilever, "-hexcut_refine", refine,
                            "-hexcut_memory_available", f"{measured / 2:.2f}", *extra])
        m = re.search(r"solver gmg, 1 rank\(s\)\) needs about ([0-9.]+) GiB per rank", err)
        check(rc == 2 and m and 1.0 <= float(m.group(1)) / measured < 1.3,
              f"gmg's estimate for the cantilever refined {refine} {' '.join(extra)} "
              f"({m.group(1) if m else '?'} GiB) is 1-1.3x the measured {measured:.2f} GiB: "
              f"{'' if m else err.strip()[-300:]}")
    for args, message in [(["-ksp_type", "nosuchtype"], "invalid PETSc option: Unable to find requested KSP type nosuchtype"),
                          (["-ksp_type", "cg", "-ksp_rtol", "abc"], "invalid PETSc option: Input string abc has no numeric value"),
                          (["-hexcut_memory_available", "lots"], "-hexcut_memory_available must be a number of GiB"),
                          (["-gmg_shared_blocks", "abc"], "invalid PETSc option: Unknown logical value: abc")]:
        rc, out, err = run(["--check", good, *args])
        check(rc == 2 and message in err and "PETSC ERROR" not in err,
              f"--check {' '.join(args)}: exit {rc}: {err.strip()}")
    # The deck must be UTF-8 (it is stored in the result file and names reach XML).
    raw = GOOD.encode() + b"# caf\xe9 au lait\n"
    with open(f"{d}/latin1.yaml", "wb") as f:
        f.write(raw)
    rc, out, err = run(["--check", f"{d}/latin1.yaml"])
    check(rc == 2 and f"{d}/latin1.yaml:13: the deck is not valid UTF-8 (column 6)" in err,
          f"non-UTF-8 bytes in a comment: exit {rc}: {err.strip()}")
    # A default output name (the deck's stem) that the index cannot refer to.
    colon = write(d, "job_12:30.yaml", GOOD)
    rc, out, err = run(["--check", colon])
    check(rc == 2 and "give output.name" in err, f"deck file name with ':' and no output.name: exit {rc}: {err.strip()}")

    # A solve that cannot converge: exit 3, the steps written before stay readable.
    dyn = GOOD.replace("solver: {type: direct}",
                       "analysis: {type: dynamic, dt: 1.0e-4, steps: 5}\n"
                       "solver: {type: cg-jacobi, rtol: 1.0e-12, max_iterations: 3}\n"
                       f"output: {{directory: {d}, name: failing}}\n")
    path = write(d, "failing.yaml", dyn)
    rc, out, err = run([path])
    ok = rc == 3 and "DIVERGED_ITS" in err
    with h5py.File(f"{d}/failing.h5", "r") as f:
        ok = ok and f["steps"].attrs["last_complete_step"] == 0 and f["steps/000000/displacement"].shape[1] == 3
    check(ok, f"non-converging solve: exit {rc}: {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
