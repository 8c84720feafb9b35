#!/usr/bin/python3
"""Restart of a run whose topology changed: re-open + truncate on the writer's ranks.

usage: check_cut_restart.py WORKDIR LAUNCHER... WRITER

For K in (2, 1): runs `LAUNCHER... WRITER WORKDIR/restart_K.h5 --cuts --reopen-truncate K`
(steps 1..3 with a new mesh at step 2, then ResultWriter::open + truncate_steps_after(K)),
checks the point counts and mesh the writer reports (open: the mesh of step 2, 45 points;
after K = 2 still that mesh; after K = 1 the original /mesh, 36 points), then checks the
truncated file and its .xmf with check_result_file.check_cuts.
"""
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_result_file  # noqa: E402

EXPECTED = {  # K -> (num_points, mesh) after truncate_steps_after(K)
    2: (45, "/steps/000002/mesh"),
    1: (36, "/mesh"),
}


def main():
    workdir, command = sys.argv[1], sys.argv[2:]
    os.makedirs(workdir, exist_ok=True)
    for k, (points, mesh) in EXPECTED.items():
        h5 = os.path.join(workdir, f"restart_{k}.h5")
        run = subprocess.run(command + [h5, "--cuts", "--reopen-truncate", str(k)],
                             capture_output=True, text=True, timeout=240)
        print(run.stdout)
        print(run.stderr, file=sys.stderr)
        if run.returncode != 0:
            raise AssertionError(f"writer exited {run.returncode}")
        reopened = re.search(r"^reopened: num_points=(\d+) num_cells=(\d+) mesh=(\S+)$",
                             run.stdout, re.M)
        truncated = re.search(rf"^truncated after {k}: num_points=(\d+) num_cells=(\d+) "
                              r"mesh=(\S+)$", run.stdout, re.M)
        if not reopened or not truncated:
            raise AssertionError("the writer did not report its mesh")
        if reopened.groups() != ("45", "12", "/steps/000002/mesh"):
            raise AssertionError(f"open() after step 3 reports {reopened.groups()}")
        if truncated.groups() != (str(points), "12", mesh):
            raise AssertionError(f"truncate_steps_after({k}) reports {truncated.groups()}")
        check_result_file.check_cuts(h5, truncated_after=k)
        print(f"OK: truncated after {k}: {points} points, mesh {mesh}")


if __name__ == "__main__":
    main()
