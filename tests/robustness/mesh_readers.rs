//! Mesh import and export (issue "Bring your own geometry"): round trips through the Gmsh
//! and Abaqus writers and readers, real Gmsh output (`tests/meshes/make_fixtures.py`), a
//! hand-written `.inp`, one test per class of malformed input (typed error naming the file and
//! the line or entity), and a fuzzer mutating small seed files (no input may panic; a mutant
//! that ever does is kept under `tests/corpus/meshes/`).

use fricsens::element::Shape;
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
    // Gmsh: a 27-node hexahedron, an 18-node prism, a pyramid in place of the cube's hex8
    for (t, name) in [
        (12, "27-node second order hexahedron"),
        (13, "18-node second order prism"),
        (7, "5-node pyramid"),
    ] {
        let text = one_hex().replace("\n3 1 5 1\n", &format!("\n3 1 {t} 1\n"));
        let p = file_with(&format!("unsupported-{t}"), "unsupported.msh", &text);
        let header = line_of(&text, &format!("3 1 {t} 1"));
        let e = rejects(
            &p,
            None,
            &[
                &format!("type {t}, {name}"),
                "20-node hexahedron",
                &format!("line {header}"),
            ],
        );
        assert!(matches!(e, ImportError::UnsupportedElement { .. }), "{e}");
    }
    // Abaqus: C3D27, and the variable-node C3D15V
    for ty in ["C3D27", "C3D15V"] {
        let text = std::fs::read_to_string(fixtures().join("c3d10.inp"))
            .unwrap()
            .replace("TYPE=C3D10", &format!("TYPE={ty}"));
        let p = file_with(&format!("unsupported-{ty}"), "unsupported.inp", &text);
        let e = rejects(&p, None, &[ty, "line 13", "C3D20"]);
        assert!(matches!(e, ImportError::UnsupportedElement { .. }), "{e}");
    }
}

#[test]
fn a_wrong_node_count_for_its_type_names_the_element_and_its_line() {
    // Gmsh: a tet10 of quad_tet10.msh with a node tag too few, and one too many
    let text = std::fs::read_to_string(fixtures().join("quad_tet10.msh")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| *l == "$Elements").unwrap();
    // the first element line of the tetrahedra's block (type 11)
    let block = (header..lines.len())
        .find(|&k| {
            let f: Vec<&str> = lines[k].split_whitespace().collect();
            f.len() == 4 && f[0] == "3" && f[2] == "11"
        })
        .unwrap();
    let line = block + 2; // 1-based line of the block's first element
    let first: Vec<&str> = lines[block + 1].split_whitespace().collect();
    assert_eq!(first.len(), 11);
    let id = first[0];
    for (case, replaced) in [
        ("short", first[..10].join(" ")),
        ("long", format!("{} 1", first.join(" "))),
    ] {
        let mut l = lines.clone();
        l[block + 1] = &replaced;
        let p = file_with(
            &format!("count-{case}"),
            "count.msh",
            &(l.join("\n") + "\n"),
        );
        let e = rejects(
            &p,
            None,
            &[
                &format!("element {id}:"),
                "10-node second order tetrahedron has 10",
                &format!("line {line}"),
            ],
        );
        assert!(matches!(e, ImportError::Syntax { .. }), "{e}");
    }
    // Abaqus: a C3D10 with nine nodes, a C3D20 continued with a node too few
    let text = std::fs::read_to_string(fixtures().join("c3d10.inp"))
        .unwrap()
        .replace("9, 10\n", "9\n");
    let p = file_with("count-inp", "count.inp", &text);
    let e = rejects(
        &p,
        None,
        &["C3D10", "an id and 10 nodes, found 10 values", "line 14"],
    );
    assert!(matches!(e, ImportError::Syntax { .. }), "{e}");
    let hex = std::fs::read_to_string(fixtures().join("quad_hex20.inp")).unwrap();
    let at = hex.find("*ELEMENT, type=C3D20").unwrap();
    let line = 2 + hex[..at].lines().count();
    let start = at + hex[at..].find('\n').unwrap() + 1;
    let second = start + hex[start..].find('\n').unwrap() + 1;
    let end = second + hex[second..].find('\n').unwrap();
    // drop the continuation line's last node
    let cut = second + hex[second..end].rfind(',').unwrap();
    let text = format!("{}{}", &hex[..cut], &hex[end..]);
    let p = file_with("count-c3d20", "count20.inp", &text);
    let e = rejects(
        &p,
        None,
        &[
            "C3D20",
            "an id and 20 nodes, found 20 values",
            &format!("line {line}"),
        ],
    );
    assert!(matches!(e, ImportError::Syntax { .. }), "{e}");
}

