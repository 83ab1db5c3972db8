//! Mesh import and export (issue "Bring your own geometry"): round trips through the Gmsh
//! and Abaqus writers and readers, real Gmsh output (`tests/meshes/make_fixtures.py`), a
//! hand-written `.inp`, one test per class of malformed input (typed error naming the file and
//! the line or entity), and a fuzzer mutating small seed files (no input may panic; a mutant
//! that ever does is kept under `tests/corpus/meshes/`).

use fricsens::mesh::import::{FileFace, ImportError, ImportedBody, MeshFile};
use fricsens::mesh::{abaqus, gmsh, Axis, BlockSpec, Mesh, Zone};
use nalgebra::Vector3;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/meshes")
}

/// A fresh scratch directory for one test.
fn scratch(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fricsens-meshes-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A graded block `name` of nx x ny x nz hex8 at an odd origin (coordinates with full
/// mantissas), and its reference coordinates.
fn block(name: &str, n: [usize; 3]) -> (Mesh, Vec<Vector3<f64>>) {
    let mut m = Mesh::default();
    m.add_block(BlockSpec {
        element: fricsens::element::Shape::Hex8,
        name: name.into(),
        origin: [0.3, -1.7, 2.1],
        x: Axis {
            length: 1.1,
            zones: vec![Zone {
                fraction: 1.0,
                elements: n[0],
                ratio: 3.0,
            }],
        },
        y: Axis::uniform(0.7, n[1]),
        z: Axis::uniform(0.9 / 7.0, n[2]),
    })
    .unwrap();
    let x = m.coordinates::<f64>(&m.block_geometry());
    (m, x)
}

fn import(
    path: &Path,
    prefix: &str,
    set: Option<&str>,
) -> Result<(Mesh, ImportedBody), ImportError> {
    let f = fricsens::mesh::read(path)?;
    let mut m = Mesh::default();
    let b = f.add_to(&mut m, prefix, set)?;
    Ok((m, b))
}

/// A face's nodes rotated to start at the smallest (orientation kept).
fn canonical(face: &[usize]) -> Vec<usize> {
    let k = (0..face.len()).min_by_key(|&k| face[k]).unwrap_or(0);
    face[k..].iter().chain(&face[..k]).copied().collect()
}

fn face_set(m: &Mesh, name: &str, map: &dyn Fn(usize) -> usize) -> BTreeSet<Vec<usize>> {
    m.face_sets[name]
        .iter()
        .map(|f| canonical(&f.nodes.iter().map(|&n| map(n)).collect::<Vec<_>>()))
        .collect()
}

/// The error of importing `path` (all solids), which must contain each of `needles`.
#[track_caller]
fn rejects(path: &Path, set: Option<&str>, needles: &[&str]) -> ImportError {
    let e = match import(path, "b", set) {
        Ok(_) => panic!("{} was accepted", path.display()),
        Err(e) => e,
    };
    let msg = e.to_string();
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    assert!(msg.contains(&name), "the file name is not in: {msg}");
    for n in needles {
        assert!(msg.contains(n), "`{n}` is not in: {msg}");
    }
    e
}

/// 1-based line of the first line of `text` that is exactly `what`.
fn line_of(text: &str, what: &str) -> usize {
    1 + text.lines().position(|l| l.trim_end() == what).unwrap()
}

// ---------------------------------------------------------------------------------------
// Round trips
// ---------------------------------------------------------------------------------------

#[test]
fn round_trips_through_gmsh_ascii_binary_and_abaqus_are_exact() {
    let dir = scratch("round-trip");
    let (m, x) = block("b", [3, 2, 2]);
    let bodies = vec![("b".to_string(), 0)];
    let files = [dir.join("b.msh"), dir.join("b_bin.msh"), dir.join("b.inp")];
    gmsh::write(&m, &x, &bodies, &files[0], false).unwrap();
    gmsh::write(&m, &x, &bodies, &files[1], true).unwrap();
    abaqus::write(&m, &x, &bodies, &files[2]).unwrap();
    for file in &files {
        let (m2, body) = import(file, "b", Some("b")).unwrap_or_else(|e| panic!("{e}"));
        let x2 = m2.coordinates::<f64>(&m2.block_geometry());
        // hand count: 4 x 3 x 3 nodes, 3 x 2 x 2 elements
        assert_eq!(m2.n_nodes(), 36);
        assert_eq!(m2.n_elements(), 12);
        assert_eq!(body.element_ids, (1..=12).collect::<Vec<u64>>());
        // the writers number node n as n + 1
        let map = |n: usize| body.node_ids[&(n as u64 + 1)];
        for n in 0..m.n_nodes() {
            for c in 0..3 {
                assert_eq!(
                    x2[map(n)][c].to_bits(),
                    x[n][c].to_bits(),
                    "{file:?} node {n}"
                );
            }
        }
        for e in 0..m.n_elements() {
            let mapped: Vec<usize> = m.element_nodes(e).iter().map(|&n| map(n)).collect();
            assert_eq!(mapped, m2.element_nodes(e), "{file:?} element {e}");
        }
        for side in ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"] {
            let a = face_set(&m, &format!("b.{side}"), &map);
            let b = face_set(&m2, &format!("b.{side}"), &|n| n);
            assert_eq!(a, b, "{file:?} face set {side}");
            let mut na: Vec<usize> = m.node_sets[&format!("b.{side}")]
                .iter()
                .map(|&n| map(n))
                .collect();
            na.sort_unstable();
            assert_eq!(
                na,
                m2.node_sets[&format!("b.{side}")],
                "{file:?} node set {side}"
            );
        }
        // boundary: 2 (3 x 2 + 2 x 2 + 3 x 2) quads
        assert_eq!(m2.face_sets["b.boundary"].len(), 32);
        let mut want: BTreeSet<String> = m.node_sets.keys().cloned().collect();
        want.extend(["b.b".to_string(), "b.boundary".to_string()]);
        assert_eq!(
            m2.node_sets.keys().cloned().collect::<BTreeSet<_>>(),
            want,
            "{file:?}"
        );
        let mut want: BTreeSet<String> = m.face_sets.keys().cloned().collect();
        want.insert("b.boundary".into());
        assert_eq!(
            m2.face_sets.keys().cloned().collect::<BTreeSet<_>>(),
            want,
            "{file:?}"
        );
    }
}

#[test]
fn two_bodies_written_together_read_back_one_by_one() {
    let dir = scratch("two-bodies");
    let (mut m, _) = block("a", [2, 1, 1]);
    m.add_block(BlockSpec {
        element: fricsens::element::Shape::Hex8,
        name: "c".into(),
        origin: [5.0, 0.0, 0.0],
        x: Axis::uniform(1.0, 1),
        y: Axis::uniform(1.0, 1),
        z: Axis::uniform(1.0, 3),
    })
    .unwrap();
    let x = m.coordinates::<f64>(&m.block_geometry());
    let bodies = vec![("a".to_string(), 0), ("c".to_string(), 1)];
    for (k, file) in ["ab.msh", "ab_bin.msh", "ab.inp"].iter().enumerate() {
        let p = dir.join(file);
        match k {
            0 => gmsh::write(&m, &x, &bodies, &p, false).unwrap(),
            1 => gmsh::write(&m, &x, &bodies, &p, true).unwrap(),
            _ => abaqus::write(&m, &x, &bodies, &p).unwrap(),
        }
        let f = fricsens::mesh::read(&p).unwrap();
        let mut m2 = Mesh::default();
        let ba = f.add_to(&mut m2, "a", Some("a")).unwrap();
        let bc = f.add_to(&mut m2, "c", Some("c")).unwrap();
        assert_eq!((ba.element_ids.len(), bc.element_ids.len()), (2, 3));
        assert_eq!(m2.n_nodes(), 12 + 16);
        // zmax of c: one quad; of a: two
        assert_eq!(m2.face_sets["c.zmax"].len(), 1);
        assert_eq!(m2.face_sets["a.zmax"].len(), 2);
        assert_eq!(m2.node_sets["c.zmax"].len(), 4);
    }
}

/// A file without its lines (ASCII lines and binary offsets differ).
#[allow(clippy::type_complexity)]
fn contents(
    f: &MeshFile,
) -> (
    Vec<(u64, [u64; 3])>,
    Vec<(u64, Vec<u64>)>,
    Vec<(u64, String, Vec<u64>)>,
    BTreeMap<String, Vec<usize>>,
    BTreeMap<String, Vec<u64>>,
    BTreeMap<String, Vec<Vec<u64>>>,
) {
    (
        f.nodes
            .iter()
            .map(|n| (n.id, n.x.map(f64::to_bits)))
            .collect(),
        f.elements.iter().map(|e| (e.id, e.nodes.clone())).collect(),
        f.other_elements
            .iter()
            .map(|e| (e.id, e.kind.clone(), e.nodes.clone()))
            .collect(),
        f.element_sets.clone(),
        f.node_sets.clone(),
        f.face_sets
            .iter()
            .map(|(k, v)| {
                let faces = v
                    .iter()
                    .map(|f| match f {
                        FileFace::Nodes { nodes, .. } => nodes.clone(),
                        FileFace::Side { element, side, .. } => vec![*element, *side as u64],
                    })
                    .collect();
                (k.clone(), faces)
            })
            .collect(),
    )
}

#[test]
fn ascii_and_binary_msh_of_one_mesh_read_to_equal_files() {
    let dir = scratch("ascii-binary");
    let (m, x) = block("b", [2, 3, 1]);
    let bodies = vec![("b".to_string(), 0)];
    gmsh::write(&m, &x, &bodies, &dir.join("a.msh"), false).unwrap();
    gmsh::write(&m, &x, &bodies, &dir.join("b.msh"), true).unwrap();
    let a = fricsens::mesh::read(&dir.join("a.msh")).unwrap();
    let b = fricsens::mesh::read(&dir.join("b.msh")).unwrap();
    assert_eq!(contents(&a), contents(&b));
    assert_eq!(a.nodes.len(), 3 * 4 * 2);
    // and so are Gmsh's own ASCII and binary files
    let a = fricsens::mesh::read(&fixtures().join("gmsh_box.msh")).unwrap();
    let b = fricsens::mesh::read(&fixtures().join("gmsh_box_bin.msh")).unwrap();
    assert_eq!(contents(&a), contents(&b));
}

// ---------------------------------------------------------------------------------------
// Real Gmsh output and a hand-written .inp
// ---------------------------------------------------------------------------------------

#[test]
fn gmsh_ascii_binary_and_inp_exports_of_one_model_give_one_body() {
    let mut names = Vec::new();
    for file in ["gmsh_box.msh", "gmsh_box_bin.msh", "gmsh_box.inp"] {
        let p = fixtures().join(file);
        let (m, _) = import(&p, "box", Some("block")).unwrap_or_else(|e| panic!("{e}"));
        let x = m.coordinates::<f64>(&m.block_geometry());
        // the 2 x 1 x 1 box in 2 x 2 x 2 hexahedra
        assert_eq!(m.n_nodes(), 27, "{file}");
        assert_eq!(m.n_elements(), 8, "{file}");
        assert_eq!(m.face_sets["box.boundary"].len(), 24, "{file}");
        for (set, xv, normal) in [("box.left", 0.0, -1.0), ("box.PhysicalSurface3", 2.0, 1.0)] {
            let faces = &m.face_sets[set];
            assert_eq!(faces.len(), 4, "{file} {set}");
            assert_eq!(m.node_sets[set].len(), 9, "{file} {set}");
            for f in faces.iter() {
                let p: Vec<_> = f.nodes.iter().map(|&n| x[n]).collect();
                assert!(p.iter().all(|q| q[0] == xv));
                let n = (p[1] - p[0]).cross(&(p[3] - p[0]));
                assert!(
                    n[0] * normal > 0.0 && n[1] == 0.0 && n[2] == 0.0,
                    "{file} {set}: {n:?}"
                );
            }
        }
        let mut keys: Vec<String> = m.node_sets.keys().cloned().collect();
        keys.extend(m.face_sets.keys().map(|k| format!("faces {k}")));
        names.push(keys);
    }
    let msh = [
        "box.PhysicalSurface3",
        "box.all",
        "box.block",
        "box.boundary",
        "box.left",
        "faces box.PhysicalSurface3",
        "faces box.boundary",
        "faces box.left",
    ];
    assert_eq!(names[0], msh);
    assert_eq!(names[1], msh);
    // Gmsh's .inp adds its per-entity element sets Surface1, Surface2 (CPS4) and Volume1
    let mut inp: Vec<&str> = msh.to_vec();
    inp.extend([
        "box.Surface1",
        "box.Surface2",
        "box.Volume1",
        "faces box.Surface1",
        "faces box.Surface2",
    ]);
    inp.sort_by_key(|s| (s.starts_with("faces"), s.to_string()));
    assert_eq!(names[2], inp);
}

#[test]
fn gmsh_parametric_nodes_are_read_past() {
    let a = fricsens::mesh::read(&fixtures().join("gmsh_box.msh")).unwrap();
    let b = fricsens::mesh::read(&fixtures().join("gmsh_box_param.msh")).unwrap();
    assert_eq!(contents(&a), contents(&b));
}

/// The unused-node rule for Gmsh files relies on Gmsh writing no node that no saved element
/// uses: with one physical surface, only its nodes are written.
#[test]
fn gmsh_writes_only_the_nodes_its_saved_elements_use() {
    let p = fixtures().join("gmsh_surface_only.msh");
    let f = fricsens::mesh::read(&p).unwrap();
    let used: BTreeSet<u64> = f
        .other_elements
        .iter()
        .flat_map(|e| e.nodes.iter().copied())
        .collect();
    let nodes: BTreeSet<u64> = f.nodes.iter().map(|n| n.id).collect();
    // the x = 0 face of 2 x 2 quadrangles
    assert_eq!(nodes.len(), 9);
    assert_eq!(used, nodes);
    assert_eq!(f.face_sets["left"].len(), 4);
    let e = rejects(&p, None, &["has no solid element"]);
    assert!(matches!(e, ImportError::EmptyBody { .. }), "{e}");
}

#[test]
fn a_hand_written_inp_with_includes_generate_continuations_and_sides() {
    let p = fixtures().join("hand.inp");
    let f = fricsens::mesh::read(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(f.nodes.len(), 12);
    assert_eq!(f.elements.len(), 2);
    assert_eq!(f.elements[0].nodes, [1, 2, 5, 4, 7, 8, 11, 10]);
    assert_eq!(f.nodes[2].x, [2.0, 0.0, 0.0]);
    assert_eq!(f.element_sets["Bricks"], [0, 1]);
    assert_eq!(f.element_sets["First"], [0]);
    assert_eq!(f.node_sets["XMIN"], [1, 4, 7, 10]);
    assert_eq!(f.node_sets["ends"], [1, 3, 4, 6, 7, 9, 10, 12]);
    assert_eq!(f.node_sets["everything"].len(), 12);
    assert_eq!(f.face_sets["top"].len(), 2);
    assert_eq!(f.face_sets["right"].len(), 1);
    // node 12 is on line 14 of hand_nodes.inp
    let at = f.place(f.nodes[11].line).to_string();
    assert!(at.ends_with("hand_nodes.inp, line 14"), "{at}");
    // and element 2 on line 9 of hand.inp (after the include and a continued line)
    let at = f.place(f.elements[1].line).to_string();
    assert!(at.ends_with("hand.inp, line 9"), "{at}");
    // the element set by another case
    let mut m = Mesh::default();
    let b = f.add_to(&mut m, "h", Some("bricks")).unwrap();
    assert_eq!(b.element_ids, [1, 2]);
    let x = m.coordinates::<f64>(&m.block_geometry());
    let right = &m.face_sets["h.right"];
    assert_eq!(right.len(), 1);
    // side S4 of element 2 = its nodes 2, 6, 7, 3 (1-based) = ids 3, 9, 12, 6
    let mut ids: Vec<u64> = right.nodes(0).iter().map(|&n| id_of(&b, n)).collect();
    ids.sort_unstable();
    assert_eq!(ids, [3, 6, 9, 12]);
    let p: Vec<_> = right.nodes(0).iter().map(|&n| x[n]).collect();
    assert!((p[1] - p[0]).cross(&(p[3] - p[0]))[0] > 0.0);
    let top = &m.face_sets["h.top"];
    assert_eq!(top.len(), 2);
    for f in top.iter() {
        let p: Vec<_> = f.nodes.iter().map(|&n| x[n]).collect();
        assert!(p.iter().all(|q| q[2] == 1.0));
        assert!((p[1] - p[0]).cross(&(p[3] - p[0]))[2] > 0.0);
    }
    assert_eq!(m.face_sets["h.boundary"].len(), 10);
    assert_eq!(m.node_sets["h.First"].len(), 8);
    assert_eq!(m.node_sets["h.right"].len(), 4);
    // only the first brick: the right side is the other body's, the top has one face
    let mut m = Mesh::default();
    f.add_to(&mut m, "f", Some("FIRST")).unwrap();
    assert!(!m.face_sets.contains_key("f.right"));
    assert_eq!(m.face_sets["f.top"].len(), 1);
    assert_eq!(m.node_sets["f.ends"].len(), 4);
}

fn id_of(b: &ImportedBody, n: usize) -> u64 {
    *b.node_ids.iter().find(|(_, &m)| m == n).unwrap().0
}

// ---------------------------------------------------------------------------------------
// Malformed input, one test per class
// ---------------------------------------------------------------------------------------

/// `text` written to `name` in a scratch directory.
fn file_with(test: &str, name: &str, text: &str) -> PathBuf {
    let p = scratch(test).join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn one_hex() -> String {
    std::fs::read_to_string(fixtures().join("one_hex.msh")).unwrap()
}

#[test]
fn the_hand_written_gmsh_cube_is_valid() {
    let (m, b) = import(&fixtures().join("one_hex.msh"), "c", Some("cube")).unwrap();
    assert_eq!(b.element_ids, [1]);
    assert_eq!(m.face_sets["c.right"].len(), 1);
    assert_eq!(m.face_sets["c.boundary"].len(), 6);
}

#[test]
fn missing_file_unknown_extension_and_random_bytes() {
    let p = fixtures().join("no_such_mesh.msh");
    assert!(matches!(
        rejects(&p, None, &["cannot read"]),
        ImportError::Io { .. }
    ));
    let p = file_with("random", "mesh.stl", "solid x");
    assert!(matches!(
        rejects(&p, None, &["unknown mesh format"]),
        ImportError::UnknownFormat { .. }
    ));
    let bytes: Vec<u8> = (0..4000u32)
        .map(|k| (k.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    for name in ["noise.msh", "noise.inp"] {
        let p = scratch("noise").join(name);
        std::fs::write(&p, &bytes).unwrap();
        let e = rejects(&p, None, &["line 1"]);
        assert!(matches!(e, ImportError::Syntax { .. }), "{e}");
    }
}

#[test]
fn truncated_files_name_the_file_and_the_place() {
    let dir = scratch("truncated");
    let (m, x) = block("b", [2, 2, 2]);
    let bodies = vec![("b".to_string(), 0)];
    let full = dir.join("full.msh");
    gmsh::write(&m, &x, &bodies, &full, false).unwrap();
    let text = std::fs::read_to_string(&full).unwrap();
    for section in ["$Nodes", "$Elements"] {
        let cut = text.find(section).unwrap() + section.len() + 40;
        let p = dir.join("cut.msh");
        std::fs::write(&p, &text[..cut]).unwrap();
        let e = rejects(&p, None, &["unexpected end of file", "line"]);
        assert!(matches!(e, ImportError::Truncated { .. }), "{e}");
    }
    let full = dir.join("full_bin.msh");
    gmsh::write(&m, &x, &bodies, &full, true).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    let p = dir.join("cut_bin.msh");
    std::fs::write(&p, &bytes[..bytes.len() - 100]).unwrap();
    let e = rejects(&p, None, &["unexpected end of file", "byte"]);
    assert!(matches!(e, ImportError::Truncated { .. }), "{e}");
}

#[test]
fn msh_2_2_is_refused_saying_how_to_write_4_1() {
    let e = rejects(
        &fixtures().join("gmsh_box_v22.msh"),
        None,
        &["line 2", "2.2", "MshFileVersion"],
    );
    assert!(matches!(e, ImportError::MshVersion { .. }));
}

#[test]
fn unsupported_element_types_are_named() {
    let text = std::fs::read_to_string(fixtures().join("gmsh_tet4.msh")).unwrap();
    let e = rejects(
        &fixtures().join("gmsh_tet4.msh"),
        None,
        &["type 4, 4-node tetrahedron", "8-node hexahedron"],
    );
    assert!(matches!(e, ImportError::UnsupportedElement { .. }));
    // the block header of the tetrahedra
    let header = text.lines().position(|l| l.starts_with("3 1 4 ")).unwrap() + 1;
    assert!(e.to_string().contains(&format!("line {header}")), "{e}");
    let e = rejects(&fixtures().join("c3d10.inp"), None, &["C3D10", "line 13"]);
    assert!(matches!(e, ImportError::UnsupportedElement { .. }));
}

#[test]
fn an_inverted_element_names_the_element_and_the_gauss_point() {
    // top and bottom swapped: the map is a reflection, det < 0 everywhere
    let text = one_hex().replace("1 1 2 3 4 5 6 7 8", "1 5 6 7 8 1 2 3 4");
    let p = file_with("inverted", "inverted.msh", &text);
    let line = line_of(&text, "1 5 6 7 8 1 2 3 4");
    let e = rejects(
        &p,
        None,
        &["element 1", "Gauss point 0", &format!("line {line}")],
    );
    match e {
        ImportError::InvertedElement { det, .. } => assert!((det + 0.125).abs() < 1e-12, "{det}"),
        e => panic!("{e}"),
    }
    // and a degenerate one: two nodes at one place (det 0 at some Gauss point... or less)
    let text = one_hex().replace("\n1 1 0\n", "\n0 0 0\n");
    let p = file_with("degenerate", "degenerate.msh", &text);
    let e = import(&p, "b", None).unwrap_err();
    assert!(
        matches!(
            e,
            ImportError::CoincidentNodes { .. } | ImportError::InvertedElement { .. }
        ),
        "{e}"
    );
}

#[test]
fn duplicate_node_ids_name_both_lines() {
    let text = one_hex().replace("\n8\n0 0 0\n", "\n7\n0 0 0\n");
    let p = file_with("dup-node", "dup.msh", &text);
    let e = rejects(
        &p,
        None,
        &["node 7 is defined twice", "line 35", "(first at", "line 34"],
    );
    assert!(matches!(e, ImportError::DuplicateNode { .. }), "{e}");
}

const TWO_BRICKS: &str = "*NODE
1, 0, 0, 0
2, 1, 0, 0
3, 2, 0, 0
4, 0, 1, 0
5, 1, 1, 0
6, 2, 1, 0
7, 0, 0, 1
8, 1, 0, 1
9, 2, 0, 1
10, 0, 1, 1
11, 1, 1, 1
12, 2, 1, 1
*ELEMENT, TYPE=C3D8, ELSET=B
1, 1, 2, 5, 4, 7, 8, 11, 10
2, 2, 3, 6, 5, 8, 9, 12, 11
";

#[test]
fn coincident_nodes_are_an_unmerged_mesh() {
    // the second brick on its own copies of the shared nodes
    let text = TWO_BRICKS.replace(
        "2, 2, 3, 6, 5, 8, 9, 12, 11",
        "2, 13, 3, 6, 14, 15, 9, 12, 16",
    ) + "*NODE\n13, 1, 0, 0\n14, 1, 1, 0\n15, 1, 0, 1\n16, 1, 1, 1\n";
    let text = text.replacen("*ELEMENT", "**\n*ELEMENT", 1);
    let p = file_with("coincident", "unmerged.inp", &text);
    let e = rejects(
        &p,
        None,
        &[
            "duplicate nodes",
            "not merged",
            "nodes 2",
            "and 13",
            "line 3",
        ],
    );
    assert!(matches!(e, ImportError::CoincidentNodes { .. }), "{e}");
}

#[test]
fn unused_nodes_in_gmsh_and_in_abaqus_sets() {
    let text = one_hex()
        .replace("1 8 1 8\n3 1 0 8\n", "1 9 1 9\n3 1 0 9\n")
        .replace("\n8\n0 0 0\n", "\n8\n9\n0 0 0\n")
        .replace("0 1 1\n$EndNodes", "0 1 1\n5 5 5\n$EndNodes");
    let p = file_with("unused", "unused.msh", &text);
    let line = line_of(&text, "5 5 5");
    let e = rejects(
        &p,
        None,
        &["node 9 is used by no element", &format!("line {line}")],
    );
    assert!(matches!(e, ImportError::UnusedNode { .. }), "{e}");
    // Abaqus: a reference point is fine...
    let text = format!("{TWO_BRICKS}*NODE\n99, 7, 7, 7\n");
    let p = file_with("unused-rp", "rp.inp", &text);
    import(&p, "b", None).unwrap();
    // ...but not in a node set with body nodes
    let text = format!("{TWO_BRICKS}*NODE, NSET=pts\n99, 7, 7, 7\n*NSET, NSET=pts\n1, 2\n");
    let p = file_with("unused-set", "rpset.inp", &text);
    let e = rejects(&p, None, &["node 99", "pts", "line 18"]);
    assert!(matches!(e, ImportError::UnusedNode { .. }), "{e}");
}

#[test]
fn a_prefix_in_use_is_refused() {
    let f = fricsens::mesh::read(&fixtures().join("one_hex.msh")).unwrap();
    let mut m = Mesh::default();
    f.add_to(&mut m, "c", None).unwrap();
    let e = f.add_to(&mut m, "c", None).unwrap_err();
    assert!(matches!(e, ImportError::PrefixTaken { .. }), "{e}");
    assert!(
        e.to_string().contains("one_hex.msh") && e.to_string().contains("'c.*'"),
        "{e}"
    );
    assert_eq!(m.n_nodes(), 8);
    f.add_to(&mut m, "d", None).unwrap();
    assert_eq!(m.n_nodes(), 16);
}

#[test]
fn a_missing_set_lists_the_sets_there_are() {
    let e = rejects(
        &fixtures().join("one_hex.msh"),
        Some("nope"),
        &["'nope'", "cube"],
    );
    assert!(matches!(e, ImportError::UnknownSet { .. }));
}

#[test]
fn an_interior_face_in_a_face_set_is_refused() {
    let text = format!("{TWO_BRICKS}*SURFACE, NAME=mid\n1, S4\n");
    let p = file_with("interior", "interior.inp", &text);
    let e = rejects(
        &p,
        None,
        &[
            "face set 'mid'",
            "not on the boundary",
            "elements 1 and 2",
            "line 18",
        ],
    );
    assert!(matches!(e, ImportError::FaceNotOnBoundary { .. }), "{e}");
    // a refused body leaves the mesh as it was
    let mut m = Mesh::default();
    fricsens::mesh::read(&p)
        .unwrap()
        .add_to(&mut m, "b", None)
        .unwrap_err();
    assert_eq!((m.n_nodes(), m.groups.len(), m.node_sets.len()), (0, 0, 0));
    // a face of no element at all
    let text = one_hex().replace("2 2 3 7 6", "2 2 3 7 5");
    let p = file_with("no-face", "noface.msh", &text);
    let e = rejects(
        &p,
        None,
        &["face set 'right'", "[2, 3, 7, 5]", "face of no element"],
    );
    assert!(matches!(e, ImportError::FaceNotFound { .. }), "{e}");
}

#[test]
fn an_element_naming_a_missing_node() {
    let text = one_hex().replace("1 1 2 3 4 5 6 7 8", "1 1 2 3 4 5 6 7 88");
    let p = file_with("missing-node", "missing.msh", &text);
    let line = line_of(&text, "1 1 2 3 4 5 6 7 88");
    let e = rejects(
        &p,
        None,
        &["element 1 names node 88", &format!("line {line}")],
    );
    assert!(matches!(e, ImportError::MissingNode { .. }), "{e}");
    // and a set naming one
    let text = format!("{TWO_BRICKS}*NSET, NSET=s\n1, 77\n");
    let p = file_with("missing-set-node", "setnode.inp", &text);
    let e = rejects(&p, None, &["set 's' names node 77", "line 18"]);
    assert!(matches!(e, ImportError::MissingMember { .. }), "{e}");
}

#[test]
fn includes_of_a_missing_file_and_in_a_cycle() {
    let e = rejects(
        &fixtures().join("include_missing.inp"),
        None,
        &["no_such_file.inp", "included at", "line 2"],
    );
    assert!(matches!(e, ImportError::Io { .. }), "{e}");
    let e = rejects(
        &fixtures().join("cycle_a.inp"),
        None,
        &["cycle_b.inp, line 4", "makes a cycle"],
    );
    assert!(matches!(e, ImportError::IncludeCycle { .. }), "{e}");
}

#[test]
fn parts_and_instances_are_refused_with_advice() {
    let text = format!("*PART, NAME=p\n{TWO_BRICKS}*END PART\n");
    let p = file_with("parts", "parts.inp", &text);
    let e = rejects(&p, None, &["*PART", "flat input file", "line 1"]);
    assert!(matches!(e, ImportError::Unsupported { .. }), "{e}");
}

#[test]
fn non_finite_coordinates_and_duplicate_elements() {
    let text = TWO_BRICKS.replace("5, 1, 1, 0", "5, 1, nan, 0");
    let p = file_with("nan", "nan.inp", &text);
    let e = rejects(&p, None, &["node 5", "not finite", "line 6"]);
    assert!(matches!(e, ImportError::NonFiniteNode { .. }), "{e}");
    let text = TWO_BRICKS.replace("2, 2, 3, 6", "1, 2, 3, 6");
    let p = file_with("dup-element", "dupel.inp", &text);
    let e = rejects(
        &p,
        None,
        &["element 1 is defined twice", "line 15", "line 16"],
    );
    assert!(matches!(e, ImportError::DuplicateElement { .. }), "{e}");
}

// ---------------------------------------------------------------------------------------
// Fuzzing
// ---------------------------------------------------------------------------------------

/// A campaign of the library's mesh fuzzer (`fricsens::studies::mesh_fuzz`, also
/// `fricsens fuzz-meshes`): its built-in seeds (a block written as .msh ASCII, binary and
/// .inp), the hand-written .inp (with its include) and real Gmsh binary output.
fn fuzz(n: usize, seed: u64) {
    use fricsens::studies::mesh_fuzz::{builtin_seeds, run, seed_from, MeshFuzzOptions};
    let mut seeds = builtin_seeds().unwrap();
    for f in ["hand.inp", "gmsh_box_bin.msh"] {
        seeds.push(seed_from(&fixtures().join(f)).unwrap());
    }
    let dir = scratch(&format!("fuzz-{seed}"));
    let opts = MeshFuzzOptions {
        mutants: n,
        seed,
        seeds,
        includes: vec![fixtures().join("hand_nodes.inp")],
        corpus: Some(corpus()),
    };
    let report = run(&opts, &dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    println!("{}", report.markdown());
    assert!(report.clean(), "{}", report.markdown());
    // the mutator must reach both outcomes
    assert!(
        report.accepted > 0 && report.refused_total() > n / 4,
        "{} accepted, {} refused",
        report.accepted,
        report.refused_total()
    );
}

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/meshes")
}

#[test]
fn fuzzed_mesh_files_never_panic() {
    fuzz(2000, 0x9E37_79B9_7F4A_7C15);
}

#[test]
#[ignore = "100 000 mutants: cargo test --release --test robustness mesh_readers::fuzz_long -- --ignored"]
fn fuzz_long() {
    // another seed: MESH_FUZZ_SEED=12345
    let seed = std::env::var("MESH_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0xD1B5_4A32_D192_ED03);
    fuzz(100_000, seed);
}

/// Every mutant that once panicked (`tests/corpus/meshes/`) now reads to a value or a typed
/// error.
#[test]
fn the_corpus_of_once_panicking_meshes_passes() {
    let Ok(dir) = std::fs::read_dir(corpus()) else {
        return;
    };
    for f in dir {
        let p = f.unwrap().path();
        if p.extension().is_some_and(|e| e == "msh" || e == "inp") {
            assert!(
                fricsens::studies::mesh_fuzz::survives(&p).is_ok(),
                "{} panics",
                p.display()
            );
        }
    }
}

/// Time and memory stay linear: a 40 x 40 x 40 block (64 000 hex8) through both formats.
#[test]
#[ignore = "timing: cargo test --release --test robustness mesh_readers::large -- --ignored --nocapture"]
fn large_block_through_both_formats() {
    let dir = scratch("large");
    let (m, x) = block("b", [40, 40, 40]);
    let bodies = vec![("b".to_string(), 0)];
    for (name, k) in [("l.msh", 0), ("l_bin.msh", 1), ("l.inp", 2)] {
        let p = dir.join(name);
        let t = std::time::Instant::now();
        match k {
            0 => gmsh::write(&m, &x, &bodies, &p, false).unwrap(),
            1 => gmsh::write(&m, &x, &bodies, &p, true).unwrap(),
            _ => abaqus::write(&m, &x, &bodies, &p).unwrap(),
        }
        let written = t.elapsed();
        let t = std::time::Instant::now();
        let f = fricsens::mesh::read(&p).unwrap();
        let read = t.elapsed();
        let t = std::time::Instant::now();
        let mut m2 = Mesh::default();
        f.add_to(&mut m2, "b", Some("b")).unwrap();
        println!(
            "{name}: {} bytes, write {written:?}, read {read:?}, add_to {:?}",
            std::fs::metadata(&p).unwrap().len(),
            t.elapsed()
        );
        assert_eq!(m2.n_elements(), 64_000);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn meshes_of_two_bodies_that_overlap_at_the_start_are_refused_naming_nodes_and_depth() {
    // tests/meshes/overlap.{inp,toml}: the upper brick's bottom face starts 0.1 inside the
    // lower brick's top face (by construction of the hand-written file)
    use fricsens::solver::{AnalysisError, PrecheckError, Solver};
    let scene = fricsens::scene::Scene::from_file(&fixtures().join("overlap.toml")).unwrap();
    let model = scene.build().unwrap();
    let bottom = &model.mesh.node_sets["upper.UpperBottom"];
    let err = match Solver::new(&model) {
        Err(e) => e,
        Ok(_) => panic!("overlapping meshes accepted"),
    };
    let message = err.to_string();
    match err {
        AnalysisError::Precheck(PrecheckError::Overlap { pair, nodes, .. }) => {
            assert_eq!(pair, "stack");
            let named: BTreeSet<usize> = nodes.iter().map(|(n, _)| *n).collect();
            assert_eq!(named, bottom.iter().copied().collect::<BTreeSet<_>>());
            for (n, depth) in &nodes {
                assert!((depth - 0.1).abs() <= 1e-12, "node {n}: depth {depth}");
            }
        }
        other => panic!("not an overlap: {other}"),
    }
    for needle in [
        "'stack'",
        "4 hitting node(s) start inside the target",
        "1.000e-1",
    ] {
        assert!(message.contains(needle), "{needle:?} not in {message}");
    }
}
