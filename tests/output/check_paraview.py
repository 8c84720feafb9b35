"""Reads hexcut's XDMF indexes with each of ParaView's three XDMF readers (run with pvbatch).

usage: pvbatch check_paraview.py --fixture CUTS.h5 PLAIN.h5...
       pvbatch check_paraview.py --run RUN.h5... [--cut-time T]

The readers of ParaView 5.11: "XDMF Reader" (XDMFReader, Xdmf2), Xdmf3ReaderS (the one
the GUI picks for .xmf) and Xdmf3ReaderT. Each opens both indexes of every file (the
volume index RUN.xmf and the surface index RUN_surface.xmf) and must give, at every time,
one unstructured grid with the step's mesh and every field as a full (not partial) array.

--fixture: files of output_write_result_file. CUTS.h5 (--cuts: steps 1..3 at t = 0.25,
0.5, 0.75; step 2 splits the body in two; surfaces on steps 1 and 3); PLAIN.h5 (steps 0, 1,
no surfaces; any name). Every array read is compared with the values the fixture writes
(check_result_file.expected: the stress's components xx, yy, zz, xy, yz, xz, the pressure
-tr/3, principal values and directions) and trace(stress) + 3 pressure = 0 is checked.

--run: results of hexcut. Every array read is compared with the file's dataset (h5py),
and the stress with its own invariants: trace = -3p, von Mises from the 6 components, the
principal values are the eigenvalues of the tensor ParaView shows and the principal
directions its eigenvectors, and Glyph orients along principal_direction_1. With
--cut-time T (the time of the step the cut acts in), asked for T the readers return the
new, split mesh (two pieces), the step before has one piece.

Paths are made absolute: ParaView 5.11's Xdmf3 readers join a bare file name and the
index's dataset file wrongly ("run.xmfrun.h5").
"""
import os
import sys

import h5py
import numpy as np
from paraview import servermanager as sm
from paraview.simple import (Connectivity, Delete, Glyph, XDMFReader, Xdmf3ReaderS,
                             Xdmf3ReaderT)
from vtk.util.numpy_support import vtk_to_numpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_result_file as fixture  # noqa: E402

READERS = {
    "XDMF Reader (Xdmf2)": lambda path: XDMFReader(FileNames=[path]),
    "Xdmf3ReaderS": lambda path: Xdmf3ReaderS(FileName=[path]),
    "Xdmf3ReaderT": lambda path: Xdmf3ReaderT(FileName=[path]),
}
VTK_HEXAHEDRON, VTK_TRIANGLE = 12, 5
# ParaView's names for a 6-component array: the order hexcut's stress is stored in.
SYMMETRIC_COMPONENTS = ["XX", "YY", "ZZ", "XY", "YZ", "XZ"]


def expect(condition, message):
    if not condition:
        raise AssertionError(message)


def times_of(reader):
    t = reader.TimestepValues
    return [float(x) for x in t] if hasattr(t, "__len__") else [float(t)]


def fetch(reader, t, label):
    """The reader's output at time t: must be one unstructured grid."""
    reader.UpdatePipeline(t)
    data = sm.Fetch(reader)
    expect(data.IsA("vtkUnstructuredGrid"), f"{label}: {data.GetClassName()}, not one grid")
    return data


def arrays(data):
    """{name: (rows, cols) array} of the point and cell data."""
    out = {}
    for attributes in (data.GetPointData(), data.GetCellData()):
        for i in range(attributes.GetNumberOfArrays()):
            a = vtk_to_numpy(attributes.GetArray(i))
            out[attributes.GetArrayName(i)] = a.reshape(a.shape[0], -1)
    return out


def check_no_partial_arrays(reader, label):
    """Every array is on the whole data set (a partial one colours part of it grey)."""
    for info in (reader.GetPointDataInformation(), reader.GetCellDataInformation()):
        for name in info.keys():
            expect(not info.GetArray(name).GetIsPartial(), f"{label}: partial array {name}")


