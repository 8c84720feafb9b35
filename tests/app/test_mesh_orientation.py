"""A mesh used as a solid gives the same cells whatever the orientation of its faces
(issue 8): the field report's inside-out cube subtracted from a box leaves 936 cells with
the hole in layers k = 3..6, for the report's file, the outward file, one face flipped,
random faces flipped, and as binary STL; a hollow box given as two shells stays hollow;
a one-sided mesh (Möbius strip) is refused with deck.yaml:LINE naming the file, exit 2;
a blade is not a solid and is not oriented (the same strip is a valid blade)."""
import math
import os
import random
import re
import struct
import sys

import h5py
import numpy as np

from cli_helpers import Checks, run, tempdir, write

DECK = """\
lattice: {{bounds: [[0, 0, 0], [1, 1, 1]], h: 0.1}}
materials:
  steel: {{E: 200.0e9, nu: 0.3, rho: 7800}}
geometry:
  - add: {{box: {{min: [0, 0, 0], max: [1, 1, 1]}}}}
  - subtract: {{mesh: {{file: {mesh}}}}}
boundary:
  fixed:
    - where: {{plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}
  gravity: [0, 0, -9.81]
solver: {{type: direct}}
output: {{directory: {out}, name: {name}}}
{extra}"""

CORNERS = [(0.3, 0.3, 0.3), (0.7, 0.3, 0.3), (0.7, 0.7, 0.3), (0.3, 0.7, 0.3),
           (0.3, 0.3, 0.7), (0.7, 0.3, 0.7), (0.7, 0.7, 0.7), (0.3, 0.7, 0.7)]
# The report's faces: every one inside-out (1 2 3 4 at z = 0.3 turns counter-clockwise
# seen from +z, into the cube).
REPORT_FACES = [[1, 2, 3, 4], [5, 8, 7, 6], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 8, 4], [4, 8, 5, 1]]


def obj(corners, faces):
    lines = [f"v {x} {y} {z}" for x, y, z in corners]
    lines += ["f " + " ".join(str(i) for i in f) for f in faces]
    return "\n".join(lines) + "\n"


def flipped(faces, which):
    return [list(reversed(f)) if i in which else f for i, f in enumerate(faces)]


def binary_stl(corners, faces):
    tris = [(f[0], f[t], f[t + 1]) for f in faces for t in range(1, len(f) - 1)]
    data = b"binary stl".ljust(80, b" ") + struct.pack("<I", len(tris))
    for t in tris:
        data += struct.pack("<3f", 0.0, 0.0, 0.0)
        for i in t:
            data += struct.pack("<3f", *corners[i - 1])
        data += b"\0\0"
    return data


def cells_of_check(out):
    """Cell count that --check reports ('DECK: N cells, M DOFs, ...'), if the deck is valid."""
    m = re.search(r": (\d+) cells, \d+ DOFs", out)
    return int(m.group(1)) if m and "deck is valid" in out else None


def mobius_obj(n=24):
    lines, faces = [], []
    for i in range(n):
        th = 2 * math.pi * i / n
        c = (math.cos(th), math.sin(th), 0.0)
        d = (math.cos(th / 2) * c[0], math.cos(th / 2) * c[1], math.sin(th / 2))
        for s in (1, -1):  # top 2i+1, bottom 2i+2 (1-based)
            lines.append("v %.9f %.9f %.9f" % tuple(0.5 + 0.3 * (c[a] + 0.3 * s * d[a]) for a in range(3)))
    for i in range(n):
        t0, b0 = 2 * i + 1, 2 * i + 2
        t1, b1 = 2 * ((i + 1) % n) + 1, 2 * ((i + 1) % n) + 2
        if i + 1 == n:
            t1, b1 = b1, t1  # the half twist
        faces.append(f"f {b0} {b1} {t1} {t0}")
    return "\n".join(lines + faces) + "\n"


