#!/usr/bin/python3
"""Checks a result file written by output_write_result_file (see write_result_file.cpp).

usage: check_result_file.py FILE.h5 [--steps N]
       check_result_file.py FILE.h5 --cuts [--truncated-after K]
       check_result_file.py FILE.h5 --indexes      (any result file: check_indexes only)

Checks names, shapes, dtypes and values of every dataset against the formulas the writer
uses, then checks the XDMF indexes with check_indexes (below). Exits non-zero on the first
failure.

check_indexes(FILE.h5) works on any hexcut result file (the CLI tests use it): every index
hexcut writes for it (RUN.xmf, and RUN_surface.xmf exactly when a complete step has a
non-empty surface) parses as XML, lists the complete steps with their times and meshes,
and every `file:dataset` it references is the result file and a dataset in it with the
declared dimensions and number type, the grid's row count and the documented
AttributeType.

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

FORMAT_VERSION = 2
POINT_FIELDS = {"displacement": 3, "velocity": 3, "acceleration": 3}  # name -> columns
ODD_FIELD = 'energy & <odd> "name"'  # a name XML must escape
CELL_FIELDS = {"stress": 6, "von_mises": 1, "pressure": 1, ODD_FIELD: 1,
               **{f"principal_stress_{k}": 1 for k in (1, 2, 3)},
               **{f"principal_direction_{k}": 3 for k in (1, 2, 3)}}


def value(kind, step, rows, cols):
    r = np.arange(rows, dtype=np.float64)[:, None]
    c = np.arange(cols, dtype=np.float64)[None, :]
    return 1e6 * kind + 1000.0 * step + 10.0 * r + c + 0.25


def expected(name, step, rows):
    """(rows, cols) values write_result_file.cpp writes for field `name` at `step`."""
    kinds = {"displacement": 1, "velocity": 2, "acceleration": 3, "stress": 4, "von_mises": 5,
             ODD_FIELD: 9}
    if name in kinds:
        cols = POINT_FIELDS.get(name) or CELL_FIELDS[name]
        return value(kinds[name], step, rows, cols)
    if name == "pressure":  # -tr/3 of the stress (xx, yy, zz, xy, yz, xz)
        s = value(4, step, rows, 6)
        return (-(s[:, 0] + s[:, 1] + s[:, 2]) / 3.0)[:, None]
    k = int(name[-1]) - 1
    if name.startswith("principal_stress_"):  # column k of a 3-column table
        return value(7, step, rows, 3)[:, k:k + 1]
    return value(8, step, rows, 9)[:, 3 * k:3 * k + 3]  # principal_direction_: row k of 3x3


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
    expect(f.attrs["format_version"] == FORMAT_VERSION, "format_version attribute")
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
            for name, cols in fields.items():
                shape = (rows,) if cols == 1 else (rows, cols)
                data = check_dataset(f, f"{g.name}/{name}", shape, "<f8")
                expect(np.array_equal(data.reshape(rows, cols), expected(name, s, rows)),
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
    for name in POINT_FIELDS:
        data = check_dataset(f, f"{slot.name}/{name}", (NP, 3), "<f8")
        expect(np.array_equal(data, expected(name, last, NP)), f"checkpoint {name}")
    links = check_dataset(f, f"{slot.name}/topology/links", (NC,), "<i4")
    expect(np.array_equal(links, 100 * last + np.arange(NC)), "checkpoint links")


def check_xdmf(h5path, steps):
    """The fixture's indexes: the generic checks, then its fields' attributes."""
    volume, surface = check_indexes(h5path)
    expect(surface is None, "a surface index for a file without surfaces")
    grids = volume.find("Domain/Grid").findall("Grid")
    expect(len(grids) == steps, f"{len(grids)} grids in xmf, expected {steps}")
    for s, grid in enumerate(grids):
        expect(float(grid.find("Time").get("Value")) == 0.25 * s, f"grid {s} time")
        expect(int(grid.find("Topology").get("NumberOfElements")) == NC, "NumberOfElements")
        attrs = {a.get("Name"): a for a in grid.findall("Attribute")}
        expect(set(attrs) == set(POINT_FIELDS) | set(CELL_FIELDS) |
               {"cell_material", "cell_youngs_modulus"}, f"grid {s} attributes {set(attrs)}")
        for name in POINT_FIELDS:
            expect(attrs[name].get("Center") == "Node", f"{name} center")
        for name in CELL_FIELDS:
            expect(attrs[name].get("Center") == "Cell", f"{name} center")
        # What ParaView shows: the stress as 6 components XX..XZ (Matrix: no reader
        # reorders it), principal values as scalars, principal directions as vectors.
        for name, want in (("stress", "Matrix"), ("principal_stress_1", "Scalar"),
                           ("principal_direction_3", "Vector")):
            expect(attrs[name].get("AttributeType") == want, f"{name} AttributeType")


# ------------------------------------------------------------------------ the indexes
NUMBER_TYPES = {("Float", 8): "<f8", ("Float", 4): "<f4", ("Int", 8): "<i8",
                ("Int", 4): "<i4", ("UChar", 1): "|u1"}


def index_paths(h5path):
    """(volume index, surface index) of a result file (result_writer.hpp index_paths)."""
    stem = h5path[:-3] if h5path.endswith(".h5") and len(h5path) > 3 else h5path
    return stem + ".xmf", stem + "_surface.xmf"


def attribute_type(shape):
    """The documented AttributeType of a (rows,) or (rows, cols) table."""
    cols = shape[1:]
    return {(): "Scalar", (1,): "Scalar", (3,): "Vector", (9,): "Tensor"}.get(cols, "Matrix")


def complete_steps(f):
    return [k for k in sorted(f["/steps"]) if k.isdigit() and f["/steps"][k].attrs["complete"] == 1]


def ref(grid, path):
    item = grid.find(path)
    expect(item is not None, f"{grid.get('Name')}: no {path}")
    return item.text.strip().partition(":")[2]


def check_data_items(f, grid, basename):
    """Every DataItem under `grid` names the result file (relative: its basename, "./" in
    front when it starts with a non-ASCII character) and an existing dataset with the
    declared dimensions and number type."""
    want_file = ("./" if ord(basename[0]) >= 0x80 else "") + basename
    for item in grid.iter("DataItem"):
        file_part, _, dataset = item.text.strip().partition(":")
        expect(file_part == want_file, f"reference {item.text!r} is not {want_file!r}")
        expect(dataset in f and isinstance(f[dataset], h5py.Dataset),
               f"xmf references missing dataset {dataset!r}")
        dims = tuple(int(x) for x in item.get("Dimensions").split())
        expect(f[dataset].shape == dims, f"{dataset}: xmf dims {dims} != {f[dataset].shape}")
        want = NUMBER_TYPES[(item.get("NumberType"), int(item.get("Precision")))]
        expect(f[dataset].dtype == np.dtype(want), f"{dataset}: xmf type {want}")


def check_grid(f, grid, basename, time, topology, cells, points):
    """One Uniform grid: time, topology and geometry datasets, attribute types and sizes."""
    expect(grid.get("GridType") == "Uniform", f"{grid.get('Name')}: not Uniform")
    expect(float(grid.find("Time").get("Value")) == time, f"{grid.get('Name')}: time")
    topo = grid.find("Topology")
    expect(topo.get("TopologyType") == topology, f"{grid.get('Name')}: topology type")
    expect(ref(grid, "Topology/DataItem") == cells, f"{grid.get('Name')}: topology {cells}")
    n_cells, n_points = f[cells].shape[0], f[points].shape[0]
    expect(int(topo.get("NumberOfElements")) == n_cells, f"{grid.get('Name')}: NumberOfElements")
    expect(grid.find("Geometry").get("GeometryType") == "XYZ", "geometry type")
    expect(ref(grid, "Geometry/DataItem") == points, f"{grid.get('Name')}: geometry {points}")
    names = [a.get("Name") for a in grid.findall("Attribute")]
    expect(len(names) == len(set(names)), f"{grid.get('Name')}: repeated attribute")
    for a in grid.findall("Attribute"):
        shape = f[ref(a, "DataItem")].shape
        expect(a.get("AttributeType") == attribute_type(shape),
               f"{a.get('Name')}: AttributeType {a.get('AttributeType')} for {shape}")
        rows = {"Node": n_points, "Cell": n_cells}.get(a.get("Center"))
        expect(rows == shape[0], f"{a.get('Name')}: {shape[0]} rows, Center {a.get('Center')}")
    check_data_items(f, grid, basename)


def parse_index(path):
    """The index's root: well-formed XML, Xdmf 3.0, one temporal collection."""
    expect(os.path.exists(path), f"missing {path}")
    root = ET.parse(path).getroot()  # raises on malformed XML (or bytes that are not UTF-8)
    expect(root.tag == "Xdmf" and root.get("Version") == "3.0", f"{path}: Xdmf root")
    collections = root.findall("Domain/Grid")
    expect(len(collections) == 1 and collections[0].get("GridType") == "Collection" and
           collections[0].get("CollectionType") == "Temporal",
           f"{path}: not one temporal collection")
    return root


