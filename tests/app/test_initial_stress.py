"""initial_stress: a residual stress sigma0 of the cells (doc/theory.md "Initial stress",
doc/user-guide.md "initial_stress"), checked against what equilibrium says independently:

- a uniform sigma0 (every component) leaves a free block at rest: u = 0 exactly in a
  dynamic run without supports and in a static one with 3-2-1 supports, and the stress
  output is sigma0 itself (von Mises of sigma0);
- a self-equilibrated linear field sigma_xx = a + b (y - y0) leaves the uncut bar at rest;
  cut in half (ends on rollers), each half relaxes: the cut opens by (a + b (y - y0)) L / E
  (the exact solution: axial stretch plus pure bending of each half), the mean opening
  exactly, the slope to the trilinear elements' bending error, which shrinks ~4x with h/2;
  the total stress sigma0 + sigma(u) after the cut is near zero; 2 ranks = 1 rank; on
  composite elements of level 1 the neutral line opens by a L / E as well;
- a field not in equilibrium, sigma_xx = k x (nu = 0, ends clamped), acts as the body force
  div sigma0 = k: u_x = k x (L - x) / (2 E), exact at the nodes;
- the same field from an HDF5 dataset (file + dataset) gives the expression's result;
  NaN cells keep the earlier entry's value and are reported;
- bad entries are refused with exit 2 and 'deck.yaml:LINE: message'."""
import os

import h5py
import numpy as np

from cli_helpers import Checks, run, tempdir, write

E = 1.0e6


def last_step(path):
    with h5py.File(path) as f:
        key = sorted(f["steps"].keys())[-1]
        g = f["steps/" + key]
        mesh = g.attrs["mesh"].decode()
        out = {k: g[k][()] for k in g.keys() if isinstance(g[k], h5py.Dataset)}
        out["points"] = f[mesh + "/points"][()]
        out["cells"] = f[mesh + "/cell_index"][()] if (mesh + "/cell_index") in f else None
        return out


def bar_deck(n, initial, cut, ranks_dir, nu=0.3, supports=None):
    """A bar 0.16 x 0.08 x 0.04 m with n cells per 0.01 m; ends on rollers (u_x = 0),
    u_y = u_z = 0 at the centre of each end face, u_z = 0 along its line z = 0.02."""
    h = 0.01 / n
    e = 1e-4
    rollers = f"""    - where: {{plane: {{point: [0, 0, 0], normal: [1, 0, 0]}}}}
      components: [x]
    - where: {{plane: {{point: [0.16, 0, 0], normal: [1, 0, 0]}}}}
      components: [x]
    - where: {{box: {{min: [{-e}, {0.04 - e}, {0.02 - e}], max: [{e}, {0.04 + e}, {0.02 + e}]}}}}
    - where: {{box: {{min: [{0.16 - e}, {0.04 - e}, {0.02 - e}], max: [{0.16 + e}, {0.04 + e}, {0.02 + e}]}}}}
    - where: {{box: {{min: [{-e}, -1, {0.02 - e}], max: [{e}, 1, {0.02 + e}]}}}}
      components: [z]
    - where: {{box: {{min: [{0.16 - e}, -1, {0.02 - e}], max: [{0.16 + e}, 1, {0.02 + e}]}}}}
      components: [z]
"""
    blade = "cuts:\n  - blade: {polygon: [[0.08, -1, -1], [0.08, 1, -1], [0.08, 1, 1], [0.08, -1, 1]]}\n"
    return f"""lattice: {{h: {h}, dims: [{16 * n}, {8 * n}, {4 * n}]}}
materials: {{m: {{E: {E}, nu: {nu}, rho: 1000}}}}
geometry: [{{add: {{box: {{min: [0, 0, 0], max: [0.16, 0.08, 0.04]}}}}}}]
boundary:
  fixed:
{supports or rollers}initial_stress:
{initial}{blade if cut else ""}solver: {{type: direct}}
output: {{directory: {ranks_dir}}}
"""


def entry_line(deck, k=0):
    """The deck line (1-based) of initial_stress entry k."""
    return deck.splitlines().index("initial_stress:") + 2 + k