def main():
    d = tempdir()
    check = Checks()
    rng = random.Random(8)
    variants = [
        ("the report's file (inside-out)", "report.obj", obj(CORNERS, REPORT_FACES)),
        ("outward", "outward.obj", obj(CORNERS, flipped(REPORT_FACES, range(6)))),
        ("one face flipped", "one.obj", obj(CORNERS, flipped(REPORT_FACES, {2}))),
        ("five faces flipped", "five.obj", obj(CORNERS, flipped(REPORT_FACES, {0, 1, 3, 4, 5}))),
    ]
    for k in range(3):
        which = set(rng.sample(range(6), rng.randint(1, 5)))
        variants.append((f"faces {sorted(which)} flipped", f"random{k}.obj", obj(CORNERS, flipped(REPORT_FACES, which))))
    variants.append(("binary STL, inside-out", "report.stl", binary_stl(CORNERS, REPORT_FACES)))

    for what, name, content in variants:
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(content.encode() if isinstance(content, str) else content)
        deck = write(d, "deck.yaml", DECK.format(mesh=name, out=d, name="r", extra=""))
        rc, out, err = run(["--check", deck])
        check(rc == 0 and cells_of_check(out) == 936, f"{what}: --check reports 936 cells: {out.strip()} {err.strip()}")

    # A full run on the report's file: the removed cells are exactly i, j, k = 3..6.
    deck = write(d, "solve.yaml", DECK.format(mesh="report.obj", out=d, name="solve", extra=""))
    rc, out, err = run([deck])
    ok = rc == 0
    if ok:
        with h5py.File(os.path.join(d, "solve.h5"), "r") as f:
            ijk = f["/mesh/cell_lattice_index"][:]
        present = np.zeros((10, 10, 10), bool)
        present[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = True
        hole = np.argwhere(~present)
        ok = len(ijk) == 936 and len(hole) == 64 and hole.min(axis=0).tolist() == [3, 3, 3] \
            and hole.max(axis=0).tolist() == [6, 6, 6]
        layers = sorted(set(hole[:, 2].tolist()))
    check(ok, f"run: 936 cells, the hole in layers k = 3..6: {err.strip()} {locals().get('layers')}")

    # A hollow box as two shells in one file, [0.1,0.9]^3 and [0.3,0.7]^3, in every
    # combination of orientations: 8^3 - 4^3 = 448 cells.
    outer = [tuple(0.1 + 0.8 * (c - 0.3) / 0.4 for c in p) for p in CORNERS]
    inner_faces = [[i + 8 for i in f] for f in REPORT_FACES]
    for outer_flip in (set(), set(range(6))):
        for inner_flip in (set(), set(range(6)), {1, 4}):
            text = obj(outer + CORNERS, flipped(REPORT_FACES, outer_flip) + flipped(inner_faces, inner_flip))
            write(d, "hollow.obj", text)
            deck = write(d, "hollow.yaml", DECK.format(mesh="hollow.obj", out=d, name="h", extra="").replace(
                "  - add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}\n  - subtract: {mesh: {file: hollow.obj}}",
                "  - add: {mesh: {file: hollow.obj}}").replace("point: [0, 0, 0]", "point: [0, 0, 0.1]"))
            rc, out, err = run(["--check", deck])
            check(rc == 0 and cells_of_check(out) == 448,
                  f"hollow box (outer flips {len(outer_flip)}, inner {sorted(inner_flip)}): 448 cells: "
                  f"{out.strip()} {err.strip()}")

    # A Möbius strip as a solid: exit 2, the deck line of its file, the file named.
    write(d, "moebius.obj", mobius_obj())
    deck = write(d, "moebius.yaml", DECK.format(mesh="moebius.obj", out=d, name="m", extra=""))
    rc, out, err = run(["--check", deck])
    check(rc == 2 and f"{deck}:6: mesh 'moebius.obj':" in err and "cannot be oriented" in err,
          f"Möbius strip as a solid: exit {rc}: {err.strip()}")
    # The same strip as a blade: blades are open surfaces, not oriented; the deck is valid.
    blade = DECK.format(mesh="report.obj", out=d, name="b", extra="cuts:\n  - blade: {mesh: {file: moebius.obj}}\n")
    deck = write(d, "blade.yaml", blade)
    rc, out, err = run(["--check", deck])
    check(rc == 0, f"Möbius strip as a blade: exit {rc}: {out.strip()} {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