def check_stress_names(reader, label):
    a = reader.GetCellDataInformation().GetArray("stress")
    names = [a.GetComponentName(i) for i in range(a.GetNumberOfComponents())]
    expect(names == SYMMETRIC_COMPONENTS, f"{label}: stress components {names}")


def pieces(reader, t):
    conn = Connectivity(Input=reader)
    conn.ExtractionMode = "Extract All Regions"
    conn.UpdatePipeline(t)
    data = sm.Fetch(conn)
    Delete(conn)
    return int(data.GetPointData().GetArray("RegionId").GetRange()[1]) + 1


def tensor(s):
    """(n, 3, 3) from (n, 6) in ParaView's order xx, yy, zz, xy, yz, xz."""
    t = np.empty((len(s), 3, 3))
    for (i, j), c in {(0, 0): 0, (1, 1): 1, (2, 2): 2, (0, 1): 3, (1, 2): 4, (0, 2): 5}.items():
        t[:, i, j] = t[:, j, i] = s[:, c]
    return t


def check_trace(a, label):
    s, p = a["stress"], a["pressure"][:, 0]
    scale = max(np.abs(s).max(), 1e-300)
    worst = np.abs(s[:, 0] + s[:, 1] + s[:, 2] + 3.0 * p).max()
    expect(worst <= 1e-12 * scale,
           f"{label}: max |trace + 3p| = {worst:.3e} (|stress| {scale:.3e})")
    return worst


def check_invariants(a, label):
    """The stress ParaView shows against its own derived fields."""
    worst = check_trace(a, label)
    s = a["stress"]
    scale = max(np.abs(s).max(), 1e-300)
    t = tensor(s)
    dev = t - np.trace(t, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
    vm = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
    expect(np.abs(vm - a["von_mises"][:, 0]).max() <= 1e-9 * scale, f"{label}: von Mises")
    eig = np.linalg.eigvalsh(t)[:, ::-1]  # descending, as principal_stress_1 >= _2 >= _3
    for k in range(3):
        lam = a[f"principal_stress_{k + 1}"][:, 0]
        expect(np.abs(eig[:, k] - lam).max() <= 1e-9 * scale, f"{label}: principal_stress_{k + 1}")
        d = a[f"principal_direction_{k + 1}"]
        expect(np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12), f"{label}: |direction|")
        residual = np.einsum("nij,nj->ni", t, d) - lam[:, None] * d
        expect(np.abs(residual).max() <= 1e-9 * scale,
               f"{label}: direction {k + 1} not an eigenvector")
    return worst


def check_glyph(reader, t, a, label):
    """Glyph takes principal_direction_1: one line per cell, along the direction."""
    glyph = Glyph(Input=reader, GlyphType="Line")
    glyph.GlyphType.Resolution = 1  # two points per line
    glyph.OrientationArray = ["CELLS", "principal_direction_1"]
    glyph.ScaleArray = ["POINTS", "No scale array"]
    glyph.GlyphMode = "All Points"
    glyph.UpdatePipeline(t)
    pts = vtk_to_numpy(sm.Fetch(glyph).GetPoints().GetData())
    Delete(glyph)
    d = a["principal_direction_1"]
    expect(len(pts) == 2 * len(d), f"{label}: {len(pts)} glyph points for {len(d)} cells")
    seg = pts[1::2] - pts[0::2]
    seg /= np.linalg.norm(seg, axis=1)[:, None]
    # Line glyphs do not tell the direction's sign; compare up to it, in float (VTK's points).
    expect(np.abs(np.abs(np.einsum("ni,ni->n", seg, d)) - 1.0).max() < 1e-5,
           f"{label}: glyphs not along principal_direction_1")


