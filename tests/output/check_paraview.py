"""Opens result indexes with ParaView's XDMF readers (run with pvbatch; optional test).

usage: pvbatch check_paraview.py CUTS.xmf PLAIN.xmf

CUTS.xmf: the index of `output_write_result_file --cuts` (steps 1..3 at t = 0.25, 0.5,
0.75; step 2 splits the body in two; surfaces on steps 1 and 3). PLAIN.xmf: an index
without cuts or surfaces. For the Xdmf2 reader ("XDMF Reader") and the Xdmf3 temporal
reader, checks at every time that the volume block has the step's point count and number
of connected pieces, and that the surface block holds the step's triangles or is empty;
and that an index without surfaces still reads as one unstructured grid.
"""
import sys

from paraview import servermanager as sm
from paraview.simple import Connectivity, Delete, XDMFReader, Xdmf3ReaderT

# time -> (volume points, volume pieces, surface points, surface triangles); None: no surface
CUTS = {0.25: (36, 1, 8, 12), 0.5: (45, 2, None, None), 0.75: (45, 2, 16, 24)}


def expect(condition, message):
    if not condition:
        raise AssertionError(message)


def pieces(source, t):
    conn = Connectivity(Input=source)
    conn.ExtractionMode = "Extract All Regions"
    conn.UpdatePipeline(t)
    data = sm.Fetch(conn)
    Delete(conn)
    volume = data.GetBlock(0) if data.IsA("vtkMultiBlockDataSet") else data
    return int(volume.GetPointData().GetArray("RegionId").GetRange()[1]) + 1


def check_cuts(make, label):
    reader = make()
    times = list(reader.TimestepValues)
    expect(times == sorted(CUTS), f"{label}: times {times}")
    for t, (npts, npieces, spts, stris) in CUTS.items():
        reader.UpdatePipeline(t)
        data = sm.Fetch(reader)
        expect(data.IsA("vtkMultiBlockDataSet") and data.GetNumberOfBlocks() == 2,
               f"{label} t={t}: {data.GetClassName()} is not volume + surface")
        volume, surface = data.GetBlock(0), data.GetBlock(1)
        expect(volume.IsA("vtkUnstructuredGrid"), f"{label} t={t}: volume {volume}")
        expect(volume.GetNumberOfPoints() == npts and volume.GetNumberOfCells() == 12,
               f"{label} t={t}: volume {volume.GetNumberOfPoints()} points")
        expect(volume.GetCellType(0) == 12, f"{label} t={t}: not hexahedra")
        expect(volume.GetPointData().GetArray("displacement") is not None, "displacement")
        expect(pieces(reader, t) == npieces, f"{label} t={t}: pieces")
        if spts is None:
            empty = surface is None or (surface.IsA("vtkMultiBlockDataSet") and
                                        surface.GetNumberOfBlocks() == 0)
            expect(empty, f"{label} t={t}: a surface where the step has none")
        else:
            expect(surface is not None and surface.IsA("vtkUnstructuredGrid"),
                   f"{label} t={t}: surface {surface}")
            expect(surface.GetNumberOfPoints() == spts and surface.GetNumberOfCells() == stris,
                   f"{label} t={t}: surface {surface.GetNumberOfPoints()} points")
            expect(surface.GetCellType(0) == 5, f"{label} t={t}: not triangles")
            expect(surface.GetCellData().GetArray("cut_id") is not None, "cut_id")
            expect(surface.GetPointData().GetArray("owner_cell") is not None, "owner_cell")
            cut = surface.GetCellData().GetArray("cut_id").GetRange()
            expect(cut == ((0.0, 0.0) if npieces == 1 else (0.0, 1.0)), f"cut_id range {cut}")
    Delete(reader)
    print(f"OK: {label}")


def check_plain(path):
    reader = XDMFReader(FileNames=[path])
    reader.UpdatePipeline(reader.TimestepValues[0])
    data = sm.Fetch(reader)
    expect(data.IsA("vtkUnstructuredGrid"), f"plain index reads as {data.GetClassName()}")
    Delete(reader)
    print("OK: index without surfaces is one unstructured grid")


def main():
    cuts, plain = sys.argv[1], sys.argv[2]
    check_cuts(lambda: XDMFReader(FileNames=[cuts]), "XDMF Reader (Xdmf2)")
    check_cuts(lambda: Xdmf3ReaderT(FileName=[cuts]), "Xdmf3ReaderT")
    check_plain(plain)


if __name__ == "__main__":
    main()
