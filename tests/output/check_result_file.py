#!/usr/bin/python3
"""Checks a result file written by output_write_result_file (see write_result_file.cpp).

usage: check_result_file.py FILE.h5 [--steps N]
       check_result_file.py FILE.h5 --cuts [--truncated-after K]

Checks names, shapes, dtypes and values of every dataset against the formulas the writer
uses, then parses the .xmf with xml.etree and checks that every referenced dataset exists
in the .h5 with the stated dimensions and number type. Exits non-zero on the first failure.

--cuts: the file of `output_write_result_file --cuts` (steps 1..3; step 2 splits the
vertex copies of the plane i = 2 and writes a new mesh; surfaces on steps 1 and 3), read
the way doc/output-format.md tells: each step's mesh is the group named by the step's
`mesh` attribute, its surface is /steps/NNNNNN/surface. Meshes and surfaces are checked
for geometric invariants (cell corners on their lattice cube, closed outward surfaces
enclosing the body's volume, cut faces on the cut plane, owner cells containing their
vertices) rather than against a copy of the writer's tables. --truncated-after K: the file
was then re-opened and truncated after step K.
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
            names = {a.get("Name") for a in grid.findall("Attribute")}
            expect(names >= set(POINT_FIELDS) | set(CELL_FIELDS), f"grid {s} attributes {names}")
            check_data_items(f, grid, basename)
            for a in grid.findall("Attribute"):
                cols = f[a.find("DataItem").text.split(":", 1)[1]].shape[1:]
                want = {(): "Scalar", (3,): "Vector", (6,): "Tensor6", (9,): "Tensor"}[cols]
                expect(a.get("AttributeType") == want, f"{a.get('Name')} AttributeType")
                expect(a.get("Center") in ("Node", "Cell"), "Center")
            for name in POINT_FIELDS:
                a = grid.find(f"Attribute[@Name='{name}']")
                expect(a.get("Center") == "Node", f"{name} center")


# ----------------------------------------------------------------------------- --cuts
CUT_STEPS = (1, 2, 3)
CUT_MESH_STEP = 2  # the step whose write_mesh split the vertex copies
SURFACE_BOXES = {1: 1, 3: 2}  # step -> closed boxes in its surface
NP_SPLIT = NP + (NY + 1) * (NZ + 1)
CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                    [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])


def surface_offset(step):
    return np.array([0.001, 0.002, 0.003]) * step


def step_mesh(f, name):
    """The documented rule: a step's mesh is the group its `mesh` attribute names."""
    return text(f[f"/steps/{name}"].attrs["mesh"])


