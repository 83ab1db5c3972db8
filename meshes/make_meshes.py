#!/usr/bin/env python3
"""Make fricsens' mesh files with Gmsh, and check every one of them.

Regenerate (from the repository root; the script writes only into ``meshes/``)::

    python3 -m venv /work/gmsh-venv        # any venv will do
    /work/gmsh-venv/bin/pip install gmsh numpy
    /work/gmsh-venv/bin/python meshes/make_meshes.py

The output is deterministic: running the script twice gives byte-identical files
(Gmsh runs single-threaded; the Abaqus heading holds the bare file name, not a path).
It was last run with the Gmsh version printed at the top of its output.

Units: consistent units, lengths in mm (moduli in MPa, forces in N, pressures in MPa
for the analyses that read these meshes). The meshes themselves carry lengths only.

Every element is an 8-node hexahedron (Gmsh type 5); the face sets are 4-node
quadrangles (type 3), each a face of a hex of its body and numbered so that its normal
(x2 - x0) x (x3 - x1) points out of the body. Files are MSH 4.1 ASCII unless said
otherwise (coordinates printed with 16 significant digits, "%.16g", so about 1 ulp off
the doubles Gmsh had; the binary file holds them exactly). Only the elements of physical
groups are saved (volume groups = bodies, surface groups = face sets), but every node of
a saved hex is saved, including the nodes on entities in no group; no node is saved
that no saved element uses. The $Entities section lists every geometric entity, in a
group or not. Node tags run 1..N and element tags 1..M (face quads first, then hexes).

The plane-strain meshes (Hertz, punch) are OpenCASCADE geometry, one hex layer thick
along z: a 2-D mesh recombined into quads (Frontal-Delaunay for quads, then Blossom
full-quad recombination: plain Blossom left a few triangles, i.e. prisms) extruded with
one layer. No boolean operation is made between the bodies, so their coincident contact
points stay two points with two nodes. Their front/back (z = 0 and z = t) faces are in
no group. The Lamé meshes are built-in-kernel geometry, meshed transfinite.

Files
-----
``hertz-cylinders.msh``
    Hertz line contact of two elastic cylinders, plane strain, symmetric about x = 0
    (each body is a quarter disc on x >= 0, thickness t = 0.025 along z).
    "upper": radius R1 = 8, centre (0, 8, 0); "lower": radius R2 = 12, centre
    (0, -12, 0). They touch at the origin, where EACH body has its own node (two
    coincident nodes, not merged; likewise at (0, 0, t)). Mesh size 0.0167 within 0.6
    of the origin (the contact half-width is about a = 0.3: 18 elements across it), growing linearly to 1.2
    at distance 6. Groups: volumes "upper", "lower"; surfaces "upper-contact" (arc),
    "upper-top" (y = 8), "upper-sym" (x = 0), "lower-contact" (arc), "lower-bottom"
    (y = -12), "lower-sym" (x = 0).
``hertz-cylinders-binary.msh``
    The same mesh in MSH 4.1 binary, to test a binary reader.
``hertz-cylinders.inp``
    The same mesh in Abaqus input format as Gmsh writes it, to test an .inp reader:
    *Heading, *NODE (coordinates with 14 significant digits, "%.14g"), C3D8 elements
    per volume entity (*ELEMENT, type=C3D8, ELSET=VolumeN), CPS4 quads per surface
    entity (*ELEMENT, type=CPS4, ELSET=SurfaceN), then one *ELSET and one *NSET per
    physical group, named after it (options Mesh.SaveGroupsOfElements =
    Mesh.SaveGroupsOfNodes = -1100: groups of dimensions 2 and 3 only). Element and
    node numbers are the .msh tags here (Gmsh numbers the saved nodes 1..N, which is
    the .msh numbering when every node is saved). Set lines end in ", ".
``lame-octant.msh``
    Lamé's thick-walled sphere under pressure: the octant x, y, z >= 0 of a spherical
    shell, inner radius a = 1, outer radius b = 2. Structured (transfinite) hex mesh
    from the cube-sphere split of the octant into three blocks (12 x 12 elements on each
    block's spherical faces, i.e. 24 along each quarter great circle, 16 radial layers
    graded finer towards the inner surface, progression 1.07). The surfaces on the
    spheres are sphere patches; after the 1-D mesh the script puts every curve node at
    its exact parameter (equal angles on the arcs, the exact progression on the radial
    lines; Gmsh's own placement is a few 1e-9 off and not scale-invariant), so the
    mesh is a function of (a, b) alone. Groups: volume "shell"; surfaces "inner"
    (r = a), "outer" (r = b), "xsym" (x = 0), "ysym", "zsym". Checked: |x| = a on
    "inner" and b on "outer" to 1e-12, the zero coordinate exactly 0.0 on the
    symmetry faces.
``lame-octant-scaled.msh``
    The same script and topology with a = 1.05, b = 2.1: a uniform scaling by 1.05
    about the origin. Same node tags and connectivity as lame-octant.msh; coordinates
    1.05 times those of lame-octant.msh (checked to 1e-14). For shape-sensitivity
    checks against an isotropic scaling.
``lame-octant-inner.msh``
    The same topology with a = 1.1, b = 2: a CAD change of the inner radius only.
    Same node tags and connectivity as lame-octant.msh (checked). For the
    shape-sensitivity of the response to the inner radius (finite differences of
    complete meshes against a design velocity field).
``punch-on-slab.msh``
    For a literate example: a curved punch pressed into a slab and slid along it,
    plane strain, one hex layer of thickness t = 0.5. "slab": 0 <= x <= 40,
    -10 <= y <= 0; "punch": the lower half (y <= 10) of the disc of radius 10 centred
    (20, 10, 0), touching the slab at (20, 0, 0) (each body has its own node there, not
    merged). Mesh size 0.5 within 4 of the contact point, growing to 2.5 at distance 14.
    Groups: volumes "slab", "punch"; surfaces "slab-top" (y = 0), "slab-bottom"
    (y = -10), "slab-left" (x = 0), "slab-right" (x = 40), "punch-arc" (the curved
    face), "punch-top" (y = 10).

Checks made on every file, after reading it back with the Gmsh API: every saved
element is a hex8 (volumes) or quad4 (surface groups); the hex8 Jacobian determinant
at the 2x2x2 Gauss points is positive for every element (computed here with numpy
from the node coordinates); every face-set quad is a face of a hex of its body, with
its normal outward; no node is shared between two bodies and no two nodes of one body
coincide; no node is unused; node tags are 1..N; the file is under 1.5 MB. The
node/element counts and per-group counts are printed, and the .inp is compared with
the .msh. Mesh-specific checks (radii, symmetry planes, coincident contact nodes,
identical connectivity of the Lamé variants) are in the functions below.
"""