def check_indexes(h5path):
    """Checks every index hexcut writes for `h5path` against the file's content; returns
    their roots (volume, surface or None)."""
    volume_path, surface_path = index_paths(h5path)
    for p in (h5path, volume_path, surface_path):
        expect(not os.path.exists(p + ".tmp"), f"left-over {p}.tmp")
    basename = os.path.basename(h5path)
    volume, surface = parse_index(volume_path), None
    with h5py.File(h5path, "r") as f:
        steps = complete_steps(f)
        grids = volume.find("Domain/Grid").findall("Grid")
        expect([g.get("Name") for g in grids] == [f"step_{s}" for s in steps],
               f"{volume_path}: grids {[g.get('Name') for g in grids]}, complete steps {steps}")
        for name, grid in zip(steps, grids):
            step = f[f"/steps/{name}"]
            mesh = text(step.attrs["mesh"])
            check_grid(f, grid, basename, step.attrs["time"], "Hexahedron", f"{mesh}/cells",
                       f"{mesh}/points")
            n_points, n_cells = f[f"{mesh}/points"].shape[0], f[f"{mesh}/cells"].shape[0]
            # The step's fields (as their centering says) and the mesh's cell tables.
            want = {k: "Cell" for k in ("cell_material", "cell_youngs_modulus")
                    if k in f[mesh]}
            for k, d in step.items():
                if isinstance(d, h5py.Dataset) and "centering" in d.attrs:
                    c = text(d.attrs["centering"])
                    expect(d.shape[0] == (n_points if c == "point" else n_cells),
                           f"{d.name}: {d.shape[0]} rows for centering {c}")
                    want[k] = "Node" if c == "point" else "Cell"
            got = {a.get("Name"): a.get("Center") for a in grid.findall("Attribute")}
            expect(got == want, f"step {name}: attributes {got}, expected {want}")
        with_surface = [s for s in steps if "surface" in f[f"/steps/{s}"] and
                        f[f"/steps/{s}/surface/triangles"].shape[0] > 0]
        if not with_surface:
            expect(not os.path.exists(surface_path), f"{surface_path} without surfaces")
            return volume, None
        surface = parse_index(surface_path)
        grids = surface.find("Domain/Grid").findall("Grid")
        expect([g.get("Name") for g in grids] == [f"surface_{s}" for s in with_surface],
               f"{surface_path}: grids {[g.get('Name') for g in grids]}")
        for name, grid in zip(with_surface, grids):
            base = f"/steps/{name}/surface"
            check_grid(f, grid, basename, f[f"/steps/{name}"].attrs["time"], "Triangle",
                       f"{base}/triangles", f"{base}/points")
            got = {a.get("Name"): (a.get("Center"), ref(a, "DataItem"))
                   for a in grid.findall("Attribute")}
            expect(got == {"cut_id": ("Cell", f"{base}/cut_id"),
                           "owner_cell": ("Node", f"{base}/owner_cell")},
                   f"surface {name} attributes {got}")
    return volume, surface


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
            for fname, cols in fields.items():
                shape = (rows,) if cols == 1 else (rows, cols)
                data = check_dataset(f, f"{g.name}/{fname}", shape, "<f8")
                expect(np.array_equal(data.reshape(rows, cols), expected(fname, s, rows)),
                       f"{g.name}/{fname} values")
        if s in SURFACE_BOXES:
            check_surface(f, name, s, mesh, SURFACE_BOXES[s])
    hist = check_dataset(f, "/solver_history/step", (len(steps),), "<i8")
    expect(np.array_equal(hist, steps), f"/solver_history/step {hist}")
    # The checkpoint is not truncated: still step 3's, with the split mesh's point count.
    c = f["/checkpoint"].attrs
    slot = f[f"/checkpoint/slot{c['current_slot']}"]
    expect(c["step"] == 3 and slot.attrs["complete"] == 1, "checkpoint attributes")
    for fname in POINT_FIELDS:
        data = check_dataset(f, f"{slot.name}/{fname}", (NP_SPLIT, 3), "<f8")
        expect(np.array_equal(data, expected(fname, 3, NP_SPLIT)), f"checkpoint {fname}")