def check_mesh_group(f, mesh, split):
    """Any mesh of the cut fixture: the lattice's cells; split: plane i = 2 cut."""
    npts = NP_SPLIT if split else NP
    pts = check_dataset(f, f"{mesh}/points", (npts, 3), "<f8")
    cells = check_dataset(f, f"{mesh}/cells", (NC, 8), "<i8")
    lat = check_dataset(f, f"{mesh}/cell_lattice_index", (NC, 3), "<i4")
    cidx = np.arange(NC)
    expect(np.array_equal(lat, np.stack([cidx % NX, cidx // NX % NY, cidx // (NX * NY)], 1)),
           f"{mesh}/cell_lattice_index values")
    mat = check_dataset(f, f"{mesh}/cell_material", (NC,), "<i4")
    expect(np.array_equal(mat, cidx % 2), f"{mesh}/cell_material values")
    check_dataset(f, f"{mesh}/cell_youngs_modulus", (NC,), "<f8")
    a = f[mesh].attrs
    expect(a["num_points"] == npts and a["num_cells"] == NC, f"{mesh} num_points/num_cells")
    expect(np.array_equal(a["lattice_origin"], ORIGIN) and a["lattice_h"] == H and
           np.array_equal(a["lattice_dims"], [NX, NY, NZ]), f"{mesh} lattice attributes")
    expect(text(f[f"{mesh}/points"].attrs["unit"]) == "m", f"{mesh}/points unit")
    # Every cell's corners are the corners of its lattice cube, in VTK order.
    want = ORIGIN + H * (lat[:, None, :] + CORNERS[None, :, :])
    expect(np.array_equal(pts[cells], want), f"{mesh}: cell corners off their lattice cube")
    expect(np.array_equal(np.unique(cells), np.arange(npts)), f"{mesh}: unused points")
    # The cells on either side of the plane i = 2 share points unless the mesh is split.
    left, right = np.unique(cells[lat[:, 0] < 2]), np.unique(cells[lat[:, 0] >= 2])
    shared = len(np.intersect1d(left, right))
    expect(shared == (0 if split else (NY + 1) * (NZ + 1)), f"{mesh}: {shared} shared points")
    return npts


def check_surface(f, name, step, mesh, boxes):
    base = f"/steps/{name}/surface"
    nv, nt = 8 * boxes, 12 * boxes
    pts = check_dataset(f, f"{base}/points", (nv, 3), "<f8")
    owner = check_dataset(f, f"{base}/owner_cell", (nv,), "<i4")
    tri = check_dataset(f, f"{base}/triangles", (nt, 3), "<i8")
    cut = check_dataset(f, f"{base}/cut_id", (nt,), "<i4")
    a = f[base].attrs
    expect(a["num_points"] == nv and a["num_triangles"] == nt, f"{base} counts")
    expect(text(a["mesh"]) == mesh, f"{base}@mesh")
    expect(text(f[f"{base}/points"].attrs["unit"]) == "m", f"{base}/points unit")
    expect(tri.min() >= 0 and tri.max() < nv, f"{base}: vertex index out of range")
    ref = pts - surface_offset(step)
    grid = (ref - ORIGIN) / H
    expect(np.allclose(grid, np.round(grid)), f"{base}: vertices off the lattice")
    grid = np.round(grid).astype(int)
    # Closed and consistently oriented: each directed edge once, its reverse once.
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    directed = set(map(tuple, edges))
    expect(len(directed) == len(edges), f"{base}: repeated directed edge")
    expect(directed == set(map(tuple, edges[:, ::-1])), f"{base}: not closed")
    # Outward: the enclosed volume (divergence theorem) is the body's.
    p0, p1, p2 = ref[tri[:, 0]], ref[tri[:, 1]], ref[tri[:, 2]]
    volume = np.einsum("ij,ij->i", p0, np.cross(p1, p2)).sum() / 6.0
    expect(np.isclose(volume, NX * NY * NZ * H ** 3), f"{base}: enclosed volume {volume}")
    # Each vertex moves with a cell of the step's mesh whose cube holds it.
    expect(owner.min() >= 0 and owner.max() < f[f"{mesh}/cells"].shape[0], f"{base}: owner")
    ijk = f[f"{mesh}/cell_lattice_index"][()][owner]
    expect(np.all((ijk <= grid) & (grid <= ijk + 1)), f"{base}: owner cell misses its vertex")
    # Cut faces: exactly the triangles on the cut plane x = origin + 2h.
    on_plane = np.all(grid[tri][:, :, 0] == 2, axis=1)
    expect(np.array_equal(cut, on_plane.astype(np.int32)), f"{base}: cut_id {cut}")
    expect(on_plane.sum() == (0 if boxes == 1 else 4), f"{base}: {on_plane.sum()} cut triangles")
    if boxes > 1:  # the two sides of the cut move with the cells on their side
        sides = ijk[tri[on_plane]][:, :, 0]
        expect(np.all(sides == sides[:, :1]) and set(sides[:, 0]) == {1, 2},
               f"{base}: cut faces' owner cells {sides}")


def check_cut_steps(f, steps):
    names = sorted(f["/steps"].keys())
    expect(names == [f"{s:06d}" for s in steps], f"step groups {names}")
    expect(f["/steps"].attrs["last_complete_step"] == steps[-1], "last_complete_step")
    for s in steps:
        name = f"{s:06d}"
        g = f[f"/steps/{name}"]
        expect(g.attrs["step"] == s and g.attrs["time"] == 0.25 * s and g.attrs["complete"] == 1,
               f"step {s} attributes")
        mesh = step_mesh(f, name)
        split = s >= CUT_MESH_STEP
        expect(mesh == (f"/steps/{CUT_MESH_STEP:06d}/mesh" if split else "/mesh"),
               f"step {s} mesh {mesh}")
        if s == CUT_MESH_STEP:
            expect(f[mesh].attrs["step"] == s, f"{mesh}@step")
        npts = check_mesh_group(f, mesh, split)
        expect(set(g.keys()) == set(POINT_FIELDS) | set(CELL_FIELDS) |
               ({"mesh"} if s == CUT_MESH_STEP else set()) |
               ({"surface"} if s in SURFACE_BOXES else set()), f"step {s} members {list(g)}")
        for fields, rows in ((POINT_FIELDS, npts), (CELL_FIELDS, NC)):
            for fname, (kind, cols) in fields.items():
                shape = (rows,) if cols == 1 else (rows, cols)
                data = check_dataset(f, f"{g.name}/{fname}", shape, "<f8")
                expect(np.array_equal(data.reshape(rows, cols), value(kind, s, rows, cols)),
                       f"{g.name}/{fname} values")
        if s in SURFACE_BOXES:
            check_surface(f, name, s, mesh, SURFACE_BOXES[s])
    hist = check_dataset(f, "/solver_history/step", (len(steps),), "<i8")
    expect(np.array_equal(hist, steps), f"/solver_history/step {hist}")
    # The checkpoint is not truncated: still step 3's, with the split mesh's point count.
    c = f["/checkpoint"].attrs
    slot = f[f"/checkpoint/slot{c['current_slot']}"]
    expect(c["step"] == 3 and slot.attrs["complete"] == 1, "checkpoint attributes")
    for fname, kind in (("displacement", 1), ("velocity", 2), ("acceleration", 3)):
        data = check_dataset(f, f"{slot.name}/{fname}", (NP_SPLIT, 3), "<f8")
        expect(np.array_equal(data, value(kind, 3, NP_SPLIT, 3)), f"checkpoint {fname}")


def check_data_items(f, grid, basename):
    for item in grid.iter("DataItem"):
        file_part, _, dataset = item.text.strip().partition(":")
        expect(file_part == basename, f"reference {item.text} is not relative")
        expect(dataset in f, f"xmf references missing dataset {dataset}")
        dims = tuple(int(x) for x in item.get("Dimensions").split())
        expect(f[dataset].shape == dims, f"{dataset}: xmf dims {dims} != {f[dataset].shape}")
        want = NUMBER_TYPES[(item.get("NumberType"), int(item.get("Precision")))]
        expect(f[dataset].dtype == np.dtype(want), f"{dataset}: xmf type {want}")


def ref(grid, path):
    item = grid.find(path)
    expect(item is not None, f"{grid.get('Name')}: no {path}")
    return item.text.strip().partition(":")[2]


def check_cut_xdmf(h5path, steps):
    xmf = os.path.splitext(h5path)[0] + ".xmf"
    root = ET.parse(xmf).getroot()
    collections = root.findall("Domain/Grid")
    expect([c.get("Name") for c in collections] == ["hexcut", "hexcut_surface"],
           f"top-level grids {[c.get('Name') for c in collections]}")
    expect(all(c.get("GridType") == "Collection" and c.get("CollectionType") == "Temporal"
               for c in collections), "temporal collections")
    volume, surface = collections
    basename = os.path.basename(h5path)
    with h5py.File(h5path, "r") as f:
        grids = volume.findall("Grid")
        expect([g.get("Name") for g in grids] == [f"step_{s:06d}" for s in steps],
               f"volume grids {[g.get('Name') for g in grids]}")
        for s, grid in zip(steps, grids):
            name = f"{s:06d}"
            mesh = step_mesh(f, name)
            expect(float(grid.find("Time").get("Value")) == 0.25 * s, f"grid {s} time")
            expect(ref(grid, "Topology/DataItem") == f"{mesh}/cells", f"step {s} topology")
            expect(ref(grid, "Geometry/DataItem") == f"{mesh}/points", f"step {s} geometry")
            topo = grid.find("Topology")
            expect(topo.get("TopologyType") == "Hexahedron" and
                   int(topo.get("NumberOfElements")) == NC, f"step {s} topology attributes")
            for a in grid.findall("Attribute"):
                path = ref(a, "DataItem")
                expect(path.startswith(f"/steps/{name}/") or path.startswith(f"{mesh}/cell_"),
                       f"step {s} attribute {a.get('Name')} from {path}")
            check_data_items(f, grid, basename)
        with_surface = [s for s in steps if s in SURFACE_BOXES]
        grids = surface.findall("Grid")
        expect([g.get("Name") for g in grids] == [f"surface_{s:06d}" for s in with_surface],
               f"surface grids {[g.get('Name') for g in grids]}")
        for s, grid in zip(with_surface, grids):
            base = f"/steps/{s:06d}/surface"
            expect(float(grid.find("Time").get("Value")) == 0.25 * s, f"surface {s} time")
            topo = grid.find("Topology")
            expect(topo.get("TopologyType") == "Triangle" and
                   int(topo.get("NumberOfElements")) == 12 * SURFACE_BOXES[s],
                   f"surface {s} topology attributes")
            expect(ref(grid, "Topology/DataItem") == f"{base}/triangles", "surface topology")
            expect(ref(grid, "Geometry/DataItem") == f"{base}/points", "surface geometry")
            attrs = {a.get("Name"): a for a in grid.findall("Attribute")}
            expect(set(attrs) == {"cut_id", "owner_cell"}, f"surface attributes {set(attrs)}")
            expect(attrs["cut_id"].get("Center") == "Cell" and
                   ref(attrs["cut_id"], "DataItem") == f"{base}/cut_id", "cut_id attribute")
            expect(attrs["owner_cell"].get("Center") == "Node" and
                   ref(attrs["owner_cell"], "DataItem") == f"{base}/owner_cell",
                   "owner_cell attribute")
            check_data_items(f, grid, basename)


def check_cuts(h5path, truncated_after=None):
    steps = [s for s in CUT_STEPS if truncated_after is None or s <= truncated_after]
    expect(not os.path.exists(h5path + ".tmp"), "left-over .h5.tmp")
    with h5py.File(h5path, "r") as f:
        check_mesh_group(f, "/mesh", split=False)
        check_input(f, h5path)
        check_cut_steps(f, steps)
    check_cut_xdmf(h5path, steps)


def check(h5path, steps=2):
    expect(not os.path.exists(h5path + ".tmp"), "left-over .h5.tmp")
    with h5py.File(h5path, "r") as f:
        check_mesh(f)
        check_input(f, h5path)
        check_steps(f, steps)
    check_xdmf(h5path, steps)


def main():
    args = sys.argv[1:]
    if "--cuts" in args:
        args.remove("--cuts")
        truncated = None
        if "--truncated-after" in args:
            i = args.index("--truncated-after")
            truncated = int(args[i + 1])
            del args[i:i + 2]
        check_cuts(args[0], truncated)
        print(f"OK: {args[0]} (cuts{'' if truncated is None else f', truncated after {truncated}'})")
        return
    steps = 2
    if "--steps" in args:
        i = args.index("--steps")
        steps = int(args[i + 1])
        del args[i:i + 2]
    check(args[0], steps)
    print(f"OK: {args[0]} ({steps} steps)")


if __name__ == "__main__":
    main()
