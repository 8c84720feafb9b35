#!/usr/bin/python3
"""A writer SIGKILLed between output steps leaves a complete, readable result file.

usage: check_killed_writer.py WORKDIR LAUNCHER... WRITER

Runs `LAUNCHER... WRITER WORKDIR/killed.h5 --steps 4 --kill-after-step 1` (the writer
kills rank 0 with SIGKILL right after step 1 closed; the launcher then tears the job down),
then checks with h5py that the file opens, holds steps 0..1 complete with the expected
values, and that the .xmf lists exactly those steps and no temporary file is left.
"""
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_result_file  # noqa: E402


def main():
    workdir, command = sys.argv[1], sys.argv[2:]
    os.makedirs(workdir, exist_ok=True)
    h5 = os.path.join(workdir, "killed.h5")
    for stale in (h5, h5 + ".tmp", *check_result_file.index_paths(h5)):
        if os.path.exists(stale):
            os.remove(stale)
    run = subprocess.run(command + [h5, "--steps", "4", "--kill-after-step", "1"],
                         capture_output=True, text=True, timeout=240)
    print(run.stdout)
    print(run.stderr, file=sys.stderr)
    if run.returncode == 0:
        raise AssertionError("the writer was expected to die, but exited 0")
    if "killing myself after step 1" not in run.stdout:
        raise AssertionError("the writer did not reach the kill point")
    check_result_file.check(h5, steps=2)
    print(f"OK: killed writer (exit {run.returncode}) left a readable file with steps 0..1")


if __name__ == "__main__":
    main()
