#!/usr/bin/python3
"""Real hexcut output through ParaView's three XDMF readers (ctest output_paraview_run).

usage: check_paraview_run.py WORKDIR PVBATCH
(environment as for tests/app: HEXCUT, HEXCUT_MPIEXEC; PYTHONPATH holding tests/app)

Runs a small dynamic deck with a cut (a 1 m bar of 20 x 2 x 2 cells, corotational, under
an oblique gravity so that every stress component is non-zero; dt = 0.05 s; a blade
through x = 0.6 m at t = 0.1 s, a multiple of dt) on 1 and on 2 ranks. Each result's
indexes must pass check_result_file.check_indexes (XML, every file:dataset exists with its
dimensions), and both runs must write the same indexes. Then `pvbatch check_paraview.py
--run` opens both indexes of the 2-rank result with each reader (arrays as in the file,
the stress invariants, Glyph, the split mesh when asked for t = 0.1); the readers see the
same index text for the 1-rank result. The same for a compare run against a shorter bar
(comparison fields NaN where the reference has no cell; the compare_summary table stays out
of the index).
"""
import os
import shutil
import subprocess
import sys

from cli_helpers import Checks, run, write

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_result_file  # noqa: E402

CUT_TIME = "0.1"
DECK = f"""lattice: {{h: 0.05, dims: [20, 2, 2]}}
materials: {{m: {{E: 1.0e6, nu: 0.3, rho: 1000}}}}
geometry: [{{add: {{box: {{min: [0, 0, 0], max: [1, 0.1, 0.1]}}}}}}]
boundary:
  fixed: [{{where: {{plane: {{point: [0, 0, 0], normal: [1, 0, 0]}}}}}}]
  gravity: [0, -4.9, -8.5]
cuts:
  - blade: {{polygon: [[0.6, -1, -1], [0.6, 1, -1], [0.6, 1, 1], [0.6, -1, 1]]}}
    time: {CUT_TIME}
analysis: {{type: dynamic, formulation: corotational, dt: 0.05, end_time: 0.25}}
solver: {{type: gmg}}
output: {{directory: OUT, name: bar}}
"""


def read(path):
    with open(path, "rb") as f:
        return f.read()


def main():
    workdir, pvbatch = sys.argv[1], sys.argv[2]
    shutil.rmtree(workdir, ignore_errors=True)  # hexcut does not replace a result
    check = Checks()
    results = []
    for ranks in (1, 2):
        d = os.path.join(workdir, f"ranks{ranks}")
        os.makedirs(d, exist_ok=True)
        deck = write(d, "bar.yaml", DECK.replace("OUT", d))
        rc, out, err = run([deck], ranks=ranks, cwd=d)
        h5 = os.path.join(d, "bar.h5")
        check(rc == 0 and "2 piece(s)" in out,
              f"the cut bar runs on {ranks} rank(s): {err.strip()}")
        try:
            check_result_file.check_indexes(h5)
            check(True, f"{ranks} rank(s): both indexes parse and every file:dataset exists")
        except (AssertionError, OSError) as e:
            check(False, f"{ranks} rank(s): indexes: {e}")
        results.append(h5)
    same = all(read(a) == read(b) for a, b in zip(*(check_result_file.index_paths(h5)
                                                    for h5 in results)))
    check(same, "1 and 2 ranks write the same indexes")

    # A compare run: the bar against a reference bar 5 cm shorter, so the comparison fields
    # are NaN in the last cells (the readers must show them as in the file) and each step
    # holds the compare_summary table, which is not a mesh field and not in the index.
    d = os.path.join(workdir, "compare")
    os.makedirs(d, exist_ok=True)
    short = DECK.replace("OUT", d).replace("name: bar", "name: short").replace(
        "max: [1, 0.1, 0.1]", "max: [0.95, 0.1, 0.1]")
    rc, out, err = run([write(d, "short.yaml", short)], cwd=d)
    compared = DECK.replace("OUT", d).replace("name: bar", "name: compared") + \
        f"compare: {{reference: {os.path.join(d, 'short.h5')}}}\n"
    rc2, out2, err2 = run([write(d, "compared.yaml", compared)], cwd=d)
    check(rc == 0 and rc2 == 0 and "compare step" in out2,
          f"the bar compared with a shorter one runs: {err.strip()} {err2.strip()}")
    results.append(os.path.join(d, "compared.h5"))

    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "check_paraview.py")
    for h5 in (results[1], results[2]):
        p = subprocess.run([pvbatch, script, "--run", h5, "--cut-time", CUT_TIME],
                           capture_output=True, text=True, timeout=600)
        print(p.stdout)
        print(p.stderr[-5000:], file=sys.stderr)
        ok_lines = [line for line in p.stdout.splitlines() if line.startswith("OK:")]
        check(p.returncode == 0 and len(ok_lines) == 3,
              f"pvbatch: every reader reads both indexes of {os.path.basename(h5)} right "
              f"(exit {p.returncode})")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
