"""compare: {reference: FILE}: the stress of a run against a reference result of the same
lattice (doc/user-guide.md, "compare"):

- a run compared with itself gives exactly zero differences and zero shielding;
- a linear run under twice the load gives sigma - sigma_ref = sigma_ref, a strain-energy
  density change of 3 W_ref and a shielding of -3 in every cell, on 1 and 2 ranks;
- a reference with an implant-like gap (cells the run has and the reference lacks) leaves
  those cells NaN and compares the others;
- a reference of another lattice, one without strain_energy_density and a missing file
  are refused with exit 2 at the deck line of compare.reference, before any solve;
- the per-material summary is stored in the step (compare_summary) with the printed means;
- ParaView reads the difference fields."""
import os
import subprocess

import h5py
import numpy as np

from cli_helpers import BEAM, Checks, run, tempdir, write


def fields(path):
    with h5py.File(path) as f:
        g = f["/steps/" + sorted(f["steps"].keys())[-1]]
        return {k: g[k][()] for k in g.keys() if isinstance(g[k], h5py.Dataset)}


def main():
    d = tempdir()
    check = Checks()
    ref_deck = write(d, "intact.yaml", BEAM + f"output: {{directory: {d}/ref}}\n")
    rc, out, err = run([ref_deck])
    check(rc == 0, f"reference run: exit {rc} {err.strip()[-200:]}")
    ref = f"{d}/ref/intact.h5"
    r = fields(ref)

    same = write(d, "same.yaml", BEAM + f"output: {{directory: {d}/same}}\ncompare: {{reference: {ref}}}\n")
    rc, out, err = run([same])
    check(rc == 0 and "compare step 1 (reference step 1): steel: 40 cells" in out,
          f"compared with itself: exit {rc} {out.strip()[-300:]} {err.strip()[-200:]}")
    s = fields(f"{d}/same/same.h5")
    zero = all(np.all(s[k] == 0) for k in ("stress_difference", "stress_difference_norm", "von_mises_change",
                                            "strain_energy_density_change", "stress_shielding"))
    check(zero, "compared with itself: every difference and the shielding are exactly 0")

    double = BEAM.replace("value: [0, 0, -1000.0]", "value: [0, 0, -2000.0]")
    for ranks in (1, 2):
        deck = write(d, f"double{ranks}.yaml", double + f"output: {{directory: {d}/double{ranks}}}\n"
                     f"compare: {{reference: {ref}}}\n")
        rc, out, err = run([deck], ranks=ranks)
        check(rc == 0, f"twice the load, {ranks} rank(s): exit {rc} {err.strip()[-200:]}")
        if rc != 0:
            continue
        t = fields(f"{d}/double{ranks}/double{ranks}.h5")
        scale = np.abs(r["stress"]).max()
        e1 = np.abs(t["stress_difference"] - r["stress"]).max() / scale
        e2 = np.abs(t["strain_energy_density_change"] - 3 * r["strain_energy_density"]).max() / r["strain_energy_density"].max()
        e3 = np.abs(t["stress_shielding"] + 3).max()
        check(max(e1, e2, e3) < 1e-7,  # the direct solve of a stiff beam: ~1e-9
               f"twice the load, {ranks} rank(s): d sigma = sigma_ref to {e1:.1e}, "
              f"dW = 3 W_ref to {e2:.1e}, shielding = -3 to {e3:.1e}")
        # The printed summary is stored in the step: one row per material.
        with h5py.File(f"{d}/double{ranks}/double{ranks}.h5") as f:
            g = f["/steps/" + sorted(f["steps"].keys())[-1]]
            tab, attrs = g["compare_summary"][()], g["compare_summary"].attrs
            cols = attrs["columns"].decode().split(",")
            row = dict(zip(cols, tab[0])) if tab.shape == (1, 6) else {}
            names = attrs["rows"].decode()
        vm_ref = np.mean(r["von_mises"])
        check(names == "steel" and row.get("cells") == 40 and row.get("reference_step") == 1
              and abs(row.get("mean_stress_shielding", 0) + 3) < 1e-7
              and abs(row.get("mean_von_mises_change", 0) - vm_ref) < 1e-7 * vm_ref
              and abs(row.get("mean_stress_difference_norm", 0)
                      - np.mean(t["stress_difference_norm"])) < 1e-9 * vm_ref,
              f"twice the load, {ranks} rank(s): compare_summary {names}: {row} "
              f"(mean von Mises of the reference {vm_ref:.6g})")

    # A reference without the cells of a slot (as a bone without its implant's cells).
    gap = BEAM.replace("  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}",
                       "  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}\n"
                       "  - subtract: {box: {min: [0.4, 0, 0], max: [0.6, 0.1, 0.2]}}")
    gap_deck = write(d, "gap.yaml", gap + f"output: {{directory: {d}/gap}}\n")
    rc, out, err = run([gap_deck])
    check(rc == 0, f"reference with a gap: exit {rc} {err.strip()[-200:]}")
    deck = write(d, "vs_gap.yaml", BEAM + f"output: {{directory: {d}/vs_gap}}\ncompare: {{reference: {d}/gap/gap.h5}}\n")
    rc, out, err = run([deck])
    check(rc == 0 and "steel: 36 cells" in out, f"against the gap: exit {rc} {out.strip()[-200:]} {err.strip()[-200:]}")
    if rc == 0:
        g = fields(f"{d}/vs_gap/vs_gap.h5")
        nans = int(np.isnan(g["stress_difference_norm"]).sum())
        check(nans == 4 and np.all(np.isfinite(g["stress_difference_norm"][~np.isnan(g["stress_difference_norm"])])),
              f"against the gap: the 4 cells the reference lacks are NaN ({nans})")

    # Refused before any work, at the line of compare.reference (the deck's last line).
    line = BEAM.count("\n") + 3  # output, compare, reference
    other = write(d, "other.yaml", BEAM.replace("h: 0.1, dims: [10, 2, 2]", "h: 0.05, dims: [20, 4, 4]")
                  + f"output: {{directory: {d}/other}}\ncompare:\n  reference: {ref}\n")
    rc, out, err = run([other])
    check(rc == 2 and f"other.yaml:{line}: compare.reference" in err and "lattice" in err
          and not os.path.exists(f"{d}/other/other.h5"), f"another lattice: exit {rc} {err.strip()}")
    nosed = write(d, "nosed.yaml", BEAM + f"output: {{directory: {d}/nosed, fields: [displacement, stress]}}\n")
    run([nosed])
    deck = write(d, "vs_nosed.yaml", BEAM + f"output: {{directory: {d}/vs_nosed}}\ncompare:\n  reference: {d}/nosed/nosed.h5\n")
    rc, out, err = run([deck])
    check(rc == 2 and "strain_energy_density" in err, f"reference without strain_energy_density: exit {rc} {err.strip()}")
    deck = write(d, "missing.yaml", BEAM + f"compare: {{reference: {d}/none.h5}}\n")
    rc, out, err = run([deck])
    check(rc == 2 and "missing.yaml:" in err, f"missing reference: exit {rc} {err.strip()}")

    # A run that would write into its own reference (a --restart of itself) is refused.
    own = write(d, "own.yaml", BEAM + f"output: {{directory: {d}/own, checkpoint_every: 1}}\n")
    run([own])
    deck = write(d, "own2.yaml", BEAM + f"output: {{directory: {d}/own, name: own}}\n"
                 f"compare: {{reference: {d}/own/own.h5}}\n")
    rc, out, err = run([deck, "--restart", f"{d}/own/own.h5"])
    check(rc == 2 and "is the result file this run writes into" in err,
          f"reference = the restarted file: exit {rc}: {err.strip()[-300:]}")

    # ParaView reads the comparison fields.
    script = os.path.join(d, "pv.py")
    with open(script, "w") as f:
        f.write("from paraview.simple import *\n"
                f"r = Xdmf3ReaderS(FileName=['{d}/double1/double1.xmf'])\n"
                "r.UpdatePipeline()\n"
                "a = r.CellData['stress_shielding'].GetRange()\n"
                "print('shielding range', a[0], a[1])\n")
    try:
        p = subprocess.run(["pvbatch", script], capture_output=True, text=True, timeout=300)
        ok = p.returncode == 0 and "shielding range -3" in p.stdout
        check(ok, f"ParaView reads stress_shielding: {p.stdout.strip()[-200:]} {p.stderr.strip()[-200:]}")
    except FileNotFoundError:
        print("skip ParaView check: pvbatch not installed")
    return check.finish()


if __name__ == "__main__":
    raise SystemExit(main())
