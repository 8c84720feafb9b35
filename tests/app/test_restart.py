"""Checkpoint and restart: a run killed midway (SIGKILL) leaves a readable file whose
last checkpoint continues, with --restart, to the same result as an uninterrupted run
(to round-off on the same number of ranks; to solver tolerance on 2 ranks). Also the
batch-chunking option -hexcut_max_steps."""
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np

from cli_helpers import ENV, HEXCUT, Checks, run, tempdir, write

DECK = """\
lattice: {h: 0.05, dims: [20, 2, 2]}
materials:
  rubber: {E: 5.0e6, nu: 0.3, rho: 1000}
geometry:
  - add: {box: {min: [0, 0, 0], max: [1.0, 0.1, 0.1]}}
boundary:
  fixed:
    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
  gravity: [0, 0, -9.81]
analysis: {type: dynamic, formulation: corotational, dt: 0.01, steps: 40}
solver: {type: direct}
output: {directory: OUT, name: bar, every: 2, checkpoint_every: 5}
"""


def final_displacement(path):
    with h5py.File(path, "r") as f:
        last = f["steps"].attrs["last_complete_step"]
        steps = sorted(int(s) for s in f["steps"])
        return last, steps, f[f"steps/{last:06d}/displacement"][:], f["solver_history/step"][:]


def rel(a, b):
    return np.abs(a - b).max() / np.abs(a).max()


def main():
    d = tempdir()
    check = Checks()

    full = write(d, "full.yaml", DECK.replace("OUT", f"{d}/full"))
    rc, out, err = run([full])
    check(rc == 0, f"uninterrupted run exits 0 ({rc}) {err}")
    last_ref, steps_ref, u_ref, _ = final_displacement(f"{d}/full/bar.h5")

    # Kill the run once step 23 is reported: the last checkpoint is step 20.
    killed = write(d, "killed.yaml", DECK.replace("OUT", f"{d}/killed"))
    p = subprocess.Popen([HEXCUT, killed], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.startswith("step 23/"):
            p.send_signal(signal.SIGKILL)
            break
    p.wait()
    check(p.returncode == -signal.SIGKILL, f"run killed at step 23 (returncode {p.returncode})")
    with h5py.File(f"{d}/killed/bar.h5", "r") as f:
        last = int(f["steps"].attrs["last_complete_step"])
        check(20 <= last <= 23 and int(f["checkpoint"].attrs["step"]) == 20,
              f"killed file readable: last step {last}, checkpoint {int(f['checkpoint'].attrs['step'])}")
    shutil.copytree(f"{d}/killed", f"{d}/killed2")

    rc, out, err = run([killed, "--restart", f"{d}/killed/bar.h5"])
    check(rc == 0 and "restarting from" in out, f"restart exits 0 ({rc}) {err}")
    last, steps, u, hist = final_displacement(f"{d}/killed/bar.h5")
    check(last == last_ref and steps == steps_ref, f"restarted file has the same steps ({steps[-3:]})")
    check(np.all(np.diff(hist) >= 0) and hist[-1] == 40, "solver history continues without duplicates")
    diff = rel(u_ref, u)
    check(diff < 1e-12, f"restart equals the uninterrupted run: relative difference {diff:.2e}")

    rc, out, err = run([killed, "--restart", f"{d}/killed2/bar.h5"], ranks=2)
    _, _, u2, _ = final_displacement(f"{d}/killed2/bar.h5")
    diff2 = rel(u_ref, u2)
    check(rc == 0 and diff2 < 1e-8, f"restart on 2 ranks equals the 1-rank run: {diff2:.2e} (exit {rc}) {err}")

    # Chunked run: two invocations of 20 steps.
    chunk = write(d, "chunk.yaml", DECK.replace("OUT", f"{d}/chunk"))
    rc1, out1, _ = run([chunk, "-hexcut_max_steps", "20"])
    rc2, out2, _ = run([chunk, "--restart", f"{d}/chunk/bar.h5", "-hexcut_max_steps", "20"])
    _, _, u3, _ = final_displacement(f"{d}/chunk/bar.h5")
    diff3 = rel(u_ref, u3)
    check(rc1 == 0 and rc2 == 0 and "stopped after 20 steps" in out1 and diff3 < 1e-12,
          f"two chunks of 20 steps equal one run: {diff3:.2e}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