import hashlib
import os
import sys

import gmsh
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

HEX8, QUAD4 = 5, 3

# Abaqus export: element sets and node sets for the physical groups of dimensions 2 and
# 3 (a negative value selects dimensions by its decimal digits: units = points,
# tens = curves, hundreds = surfaces, thousands = volumes).
INP_GROUPS = -1100


# --------------------------------------------------------------------------- set-up


def start(name):
    """A fresh Gmsh model with the options every mesh here shares."""
    if gmsh.isInitialized():
        gmsh.finalize()
    gmsh.initialize(["make_meshes"], readConfigFiles=False)
    opt = gmsh.option.setNumber
    opt("General.Terminal", 1)
    opt("General.Verbosity", 2)  # errors and warnings only
    opt("General.NumThreads", 1)  # deterministic
    opt("Geometry.AutoCoherence", 0)  # the built-in kernel merges no coincident points
    opt("Mesh.MshFileVersion", 4.1)
    opt("Mesh.Binary", 0)
    opt("Mesh.SaveAll", 0)  # only the elements of physical groups
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.Algorithm", 8)  # Frontal-Delaunay for quads
    opt("Mesh.RecombinationAlgorithm", 3)  # Blossom full-quad: no triangle left (plain
    # Blossom, 1, leaves a few triangles, which extrude into prisms)
    opt("Mesh.RecombineAll", 0)
    gmsh.model.add(name)


def write(filename, binary=False):
    gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
    gmsh.write(filename)  # relative to meshes/ (the cwd): no path in the files
    gmsh.option.setNumber("Mesh.Binary", 0)


# --------------------------------------------------------------------------- checks

# dN/dxi of the hex8 shape functions at the 2x2x2 Gauss points, Gmsh's node order:
# 0..3 the face zeta = -1 counter-clockwise, 4..7 the face zeta = +1.
_CORNERS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
_G = 1.0 / np.sqrt(3.0)
_GAUSS = np.array([[i, j, k] for k in (-_G, _G) for j in (-_G, _G) for i in (-_G, _G)])


def _shape_derivatives():
    d = np.zeros((8, 3, 8))  # gauss point, d/dxi_i, node
    for g, xi in enumerate(_GAUSS):
        f = 1.0 + _CORNERS * xi  # (8 nodes, 3)
        for i in range(3):
            o = [k for k in range(3) if k != i]
            d[g, i, :] = 0.125 * _CORNERS[:, i] * f[:, o[0]] * f[:, o[1]]
    return d


_DN = _shape_derivatives()

# the six faces of a hex8, Gmsh's node order
_HEX_FACES = [(0, 3, 2, 1), (0, 1, 5, 4), (0, 4, 7, 3), (1, 2, 6, 5), (2, 3, 7, 6), (4, 5, 6, 7)]


def hex_jacobians(xyz):
    """det J at the 8 Gauss points of each hex: xyz is (n_elem, 8, 3); returns (n_elem, 8)."""
    jac = np.einsum("gia,eaj->egij", _DN, xyz)
    return np.linalg.det(jac)


