"""Composite elements: what each level costs in accuracy and saves in time (issue 11;
doc/theory.md, "Composite elements"). Runs the project's examples on hexahedra (level 0)
and on composite elements of levels 1, 2, 3, side by side, each with solver gmg, and
prints per case and level: DOFs, set-up seconds (model, hierarchy and composite blocks:
the events hexcutSetup + hexcutAssembly of -log_view), solve seconds (hexcutSolve) or
seconds per dynamic step, peak memory, and the errors:

  cantilever        static tip deflection against Timoshenko and against level 0
  dynamic cantilever first bending period of the tip (zero crossings of u_z - mean)
                    against level 0 (linear, undamped, released from the static sag)
  bunny             static, gravity: max |u|, max von Mises, relative L2 difference of
                    the displacement field against level 0
  bunny dynamic     corotational, 16 steps of 5 ms: seconds per step after the first
  cube grid cut     the 32^3 cube cut into rods, dynamic corotational, displacement
                    difference (relative L2) against level 0 at t = 0.2 s

  /usr/bin/python3 scripts/bench/composite.py [--cases cantilever bunny ...] [--levels 0 1 2 3]
"""
import argparse
import os
import re
import subprocess
import tempfile

import h5py
import numpy as np

from benchlib import ENV, HEXCUT, example_deck, log_events


def run(deck_text, work, name, extra=()):
    """Runs a deck; returns (stdout, {event: seconds}, result path)."""
    deck = os.path.join(work, name + ".yaml")
    with open(deck, "w") as f:
        f.write(deck_text)
    p = subprocess.run([HEXCUT, deck, "-log_view", "--overwrite", *extra], env=ENV,
                       capture_output=True, text=True, cwd=work)
    if p.returncode != 0:
        raise RuntimeError(f"{name}: exit {p.returncode}: {p.stderr.strip()[-400:]}")
    return p.stdout, log_events(p.stdout), os.path.join(work, "results", name + ".h5")


def deck_of(example, name, level, edits=(), every=1, fields="[displacement, von_mises]"):
    text = example_deck(example, edits)
    text = re.sub(r"\noutput:\n(  .*\n)*", "\n", text)
    text += f"output: {{directory: results, name: {name}, every: {every}, fields: {fields}}}\n"
    if level > 0:
        text += f"discretization: {{type: composite, level: {level}}}\n"
    return text


def dofs(out):
    m = re.search(r"composite elements of level \d+: \d+ elements, (\d+) DOFs", out)
    if m:
        return int(m.group(1))
    return int(re.search(r"(\d+) DOFs \(", out).group(1))


def memory(out):
    return float(re.search(r"peak memory ([\d.]+) MiB", out).group(1))


def last_u(path):
    with h5py.File(path, "r") as f:
        steps = sorted(f["steps"].keys())
        g = f["steps/" + steps[-1]]
        mesh = g.attrs["mesh"].decode() if "mesh" in g.attrs else "/mesh"
        return f[mesh + "/points"][:], g["displacement"][:], (g["von_mises"][:] if "von_mises" in g else None)


def rel_l2(u, ref):
    return np.linalg.norm(u - ref) / np.linalg.norm(ref)


def step_seconds(out):
    walls = [float(m.group(1)) for m in re.finditer(r"^step \d+/\d+ .* wall ([\d.]+) s", out, re.M)]
    return (walls[-1] - walls[0]) / (len(walls) - 1) if len(walls) > 1 else float("nan")


def case_cantilever(work, levels):
    P, L, E, nu, b, t = 1000.0, 1.0, 200e9, 0.3, 0.1, 0.1
    I, A, G = b * t**3 / 12, b * t, E / (2 * (1 + nu))
    kappa = 10 * (1 + nu) / (12 + 11 * nu)
    timo = P * L**3 / (3 * E * I) + P * L / (kappa * G * A)
    rows, ref = [], None
    for lev in levels:
        out, ev, path = run(deck_of("cantilever.yaml", f"cant{lev}", lev), work, f"cant{lev}")
        x, u, _ = last_u(path)
        tip = -u[np.isclose(x[:, 0], 1.0), 2].mean()
        ref = tip if lev == 0 else ref
        rows.append((lev, dofs(out), ev.get("hexcutSetup", 0) + ev.get("hexcutAssembly", 0),
                     ev.get("hexcutSolve", 0), memory(out),
                     f"tip {tip:.4e} m: {100 * (tip / timo - 1):+.1f}% vs Timoshenko"
                     + (f", {100 * (tip / ref - 1):+.1f}% vs level 0" if ref else "")))
    return rows


