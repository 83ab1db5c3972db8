"""Make the second-order (and matching first-order) Gmsh fixtures of the mesh-reader tests
(tests/robustness/mesh_readers.rs), under tests/meshes/.

Run with gmsh from PyPI (made with gmsh 4.15.2):

    python3 -m venv /tmp/gmshvenv && /tmp/gmshvenv/bin/pip install gmsh
    /tmp/gmshvenv/bin/python tools/make_quadratic_meshes.py

Every mesh is of the box [0, 2] x [0, 1] x [0, 0.5] (volume 1), with the physical volume
"box" and the physical surfaces "xmin" (x = 0, area 0.5, outward normal -x) and "zmax"
(z = 0.5, area 2, outward normal +z):

* quad_tet4 / quad_tet10: an unstructured tetrahedral mesh (Gmsh types 4 and 11; the
  surfaces are triangles, types 2 and 9);
* quad_hex8 / quad_hex20: a transfinite 2 x 2 x 2 hexahedral mesh (types 5 and 17; second
  order incomplete, the 20-node serendipity hexahedron; surfaces types 3 and 16);
* quad_wedge6 / quad_wedge15: a triangulated xy rectangle extruded along z in two layers
  (prisms, types 6 and 18, second order incomplete; "xmin" is quadrangles, types 3 and 16,
  "zmax" triangles, types 2 and 9).

Each is written as MSH 4.1 ASCII (`.msh`) and as Abaqus input (`.inp`, Gmsh's INP export);
quad_tet10 also as binary MSH 4.1 (`quad_tet10_bin.msh`). The box's edges are straight, so
every mid-edge node lies at the middle of its edge: the tests check that the readers put
each mid-edge node of Gmsh's order where fricsens' order expects it.
"""
import os
import sys

import gmsh

LX, LY, LZ = 2.0, 1.0, 0.5
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "meshes")


def surface_at(dim_tags, axis, value):
    """The surface of `dim_tags` (dim 2) flat at `axis` = `value` (OCC pads its bounding
    boxes by 1e-7)."""
    found = []
    for dim, tag in dim_tags:
        box = gmsh.model.getBoundingBox(dim, tag)
        lo, hi = box[axis], box[axis + 3]
        if abs(lo - value) < 1e-6 and abs(hi - value) < 1e-6:
            found.append(tag)
    assert len(found) == 1, (axis, value, found)
    return found[0]


def groups(volume):
    surfaces = gmsh.model.getEntities(2)
    gmsh.model.addPhysicalGroup(3, [volume], name="box")
    gmsh.model.addPhysicalGroup(2, [surface_at(surfaces, 0, 0.0)], name="xmin")
    gmsh.model.addPhysicalGroup(2, [surface_at(surfaces, 2, LZ)], name="zmax")


def start(name):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)


def tets():
    gmsh.model.occ.addBox(0, 0, 0, LX, LY, LZ)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
    groups(1)


def hexes():
    gmsh.model.occ.addBox(0, 0, 0, LX, LY, LZ)
    gmsh.model.occ.synchronize()
    for _, t in gmsh.model.getEntities(1):
        gmsh.model.mesh.setTransfiniteCurve(t, 3)
    for _, t in gmsh.model.getEntities(2):
        gmsh.model.mesh.setTransfiniteSurface(t)
        gmsh.model.mesh.setRecombine(2, t)
    gmsh.model.mesh.setTransfiniteVolume(1)
    groups(1)


def wedges():
    s = gmsh.model.occ.addRectangle(0, 0, 0, LX, LY)
    out = gmsh.model.occ.extrude([(2, s)], 0, 0, LZ, numElements=[2], recombine=True)
    gmsh.model.occ.synchronize()
    volume = [t for d, t in out if d == 3][0]
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.6)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.6)
    groups(volume)


def make(name, build, order, binary=False):
    start(name)
    build()
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1)
    gmsh.model.mesh.generate(3)
    if order == 2:
        gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    # written from tests/meshes/ by name, so that the .inp heading holds no path
    gmsh.write(name + ".msh")
    gmsh.write(name + ".inp")
    if binary:
        gmsh.option.setNumber("Mesh.Binary", 1)
        gmsh.write(name + "_bin.msh")
    types, tags, _ = gmsh.model.mesh.getElements(3)
    nodes = gmsh.model.mesh.getNodes()[0]
    print(name, "element types", list(types), "elements", sum(len(t) for t in tags),
          "nodes", len(nodes), file=sys.stderr)
    gmsh.finalize()


os.chdir(OUT)
make("quad_tet4", tets, 1)
make("quad_tet10", tets, 2, binary=True)
make("quad_hex8", hexes, 1)
make("quad_hex20", hexes, 2)
make("quad_wedge6", wedges, 1)
make("quad_wedge15", wedges, 2)