class Mesh:
    """A mesh file as read back through the Gmsh API."""

    def __init__(self, filename):
        start("check")
        gmsh.open(filename)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        order = np.argsort(tags)
        self.node_tags = tags[order].astype(np.int64)
        self.coords = coords.reshape(-1, 3)[order]
        self._row = {int(t): i for i, t in enumerate(self.node_tags)}
        self.groups = {}  # name -> (dim, element tags, (n, k) node tags)
        types_seen = set()
        for dim, ptag in gmsh.model.getPhysicalGroups():
            name = gmsh.model.getPhysicalName(dim, ptag)
            etags, conn = [], []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, ptag):
                types, et, nt = gmsh.model.mesh.getElements(dim, ent)
                for ty, e, n in zip(types, et, nt):
                    types_seen.add(int(ty))
                    want = HEX8 if dim == 3 else QUAD4
                    assert ty == want, f"{filename}: {name} has element type {ty}, not {want}"
                    etags.append(e)
                    conn.append(n.reshape(len(e), -1))
            self.groups[name] = (dim, np.concatenate(etags).astype(np.int64),
                                 np.concatenate(conn).astype(np.int64))
        all_types, all_etags, _ = gmsh.model.mesh.getElements()
        self.element_types = sorted(int(t) for t in all_types)
        self.n_elements = sum(len(e) for e in all_etags)
        gmsh.finalize()

    def xyz(self, node_tags):
        rows = np.vectorize(self._row.__getitem__)(node_tags)
        return self.coords[rows]

    def bodies(self):
        return [n for n, g in self.groups.items() if g[0] == 3]

    def faces(self):
        return [n for n, g in self.groups.items() if g[0] == 2]

    def group_nodes(self, name):
        return np.unique(self.groups[name][2])


def check_common(filename, mesh, face_owner):
    """The checks every mesh gets; face_owner maps each surface group to its body."""
    size = os.path.getsize(filename)
    print(f"\n{filename}: {size} bytes, {len(mesh.node_tags)} nodes, "
          f"{mesh.n_elements} elements, element types {mesh.element_types}")
    assert set(mesh.element_types) <= {HEX8, QUAD4}
    assert size < 1_500_000
    used = set()
    body_nodes = {}
    min_det = np.inf
    for body in mesh.bodies():
        _, etags, conn = mesh.groups[body]
        det = hex_jacobians(mesh.xyz(conn))
        assert (det > 0).all(), f"{filename}: {body} has {np.sum(det <= 0)} det J <= 0"
        # scale-free measure: smallest det J over the element's largest
        rel = (det.min(axis=1) / det.max(axis=1)).min()
        min_det = min(min_det, det.min())
        print(f"  volume {body!r:18} {len(etags):6d} hex8, {len(np.unique(conn)):6d} nodes, "
              f"det J in [{det.min():.4e}, {det.max():.4e}], "
              f"min over elements of min/max det J {rel:.3f}")
        used.update(conn.ravel().tolist())
        body_nodes[body] = set(conn.ravel().tolist())
        # no crack: no two nodes of one body at the same place
        nodes = np.unique(conn)
        n_places = len(np.unique(mesh.xyz(nodes), axis=0))
        assert n_places == len(nodes), f"{filename}: {body} has coincident nodes"
    names = mesh.bodies()
    for i, b1 in enumerate(names):
        for b2 in names[i + 1:]:
            shared = body_nodes[b1] & body_nodes[b2]
            assert not shared, f"{filename}: {b1} and {b2} share {len(shared)} nodes"
    for face in mesh.faces():
        _, etags, conn = mesh.groups[face]
        body = face_owner[face]
        hexes = mesh.groups[body][2]
        owner = {frozenset(h[list(f)]): i for i, h in enumerate(hexes) for f in _HEX_FACES}
        missing = sum(frozenset(q) not in owner for q in conn)
        assert missing == 0, f"{filename}: {missing} quads of {face} are no face of {body}"
        # which way the quads' node order turns: normal (x2 - x0) x (x3 - x1) against
        # the direction from the owning hex's centroid to the quad's centroid
        xq = mesh.xyz(conn)
        xh = mesh.xyz(hexes[[owner[frozenset(q)] for q in conn]])
        normal = np.cross(xq[:, 2] - xq[:, 0], xq[:, 3] - xq[:, 1])
        outward = np.einsum("ij,ij->i", normal, xq.mean(axis=1) - xh.mean(axis=1)) > 0
        assert outward.all(), f"{filename}: {face} has inward-numbered quads"
        print(f"  surface {face!r:17} {len(etags):6d} quad4, {len(np.unique(conn)):6d} nodes "
              f"(all faces of {body!r} hexes; {outward.sum()} of {len(conn)} numbered "
              f"with the outward normal)")
        used.update(conn.ravel().tolist())
    unused = len(mesh.node_tags) - len(used & set(mesh.node_tags.tolist()))
    assert unused == 0 and used <= set(mesh.node_tags.tolist())
    assert np.array_equal(mesh.node_tags, np.arange(1, len(mesh.node_tags) + 1))
    print(f"  nodes written but used by no saved element: {unused}; "
          f"node tags {mesh.node_tags.min()}..{mesh.node_tags.max()}; min det J {min_det:.4e}")
    return min_det