#[test]
fn an_unknown_side_names_the_element_its_shape_and_the_line() {
    // S5 of a tetrahedron (it has S1..S4), S6 of a wedge (S1..S5), S7 of anything
    let tet = std::fs::read_to_string(fixtures().join("c3d10.inp")).unwrap();
    let text = format!("{tet}*SURFACE, NAME=top\n1, S5\n");
    let p = file_with("side-tet", "side.inp", &text);
    let e = rejects(
        &p,
        None,
        &[
            "face set 'top'",
            "element 1 is a tet10",
            "S1..S4, not S5",
            "line 16",
        ],
    );
    assert!(matches!(e, ImportError::UnknownSide { .. }), "{e}");
    let wedge = std::fs::read_to_string(fixtures().join("quad_wedge6.inp")).unwrap();
    let first = wedge
        .lines()
        .skip_while(|l| !l.contains("C3D6"))
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .to_string();
    let text = format!("{wedge}*SURFACE, NAME=w\n{first}, S6\n");
    let line = text.lines().count();
    let p = file_with("side-wedge", "side.inp", &text);
    let e = rejects(
        &p,
        Some("box"),
        &[
            &format!("element {first} is a wedge6"),
            "S1..S5, not S6",
            &format!("line {line}"),
        ],
    );
    assert!(matches!(e, ImportError::UnknownSide { .. }), "{e}");
    let text = format!("{tet}*SURFACE, NAME=top\n1, S7\n");
    let p = file_with("side-seven", "side.inp", &text);
    let e = rejects(&p, None, &["side 'S7' is not S1..S6", "line 16"]);
    assert!(matches!(e, ImportError::Syntax { .. }), "{e}");
}

