#!/usr/bin/env python3
"""Draws slices of a hexcut result's stress fields to PNG: per chosen field one panel of the
cells cut by a lattice plane (the cells whose centres lie in the layer that holds the plane),
coloured by the cell value, empty lattice cells left white; `principal` adds a panel with the
in-plane part of the first principal direction as line segments, coloured by the first
principal stress. Reads only the HDF5 file (doc/output-format.md), with h5py and matplotlib.
  /usr/bin/python3 scripts/plot_stress.py RESULT.h5 OUT.png [--step -1] [--axis z] [--at 0.5]
      [--fields von_mises von_mises_change stress_shielding principal] [--title TEXT]
--step is an index into the complete output steps (-1: the last); --at a coordinate along
--axis in m (default: the lattice's middle). --fields defaults to von_mises, then the
comparison fields the step holds (von_mises_change, stress_shielding), then principal.
Errors (exit 2): a step, field or plane the file does not have."""
import argparse
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

AXES = {"x": 0, "y": 1, "z": 2}
LABELS = {
    "von_mises": "von Mises [Pa]",
    "von_mises_change": "change of von Mises [Pa]",
    "stress_shielding": "stress shielding (W_ref - W) / W_ref, clipped to [-1, 1]",
    "strain_energy_density": "strain-energy density [J/m^3]",
    "strain_energy_density_change": "change of strain-energy density [J/m^3]",
    "stress_difference_norm": "|sigma - sigma_ref| [Pa]",
    "principal_stress_1": "first principal stress [Pa]",
}
DIVERGING = {"von_mises_change", "stress_shielding", "strain_energy_density_change"}


class UserError(Exception):
    pass


def complete_steps(f):
    return sorted(k for k in f["steps"] if f["steps"][k].attrs.get("complete", 0))


def slice_cells(f, step, axis, at):
    """The lattice layer through the plane `axis` = `at` of output step `step` (an index into
    the complete steps): (rows of the step's cells in that layer, their in-plane lattice
    indices (n, 2), the in-plane lattice dims (2,), the lattice origin and h, the layer k, the
    step group)."""
    names = complete_steps(f)
    if not names:
        raise UserError("the file has no complete output step")
    if not -len(names) <= step < len(names):
        raise UserError(f"step index {step} out of range: the file has {len(names)} complete steps")
    g = f["steps"][names[step]]
    mesh = f[g.attrs["mesh"].decode() if isinstance(g.attrs["mesh"], bytes) else g.attrs["mesh"]]
    origin = np.asarray(mesh.attrs["lattice_origin"], dtype=float)
    h = float(mesh.attrs["lattice_h"])
    dims = np.asarray(mesh.attrs["lattice_dims"], dtype=int)
    a = AXES[axis]
    if at is None:
        at = origin[a] + 0.5 * h * dims[a]
    k = int(np.floor((at - origin[a]) / h))
    if not 0 <= k < dims[a]:
        raise UserError(f"plane {axis} = {at} m is outside the lattice "
                        f"[{origin[a]}, {origin[a] + h * dims[a]}] m")
    ijk = mesh["cell_lattice_index"][()]
    rows = np.nonzero(ijk[:, a] == k)[0]
    inplane = [b for b in range(3) if b != a]
    return rows, ijk[rows][:, inplane], dims[inplane], origin, h, k, g, inplane


def field_image(g, rows, ij, dims2, name):
    """Cell field `name` of step group `g` on the layer: an (ny, nx) array (row = second in-plane
    axis), NaN where the lattice has no cell."""
    if name not in g:
        have = ", ".join(sorted(k for k in g if g[k].attrs.get("centering", b"") in (b"cell", "cell")))
        raise UserError(f"the step has no cell field '{name}' (it has: {have})")
    values = g[name][()]
    if values.ndim != 1:
        raise UserError(f"'{name}' is not a scalar cell field (shape {values.shape})")
    img = np.full((dims2[1], dims2[0]), np.nan)
    img[ij[:, 1], ij[:, 0]] = values[rows]
    return img


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("result")
    ap.add_argument("out")
    ap.add_argument("--step", type=int, default=-1)
    ap.add_argument("--axis", default="z", choices=list(AXES))
    ap.add_argument("--at", type=float, default=None, help="plane position along --axis [m]")
    ap.add_argument("--fields", nargs="+", default=None)
    ap.add_argument("--title", default="")
    a = ap.parse_args(argv)
    try:
        with h5py.File(a.result, "r") as f:
            rows, ij, dims2, origin, h, k, g, inplane = slice_cells(f, a.step, a.axis, a.at)
            fields = a.fields or (["von_mises"] + [n for n in ("von_mises_change", "stress_shielding")
                                                   if n in g] + ["principal"])
            panels = []
            for name in fields:
                if name == "principal":
                    for need in ("principal_direction_1", "principal_stress_1"):
                        if need not in g:
                            raise UserError(f"'principal' needs the step's '{need}' "
                                            "(output field principal_directions)")
                    d = g["principal_direction_1"][()][rows][:, inplane]
                    panels.append((name, field_image(g, rows, ij, dims2, "principal_stress_1"), d))
                else:
                    panels.append((name, field_image(g, rows, ij, dims2, name), None))
            time = float(g.attrs.get("time", 0.0))
    except (UserError, OSError) as e:
        print(f"plot_stress.py: {a.result}: {e}", file=sys.stderr)
        return 2
    lo = [origin[b] for b in inplane]
    extent = [lo[0], lo[0] + h * dims2[0], lo[1], lo[1] + h * dims2[1]]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False)
    names = "xyz"
    for ax, (name, img, d) in zip(axes[0], panels):
        finite = img[np.isfinite(img)]
        if name == "stress_shielding":
            # A relative loss: 1 is fully shielded, -1 twice the reference's energy; beyond
            # that (cells the reference barely loaded) the colour saturates.
            kw = dict(cmap="coolwarm", vmin=-1.0, vmax=1.0)
        elif (name in DIVERGING or d is not None) and finite.size:
            m = float(np.max(np.abs(finite))) or 1.0
            kw = dict(cmap="coolwarm", vmin=-m, vmax=m)
        else:
            kw = dict(cmap="viridis")
        im = ax.imshow(img, origin="lower", extent=extent, interpolation="nearest", **kw)
        fig.colorbar(im, ax=ax, shrink=0.8, label=LABELS.get(name if d is None else "principal_stress_1", name))
        if d is not None:
            # Segments through the cell centres, half a cell long each way, in-plane part.
            c = np.asarray(lo) + h * (ij + 0.5)
            seg = 0.45 * h * d
            ax.plot(np.stack([c[:, 0] - seg[:, 0], c[:, 0] + seg[:, 0]]),
                    np.stack([c[:, 1] - seg[:, 1], c[:, 1] + seg[:, 1]]), "k-", lw=0.6)
            ax.set_title("first principal direction")
        else:
            ax.set_title(name)
        ax.set_xlabel(f"{names[inplane[0]]} [m]")
        ax.set_ylabel(f"{names[inplane[1]]} [m]")
    plane = origin[AXES[a.axis]] + h * (k + 0.5)
    fig.suptitle((a.title + "\n" if a.title else "") +
                 f"t = {time:g} s, cells with centre {a.axis} = {plane:g} m")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
