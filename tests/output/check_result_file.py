#!/usr/bin/python3
"""Checks a result file written by output_write_result_file (see write_result_file.cpp).

usage: check_result_file.py FILE.h5 [--steps N]

Checks names, shapes, dtypes and values of every dataset against the formulas the writer
uses, then parses the .xmf with xml.etree and checks that every referenced dataset exists
in the .h5 with the stated dimensions and number type. Exits non-zero on the first failure.
"""
import os
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np

NX, NY, NZ = 3, 2, 2
NP = (NX + 1) * (NY + 1) * (NZ + 1)
NC = NX * NY * NZ
H = 0.5
ORIGIN = np.array([1.0, 2.0, 3.0])

POINT_FIELDS = {"displacement": (1, 3), "velocity": (2, 3), "acceleration": (3, 3)}
CELL_FIELDS = {"stress": (4, 6), "von_mises": (5, 1), "pressure": (6, 1),
               "principal_stress": (7, 3), "principal_directions": (8, 9)}


def value(kind, step, rows, cols):
    r = np.arange(rows, dtype=np.float64)[:, None]
    c = np.arange(cols, dtype=np.float64)[None, :]
    return 1e6 * kind + 1000.0 * step + 10.0 * r + c + 0.25


def text(v):
    if isinstance(v, np.ndarray):
        v = v[()]
    return v.decode("utf-8") if isinstance(v, (bytes, np.bytes_)) else str(v)


def expect(condition, message):
    if not condition:
        raise AssertionError(message)


def check_dataset(f, path, shape, dtype):
    expect(path in f, f"missing dataset {path}")
    d = f[path]
    expect(isinstance(d, h5py.Dataset), f"{path} is not a dataset")
    expect(d.shape == shape, f"{path}: shape {d.shape} != {shape}")
    expect(d.dtype == np.dtype(dtype), f"{path}: dtype {d.dtype} != {dtype}")
    return d[()]