def on_plane(mesh, face, axis, value, tol=0.0):
    x = mesh.xyz(mesh.group_nodes(face))[:, axis]
    err = np.abs(x - value).max()
    assert err <= tol, f"{face}: coordinate {axis} off {value} by {err}"
    return err


def on_circle(mesh, face, centre, radius, tol):
    x = mesh.xyz(mesh.group_nodes(face))
    err = np.abs(np.hypot(x[:, 0] - centre[0], x[:, 1] - centre[1]) - radius).max()
    assert err <= tol, f"{face}: off its circle by {err}"
    return err


def sha(filename):
    with open(filename, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()[:16]


# --------------------------------------------------------------------------- plane strain


def extrude_one_layer(surface, t, classify):
    """Extrude a recombined OCC surface by t along z with one hex layer.

    classify maps a name to a predicate on the centre of mass (x, y, z) of a lateral
    face; returns (volume tag, {name: [lateral surface tags]}), each lateral face
    claimed by exactly one name."""
    out = gmsh.model.occ.extrude([(2, surface)], 0, 0, t, numElements=[1], recombine=True)
    assert out[1][0] == 3
    faces = {name: [] for name in classify}
    for dim, tag in out[2:]:
        c = gmsh.model.occ.getCenterOfMass(dim, tag)
        names = [name for name, test in classify.items() if test(*c)]
        assert len(names) == 1, (tag, c, names)
        faces[names[0]].append(tag)
    return out[1][1], faces


def size_field(points, size_min, size_max, dist_min, dist_max):
    f = gmsh.model.mesh.field
    d = f.add("Distance")
    f.setNumbers(d, "PointsList", points)
    th = f.add("Threshold")
    f.setNumber(th, "InField", d)
    f.setNumber(th, "SizeMin", size_min)
    f.setNumber(th, "SizeMax", size_max)
    f.setNumber(th, "DistMin", dist_min)
    f.setNumber(th, "DistMax", dist_max)
    f.setAsBackgroundMesh(th)


def groups(spec):
    """spec: [(dim, [entity tags], name)], physical tags 1, 2, ... per dimension."""
    count = {2: 0, 3: 0}
    for dim, tags, name in spec:
        count[dim] += 1
        gmsh.model.addPhysicalGroup(dim, tags, tag=count[dim], name=name)


# --------------------------------------------------------------------------- Hertz

HZ_R1, HZ_R2, HZ_T = 8.0, 12.0, 0.025


def make_hertz():
    start("hertz-cylinders")
    # OpenCASCADE, and no boolean operation between the bodies: their two points at
    # the origin stay two points (the built-in kernel's extrusion needs its
    # "coherence" step, which would merge them).
    occ = gmsh.model.occ
    R1, R2, t = HZ_R1, HZ_R2, HZ_T
    eps = 1e-9
    # upper quarter disc: arc (0,0)->(R1,R1) about (0,R1), top y = R1, symmetry x = 0
    u0 = occ.addPoint(0, 0, 0)
    uc = occ.addPoint(0, R1, 0)
    u1 = occ.addPoint(R1, R1, 0)
    u_surf = occ.addPlaneSurface([occ.addCurveLoop(
        [occ.addCircleArc(u0, uc, u1), occ.addLine(u1, uc), occ.addLine(uc, u0)])])
    # lower quarter disc: symmetry x = 0, bottom y = -R2, arc (R2,-R2)->(0,0) about (0,-R2)
    l0 = occ.addPoint(0, 0, 0)  # a second point at the origin: the lower body's own
    lc = occ.addPoint(0, -R2, 0)
    l1 = occ.addPoint(R2, -R2, 0)
    l_surf = occ.addPlaneSurface([occ.addCurveLoop(
        [occ.addLine(l0, lc), occ.addLine(lc, l1), occ.addCircleArc(l1, lc, l0)])])
    u_vol, u = extrude_one_layer(u_surf, t, {
        "upper-top": lambda x, y, z: abs(y - R1) < eps,
        "upper-sym": lambda x, y, z: abs(x) < eps,
        "upper-contact": lambda x, y, z: abs(y - R1) > eps and abs(x) > eps})
    l_vol, lo = extrude_one_layer(l_surf, t, {
        "lower-bottom": lambda x, y, z: abs(y + R2) < eps,
        "lower-sym": lambda x, y, z: abs(x) < eps,
        "lower-contact": lambda x, y, z: abs(y + R2) > eps and abs(x) > eps})
    occ.synchronize()
    for s in (u_surf, l_surf):
        gmsh.model.mesh.setRecombine(2, s)
    origin = [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(
        -eps, -eps, -eps, eps, eps, eps, dim=0)]
    assert sorted(origin) == sorted([u0, l0]), origin
    size_field(origin, 0.0167, 1.2, 0.6, 6.0)
    groups([(3, [u_vol], "upper"), (3, [l_vol], "lower")]
           + [(2, u[n], n) for n in ("upper-contact", "upper-top", "upper-sym")]
           + [(2, lo[n], n) for n in ("lower-contact", "lower-bottom", "lower-sym")])
    gmsh.model.mesh.generate(3)
    write("hertz-cylinders.msh")
    write("hertz-cylinders-binary.msh", binary=True)
    gmsh.option.setNumber("Mesh.SaveGroupsOfElements", INP_GROUPS)
    gmsh.option.setNumber("Mesh.SaveGroupsOfNodes", INP_GROUPS)
    write("hertz-cylinders.inp")
    gmsh.finalize()


HZ_OWNER = {"upper-contact": "upper", "upper-top": "upper", "upper-sym": "upper",
            "lower-contact": "lower", "lower-bottom": "lower", "lower-sym": "lower"}


def check_hertz():
    results = {}
    for fn in ("hertz-cylinders.msh", "hertz-cylinders-binary.msh"):
        m = Mesh(fn)
        results[fn] = m
        min_det = check_common(fn, m, HZ_OWNER)
        for body in ("upper", "lower"):
            n = len(m.groups[body][1])
            assert n < 2500, f"{body}: {n} hexes"
        e1 = on_circle(m, "upper-contact", (0, HZ_R1), HZ_R1, 1e-12)
        e2 = on_circle(m, "lower-contact", (0, -HZ_R2), HZ_R2, 1e-12)
        on_plane(m, "upper-top", 1, HZ_R1)
        on_plane(m, "lower-bottom", 1, -HZ_R2)
        on_plane(m, "upper-sym", 0, 0.0)
        on_plane(m, "lower-sym", 0, 0.0)
        for body in ("upper", "lower"):
            z = m.xyz(np.unique(m.groups[body][2]))[:, 2]
            assert set(np.unique(z).tolist()) == {0.0, HZ_T}, f"{body}: z not in {{0, t}}"
        # the contact point: one node per body at (0,0,0), and at (0,0,t)
        for z in (0.0, HZ_T):
            at = [tag for tag, x in zip(m.node_tags, m.coords)
                  if x[0] == 0.0 and x[1] == 0.0 and x[2] == z]
            owners = sorted(b for tag in at for b in ("upper", "lower")
                            if tag in m.groups[b][2])
            assert len(at) == 2 and owners == ["lower", "upper"], (z, at, owners)
        print(f"  contact point: two nodes at (0,0,0) and two at (0,0,t), one of each "
              f"pair per body; arc nodes on their circles to {max(e1, e2):.1e}")
        for face in ("upper-contact", "lower-contact"):
            x = m.xyz(m.groups[face][2])[:, :, 0]
            within = np.sum(x.max(axis=1) <= 0.3 + 1e-9)
            print(f"  {face}: {within} quads with x <= a = 0.3")
        print(f"  min det J {min_det:.4e}")
    a, b = results["hertz-cylinders.msh"], results["hertz-cylinders-binary.msh"]
    assert np.array_equal(a.node_tags, b.node_tags)
    for name in a.groups:
        assert np.array_equal(a.groups[name][1], b.groups[name][1])
        assert np.array_equal(a.groups[name][2], b.groups[name][2])
    # MSH ASCII prints coordinates with 16 significant digits ("%.16g"), one short of
    # a round trip: the binary file holds the exact doubles, the ASCII file ~1 ulp off.
    diff = np.abs(a.coords - b.coords)
    rel = (diff / np.maximum(np.abs(b.coords), 1e-300)).max()
    assert diff.max() <= 1e-14, diff.max()
    print(f"  binary file: same node tags and connectivity; {np.sum(np.any(diff > 0, axis=1))} "
          f"of {len(diff)} nodes' coordinates differ from the ASCII file's, by at most "
          f"{diff.max():.1e} (relative {rel:.1e})")
    check_inp("hertz-cylinders.inp", a)


def check_inp(filename, mesh):
    """Summarize what Gmsh wrote in the .inp and compare it with the .msh."""
    with open(filename) as f:
        lines = f.read().splitlines()
    size = os.path.getsize(filename)
    print(f"\n{filename}: {size} bytes, {len(lines)} lines")
    keywords = {}
    blocks = []  # (keyword line, data lines)
    for line in lines:
        if line.startswith("*") and not line.startswith("**"):
            blocks.append((line, []))
            key = line.split(",")[0].upper()
            keywords[key] = keywords.get(key, 0) + 1
        elif line.startswith("**"):
            blocks.append((line, []))
        elif blocks:
            blocks[-1][1].append(line)
    for key, n in keywords.items():
        print(f"  {key}: {n}")
    nodes = {}
    elsets, nsets, elements = {}, {}, {}
    for head, data in blocks:
        h = head.upper().replace(" ", "")
        if h == "*NODE":
            for d in data:
                v = d.split(",")
                nodes[int(v[0])] = [float(s) for s in v[1:4]]
        elif h.startswith("*ELEMENT,"):
            set_name = head.split("ELSET=")[1]
            typ = h.split("TYPE=")[1].split(",")[0]
            ids = [[int(s) for s in d.split(",") if s.strip()] for d in data]
            elements[set_name] = (typ, ids)
            print(f"  {head}  ({len(ids)} elements)")
        elif h.startswith("*ELSET,"):
            elsets[head.split("ELSET=")[1]] = [int(s) for d in data for s in d.split(",") if s.strip()]
        elif h.startswith("*NSET,"):
            nsets[head.split("NSET=")[1]] = [int(s) for d in data for s in d.split(",") if s.strip()]
    for name, ids in elsets.items():
        print(f"  *ELSET,ELSET={name}: {len(ids)} elements")
    for name, ids in nsets.items():
        print(f"  *NSET,NSET={name}: {len(ids)} nodes")
    print(f"  *NODE: {len(nodes)} nodes, numbers {min(nodes)}..{max(nodes)}")
    # the .inp against the .msh: same element numbers per group, same node positions
    for name, (dim, etags, conn) in mesh.groups.items():
        assert sorted(elsets[name]) == sorted(etags.tolist()), name
        assert len(nsets[name]) == len(np.unique(conn)), name
    by_num = {e[0]: e[1:] for typ, ids in elements.values() for e in ids}
    same_numbers = True
    worst = 0.0
    for name, (dim, etags, conn) in mesh.groups.items():
        for e, c in zip(etags, conn):
            inp_xyz = np.array([nodes[n] for n in by_num[int(e)]])
            # the .inp prints coordinates with 14 significant digits ("%.14g")
            worst = max(worst, np.abs(inp_xyz - mesh.xyz(c)).max())
            same_numbers &= list(by_num[int(e)]) == c.tolist()
    assert worst < 1e-12, worst
    print(f"  every group's elements: same element numbers as in the .msh, node "
          f"coordinates equal to {worst:.1e} (the .inp prints 14 significant digits); "
          f"node numbers {'equal to' if same_numbers else 'DIFFERENT from'} the .msh tags")
    print("  first 30 lines:")
    for line in lines[:30]:
        print("    " + line)


# --------------------------------------------------------------------------- Lamé

LAME_N_ARC, LAME_N_RAD, LAME_PROGRESSION = 12, 16, 1.07


def make_lame(filename, a, b):
    start("lame-octant")
    geo = gmsh.model.geo
    s2, s3 = 1.0 / np.sqrt(2.0), 1.0 / np.sqrt(3.0)
    dirs = {"e1": (1, 0, 0), "e2": (0, 1, 0), "e3": (0, 0, 1),
            "m12": (s2, s2, 0), "m23": (0, s2, s2), "m13": (s2, 0, s2), "c": (s3, s3, s3)}
    origin = geo.addPoint(0, 0, 0)
    radii = (a, b)
    pt = {(k, r): geo.addPoint(*(r * np.array(d, dtype=float))) for r in radii
          for k, d in dirs.items()}
    arc_ends = [("e1", "m12"), ("e2", "m12"), ("e2", "m23"), ("e3", "m23"), ("e3", "m13"),
                ("e1", "m13"), ("c", "m12"), ("c", "m23"), ("c", "m13")]
    arc = {(p, q, r): geo.addCircleArc(pt[p, r], origin, pt[q, r])
           for r in radii for p, q in arc_ends}

    def a_(p, q, r):  # signed tag of the arc from p to q on sphere r
        return arc[p, q, r] if (p, q, r) in arc else -arc[q, p, r]

    radial = {k: geo.addLine(pt[k, a], pt[k, b]) for k in dirs}
    # the side faces (planes through the origin): one per arc
    side = {}
    for p, q in arc_ends:
        loop = geo.addCurveLoop([a_(p, q, a), radial[q], a_(q, p, b), -radial[p]])
        side[p, q] = geo.addPlaneSurface([loop])

    def side_(p, q):
        return side[p, q] if (p, q) in side else side[q, p]

    blocks = {"e1": ["e1", "m12", "c", "m13"], "e2": ["e2", "m23", "c", "m12"],
              "e3": ["e3", "m13", "c", "m23"]}
    patch = {}
    volumes = []
    for k, corners in blocks.items():
        ring = list(zip(corners, corners[1:] + corners[:1]))
        for r in radii:
            loop = geo.addCurveLoop([a_(p, q, r) for p, q in ring])
            patch[k, r] = geo.addSurfaceFilling([loop], sphereCenterTag=origin)
        shell = geo.addSurfaceLoop([patch[k, a], patch[k, b]] + [side_(p, q) for p, q in ring])
        volumes.append(geo.addVolume([shell]))
    geo.synchronize()
    mesh = gmsh.model.mesh
    for tag in arc.values():
        mesh.setTransfiniteCurve(tag, LAME_N_ARC + 1)
    for tag in radial.values():
        mesh.setTransfiniteCurve(tag, LAME_N_RAD + 1, "Progression", LAME_PROGRESSION)
    for tag in list(side.values()) + list(patch.values()):
        mesh.setTransfiniteSurface(tag)
        mesh.setRecombine(2, tag)
    for v in volumes:
        mesh.setTransfiniteVolume(v)
    groups([(3, volumes, "shell"),
            (2, [patch[k, a] for k in blocks], "inner"),
            (2, [patch[k, b] for k in blocks], "outer"),
            (2, [side["e2", "m23"], side["e3", "m23"]], "xsym"),
            (2, [side["e1", "m13"], side["e3", "m13"]], "ysym"),
            (2, [side["e1", "m12"], side["e2", "m12"]], "zsym")])
    mesh.generate(1)
    # Gmsh places a transfinite curve's nodes by a numerical arc length, a few 1e-9 off
    # the exact parameters (and differently for a = 1 and a = 1.05): put each curve node
    # at its exact parameter (equal angles on the arcs, the exact geometric progression
    # on the radial lines) before the surfaces and volumes are meshed from them, so that
    # the mesh is a function of a and b alone and scales exactly with them.
    q, n = LAME_PROGRESSION, LAME_N_RAD
    fractions = {tag: np.arange(LAME_N_ARC + 1) / LAME_N_ARC for tag in arc.values()}
    fractions.update({tag: (q ** np.arange(n + 1) - 1) / (q ** n - 1) for tag in radial.values()})
    moved = 0.0
    for tag, f in fractions.items():
        nodes, xyz, par = mesh.getNodes(1, tag, includeBoundary=False)
        for node, x, t in zip(nodes, xyz.reshape(-1, 3), par):
            exact = f[np.argmin(np.abs(f - t))]
            assert abs(exact - t) < 1e-6, (tag, t, exact)
            new_x = gmsh.model.getValue(1, tag, [exact])
            moved = max(moved, np.abs(new_x - x).max())
            mesh.setNode(node, new_x, [exact])
    print(f"  {filename}: curve nodes moved to their exact parameters, by at most {moved:.1e}")
    mesh.generate(3)
    # Gmsh numbers a surface's quads after the surface's own orientation, which for
    # these hand-built surfaces points into the shell on some: reverse those, so that
    # every face-set quad is numbered with the outward normal (as in the other files).
    outward = {"inner": lambda c: -c, "outer": lambda c: c,
               "xsym": lambda c: [-1, 0, 0], "ysym": lambda c: [0, -1, 0],
               "zsym": lambda c: [0, 0, -1]}
    reversed_ = []
    for _, ptag in gmsh.model.getPhysicalGroups(2):
        name = gmsh.model.getPhysicalName(2, ptag)
        for ent in gmsh.model.getEntitiesForPhysicalGroup(2, ptag):
            _, _, nodes = mesh.getElements(2, ent)
            x = np.array([mesh.getNode(n)[0] for n in nodes[0]]).reshape(-1, 4, 3)
            normal = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
            c = x.mean(axis=1)
            dots = np.einsum("ij,ij->i", normal, np.array([outward[name](ci) for ci in c]))
            assert (dots > 0).all() or (dots < 0).all(), (name, ent)
            if dots[0] < 0:
                mesh.reverse([(2, ent)])
                reversed_.append(int(ent))
    print(f"  {filename}: reversed the quads of surfaces {reversed_} (inward-numbered)")
    write(filename)
    gmsh.finalize()


LAME_OWNER = {f: "shell" for f in ("inner", "outer", "xsym", "ysym", "zsym")}


def check_lame(filename, a, b):
    m = Mesh(filename)
    min_det = check_common(filename, m, LAME_OWNER)
    r_in = np.linalg.norm(m.xyz(m.group_nodes("inner")), axis=1)
    r_out = np.linalg.norm(m.xyz(m.group_nodes("outer")), axis=1)
    err_in, err_out = np.abs(r_in - a).max(), np.abs(r_out - b).max()
    assert err_in <= 1e-12 and err_out <= 1e-12, (err_in, err_out)
    sym = [on_plane(m, f, i, 0.0, 1e-14) for i, f in enumerate(("xsym", "ysym", "zsym"))]
    exact = all(e == 0.0 for e in sym)
    r_all = np.linalg.norm(m.coords, axis=1)
    assert r_all.min() >= a - 1e-12 and r_all.max() <= b + 1e-12
    assert (m.coords >= 0.0).all()
    print(f"  |x| on inner: {a} to {err_in:.1e}; on outer: {b} to {err_out:.1e}; "
          f"symmetry faces' zero coordinate: {'exactly 0.0' if exact else max(sym)}; "
          f"min det J {min_det:.4e}")
    return m


def compare_topology(m0, m1, name, scale=None):
    assert np.array_equal(m0.node_tags, m1.node_tags), name
    assert list(m0.groups) == list(m1.groups), name
    for g in m0.groups:
        assert np.array_equal(m0.groups[g][1], m1.groups[g][1]), (name, g)
        assert np.array_equal(m0.groups[g][2], m1.groups[g][2]), (name, g)
    msg = f"  {name}: same node tags, element tags and connectivity as lame-octant.msh"
    if scale is not None:
        err = np.abs(m1.coords - scale * m0.coords).max()
        assert err <= 1e-14, err
        msg += f"; coordinates = {scale} x lame-octant.msh's to {err:.1e}"
    else:
        moved = np.any(m1.coords != m0.coords, axis=1).sum()
        msg += f"; {moved} of {len(m0.coords)} nodes moved"
    print(msg)


# --------------------------------------------------------------------------- punch on slab

PS_T, PS_R = 0.5, 10.0


def make_punch():
    start("punch-on-slab")
    occ = gmsh.model.occ  # as for Hertz: no boolean between the bodies
    eps = 1e-9
    # slab 0 <= x <= 40, -10 <= y <= 0, with a point at the contact point (20, 0)
    s = [occ.addPoint(*p) for p in ((0, -10, 0), (40, -10, 0), (40, 0, 0), (20, 0, 0), (0, 0, 0))]
    s_surf = occ.addPlaneSurface([occ.addCurveLoop(
        [occ.addLine(s[i], s[(i + 1) % 5]) for i in range(5)])])
    # punch: lower half of the disc of radius 10 about (20, 10); its own point at (20, 0)
    pc = occ.addPoint(20, 10, 0)
    pl, pb, pr = (occ.addPoint(*p) for p in ((10, 10, 0), (20, 0, 0), (30, 10, 0)))
    p_surf = occ.addPlaneSurface([occ.addCurveLoop(
        [occ.addCircleArc(pl, pc, pb), occ.addCircleArc(pb, pc, pr), occ.addLine(pr, pl)])])
    s_vol, sf = extrude_one_layer(s_surf, PS_T, {
        "slab-top": lambda x, y, z: abs(y) < eps,
        "slab-bottom": lambda x, y, z: abs(y + 10) < eps,
        "slab-left": lambda x, y, z: abs(x) < eps,
        "slab-right": lambda x, y, z: abs(x - 40) < eps})
    p_vol, pf = extrude_one_layer(p_surf, PS_T, {
        "punch-top": lambda x, y, z: abs(y - 10) < eps,
        "punch-arc": lambda x, y, z: abs(y - 10) > eps})
    occ.synchronize()
    for surf in (s_surf, p_surf):
        gmsh.model.mesh.setRecombine(2, surf)
    contact = [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(
        20 - eps, -eps, -eps, 20 + eps, eps, eps, dim=0)]
    assert sorted(contact) == sorted([s[3], pb]), contact
    size_field(contact, 0.5, 2.5, 4.0, 14.0)
    groups([(3, [s_vol], "slab"), (3, [p_vol], "punch")]
           + [(2, sf[n], n) for n in ("slab-top", "slab-bottom", "slab-left", "slab-right")]
           + [(2, pf[n], n) for n in ("punch-arc", "punch-top")])
    gmsh.model.mesh.generate(3)
    write("punch-on-slab.msh")
    gmsh.finalize()


PS_OWNER = {"slab-top": "slab", "slab-bottom": "slab", "slab-left": "slab",
            "slab-right": "slab", "punch-arc": "punch", "punch-top": "punch"}


def check_punch():
    fn = "punch-on-slab.msh"
    m = Mesh(fn)
    min_det = check_common(fn, m, PS_OWNER)
    n = sum(len(m.groups[b][1]) for b in ("slab", "punch"))
    assert n < 1500, n
    on_plane(m, "slab-top", 1, 0.0)
    on_plane(m, "slab-bottom", 1, -10.0)
    on_plane(m, "slab-left", 0, 0.0)
    on_plane(m, "slab-right", 0, 40.0)
    on_plane(m, "punch-top", 1, 10.0)
    err = on_circle(m, "punch-arc", (20, 10), PS_R, 1e-12)
    for z in (0.0, PS_T):
        at = [tag for tag, x in zip(m.node_tags, m.coords)
              if x[0] == 20.0 and x[1] == 0.0 and x[2] == z]
        assert len(at) == 2, at
    print(f"  {n} hexes in all; two nodes (one per body) at (20,0,0) and at (20,0,t); "
          f"arc nodes on the circle to {err:.1e}; min det J {min_det:.4e}")


# --------------------------------------------------------------------------- main


def main():
    os.chdir(HERE)
    gmsh.initialize(readConfigFiles=False)
    print(f"Gmsh {gmsh.option.getString('General.Version')}, numpy {np.__version__}")
    gmsh.finalize()

    make_hertz()
    check_hertz()

    lame = [("lame-octant.msh", 1.0, 2.0), ("lame-octant-scaled.msh", 1.05, 2.1),
            ("lame-octant-inner.msh", 1.1, 2.0)]
    checked = {}
    for fn, a, b in lame:
        make_lame(fn, a, b)
        checked[fn] = check_lame(fn, a, b)
    print()
    compare_topology(checked["lame-octant.msh"], checked["lame-octant-scaled.msh"],
                     "lame-octant-scaled.msh", scale=1.05)
    compare_topology(checked["lame-octant.msh"], checked["lame-octant-inner.msh"],
                     "lame-octant-inner.msh")

    make_punch()
    check_punch()

    print("\nsha256 (first 16 hex digits):")
    for fn in sorted(os.listdir(".")):
        if fn.endswith((".msh", ".inp")):
            print(f"  {fn:30} {os.path.getsize(fn):9d} bytes  {sha(fn)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
