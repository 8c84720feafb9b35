"""Shared helpers for the command-line tests: run hexcut, write decks to a temp dir."""
import os
import subprocess
import tempfile

HEXCUT = os.environ["HEXCUT"]
MPIEXEC = os.environ.get("HEXCUT_MPIEXEC", "mpiexec").split()
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")


# A steel beam 1 m x 0.2 m x 0.2 m, clamped at x = 0, pulled down at its tip: the
# smallest deck the CLI tests vary (its line numbers are used by test_deck_errors.py).
BEAM = """\
lattice: {h: 0.1, dims: [10, 2, 2]}
materials:
  steel: {E: 200.0e9, nu: 0.3, rho: 7800}
geometry:
  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}
boundary:
  fixed:
    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
  traction:
    - where: {plane: {point: [1.0, 0, 0], normal: [1, 0, 0]}}
      value: [0, 0, -1000.0]
solver: {type: direct}
"""


def run(args, ranks=1, cwd=None):
    cmd = ([*MPIEXEC, "-n", str(ranks)] if ranks > 1 else []) + [HEXCUT, *args]
    p = subprocess.run(cmd, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def write(directory, name, text):
    path = os.path.join(directory, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def tempdir():
    return tempfile.mkdtemp(prefix="hexcut-test-")


class Checks:
    """Collects named checks, prints 'ok'/'FAIL' per check and the closing tally line
    that CI reads ('N passed, N failed')."""

    def __init__(self):
        self.passed = 0
        self.failed = []

    def __call__(self, ok, what):
        print(("ok  " if ok else "FAIL"), what, flush=True)
        if ok:
            self.passed += 1
        else:
            self.failed.append(what)

    def finish(self):
        print(f"{self.passed} passed, {len(self.failed)} failed")
        return 1 if self.failed else 0
