#!/usr/bin/python3
"""Writes the synthetic proximal-femur CT phantom and the stem mesh of the femur_implant
example (README.md here):

  femur_ct.nii.gz  a CT-like volume in Hounsfield units, 1 mm voxels (NIfTI, RAS, mm),
                   built from primitives: a hollow shaft (cortical wall, marrow canal), a
                   metaphysis, a neck at 130 degrees to the shaft, a head and a greater
                   trochanter, each a cortical shell around trabecular bone, in soft tissue;
  stem.obj         a straight press-fit stem: a tapered octagonal shaft rod wider than the
                   marrow canal (reamed into the cortex) and a neck rod that
                   overlaps it (hexcut unites overlapping pieces), in the implant's own frame
                   (origin at the neck-shaft junction, shaft along -z, neck in the x-z plane).

Usage: /usr/bin/python3 make_phantom.py [OUTDIR]   (default: this folder). Deterministic.
Needs numpy and nibabel (Debian python3-numpy, python3-nibabel).
"""
import math
import os
import sys

import nibabel
import numpy as np

VOXEL = 1.0e-3                      # m
SHAPE = (110, 60, 215)              # voxels along x (lateral +), y, z (up)
SHAFT_AXIS = (0.07, 0.03)           # x, y of the shaft axis [m]
JUNCTION = np.array([0.07, 0.03, 0.15])   # neck-shaft junction on the shaft axis [m]
NECK_ANGLE = 130.0                  # neck-shaft angle [degrees]
NECK_DIR = np.array([-math.sin(math.radians(180 - NECK_ANGLE)), 0.0, math.cos(math.radians(180 - NECK_ANGLE))])
HEAD_CENTRE = JUNCTION + 0.055 * NECK_DIR
TROCHANTER = np.array([0.085, 0.03, 0.155])

# Hounsfield units of the tissues (typical values; doc/user-guide.md "Stress analysis")
SOFT, MARROW, TRABECULAR, CORTICAL = 40, 30, 300, 1400


def phantom():
    """HU per voxel, indexed [i, j, k] (x, y, z) at voxel centres."""
    x, y, z = [(np.arange(n) + 0.5) * VOXEL for n in SHAPE]
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
    hu = np.full(SHAPE, SOFT, dtype=np.int16)

    def shell(inside, wall, core_hu, wall_hu):
        # inside: distance below the surface (> 0 inside); wall: cortical thickness [m]
        np.putmask(hu, (inside > 0) & (inside <= wall) & (hu < wall_hu), wall_hu)
        np.putmask(hu, (inside > wall) & (hu < core_hu), core_hu)

    r_shaft = np.hypot(X - SHAFT_AXIS[0], Y - SHAFT_AXIS[1])
    # shaft: cortical wall from 8 to 14 mm radius with marrow inside, up to the metaphysis
    body = (Z < JUNCTION[2] + 0.005) & (r_shaft < 0.014)
    np.putmask(hu, body & (r_shaft >= 0.008), CORTICAL)
    np.putmask(hu, body & (r_shaft < 0.008) & (Z < 0.12), MARROW)
    # metaphysis (z > 0.12 m): trabecular bone fills the canal
    np.putmask(hu, body & (r_shaft < 0.008) & (Z >= 0.12), TRABECULAR)
    # neck: a cylinder of radius 16 mm from the junction to the head centre, 2 mm cortex
    rel = np.stack([X - JUNCTION[0], Y - JUNCTION[1], Z - JUNCTION[2]], axis=-1)
    along = rel @ NECK_DIR
    radial = np.linalg.norm(rel - along[..., None] * NECK_DIR, axis=-1)
    neck_in = np.where((along > 0) & (along < 0.055), 0.016 - radial, -1.0)
    shell(neck_in, 0.002, TRABECULAR, 1200)
    # head: a sphere of radius 22 mm, 2 mm subchondral cortex
    head_in = 0.022 - np.linalg.norm(rel - (HEAD_CENTRE - JUNCTION), axis=-1)
    shell(head_in, 0.002, TRABECULAR + 50, 1000)
    # greater trochanter: a sphere of radius 18 mm, 1.5 mm cortex
    troch_in = 0.018 - np.linalg.norm(np.stack([X, Y, Z], axis=-1) - TROCHANTER, axis=-1)
    shell(troch_in, 0.0015, TRABECULAR - 100, 800)
    return hu


def octagonal_rod(a, b, ra, rb, first):
    """OBJ lines of a closed octagonal prism from point a (radius ra) to b (radius rb);
    vertex numbers start at `first`."""
    axis = (b - a) / np.linalg.norm(b - a)
    u = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    lines = []
    for centre, r in ((a, ra), (b, rb)):
        for i in range(8):
            t = 2 * math.pi * i / 8
            p = centre + r * (math.cos(t) * u + math.sin(t) * v)
            lines.append(f"v {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}")
    n = first
    lines += [f"f {n + i} {n + (i + 1) % 8} {n + 8 + (i + 1) % 8} {n + 8 + i}" for i in range(8)]
    lines.append("f " + " ".join(str(n + i) for i in range(7, -1, -1)))
    lines.append("f " + " ".join(str(n + 8 + i) for i in range(8)))
    return lines


def stem():
    """The stem in its own frame [m]: shaft rod from 80 mm below the junction (radius 9.5 mm)
    to 5 mm above it (radius 10.5 mm), wider than the 8 mm marrow canal: the canal is
    reamed and the stem sits press-fit against the cortex (bonded); neck rod of radius
    6 mm from 10 mm below the junction along the neck direction to 55 mm out, the centre
    of the femoral head, where the ball sits."""
    shaft = octagonal_rod(np.array([0.0, 0.0, -0.08]), np.array([0.0, 0.0, 0.005]), 0.0095, 0.0105, 1)
    neck = octagonal_rod(-0.01 * NECK_DIR, 0.055 * NECK_DIR, 0.006, 0.006, 17)
    return "# hexcut femur_implant example: straight stem (make_phantom.py)\n" + "\n".join(shaft + neck) + "\n"


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    os.makedirs(out, exist_ok=True)
    affine = np.diag([VOXEL * 1e3] * 3 + [1.0])   # mm; voxel (0,0,0) centred at 0.5 mm
    affine[:3, 3] = 0.5 * VOXEL * 1e3
    img = nibabel.Nifti1Image(phantom(), affine)
    img.header.set_xyzt_units("mm")
    img.header.set_sform(affine, code=1)
    img.header.set_qform(affine, code=1)
    nibabel.save(img, os.path.join(out, "femur_ct.nii.gz"))
    with open(os.path.join(out, "stem.obj"), "w") as f:
        f.write(stem())
    print(f"wrote {out}/femur_ct.nii.gz ({SHAPE[0]} x {SHAPE[1]} x {SHAPE[2]} voxels of 1 mm) and {out}/stem.obj")


if __name__ == "__main__":
    main()