def opening(r):
    """Per lattice vertex on the cut plane x = 0.08 (line z = 0.02): y and the jump of u_x."""
    p, u = r["points"], r["displacement"]
    on = np.isclose(p[:, 0], 0.08) & np.isclose(p[:, 2], 0.02)
    ys = np.unique(np.round(p[on, 1], 12))
    gap = []
    for y in ys:
        ux = u[on & np.isclose(p[:, 1], y), 0]
        gap.append(ux.max() - ux.min())
    return ys, np.array(gap)


def main():
    d = tempdir()
    check = Checks()
    a, b = 1.0e4, 1.0e5  # Pa, Pa/m
    linear = f'  - value: ["{a} + {b} * (y - 0.04)", 0, 0, 0, 0, 0]\n'

    # 1. Uniform sigma0 (all six components, ParaView order): a free block stays at rest.
    s0 = [3.0e3, -1.0e3, 2.0e3, 5.0e2, -7.0e2, 4.0e2]
    uniform = "  - value: [" + ", ".join(str(v) for v in s0) + "]\n"
    free = f"""lattice: {{h: 0.01, dims: [6, 5, 4]}}
materials: {{m: {{E: {E}, nu: 0.3, rho: 1000}}}}
geometry: [{{add: {{sphere: {{centre: [0.03, 0.025, 0.02], radius: 0.024}}}}}}]
initial_stress:
{uniform}analysis: {{type: dynamic, dt: 0.001, steps: 3}}
solver: {{type: gmg}}
output: {{directory: {d}/free}}
"""
    rc, out, err = run([write(d, "free.yaml", free)])
    check(rc == 0, f"free sphere with uniform sigma0 runs: exit {rc} {err.strip()[-300:]}")
    if rc == 0:
        r = last_step(f"{d}/free/free.h5")
        sig = r["stress"]
        vm = np.sqrt(0.5 * ((s0[0] - s0[1]) ** 2 + (s0[1] - s0[2]) ** 2 + (s0[2] - s0[0]) ** 2)
                     + 3 * (s0[3] ** 2 + s0[4] ** 2 + s0[5] ** 2))
        check(np.abs(r["displacement"]).max() == 0.0 and np.abs(r["velocity"]).max() == 0.0,
              f"free body, uniform sigma0, 3 dynamic steps: max |u| = {np.abs(r['displacement']).max():.3g} "
              "(exactly 0: the uncut body is in equilibrium)")
        check(np.allclose(sig, s0, rtol=0, atol=1e-9 * max(map(abs, s0)))
              and np.allclose(r["von_mises"], vm, rtol=1e-12),
              f"stress output = sigma0 in every cell, von Mises {r['von_mises'].mean():.6g} (sigma0's: {vm:.6g})")

    static321 = """    - where: {box: {min: [-1, -1, -1], max: [1.0e-4, 1.0e-4, 1.0e-4]}}
    - where: {box: {min: [0.16, -1, -1], max: [1, 1.0e-4, 1.0e-4]}}
      components: [y, z]
    - where: {box: {min: [-1, 0.08, -1], max: [1.0e-4, 1, 1.0e-4]}}
      components: [z]
"""
    deck = bar_deck(1, uniform, False, f"{d}/s321", supports=static321)
    rc, out, err = run([write(d, "s321.yaml", deck)])
    r = last_step(f"{d}/s321/s321.h5") if rc == 0 else None
    check(rc == 0 and np.abs(r["displacement"]).max() == 0.0,
          f"static, 3-2-1 supports, uniform sigma0: exit {rc}, u = 0 exactly {err.strip()[-200:]}")

    # 2. A self-equilibrated linear field: the uncut bar stays at rest ...
    rc, out, err = run([write(d, "uncut.yaml", bar_deck(1, linear, False, f"{d}/uncut"))])
    if rc == 0:
        r = last_step(f"{d}/uncut/uncut.h5")
        # cell centres from the cell's corner points: stress_xx = a + b (y_c - 0.04)
        check(np.abs(r["displacement"]).max() == 0.0,
              f"uncut bar, sigma_xx = a + b (y - y0): u = 0 exactly (max {np.abs(r['displacement']).max():.3g})")
        sxx = np.sort(np.unique(np.round(r["stress"][:, 0], 6)))
        want = a + b * (np.arange(8) * 0.01 + 0.005 - 0.04)
        check(np.allclose(sxx, want, rtol=1e-12) and np.abs(r["stress"][:, 1:]).max() == 0.0,
              f"uncut bar: stress_xx takes the 8 cell-centre values a + b (y_c - y0): {sxx}")
    else:
        check(False, f"uncut bar: exit {rc} {err.strip()[-300:]}")

    # ... and cut in half each half relaxes: the cut opens by (a + b (y - y0)) L / E.
    L = 0.16
    slope_error = []
    for n in (1, 2):
        rc, out, err = run([write(d, f"cut{n}.yaml", bar_deck(n, linear, True, f"{d}/cut{n}"))])
        if rc != 0:
            check(False, f"cut bar h = {0.01 / n}: exit {rc} {err.strip()[-300:]}")
            continue
        r = last_step(f"{d}/cut{n}/cut{n}.h5")
        ys, gap = opening(r)
        mid = np.isclose(ys, 0.04)
        exact = (a + b * (ys - 0.04)) * L / E
        slope = np.polyfit(ys, gap, 1)[0]
        slope_error.append(abs(slope / (b * L / E) - 1))
        check(abs(gap[mid][0] / exact[mid][0] - 1) < 1e-9 and abs(gap.mean() / exact.mean() - 1) < 1e-9,
              f"cut bar h = {0.01 / n}: opening at the neutral line {gap[mid][0]:.6e} m, mean {gap.mean():.6e} m "
              f"(a L / E = {a * L / E:.6e})")
        check(slope_error[-1] < 0.05,
              f"cut bar h = {0.01 / n}: opening slope {slope:.5g} (b L / E = {b * L / E:.5g}; "
              f"{100 * slope_error[-1]:.2f} % off: trilinear bending)")
        total = np.abs(r["stress"]).max()
        check(total < 0.1 * a,
              f"cut bar h = {0.01 / n}: total stress after the cut max |sigma0 + sigma(u)| = {total:.4g} Pa "
              f"(sigma0 up to {a + 0.04 * b:.3g} Pa: released)")
        if n == 1:
            rc2, out2, err2 = run([write(d, "cut1r2.yaml", bar_deck(1, linear, True, f"{d}/cut1r2"))], ranks=2)
            r2 = last_step(f"{d}/cut1r2/cut1r2.h5") if rc2 == 0 else None
            same = rc2 == 0 and np.allclose(r2["displacement"], r["displacement"], rtol=0,
                                            atol=1e-10 * np.abs(r["displacement"]).max())
            check(same, f"cut bar on 2 ranks = 1 rank: exit {rc2} {err2.strip()[-200:]}")
    # Composite elements of level 1 (coarse cells as elements): the same load through I^T; the
    # axial part of the opening is in their space too, so the neutral line opens by a L / E.
    comp = bar_deck(1, linear, True, f"{d}/comp").replace(
        "solver: {type: direct}", "solver: {type: gmg}\ndiscretization: {type: composite, level: 1}")
    rc, out, err = run([write(d, "comp.yaml", comp)])
    if rc == 0:
        ys, gap = opening(last_step(f"{d}/comp/comp.h5"))
        mid = gap[np.isclose(ys, 0.04)][0]
        check(abs(mid / (a * L / E) - 1) < 1e-7,
              f"composite level 1, cut bar: opening at the neutral line {mid:.6e} m (a L / E = {a * L / E:.6e})")
    else:
        check(False, f"composite cut bar: exit {rc} {err.strip()[-300:]}")
    if len(slope_error) == 2:
        check(slope_error[1] < slope_error[0] / 3,
              f"the slope error shrinks with h: {100 * slope_error[0]:.2f} % -> {100 * slope_error[1]:.2f} %")

    # 3. Not in equilibrium: sigma_xx = k x acts as the body force k e_x (nu = 0, clamped ends).
    k = 1.0e5
    clamps = """    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
    - where: {plane: {point: [0.16, 0, 0], normal: [1, 0, 0]}}
"""
    deck = bar_deck(1, f'  - value: ["{k} * x", 0, 0, 0, 0, 0]\n', False, f"{d}/kx", nu=0.0, supports=clamps)
    rc, out, err = run([write(d, "kx.yaml", deck)])
    if rc == 0:
        r = last_step(f"{d}/kx/kx.h5")
        x = r["points"][:, 0]
        exact = k * x * (L - x) / (2 * E)
        err_max = np.abs(r["displacement"][:, 0] - exact).max()
        check(err_max < 1e-9 * exact.max() and np.abs(r["displacement"][:, 1:]).max() < 1e-12 * exact.max(),
              f"sigma_xx = k x: u_x = k x (L - x) / (2E) at every node (max error {err_max:.3g} m of {exact.max():.4g})")
    else:
        check(False, f"sigma_xx = k x: exit {rc} {err.strip()[-300:]}")

    # 4. The same linear field from an HDF5 dataset (nz, ny, nx, 6), with a NaN row that
    # keeps the earlier entry's value.
    nx, ny, nz = 16, 8, 4
    yc = (np.arange(ny) + 0.5) * 0.01
    data = np.zeros((nz, ny, nx, 6))
    data[..., 0] = (a + b * (yc - 0.04))[None, :, None]
    with h5py.File(f"{d}/sigma0.h5", "w") as f:
        f["s"] = data
        holed = data.copy()
        holed[:, 0, :, :] = np.nan  # the row y_c = 0.005 m: no value there
        f["holed"] = holed
        f["wrong"] = data[:, :, :8]
    rc, out, err = run([write(d, "file.yaml", bar_deck(1, "  - {file: sigma0.h5, dataset: s}\n", True, f"{d}/file"))])
    ref = last_step(f"{d}/cut1/cut1.h5")
    if rc == 0:
        r = last_step(f"{d}/file/file.h5")
        diff = np.abs(r["displacement"] - ref["displacement"]).max()
        check(diff <= 1e-12 * np.abs(ref["displacement"]).max(),
              f"sigma0 from an HDF5 dataset = the expression: max |du| = {diff:.3g} m")
    else:
        check(False, f"sigma0 from a dataset: exit {rc} {err.strip()[-300:]}")
    # the holed dataset after the expression: its NaN row keeps the expression's values
    entries = linear + "  - {file: sigma0.h5, dataset: holed}\n"
    holed_deck = bar_deck(1, entries, True, f"{d}/holed")
    rc, out, err = run([write(d, "holed.yaml", holed_deck)])
    if rc == 0:
        r = last_step(f"{d}/holed/holed.h5")
        diff = np.abs(r["displacement"] - ref["displacement"]).max()
        check(diff <= 1e-12 * np.abs(ref["displacement"]).max() and
              f"holed.yaml:{entry_line(holed_deck, 1)}: warning: the dataset has no value (NaN) in 64 of the 512 cells" in out + err,
              f"NaN cells keep the earlier entry's value and are reported: max |du| = {diff:.3g} m "
              f"{(out + err).strip()[-300:]}")
    else:
        check(False, f"holed dataset: exit {rc} {err.strip()[-300:]}")

    # 5. Bad entries: exit 2 with the deck line, before any solve.
    bad = {
        "a time-dependent expression": ('  - value: ["1e3 * t", 0, 0, 0, 0, 0]\n', "fixed in time"),
        "five components": ("  - value: [1, 2, 3, 4, 5]\n", "list of 6 numbers or expressions"),
        "a dataset of another shape": ("  - {file: sigma0.h5, dataset: wrong}\n", "must be (nz, ny, nx, 6) = (4, 8, 16, 6)"),
        "a missing dataset": ("  - {file: sigma0.h5, dataset: nothere}\n", "no dataset 'nothere'"),
        "value and file": ("  - {value: [1, 0, 0, 0, 0, 0], file: sigma0.h5, dataset: s}\n", "not both"),
        "an unknown material": ("  - {material: steel, value: [1, 0, 0, 0, 0, 0]}\n", "steel"),
        "an expression that is not finite": ('  - value: ["1 / (x - 0.005)", 0, 0, 0, 0, 0]\n', "is inf at x = 0.005"),
    }
    for what, (entry, msg) in bad.items():
        deck = bar_deck(1, entry, False, f"{d}/bad")
        line = entry_line(deck)
        path = write(d, "bad.yaml", deck)
        rc, out, err = run([path])
        check(rc == 2 and f"bad.yaml:{line}:" in err and msg in err and not os.path.exists(f"{d}/bad/bad.h5"),
              f"{what}: exit {rc}, {err.strip()[-200:]}")
    coro = bar_deck(1, linear, False, f"{d}/bad") + "analysis: {formulation: corotational}\n"
    rc, out, err = run([write(d, "bad.yaml", coro)])
    check(rc == 2 and f"bad.yaml:{entry_line(coro)}:" in err and "formulation: linear" in err,
          f"corotational with initial stress (not implemented): exit {rc}, {err.strip()[-200:]}")
    return check.finish()


if __name__ == "__main__":
    raise SystemExit(main())
