"""Make the real-Gmsh fixtures of tests/robustness/mesh_readers.rs (made with gmsh 4.15.2 from
pip; run from this directory: python3 make_fixtures.py).

A 2 x 1 x 1 box of 2 x 2 x 2 hexahedra (transfinite, recombined), physical volume "block",
physical surface "left" (x = 0) and an unnamed physical surface (x = 2, tag 3), written as
MSH 4.1 ASCII, binary, ASCII with parametric node coordinates, MSH 2.2 and Abaqus .inp; the
same box with only "left" (Gmsh then writes only that surface's elements and nodes: no node
that no element uses, which the unused-node rule relies on); and a small tetrahedral mesh
(element type 4, unsupported)."""
import gmsh


def box(volume_and_right):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("box")
    gmsh.model.occ.addBox(0, 0, 0, 2, 1, 1)
    gmsh.model.occ.synchronize()
    for _, t in gmsh.model.getEntities(1):
        gmsh.model.mesh.setTransfiniteCurve(t, 3)
    for _, t in gmsh.model.getEntities(2):
        gmsh.model.mesh.setTransfiniteSurface(t)
        gmsh.model.mesh.setRecombine(2, t)
    gmsh.model.mesh.setTransfiniteVolume(1)
    if volume_and_right:
        gmsh.model.addPhysicalGroup(3, [1], name="block")
    gmsh.model.addPhysicalGroup(2, [1], name="left")
    if volume_and_right:
        gmsh.model.addPhysicalGroup(2, [2])  # unnamed: tag 3
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)


box(True)
gmsh.write("gmsh_box.msh")
gmsh.option.setNumber("Mesh.Binary", 1)
gmsh.write("gmsh_box_bin.msh")
gmsh.option.setNumber("Mesh.Binary", 0)
gmsh.write("gmsh_box.inp")
gmsh.option.setNumber("Mesh.SaveParametric", 1)
gmsh.write("gmsh_box_param.msh")
gmsh.option.setNumber("Mesh.SaveParametric", 0)
gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
gmsh.write("gmsh_box_v22.msh")
gmsh.finalize()

box(False)
gmsh.write("gmsh_surface_only.msh")
gmsh.finalize()

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
gmsh.model.occ.synchronize()
gmsh.option.setNumber("Mesh.MeshSizeMin", 2.0)
gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0)
gmsh.model.mesh.generate(3)
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
gmsh.write("gmsh_tet4.msh")
gmsh.finalize()