def check_cut_xdmf(h5path, steps):
    """The --cuts fixture's indexes: the generic checks, then what the fixture implies."""
    volume, surface = check_indexes(h5path)
    expect(surface is not None, "no surface index")
    expect([c.get("Name") for c in volume.findall("Domain/Grid")] == ["hexcut"],
           "volume collection")
    expect([c.get("Name") for c in surface.findall("Domain/Grid")] == ["hexcut_surface"],
           "surface collection")
    with h5py.File(h5path, "r") as f:
        grids = volume.find("Domain/Grid").findall("Grid")
        expect([g.get("Name") for g in grids] == [f"step_{s:06d}" for s in steps],
               f"volume grids {[g.get('Name') for g in grids]}")
        for s, grid in zip(steps, grids):
            name = f"{s:06d}"
            mesh = step_mesh(f, name)
            expect(mesh == ("/mesh" if s < CUT_MESH_STEP else f"/steps/{CUT_MESH_STEP:06d}/mesh"),
                   f"step {s} mesh {mesh}")
            expect(float(grid.find("Time").get("Value")) == 0.25 * s, f"grid {s} time")
            expect(ref(grid, "Topology/DataItem") == f"{mesh}/cells", f"step {s} topology")
            expect(ref(grid, "Geometry/DataItem") == f"{mesh}/points", f"step {s} geometry")
            for a in grid.findall("Attribute"):
                path = ref(a, "DataItem")
                expect(path.startswith(f"/steps/{name}/") or path.startswith(f"{mesh}/cell_"),
                       f"step {s} attribute {a.get('Name')} from {path}")
        with_surface = [s for s in steps if s in SURFACE_BOXES]
        grids = surface.find("Domain/Grid").findall("Grid")
        expect([g.get("Name") for g in grids] == [f"surface_{s:06d}" for s in with_surface],
               f"surface grids {[g.get('Name') for g in grids]}")
        for s, grid in zip(with_surface, grids):
            expect(float(grid.find("Time").get("Value")) == 0.25 * s, f"surface {s} time")
            expect(int(grid.find("Topology").get("NumberOfElements")) == 12 * SURFACE_BOXES[s],
                   f"surface {s} triangles")


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
    if "--indexes" in args:
        args.remove("--indexes")
        check_indexes(args[0])
        print(f"OK: indexes of {args[0]}")
        return
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