# ---------------------------------------------------------------------------- fixture
def check_fixture_grid(data, step, npts, label):
    expect(data.GetNumberOfPoints() == npts and data.GetNumberOfCells() == fixture.NC,
           f"{label}: {data.GetNumberOfPoints()} points, {data.GetNumberOfCells()} cells")
    expect(data.GetCellType(0) == VTK_HEXAHEDRON, f"{label}: not hexahedra")
    a = arrays(data)
    for name, rows in [(n, npts) for n in fixture.POINT_FIELDS] + \
                      [(n, fixture.NC) for n in fixture.CELL_FIELDS]:
        expect(name in a, f"{label}: no array {name!r} (arrays {sorted(a)})")
        want = fixture.expected(name, step, rows)
        expect(a[name].shape == want.shape and np.array_equal(a[name], want),
               f"{label}: {name} {a[name][:1]} != {want[:1]}")
    check_trace(a, label)


def check_fixture_cuts(h5path):
    volume, surface = (os.path.abspath(p) for p in fixture.index_paths(h5path))
    for reader_label, make in READERS.items():
        reader = make(volume)
        times = times_of(reader)
        expect(times == [0.25, 0.5, 0.75], f"{reader_label}: times {times}")
        for step, npts, npieces in ((1, fixture.NP, 1), (2, fixture.NP_SPLIT, 2),
                                    (3, fixture.NP_SPLIT, 2)):
            label = f"{reader_label} {os.path.basename(volume)} t={0.25 * step}"
            check_fixture_grid(fetch(reader, 0.25 * step, label), step, npts, label)
            expect(pieces(reader, 0.25 * step) == npieces, f"{label}: pieces")
        check_no_partial_arrays(reader, reader_label)
        check_stress_names(reader, reader_label)
        Delete(reader)
        reader = make(surface)
        times = times_of(reader)
        expect(times == [0.25, 0.75], f"{reader_label}: surface times {times}")
        for t, boxes, cut in ((0.25, 1, (0.0, 0.0)), (0.75, 2, (0.0, 1.0))):
            label = f"{reader_label} {os.path.basename(surface)} t={t}"
            data = fetch(reader, t, label)
            expect(data.GetNumberOfPoints() == 8 * boxes and data.GetNumberOfCells() == 12 * boxes,
                   f"{label}: {data.GetNumberOfPoints()} points")
            expect(data.GetCellType(0) == VTK_TRIANGLE, f"{label}: not triangles")
            a = arrays(data)
            expect(set(a) == {"cut_id", "owner_cell"}, f"{label}: arrays {sorted(a)}")
            expect(data.GetCellData().GetArray("cut_id").GetRange() == cut, f"{label}: cut_id")
        Delete(reader)
        print(f"OK: {reader_label}: {os.path.basename(h5path)} volume and surface indexes")


def check_fixture_plain(h5path):
    volume, surface = (os.path.abspath(p) for p in fixture.index_paths(h5path))
    expect(not os.path.exists(surface), f"{surface} for a file without surfaces")
    for reader_label, make in READERS.items():
        reader = make(volume)
        times = times_of(reader)
        expect(times == [0.0, 0.25], f"{reader_label}: times {times}")
        for step in (0, 1):
            label = f"{reader_label} {os.path.basename(volume)} t={0.25 * step}"
            check_fixture_grid(fetch(reader, 0.25 * step, label), step, fixture.NP, label)
        check_no_partial_arrays(reader, reader_label)
        check_stress_names(reader, reader_label)
        Delete(reader)
        print(f"OK: {reader_label}: {os.path.basename(volume)}")