def case_dynamic_cantilever(work, levels):
    rows, ref = [], None
    for lev in levels:
        deck = deck_of("cantilever_dynamic.yaml", f"dyn{lev}", lev,
                       [("formulation: corotational", "formulation: linear"),
                        ("end_time: 3.0      # s", "end_time: 1.5"),
                        ("rayleigh: [0.1, 0.0]", "rayleigh: [0.0, 0.0]")], fields="[displacement]")
        out, ev, path = run(deck, work, f"dyn{lev}")
        with h5py.File(path, "r") as f:
            x = f["mesh/points"][:]
            tip = np.isclose(x[:, 0], 1.0)
            names = sorted(f["steps"].keys())
            t = np.array([f["steps/" + s].attrs["time"] for s in names])
            uz = np.array([f["steps/" + s]["displacement"][:][tip, 2].mean() for s in names])
        # Released from rest under gravity: oscillates about the static sag, halfway between
        # the extremes; crossings of it in either direction are half a period apart.
        z = uz - 0.5 * (uz.max() + uz.min())
        cross = [t[i] - z[i] * (t[i + 1] - t[i]) / (z[i + 1] - z[i])
                 for i in range(len(z) - 1) if (z[i] < 0) != (z[i + 1] < 0)]
        period = 2 * np.mean(np.diff(cross)) if len(cross) > 1 else float("nan")
        ref = period if lev == 0 else ref
        # Per step without the output (written every step here).
        per_step = step_seconds(out) - ev.get("hexcutOutput", 0) / len(names)
        rows.append((lev, dofs(out), ev.get("hexcutSetup", 0) + ev.get("hexcutAssembly", 0),
                     per_step, memory(out),
                     f"period {period:.4f} s" + (f", {100 * (period / ref - 1):+.1f}% vs level 0" if ref else "")))
    return rows


def case_bunny(work, levels):
    rows, ref = [], None
    for lev in levels:
        out, ev, path = run(deck_of("bunny.yaml", f"bunny{lev}", lev), work, f"bunny{lev}")
        x, u, vm = last_u(path)
        with h5py.File(path, "r") as f:
            mat = f["mesh/cell_material"][:]
        ref = (u, vm) if lev == 0 else ref
        umax = np.linalg.norm(u, axis=1).max()
        rows.append((lev, dofs(out), ev.get("hexcutSetup", 0) + ev.get("hexcutAssembly", 0),
                     ev.get("hexcutSolve", 0), memory(out),
                     f"max|u| {umax:.3e} m, max von Mises tissue {vm[mat == 0].max():.3e} Pa, "
                     f"core {vm[mat == 1].max():.3e} Pa"
                     + (f", L2 diff {rel_l2(u, ref[0]):.3f}" if lev > 0 else "")))
    return rows


def case_bunny_dynamic(work, levels):
    rows = []
    for lev in levels:
        deck = deck_of("bunny.yaml", f"bdyn{lev}", lev,
                       [("analysis:\n  type: static",
                         "analysis:\n  type: dynamic\n  formulation: corotational\n  dt: 0.005\n"
                         "  steps: 16\n  rayleigh: [5.0, 0.0]")], every=1000)
        out, ev, path = run(deck, work, f"bdyn{lev}")
        rows.append((lev, dofs(out), ev.get("hexcutSetup", 0), step_seconds(out), memory(out),
                     "corotational step (s/step in the solve column)"))
    return rows


def case_cube_grid_cut(work, levels):
    rows, ref = [], None
    for lev in levels:
        deck = deck_of("cube_grid_cut.yaml", f"cube{lev}", lev, [("end_time: 0.5", "end_time: 0.2")],
                       every=1000)
        out, ev, path = run(deck, work, f"cube{lev}")
        x, u, _ = last_u(path)
        ref = u if lev == 0 else ref
        rows.append((lev, dofs(out), ev.get("hexcutSetup", 0), step_seconds(out), memory(out),
                     f"max|u| {np.linalg.norm(u, axis=1).max():.3f} m"
                     + (f", L2 diff {rel_l2(u, ref):.3f} at t = 0.2 s" if lev > 0 else "")))
    return rows


CASES = {
    "cantilever": case_cantilever,
    "dynamic_cantilever": case_dynamic_cantilever,
    "bunny": case_bunny,
    "bunny_dynamic": case_bunny_dynamic,
    "cube_grid_cut": case_cube_grid_cut,
}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    ap.add_argument("--levels", nargs="*", type=int, default=[0, 1, 2, 3])
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="hexcut_composite_")
    print(f"| case | level | DOFs | set-up s | solve s (static) / s per step | peak MiB | result |")
    print("|---|---|---|---|---|---|---|")
    for name in args.cases:
        try:
            rows = CASES[name](work, args.levels)
        except RuntimeError as e:
            print(f"| {name} | – | – | – | – | – | failed: {e} |")
            continue
        for lev, n, setup, solve, mem, what in rows:
            print(f"| {name} | {lev} | {n} | {setup:.2f} | {solve:.3f} | {mem:.0f} | {what} |", flush=True)


if __name__ == "__main__":
    main()
