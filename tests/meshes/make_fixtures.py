"""Make the real-Gmsh fixtures: a 2 x 1 x 1 box of 2 x 2 x 2 hexahedra (transfinite,
recombined), physical volume "block", physical surface "left" (x = 0) and an unnamed physical
surface (x = 2, tag 3), written as MSH 4.1 ASCII, MSH 4.1 binary and Abaqus .inp.
Run from this directory: python3 make_fixtures.py (made with gmsh 4.15.2 from pip)."""
import gmsh

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
gmsh.model.addPhysicalGroup(3, [1], name="block")
gmsh.model.addPhysicalGroup(2, [1], name="left")
gmsh.model.addPhysicalGroup(2, [2])  # unnamed: tag 3
gmsh.model.mesh.generate(3)
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
gmsh.write("gmsh_box.msh")
gmsh.option.setNumber("Mesh.Binary", 1)
gmsh.write("gmsh_box_bin.msh")
gmsh.option.setNumber("Mesh.Binary", 0)
gmsh.write("gmsh_box.inp")
gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
gmsh.write("gmsh_box_v22.msh")
gmsh.finalize()

# a tetrahedral mesh (unsupported element type 4), small
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