def check_mesh(f):
    pts = check_dataset(f, "/mesh/points", (NP, 3), "<f8")
    idx = np.arange(NP)
    ijk = np.stack([idx % (NX + 1), idx // (NX + 1) % (NY + 1), idx // ((NX + 1) * (NY + 1))], 1)
    expect(np.array_equal(pts, ORIGIN + H * ijk), "/mesh/points values")
    cells = check_dataset(f, "/mesh/cells", (NC, 8), "<i8")
    cidx = np.arange(NC)
    ci, cj, ck = cidx % NX, cidx // NX % NY, cidx // (NX * NY)

    def vid(i, j, k):
        return i + (NX + 1) * (j + (NY + 1) * k)

    want = np.stack([vid(ci, cj, ck), vid(ci + 1, cj, ck), vid(ci + 1, cj + 1, ck),
                     vid(ci, cj + 1, ck), vid(ci, cj, ck + 1), vid(ci + 1, cj, ck + 1),
                     vid(ci + 1, cj + 1, ck + 1), vid(ci, cj + 1, ck + 1)], 1)
    expect(np.array_equal(cells, want), "/mesh/cells values")
    lat = check_dataset(f, "/mesh/cell_lattice_index", (NC, 3), "<i4")
    expect(np.array_equal(lat, np.stack([ci, cj, ck], 1)), "/mesh/cell_lattice_index values")
    mat = check_dataset(f, "/mesh/cell_material", (NC,), "<i4")
    expect(np.array_equal(mat, cidx % 2), "/mesh/cell_material values")
    ym = check_dataset(f, "/mesh/cell_youngs_modulus", (NC,), "<f8")
    expect(np.array_equal(ym, np.where(cidx % 2 == 0, 210e9, 70e9)), "youngs modulus values")
    m = f["/mesh"].attrs
    expect(np.array_equal(m["lattice_origin"], ORIGIN), "lattice_origin")
    expect(m["lattice_h"] == H, "lattice_h")
    expect(np.array_equal(m["lattice_dims"], [NX, NY, NZ]), "lattice_dims")
    expect(m["num_points"] == NP and m["num_cells"] == NC, "num_points/num_cells")
    expect(text(f["/mesh/points"].attrs["unit"]) == "m", "points unit")


def check_input(f, h5path):
    expect(text(f.attrs["format"]) == "hexcut-result", "format attribute")
    expect(f.attrs["format_version"] == 1, "format_version attribute")
    deck = text(f["/input/deck"][()])
    expect(deck == "# test deck\nsolver:\n  type: cg   # trailing spaces kept  \n"
           "unit: \"\u00b5m\"\n", f"deck text not verbatim: {deck!r}")
    cmd = text(f["/input/command_line"][()])
    expect(cmd.endswith("output_write_result_file " + h5path) or h5path in cmd,
           f"command line {cmd!r}")
    for name in ("hexcut_version", "hexcut_git_hash", "hdf5_version"):
        expect(len(text(f["/input"].attrs[name])) > 0, f"/input@{name}")


def check_steps(f, steps):
    names = sorted(f["/steps"].keys())
    expect(names == [f"{s:06d}" for s in range(steps)], f"step groups {names}")
    expect(f["/steps"].attrs["last_complete_step"] == steps - 1, "last_complete_step")
    for s in range(steps):
        g = f[f"/steps/{s:06d}"]
        expect(g.attrs["step"] == s and g.attrs["time"] == 0.25 * s, f"step {s} attributes")
        expect(g.attrs["complete"] == 1, f"step {s} not complete")
        expect(text(g.attrs["mesh"]) == "/mesh", f"step {s} mesh reference")
        expect(set(g.keys()) == set(POINT_FIELDS) | set(CELL_FIELDS), f"step {s} fields")
        for fields, rows, centering in ((POINT_FIELDS, NP, "point"), (CELL_FIELDS, NC, "cell")):
            for name, (kind, cols) in fields.items():
                shape = (rows,) if cols == 1 else (rows, cols)
                data = check_dataset(f, f"{g.name}/{name}", shape, "<f8")
                expect(np.array_equal(data.reshape(rows, cols), value(kind, s, rows, cols)),
                       f"{g.name}/{name} values")
                expect(text(g[name].attrs["centering"]) == centering, f"{name} centering")
    expect(text(f[f"/steps/{0:06d}/stress"].attrs["unit"]) == "Pa", "stress unit")

    hist = f["/solver_history"]
    expect(set(hist.keys()) == {"step", "time", "iterations", "residual_norm",
                                "relative_residual", "setup_seconds", "solve_seconds",
                                "converged_reason"}, f"solver_history columns {list(hist)}")
    s = np.arange(steps)
    for name, dtype, want in (("step", "<i8", s), ("time", "<f8", 0.25 * s),
                              ("iterations", "<i8", 10 + s),
                              ("residual_norm", "<f8", 1e-9 * (s + 1)),
                              ("relative_residual", "<f8", 1e-12 * (s + 1)),
                              ("setup_seconds", "<f8", 0.5 + 0 * s),
                              ("solve_seconds", "<f8", 1.5 + 0 * s),
                              ("converged_reason", "<i4", 2 + 0 * s)):
        data = check_dataset(f, f"/solver_history/{name}", (steps,), dtype)
        expect(np.array_equal(data, want), f"/solver_history/{name} values {data}")

    # Checkpoint of the last step (written with u, v, a = the step's point fields).
    last = steps - 1
    c = f["/checkpoint"].attrs
    expect(c["step"] == last and c["time"] == 0.25 * last, "checkpoint attributes")
    slot = f[f"/checkpoint/slot{c['current_slot']}"]
    expect(slot.attrs["complete"] == 1 and slot.attrs["step"] == last, "checkpoint slot")
    for name, kind in (("displacement", 1), ("velocity", 2), ("acceleration", 3)):
        data = check_dataset(f, f"{slot.name}/{name}", (NP, 3), "<f8")
        expect(np.array_equal(data, value(kind, last, NP, 3)), f"checkpoint {name}")
    links = check_dataset(f, f"{slot.name}/topology/links", (NC,), "<i4")
    expect(np.array_equal(links, 100 * last + np.arange(NC)), "checkpoint links")


NUMBER_TYPES = {("Float", 8): "<f8", ("Float", 4): "<f4", ("Int", 8): "<i8",
                ("Int", 4): "<i4", ("UChar", 1): "|u1"}


def check_xdmf(h5path, steps):
    xmf = os.path.splitext(h5path)[0] + ".xmf"
    expect(os.path.exists(xmf), f"missing {xmf}")
    expect(not os.path.exists(xmf + ".tmp"), "left-over .xmf.tmp")
    root = ET.parse(xmf).getroot()
    expect(root.tag == "Xdmf" and root.get("Version") == "3.0", "Xdmf root")
    collection = root.find("Domain/Grid")
    expect(collection.get("CollectionType") == "Temporal", "temporal collection")
    grids = collection.findall("Grid")
    expect(len(grids) == steps, f"{len(grids)} grids in xmf, expected {steps}")
    basename = os.path.basename(h5path)
    with h5py.File(h5path, "r") as f:
        for s, grid in enumerate(grids):
            expect(float(grid.find("Time").get("Value")) == 0.25 * s, f"grid {s} time")
            topo = grid.find("Topology")
            expect(topo.get("TopologyType") == "Hexahedron", "topology type")
            expect(int(topo.get("NumberOfElements")) == NC, "NumberOfElements")
            expect(grid.find("Geometry").get("GeometryType") == "XYZ", "geometry type")
            items = grid.findall(".//DataItem")
            names = {a.get("Name") for a in grid.findall("Attribute")}
            expect(names >= set(POINT_FIELDS) | set(CELL_FIELDS), f"grid {s} attributes {names}")
            for item in items:
                file_part, _, dataset = item.text.strip().partition(":")
                expect(file_part == basename, f"reference {item.text} is not relative")
                expect(dataset in f, f"xmf references missing dataset {dataset}")
                dims = tuple(int(x) for x in item.get("Dimensions").split())
                expect(f[dataset].shape == dims, f"{dataset}: xmf dims {dims} != {f[dataset].shape}")
                want = NUMBER_TYPES[(item.get("NumberType"), int(item.get("Precision")))]
                expect(f[dataset].dtype == np.dtype(want), f"{dataset}: xmf type {want}")
            for a in grid.findall("Attribute"):
                cols = f[a.find("DataItem").text.split(":", 1)[1]].shape[1:]
                want = {(): "Scalar", (3,): "Vector", (6,): "Tensor6", (9,): "Tensor"}[cols]
                expect(a.get("AttributeType") == want, f"{a.get('Name')} AttributeType")
                expect(a.get("Center") in ("Node", "Cell"), "Center")
            for name in POINT_FIELDS:
                a = grid.find(f"Attribute[@Name='{name}']")
                expect(a.get("Center") == "Node", f"{name} center")


def check(h5path, steps=2):
    expect(not os.path.exists(h5path + ".tmp"), "left-over .h5.tmp")
    with h5py.File(h5path, "r") as f:
        check_mesh(f)
        check_input(f, h5path)
        check_steps(f, steps)
    check_xdmf(h5path, steps)


def main():
    args = sys.argv[1:]
    steps = 2
    if "--steps" in args:
        i = args.index("--steps")
        steps = int(args[i + 1])
        del args[i:i + 2]
    check(args[0], steps)
    print(f"OK: {args[0]} ({steps} steps)")


if __name__ == "__main__":
    main()