#[test]
fn an_inverted_tet10_names_the_element_and_the_gauss_point() {
    // two corners swapped (with their mid-edge nodes): a reflection, det < 0 everywhere
    let text = std::fs::read_to_string(fixtures().join("c3d10.inp"))
        .unwrap()
        .replace(
            "1, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10",
            "1, 2, 1, 3, 4, 5, 7, 6, 9, 8, 10",
        );
    let p = file_with("inverted-tet10", "inverted.inp", &text);
    // (line 13 of c3d10.inp is its *ELEMENT keyword, the element on line 14)
    let e = rejects(&p, None, &["element 1", "Gauss point 0", "line 14"]);
    match e {
        // the unit tetrahedron mirrored: det J = -1 (six times its volume, negative)
        ImportError::InvertedElement { det, .. } => assert!((det + 1.0).abs() < 1e-12, "{det}"),
        e => panic!("{e}"),
    }
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
/// .inp), the hand-written .inp (with its include) and real Gmsh output (hex8 binary, hex20
/// ASCII, tet10 binary MSH; wedge15 .inp).
fn fuzz(n: usize, seed: u64) {
    use fricsens::studies::mesh_fuzz::{builtin_seeds, run, seed_from, MeshFuzzOptions};
    let mut seeds = builtin_seeds().unwrap();
    for f in [
        "hand.inp",
        "gmsh_box_bin.msh",
        "quad_hex20.msh",
        "quad_wedge15.inp",
        "quad_tet10_bin.msh",
    ] {
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

// ---------------------------------------------------------------------------------------
// Every solid shape: Gmsh's first- and second-order meshes of one box
// (tools/make_quadratic_meshes.py)
// ---------------------------------------------------------------------------------------

/// The fixtures of `tools/make_quadratic_meshes.py` and the shape each holds: the box
/// [`BOX`] with physical volume "box" and surfaces "xmin" and "zmax".
const SHAPES: [(&str, Shape); 6] = [
    ("quad_tet4", Shape::Tet4),
    ("quad_tet10", Shape::Tet10),
    ("quad_hex8", Shape::Hex8),
    ("quad_hex20", Shape::Hex20),
    ("quad_wedge6", Shape::Wedge6),
    ("quad_wedge15", Shape::Wedge15),
];

/// The box they mesh: `[0, 2] x [0, 1] x [0, 0.5]`, volume 1, surface 7.
const BOX: [f64; 3] = [2.0, 1.0, 0.5];

/// Round-off allowance of coordinates of order one.
const TOL: f64 = 1e-12;

/// Every Gmsh export of every fixture: `.msh`, `.inp` and the binary `.msh` of tet10.
fn shape_files() -> Vec<(PathBuf, Shape)> {
    let mut v = Vec::new();
    for (stem, shape) in SHAPES {
        for ext in ["msh", "inp"] {
            v.push((fixtures().join(format!("{stem}.{ext}")), shape));
        }
    }
    v.push((fixtures().join("quad_tet10_bin.msh"), Shape::Tet10));
    v
}

/// The coordinates of element `e`'s nodes.
fn element_x(m: &Mesh, x: &[Vector3<f64>], e: usize) -> Vec<Vector3<f64>> {
    m.element_nodes(e).iter().map(|&n| x[n]).collect()
}

/// The independent oracles of an imported box body `box` of `shape` elements (see
/// `gmsh_meshes_of_every_solid_shape_fill_the_box_with_straight_edges_and_outward_sides`).
fn check_box(m: &Mesh, what: &str, shape: Shape) {
    use fricsens::element::{ElementFamily, FaceFamily};
    let x = m.coordinates::<f64>(&m.block_geometry());
    assert_eq!(m.groups.len(), 1, "{what}");
    assert_eq!(m.groups[0].shape, shape, "{what}");
    // volumes: each positive, together the box's
    let family = ElementFamily::standard(shape);
    let mut volume = 0.0;
    for e in 0..m.n_elements() {
        let v = family
            .reference_volume(&element_x(m, &x, e))
            .unwrap_or_else(|err| panic!("{what}: element {e}: {err}"));
        assert!(v > 0.0, "{what}: element {e} has volume {v}");
        volume += v;
    }
    let want = BOX[0] * BOX[1] * BOX[2];
    assert!((volume - want).abs() < TOL, "{what}: volume {volume}");
    // straight edges: each mid-edge node (the edge table's order) halfway between the
    // edge's corners, one mid-edge node per edge of the mesh, every node a corner or one
    let corners = shape.corners().n_nodes();
    let mut corner_nodes = BTreeSet::new();
    let mut mids: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    for e in 0..m.n_elements() {
        let c = m.element_nodes(e);
        corner_nodes.extend(c[..corners].iter().copied());
        if !shape.is_quadratic() {
            continue;
        }
        for (k, [a, b]) in shape.edges().iter().enumerate() {
            let mid = c[corners + k];
            let halfway = (x[c[*a]] + x[c[*b]]) * 0.5;
            assert!(
                (x[mid] - halfway).norm() < TOL,
                "{what}: element {e}, edge {k}: mid node at {:?}, the edge's middle at {:?}",
                x[mid],
                halfway
            );
            let key = (c[*a].min(c[*b]), c[*a].max(c[*b]));
            assert_eq!(*mids.entry(key).or_insert(mid), mid, "{what}: edge {key:?}");
        }
    }
    assert_eq!(corner_nodes.len() + mids.len(), m.n_nodes(), "{what}");
    // the two sides: on their planes, of the side's area, each face's normal weights outward
    let faces_of = |name: &str| &m.face_sets[&format!("box.{name}")];
    let triangles = matches!(shape.corners(), Shape::Tet4);
    for (name, axis, at, sign, area, triangle) in [
        ("xmin", 0, 0.0, -1.0, BOX[1] * BOX[2], triangles),
        (
            "zmax",
            2,
            BOX[2],
            1.0,
            BOX[0] * BOX[1],
            shape.corners() != Shape::Hex8,
        ),
    ] {
        let mut normal = Vector3::zeros();
        normal[axis] = sign;
        let mut total = Vector3::zeros();
        let mut total_area = 0.0;
        let faces = faces_of(name);
        assert!(!faces.is_empty(), "{what}: {name}");
        for f in faces.iter() {
            let want = match (triangle, shape.is_quadratic()) {
                (true, false) => FaceFamily::Tri3,
                (true, true) => FaceFamily::Tri6,
                (false, false) => FaceFamily::Quad4,
                (false, true) => FaceFamily::Quad8,
            };
            assert_eq!(f.family, want, "{what}: {name}");
            let p: Vec<Vector3<f64>> = f.nodes.iter().map(|&n| x[n]).collect();
            assert!(
                p.iter().all(|q| (q[axis] - at).abs() < TOL),
                "{what}: {name}"
            );
            let w: Vector3<f64> = f.family.normal_weights(&p)[..f.nodes.len()].iter().sum();
            let a = f.family.area(&p);
            assert!(
                (w - normal * a).norm() < TOL,
                "{what}: {name}: face {:?} has normal weights {w:?}, not {a} times {normal:?}",
                f.nodes
            );
            total += w;
            total_area += a;
        }
        assert!(
            (total - normal * area).norm() < TOL,
            "{what}: {name}: {total:?}"
        );
        assert!(
            (total_area - area).abs() < TOL,
            "{what}: {name}: {total_area}"
        );
        // the side's node set: every node of the mesh on the plane
        let on_plane: Vec<usize> = (0..m.n_nodes())
            .filter(|&n| (x[n][axis] - at).abs() < TOL)
            .collect();
        assert_eq!(
            m.node_sets[&format!("box.{name}")],
            on_plane,
            "{what}: {name}"
        );
    }
    // the boundary: a closed surface (its normal weights sum to zero) around the box's
    // volume (the divergence theorem for x / 3: the weights against x sum to 3 V)
    let boundary = faces_of("boundary");
    let (mut closed, mut flux, mut area) = (Vector3::zeros(), 0.0, 0.0);
    for f in boundary.iter() {
        let p: Vec<Vector3<f64>> = f.nodes.iter().map(|&n| x[n]).collect();
        let w = f.family.normal_weights(&p);
        for (a, q) in p.iter().enumerate() {
            closed += w[a];
            flux += q.dot(&w[a]);
        }
        area += f.family.area(&p);
    }
    assert!(closed.norm() < TOL, "{what}: {closed:?}");
    assert!((flux - 3.0 * want).abs() < TOL, "{what}: {flux}");
    let surface = 2.0 * (BOX[0] * BOX[1] + BOX[0] * BOX[2] + BOX[1] * BOX[2]);
    assert!((area - surface).abs() < TOL, "{what}: {area}");
}

#[test]
fn gmsh_meshes_of_every_solid_shape_fill_the_box_with_straight_edges_and_outward_sides() {
    // Oracles: the box's volume (each element's reference volume positive, their sum 1), its
    // straight edges (each mid-edge node halfway between its edge's corners, in fricsens'
    // edge order: a wrong permutation of Gmsh's nodes puts a mid-edge node elsewhere), its
    // sides' areas and outward normals (sum of the consistent normal weights = area times
    // the unit normal), and the divergence theorem on the boundary
    for (path, shape) in shape_files() {
        let what = path.file_name().unwrap().to_string_lossy().to_string();
        let (m, _) = import(&path, "box", Some("box")).unwrap_or_else(|e| panic!("{e}"));
        check_box(&m, &what, shape);
    }
}

#[test]
fn gmsh_msh_and_inp_exports_of_one_model_have_the_same_elements_node_for_node() {
    // Gmsh's INP export writes its elements in Abaqus' node order, its MSH export in Gmsh's:
    // the two readers must give each element the same nodes in the same order (by Gmsh's
    // node ids, which both exports share), which checks the MSH reader's permutations
    // against Gmsh's own
    let elements = |path: &Path| {
        let (m, b) = import(path, "box", Some("box")).unwrap_or_else(|e| panic!("{e}"));
        let id: BTreeMap<usize, u64> = b.node_ids.iter().map(|(&i, &n)| (n, i)).collect();
        let x = m.coordinates::<f64>(&m.block_geometry());
        let mut v: Vec<Vec<u64>> = (0..m.n_elements())
            .map(|e| m.element_nodes(e).iter().map(|n| id[n]).collect())
            .collect();
        v.sort();
        let coordinates: BTreeMap<u64, Vector3<f64>> =
            b.node_ids.iter().map(|(&i, &n)| (i, x[n])).collect();
        (v, coordinates)
    };
    for (stem, _) in SHAPES {
        let (a, xa) = elements(&fixtures().join(format!("{stem}.msh")));
        let (b, xb) = elements(&fixtures().join(format!("{stem}.inp")));
        assert_eq!(a, b, "{stem}");
        assert_eq!(xa.len(), xb.len(), "{stem}");
        for (id, p) in &xa {
            assert!((p - xb[id]).norm() < 1e-9, "{stem}: node {id}");
        }
    }
}

#[test]
fn every_solid_shape_round_trips_through_gmsh_ascii_binary_and_abaqus() {
    let dir = scratch("shapes-round-trip");
    for (stem, shape) in SHAPES {
        let (m, _) = import(&fixtures().join(format!("{stem}.msh")), "box", Some("box"))
            .unwrap_or_else(|e| panic!("{e}"));
        let x = m.coordinates::<f64>(&m.block_geometry());
        let bodies = vec![("box".to_string(), 0)];
        let files = [
            dir.join(format!("{stem}.msh")),
            dir.join(format!("{stem}_bin.msh")),
            dir.join(format!("{stem}.inp")),
        ];
        gmsh::write(&m, &x, &bodies, &files[0], false).unwrap();
        gmsh::write(&m, &x, &bodies, &files[1], true).unwrap();
        abaqus::write(&m, &x, &bodies, &files[2]).unwrap();
        for file in &files {
            let (m2, body) = import(file, "box", Some("box")).unwrap_or_else(|e| panic!("{e}"));
            let what = format!("{}", file.display());
            assert_eq!(m2.groups[0].shape, shape, "{what}");
            assert_eq!(m2.n_nodes(), m.n_nodes(), "{what}");
            assert_eq!(m2.n_elements(), m.n_elements(), "{what}");
            let x2 = m2.coordinates::<f64>(&m2.block_geometry());
            // the writers number node n as n + 1
            let map = |n: usize| body.node_ids[&(n as u64 + 1)];
            for n in 0..m.n_nodes() {
                for c in 0..3 {
                    assert_eq!(x2[map(n)][c].to_bits(), x[n][c].to_bits(), "{what}");
                }
            }
            for e in 0..m.n_elements() {
                let mapped: Vec<usize> = m.element_nodes(e).iter().map(|&n| map(n)).collect();
                assert_eq!(mapped, m2.element_nodes(e), "{what} element {e}");
            }
            for set in ["xmin", "zmax", "boundary"] {
                let name = format!("box.{set}");
                assert_eq!(
                    face_set(&m, &name, &map),
                    face_set(&m2, &name, &|n| n),
                    "{what} face set {set}"
                );
                let families = |m: &Mesh| {
                    let mut v: Vec<_> = m.face_sets[&name].iter().map(|f| f.family).collect();
                    v.sort_by_key(|f| f.name());
                    v
                };
                assert_eq!(families(&m), families(&m2), "{what} face set {set}");
                let mut nodes: Vec<usize> = m.node_sets[&name].iter().map(|&n| map(n)).collect();
                nodes.sort_unstable();
                assert_eq!(nodes, m2.node_sets[&name], "{what} node set {set}");
            }
            check_box(&m2, &what, shape);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn gmsh_ascii_and_binary_second_order_files_read_alike() {
    let a = fricsens::mesh::read(&fixtures().join("quad_tet10.msh")).unwrap();
    let b = fricsens::mesh::read(&fixtures().join("quad_tet10_bin.msh")).unwrap();
    let (ca, cb) = (contents(&a), contents(&b));
    // Gmsh writes ASCII coordinates to 16 significant digits: equal to 1e-15, not bit for bit
    assert_eq!(ca.0.len(), cb.0.len());
    for ((ia, xa), (ib, xb)) in ca.0.iter().zip(&cb.0) {
        assert_eq!(ia, ib);
        for c in 0..3 {
            let (p, q) = (f64::from_bits(xa[c]), f64::from_bits(xb[c]));
            assert!((p - q).abs() <= 1e-15 * p.abs().max(1.0), "node {ia}");
        }
    }
    assert_eq!(
        (ca.1, ca.2, ca.3, ca.4, ca.5),
        (cb.1, cb.2, cb.3, cb.4, cb.5)
    );
}

#[test]
fn gmsh_tet4_and_a_hand_written_c3d10_are_read_whole() {
    // the unit cube of gmsh_tet4.msh (no physical group: every solid) and the one tet10 of
    // c3d10.inp, the unit tetrahedron with straight edges: volumes 1 and 1/6
    use fricsens::element::ElementFamily;
    for (file, shape, volume) in [
        ("gmsh_tet4.msh", Shape::Tet4, 1.0),
        ("c3d10.inp", Shape::Tet10, 1.0 / 6.0),
    ] {
        let (m, _) = import(&fixtures().join(file), "b", None).unwrap_or_else(|e| panic!("{e}"));
        let x = m.coordinates::<f64>(&m.block_geometry());
        assert_eq!(m.groups[0].shape, shape, "{file}");
        let v: f64 = (0..m.n_elements())
            .map(|e| {
                ElementFamily::standard(shape)
                    .reference_volume(&element_x(&m, &x, e))
                    .unwrap()
            })
            .sum();
        assert!((v - volume).abs() < TOL, "{file}: {v}");
        // a closed boundary of four (unit tetrahedron) or 2 x 6 (the cube) triangles a side
        let faces = &m.face_sets["b.boundary"];
        let mut closed = Vector3::zeros();
        for f in faces.iter() {
            let p: Vec<Vector3<f64>> = f.nodes.iter().map(|&n| x[n]).collect();
            closed += f.family.normal_weights(&p)[..p.len()]
                .iter()
                .sum::<Vector3<f64>>();
        }
        assert!(closed.norm() < TOL, "{file}: {closed:?}");
    }
}

/// One element of Abaqus type `ty` on nodes `x` (ids 1..), element set `E`, with a surface
/// `s` on side `side`.
fn one_element_inp(ty: &str, x: &[[f64; 3]], side: &str) -> String {
    let mut s = String::from("*NODE\n");
    for (k, p) in x.iter().enumerate() {
        s.push_str(&format!("{}, {}, {}, {}\n", k + 1, p[0], p[1], p[2]));
    }
    let ids: Vec<String> = (1..=x.len()).map(|n| n.to_string()).collect();
    // 16 entries a line at most: the id and 15 nodes, then the rest
    let (first, rest) = ids.split_at(ids.len().min(15));
    s.push_str(&format!(
        "*ELEMENT, TYPE={ty}, ELSET=E\n1, {}",
        first.join(", ")
    ));
    if !rest.is_empty() {
        s.push_str(&format!(",\n{}", rest.join(", ")));
    }
    s.push_str(&format!("\n*SURFACE, NAME=s\n1, {side}\n"));
    s
}

/// The middle of each pair of 1-based nodes of `corners`.
fn with_mids(corners: &[[f64; 3]], edges: &[[usize; 2]]) -> Vec<[f64; 3]> {
    let mut v = corners.to_vec();
    for [a, b] in edges {
        let (p, q) = (corners[a - 1], corners[b - 1]);
        v.push([
            0.5 * (p[0] + q[0]),
            0.5 * (p[1] + q[1]),
            0.5 * (p[2] + q[2]),
        ]);
    }
    v
}

#[test]
fn abaqus_sides_of_quadratic_elements_are_their_faces_with_mid_side_nodes_outward() {
    // One element of each quadratic type, nodes in the order of the Abaqus manual (corners,
    // then the middles of its edge list), and each side of the manual's face table
    // (1-based corners and the mid-side nodes of the face's edges): the face set holds that
    // face, with its area and outward unit normal (sum of its consistent normal weights)
    let r2 = 0.5_f64.sqrt();
    let r3 = 1.0 / 3.0_f64.sqrt();
    type Side = (&'static str, &'static [u64], &'static [u64], [f64; 3], f64);
    let tet: Vec<[f64; 3]> = with_mids(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        &[[1, 2], [2, 3], [3, 1], [1, 4], [2, 4], [3, 4]],
    );
    let tet_sides: [Side; 4] = [
        ("S1", &[1, 2, 3], &[5, 6, 7], [0.0, 0.0, -1.0], 0.5),
        ("S2", &[1, 2, 4], &[5, 8, 9], [0.0, -1.0, 0.0], 0.5),
        ("S3", &[2, 3, 4], &[6, 9, 10], [r3, r3, r3], 0.75_f64.sqrt()),
        ("S4", &[1, 3, 4], &[7, 8, 10], [-1.0, 0.0, 0.0], 0.5),
    ];
    // the unit right triangle swept over z in [0, 2]
    let wedge: Vec<[f64; 3]> = with_mids(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 2.0],
            [1.0, 0.0, 2.0],
            [0.0, 1.0, 2.0],
        ],
        &[
            [1, 2],
            [2, 3],
            [3, 1],
            [4, 5],
            [5, 6],
            [6, 4],
            [1, 4],
            [2, 5],
            [3, 6],
        ],
    );
    let wedge_sides: [Side; 5] = [
        ("S1", &[1, 2, 3], &[7, 8, 9], [0.0, 0.0, -1.0], 0.5),
        ("S2", &[4, 5, 6], &[10, 11, 12], [0.0, 0.0, 1.0], 0.5),
        ("S3", &[1, 2, 4, 5], &[7, 10, 13, 14], [0.0, -1.0, 0.0], 2.0),
        (
            "S4",
            &[2, 3, 5, 6],
            &[8, 11, 14, 15],
            [r2, r2, 0.0],
            2.0 * 2.0_f64.sqrt(),
        ),
        ("S5", &[1, 3, 4, 6], &[9, 12, 13, 15], [-1.0, 0.0, 0.0], 2.0),
    ];
    // the box [0, 1] x [0, 2] x [0, 3]
    let hex: Vec<[f64; 3]> = with_mids(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 3.0],
            [1.0, 0.0, 3.0],
            [1.0, 2.0, 3.0],
            [0.0, 2.0, 3.0],
        ],
        &[
            [1, 2],
            [2, 3],
            [3, 4],
            [4, 1],
            [5, 6],
            [6, 7],
            [7, 8],
            [8, 5],
            [1, 5],
            [2, 6],
            [3, 7],
            [4, 8],
        ],
    );
    let hex_sides: [Side; 6] = [
        ("S1", &[1, 2, 3, 4], &[9, 10, 11, 12], [0.0, 0.0, -1.0], 2.0),
        ("S2", &[5, 6, 7, 8], &[13, 14, 15, 16], [0.0, 0.0, 1.0], 2.0),
        ("S3", &[1, 2, 5, 6], &[9, 13, 17, 18], [0.0, -1.0, 0.0], 3.0),
        ("S4", &[2, 3, 6, 7], &[10, 14, 18, 19], [1.0, 0.0, 0.0], 6.0),
        ("S5", &[3, 4, 7, 8], &[11, 15, 19, 20], [0.0, 1.0, 0.0], 3.0),
        (
            "S6",
            &[1, 4, 5, 8],
            &[12, 16, 17, 20],
            [-1.0, 0.0, 0.0],
            6.0,
        ),
    ];
    // (Abaqus type, nodes, sides)
    type Case<'a> = (&'a str, &'a [[f64; 3]], &'a [Side]);
    let cases: [Case; 5] = [
        ("C3D10M", &tet, &tet_sides),
        ("C3D15", &wedge, &wedge_sides),
        ("C3D20R", &hex, &hex_sides),
        ("C3D4", &tet[..4], &tet_sides),
        ("C3D8", &hex[..8], &hex_sides),
    ];
    for (ty, x, sides) in cases {
        for &(side, corners, mids, normal, area) in sides {
            let what = format!("{ty} {side}");
            let p = file_with(
                &format!("side-{ty}-{side}"),
                "one.inp",
                &one_element_inp(ty, x, side),
            );
            let (m, b) = import(&p, "t", Some("e")).unwrap_or_else(|e| panic!("{what}: {e}"));
            let faces = &m.face_sets["t.s"];
            assert_eq!(faces.len(), 1, "{what}");
            let f = faces.face(0);
            let nc = f.family.n_corners();
            let ids: Vec<u64> = f.nodes.iter().map(|&n| id_of(&b, n)).collect();
            let mut c = ids[..nc].to_vec();
            c.sort_unstable();
            assert_eq!(c, corners, "{what}");
            let mut mid = ids[nc..].to_vec();
            mid.sort_unstable();
            let want: &[u64] = if x.len() > 8 { mids } else { &[] };
            assert_eq!(mid, want, "{what}");
            let xm = m.coordinates::<f64>(&m.block_geometry());
            let pts: Vec<Vector3<f64>> = f.nodes.iter().map(|&n| xm[n]).collect();
            let w: Vector3<f64> = f.family.normal_weights(&pts)[..pts.len()].iter().sum();
            let n = Vector3::from(normal);
            assert!((w - n * area).norm() < TOL, "{what}: {w:?}");
        }
    }
}

/// A deformable pair whose hitting surface is coarser than its target is warned of before the
/// first increment, with both node spacings (tests/meshes/coarse-hitting.toml: a slider of
/// elements 1.0 wide, 2.0 deep, on a base of elements 0.5, both one element deep), also when
/// the layer is thinner than the elements are wide (0.25 deep: the shortest edges are then
/// the depth on both sides); with hitting and target swapped it is not, and the solver is
/// made either way (a warning, not an error).
#[test]
fn a_hitting_surface_coarser_than_its_target_is_warned_of() {
    use fricsens::solver::{PrecheckWarning, Solver};
    let text = std::fs::read_to_string(fixtures().join("coarse-hitting.toml")).unwrap();
    let coarse = |text: &str| -> Vec<(String, f64, f64)> {
        let scene = fricsens::scene::Scene::from_toml(text, "coarse-hitting.toml").unwrap();
        let model = scene.build().unwrap();
        let solver = Solver::new(&model).unwrap();
        (solver.warnings().iter())
            .filter_map(|w| match w {
                PrecheckWarning::CoarseHitting {
                    pair,
                    hitting,
                    target,
                } => Some((pair.clone(), *hitting, *target)),
                _ => None,
            })
            .collect()
    };
    let found = coarse(&text);
    assert_eq!(found.len(), 1, "{found:?}");
    let (pair, hitting, target) = &found[0];
    assert_eq!(pair, "interface");
    assert!((hitting - 1.0).abs() < 1e-12 && (target - 0.5).abs() < 1e-12);
    let thin = text.replace("[bodies.z]\nlength = 2.0", "[bodies.z]\nlength = 0.25");
    assert_eq!(thin.matches("length = 0.25").count(), 2);
    let found = coarse(&thin);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!((found[0].1 - 1.0).abs() < 1e-12 && (found[0].2 - 0.5).abs() < 1e-12);
    let swapped = text
        .replace("hitting = \"slider.ymin\"", "hitting = \"base.ymax\"")
        .replace("faces = \"base.ymax\"", "faces = \"slider.ymin\"");
    assert_ne!(swapped, text);
    assert!(coarse(&swapped).is_empty());
}
