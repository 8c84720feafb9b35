"""PETSc options override the deck's solver, for every solver (doc/user-guide.md, "Solvers"):
the solver's defaults are set on its KSP, not in the options database, so -pc_type and
-ksp_type win, nothing of a solver's defaults stays in the database after its set-up, and
hexcut's multigrid is a PC type like the others (-pc_type hexcut) whose -gmg_* options -help
lists."""
import os
import re
import sys

from cli_helpers import BEAM, Checks, run, tempdir, write

SOLVERS = ["gmg", "gmg-cycles", "hypre", "gamg", "cg-jacobi", "direct"]


def deck(directory, name, solver, extra=""):
    text = BEAM.replace("solver: {type: direct}", f"solver: {{type: {solver}{extra}}}")
    text += f"output: {{directory: {directory}, name: {name}}}\n"
    return write(directory, name + ".yaml", text)


def solver_line(out):
    m = re.search(r"hexcut: solver (\S+) \(KSP (\S+), PC (\S+)\)", out)
    return m.groups() if m else None


def iterations(out):
    m = re.search(r"step 1/1 .* its (\d+)", out)
    return int(m.group(1)) if m else None


def main():
    check = Checks()
    d = tempdir()
    for solver in SOLVERS:
        name = solver.replace("-", "_")
        path = deck(d, name, solver)
        # The command line wins over the deck's solver type, whichever it is.
        rc, out, err = run([path, "-ksp_type", "cg", "-pc_type", "jacobi"])
        check(rc == 0 and solver_line(out) == (solver, "cg", "jacobi"),
              f"{solver}: -ksp_type cg -pc_type jacobi replace the deck's solver "
              f"(rc {rc}, {solver_line(out)}) {err[-300:]}")
        # So do the deck's own petsc_options.
        path = deck(d, name + "_deck", solver, ", petsc_options: {-pc_type: jacobi, -ksp_type: cg}")
        rc, out, err = run([path])
        check(rc == 0 and solver_line(out) == (solver, "cg", "jacobi"),
              f"{solver}: the deck's petsc_options replace its type ({solver_line(out)}) "
              f"{err[-300:]}")

    # hexcut's multigrid selected from the command line on a hypre deck: CG + hexcut's
    # cycle, a handful of iterations (hypre needs far more on this beam).
    path = deck(d, "pc_hexcut", "hypre")
    rc, out, err = run([path, "-pc_type", "hexcut"])
    its = iterations(out)
    check(rc == 0 and solver_line(out) == ("hypre", "cg", "hexcut") and its is not None and its <= 12,
          f"-pc_type hexcut on a hypre deck runs hexcut's multigrid ({solver_line(out)}, "
          f"{its} iterations) {err[-300:]}")
    rc, out, err = run([path, "--overwrite"])
    check(rc == 0 and solver_line(out) == ("hypre", "cg", "hypre"),
          f"the hypre deck alone uses hypre ({solver_line(out)})")

    # The solver's defaults reach its KSP (BoomerAMG's nodal coarsening, HMIS) but are not
    # left in the options database (-options_view prints it at the end of the run).
    rc, out, err = run([path, "--overwrite", "-ksp_view", "-options_view"])
    table = out[out.find("#PETSc Option Table entries"):]
    check(rc == 0 and "Using nodal coarsening" in out and "Coarsen type        HMIS" in out,
          "hypre's defaults are applied to its KSP (-ksp_view)")
    check("#PETSc Option Table entries" in out and "boomeramg" not in table and
          "-pc_type" not in table and "-ksp_type" not in table,
          "no solver default is left in the options database:\n" + table)

    # A user's BoomerAMG option still wins over the default it replaces.
    rc, out, err = run([path, "--overwrite", "-ksp_view", "-pc_hypre_boomeramg_coarsen_type",
                        "Falgout"])
    check(rc == 0 and "Coarsen type        Falgout" in out,
          "-pc_hypre_boomeramg_coarsen_type Falgout overrides hexcut's HMIS")

    # -help lists the multigrid's options with their help text.
    path = deck(d, "help", "gmg")
    rc, out, err = run([path, "--check", "-help"])
    check(rc == 0 and "-gmg_levels" in out and "-gmg_smoother" in out and
          "hexcut geometric multigrid" in out,
          "--check -help lists the -gmg_* options")
    # Bad values of the multigrid's options are input errors (exit 2) with the option's name.
    rc, out, err = run([path, "--check", "-gmg_levels", "-1"])
    check(rc == 2 and "-gmg_levels must be >= 1" in err, f"-gmg_levels -1 is exit 2 (rc {rc}) {err}")
    rc, out, err = run([path, "--check", "-gmg_levels", "0"])
    check(rc == 0, f"-gmg_levels 0 (automatic, as its help says) is accepted (rc {rc}) {err}")
    rc, out, err = run([path, "--check", "-gmg_gather_cells", "-5"])
    check(rc == 2 and "-gmg_gather_cells must be >= 0" in err,
          f"-gmg_gather_cells -5 is exit 2 (rc {rc}) {err}")
    rc, out, err = run([path, "--check", "-gmg_smoother", "sor"])
    check(rc == 2 and "gmg_smoother" in err, f"-gmg_smoother sor is exit 2 (rc {rc}) {err}")
    rc, out, err = run([path, "--check", "-gmg_interpolation", "smoothed", "-gmg_smoother", "gs"])
    check(rc == 2 and "needs -gmg_smoother chebyshev" in err,
          f"-gmg_interpolation smoothed with gs is exit 2 (rc {rc}) {err[-300:]}")
    comp = write(d, "comp.yaml", open(path).read() + "discretization: {type: composite, level: 1}\n")
    rc, out, err = run([comp, "--check", "-gmg_interpolation", "smoothed"])
    check(rc == 2 and "not available with composite elements" in err,
          f"-gmg_interpolation smoothed with composite elements is exit 2 (rc {rc}) {err[-300:]}")
    # -gmg_backend host_loop (the CUDA backend's cycle on the host) solves like the default
    # backend; what it does not support yet is an input error naming it, before any work.
    cantilever = os.path.join(os.environ["HEXCUT_SOURCE_DIR"], "input", "examples", "cantilever.yaml")
    for ranks in (1, 2):  # on 2 ranks through its ghost exchange
        rc, out, err = run([cantilever, "-hexcut_output_directory", os.path.join(d, f"host{ranks}")],
                           ranks=ranks)
        its_host = iterations(out)
        rc, out, err = run([cantilever, "-hexcut_output_directory", os.path.join(d, f"host_loop{ranks}"),
                            "-gmg_backend", "host_loop"], ranks=ranks)
        check(rc == 0 and its_host is not None and iterations(out) == its_host,
              f"-gmg_backend host_loop on {ranks} rank(s): the host cycle's {its_host} iterations "
              f"(rc {rc}, {iterations(out)}) {err[-300:]}")
    for args, ranks, what in (([path, "-gmg_interpolation", "smoothed"], 1,
                               "-gmg_interpolation smoothed"),
                              ([path, "-gmg_interpolation", "energy", "-gmg_precision", "single"], 1,
                               "-gmg_interpolation energy with -gmg_precision single"),
                              ([comp], 1, "composite elements")):
        rc, out, err = run([*args, "--check", "-gmg_backend", "host_loop"], ranks=ranks)
        check(rc == 2 and f"-gmg_backend host_loop does not support {what}" in err,
              f"-gmg_backend host_loop with {what} is exit 2 naming it (rc {rc}) {err[-300:]}")
    # Too deep a hierarchy is an input error naming the deepest possible; composite runs count
    # -gmg_levels from the composite level, one level below the hexahedra's level 0.
    most = {}
    for name, p in (("hexahedra", path), ("composite", comp)):
        rc, out, err = run([p, "--overwrite", "-gmg_levels", "30"])
        m = re.search(r"-gmg_levels 30: the lattice is a single cell after (\d+) levels; ask for at most (\d+)",
                      err)
        check(rc == 2 and m and m.group(1) == m.group(2), f"{name}: -gmg_levels 30 is exit 2 and says how "
              f"many levels there can be (rc {rc}) {err[-300:]}")
        most[name] = int(m.group(2)) if m else -1
    check(most["composite"] == most["hexahedra"] - 1 > 0,
          f"composite elements of level 1 allow one level less than the hexahedra ({most})")
    # The multigrid's options under another solver are unused, and PETSc says so.
    path = deck(d, "unused", "cg-jacobi")
    rc, out, err = run([path, "-gmg_levels", "2"])
    check(rc == 0 and "gmg_levels" in (out + err) and "unused" in (out + err).lower(),
          "-gmg_levels with cg-jacobi is reported unused")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