# -------------------------------------------------------------------------------- run
def check_run(h5path, cut_time):
    volume, surface = (os.path.abspath(p) for p in fixture.index_paths(h5path))
    with h5py.File(h5path, "r") as f:
        steps = [f[f"/steps/{s}"] for s in fixture.complete_steps(f)]
        times = [float(g.attrs["time"]) for g in steps]
        meshes = [fixture.text(g.attrs["mesh"]) for g in steps]
        # The step the cut acts in: the first with a new mesh. Its time is the cut time.
        cut = next((i for i, m in enumerate(meshes) if m != "/mesh"), len(meshes))
        expect(cut_time is None or times[cut] == cut_time,
               f"the cut acts at t = {times[cut:cut + 1]}, not {cut_time!r}")
        points = [f[m + "/points"].shape[0] for m in meshes]
        # Mesh fields only: a table of centering "none" (compare_summary) is not in the index.
        fields = [{k: d[()].reshape(d.shape[0], -1) for k, d in g.items()
                   if isinstance(d, h5py.Dataset) and d.attrs.get("centering", b"") != b"none"}
                  for g in steps]
        surfaces = [{k: g["surface/" + k][()] for k in ("points", "triangles", "cut_id")}
                    if "surface" in g else None for g in steps]
    worst = 0.0
    for reader_label, make in READERS.items():
        reader = make(volume)
        expect(times_of(reader) == times, f"{reader_label}: times {times_of(reader)} != {times}")
        for i, t in enumerate(times):
            label = f"{reader_label} {os.path.basename(volume)} t={t}"
            data = fetch(reader, t, label)
            expect(data.GetNumberOfPoints() == points[i],
                   f"{label}: {data.GetNumberOfPoints()} points")
            expect(data.GetCellType(0) == VTK_HEXAHEDRON, f"{label}: not hexahedra")
            a = arrays(data)
            for name, want in fields[i].items():
                # equal_nan: compare fields are NaN where the reference has no cell.
                expect(name in a and np.array_equal(a[name], want, equal_nan=True),
                       f"{label}: {name} differs from the file")
            worst = max(worst, check_invariants(a, label))
            if i == len(times) - 1:
                check_glyph(reader, t, a, label)
        check_no_partial_arrays(reader, reader_label)
        check_stress_names(reader, reader_label)
        if cut_time is not None:  # asked for the cut time itself: the split mesh
            label = f"{reader_label} asked for t = {cut_time!r}"
            data = fetch(reader, cut_time, label)
            expect(data.GetNumberOfPoints() == points[cut] != points[cut - 1],
                   f"{label}: {data.GetNumberOfPoints()} points, the cut step has {points[cut]}")
            expect(pieces(reader, cut_time) == 2 and pieces(reader, times[cut - 1]) == 1,
                   f"{label}: pieces")
        Delete(reader)

        reader = make(surface)
        with_surface = [i for i, s in enumerate(surfaces) if s is not None and len(s["triangles"])]
        expect(times_of(reader) == [times[i] for i in with_surface],
               f"{reader_label}: surface times")
        for i in with_surface:
            label = f"{reader_label} {os.path.basename(surface)} t={times[i]}"
            data = fetch(reader, times[i], label)
            s = surfaces[i]
            got = vtk_to_numpy(data.GetPoints().GetData())
            expect(np.array_equal(got, s["points"]), f"{label}: points")
            expect(data.GetNumberOfCells() == len(s["triangles"]), f"{label}: triangles")
            cut_id = vtk_to_numpy(data.GetCellData().GetArray("cut_id"))
            expect(np.array_equal(cut_id, s["cut_id"]), f"{label}: cut_id")
            expect((cut_id.max() > 0) == (i >= cut), f"{label}: cut faces")
        Delete(reader)
        print(f"OK: {reader_label}: {os.path.basename(h5path)}, {len(times)} steps, "
              f"max |trace(stress) + 3p| = {worst:.3e} Pa")


def main():
    args = sys.argv[1:]
    if args[0] == "--fixture":
        check_fixture_cuts(args[1])
        for plain in args[2:]:
            check_fixture_plain(plain)
    elif args[0] == "--run":
        cut_time = None
        if "--cut-time" in args:
            i = args.index("--cut-time")
            cut_time = float(args[i + 1])
            del args[i:i + 2]
        for h5path in args[1:]:
            check_run(h5path, cut_time)
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    main()
