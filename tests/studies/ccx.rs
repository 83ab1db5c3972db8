//! The CalculiX exporter and comparison (`src/studies/ccx.rs`).
//!
//! The deck tests need no CalculiX. The comparisons themselves are `#[ignore]`d (each runs
//! `ccx` three times and fricsens twice) and skip with a message when `ccx` is not on PATH:
//! `cargo test --release --test studies -- --ignored ccx::`.

use crate::common::{fricsens, scratch_path};

use fricsens::contact::{quad_nodes, Target};
use fricsens::element::Formulation;
use fricsens::material::{J2Plasticity, Material};
use fricsens::scene::{indentation, Scene, TargetSpec};
use fricsens::studies::ccx::{
    compare, export, find_ccx, keyword_counts, parse_dat_blocks, parse_dat_forces, variation,
    CcxError, CompareOptions, DatBlock, ExportOptions, Source,
};
use std::collections::{BTreeSet, HashMap};
use std::path::Path;

fn scene(file: &str) -> Scene {
    Scene::from_file(Path::new(file)).unwrap()
}

/// The comparison options of a test: `ccx` run in the scratch directory `work` (beta = 1e-2,
/// `threads` threads, no time limit).
fn options(ccx: std::path::PathBuf, work: std::path::PathBuf, threads: usize) -> CompareOptions {
    CompareOptions {
        ccx,
        work,
        beta: 1e-2,
        threads,
        export: ExportOptions::default(),
        time_limit: None,
    }
}

/// `model` compared with CalculiX in a scratch directory named `work` (removed afterwards);
/// `None`, with a message, where `ccx` is not installed.
fn against_calculix(
    model: &fricsens::model::Model,
    name: &str,
    work: &str,
    threads: usize,
) -> Option<fricsens::studies::ccx::Comparison> {
    let Some(ccx) = find_ccx() else {
        println!(
            "ccx not found: skipping the CalculiX comparison (install Debian package calculix-ccx)"
        );
        return None;
    };
    let work = scratch_path(work);
    let c = compare(model, name, &options(ccx, work.clone(), threads));
    let _ = std::fs::remove_dir_all(&work);
    Some(c.unwrap())
}

/// The deck's nodes (1-based id to coordinates), elements (id to nodes and element set) and
/// element surfaces (name to (element, side)), read back from its text.
struct ParsedDeck {
    nodes: HashMap<usize, [f64; 3]>,
    elements: HashMap<usize, (Vec<usize>, String)>,
    surfaces: HashMap<String, Vec<(usize, usize)>>,
}

fn parse_deck(deck: &str) -> ParsedDeck {
    let mut p = ParsedDeck {
        nodes: HashMap::new(),
        elements: HashMap::new(),
        surfaces: HashMap::new(),
    };
    let param = |l: &str, key: &str| {
        l.split(',')
            .find_map(|f| f.trim().strip_prefix(key).map(str::to_string))
            .unwrap_or_default()
    };
    let mut block = String::new();
    for l in deck.lines() {
        if l.starts_with("**") {
            continue;
        }
        if l.starts_with('*') {
            block = l.to_string();
            continue;
        }
        let f: Vec<&str> = l
            .split(',')
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .collect();
        if block.starts_with("*NODE,") || block == "*NODE" {
            let x: Vec<f64> = f[1..].iter().map(|v| v.parse().unwrap()).collect();
            p.nodes.insert(f[0].parse().unwrap(), [x[0], x[1], x[2]]);
        } else if block.starts_with("*ELEMENT") {
            let ids: Vec<usize> = f.iter().map(|v| v.parse().unwrap()).collect();
            p.elements
                .insert(ids[0], (ids[1..].to_vec(), param(&block, "ELSET=")));
        } else if block.starts_with("*SURFACE,") && block.contains("TYPE=ELEMENT") {
            let side: usize = f[1].strip_prefix('S').unwrap().parse().unwrap();
            p.surfaces
                .entry(param(&block, "NAME="))
                .or_default()
                .push((f[0].parse().unwrap(), side));
        }
    }
    p
}

/// Sides S1..S6 of a C3D8 as 1-based local nodes, from the Abaqus / CalculiX manuals (written
/// out here rather than taken from the importer, so that the test checks the exporter's
/// table).
const C3D8_SIDES: [[usize; 4]; 6] = [
    [1, 2, 3, 4],
    [5, 8, 7, 6],
    [1, 5, 6, 2],
    [2, 6, 7, 3],
    [3, 7, 8, 4],
    [4, 8, 5, 1],
];

impl ParsedDeck {
    /// The 0-based model nodes of side `side` (1-based) of element `e`.
    fn side_nodes(&self, e: usize, side: usize) -> [usize; 4] {
        let c = &self.elements[&e].0;
        C3D8_SIDES[side - 1].map(|l| c[l - 1] - 1)
    }

    /// Every element's faces (sorted model nodes) with their owners.
    fn face_owners(&self) -> HashMap<[usize; 4], usize> {
        let mut m = HashMap::new();
        for &e in self.elements.keys() {
            for side in 1..=6 {
                let mut f = self.side_nodes(e, side);
                f.sort_unstable();
                *m.entry(f).or_insert(0) += 1;
            }
        }
        m
    }

    fn x(&self, n: usize) -> [f64; 3] {
        self.nodes[&(n + 1)]
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn centroid(d: &ParsedDeck, nodes: &[usize]) -> [f64; 3] {
    let mut c = [0.0; 3];
    for &n in nodes {
        let x = d.x(n);
        for k in 0..3 {
            c[k] += x[k] / nodes.len() as f64;
        }
    }
    c
}

/// Lines of the data block that follows the first line starting with `keyword`.
fn block_lines(deck: &str, keyword: &str) -> usize {
    deck.lines()
        .skip_while(|l| !l.starts_with(keyword))
        .skip(1)
        .take_while(|l| !l.starts_with('*'))
        .count()
}

#[test]
fn indentation_deck_has_every_keyword_block_and_the_mesh_one_for_one() {
    let model = indentation(2, 4).build().unwrap();
    let deck = export(&model, &ExportOptions::default()).unwrap();
    let kw = keyword_counts(&deck.text);
    for (k, n) in [
        ("ELEMENT", 2), // the slab (C3D8I) and the rigid block (C3D8)
        ("MATERIAL", 1),
        ("ELASTIC", 1),
        ("SURFACE INTERACTION", 1),
        ("SURFACE BEHAVIOR", 1),
        ("FRICTION", 1),
        ("CONTACT PAIR", 1),
        ("RIGID BODY", 1),
        ("STEP", 2), // press (2 x 0.5) and slide (4 x 0.25)
        ("STATIC", 2),
        ("END STEP", 2),
        ("NODE PRINT", 2),
    ] {
        assert_eq!(kw.get(k), Some(&n), "*{k} in\n{kw:?}");
    }
    assert_eq!(kw.get("SURFACE"), Some(&2), "slave and master surfaces");
    assert!(kw.get("BOUNDARY").copied().unwrap_or(0) >= 5);
    assert!(kw.get("CONTROLS").copied().unwrap_or(0) >= 2);
    // nodes and elements one for one, the plane-strain slab as incompatible-mode bricks
    assert_eq!(
        block_lines(&deck.text, "*NODE,NSET=NALL"),
        model.mesh.n_nodes()
    );
    assert_eq!(
        block_lines(&deck.text, "*ELEMENT,TYPE=C3D8I"),
        model.mesh.n_elements()
    );
    assert_eq!(deck.element_types, vec!["C3D8I"]);
    assert!(!deck.nlgeom, "the indentation is small kinematics");
    assert!(!deck.text.contains("NLGEOM"));
    // the rigid block: reference and rotation nodes after the mesh and its own nodes
    let reference = deck.reference_nodes[0].unwrap();
    assert_eq!(reference, deck.nodes - 1);
    assert!(reference > model.mesh.n_nodes());
    assert!(deck.elements > model.mesh.n_elements());
    // the same increments: DIRECT, 0.5 then 0.25
    assert!(deck
        .text
        .contains("*STATIC,DIRECT\n5.000000000000e-1,1.000000000000e0"));
    assert!(deck
        .text
        .contains("*STATIC,DIRECT\n2.500000000000e-1,1.000000000000e0"));
    assert_eq!(deck.times, model.times);
    // contact constants: positive, the stick slope fricsens' tangential stiffness per area
    let pair = &model.contacts[0];
    assert!(deck.normal_stiffness[0] > 0.0 && deck.tension[0] > 0.0);
    assert!(
        (deck.stick_slope[0] * deck.median_area[0] / pair.tangential_stiffness - 1.0).abs() < 1e-12
    );
    // CalculiX reads a real from 20 characters at most
    let data = deck.text.lines().skip_while(|l| !l.starts_with("*NODE"));
    for l in data.filter(|l| !l.starts_with('*')) {
        for f in l.split(',') {
            assert!(f.trim().len() <= 20, "field '{f}' in '{l}'");
        }
    }
}

#[test]
fn a_rigid_target_pushed_by_a_force_is_a_cload_on_its_reference_node() {
    // the indentation's block pushed down by a force instead of a prescribed translation
    let mut s = indentation(2, 4);
    let TargetSpec::Rigid { motion, .. } = &mut s.contacts[0].target else {
        panic!("a rigid target")
    };
    motion[0].value = None;
    motion[0].force = Some(-12.5);
    let model = s.build().unwrap();
    let deck = export(&model, &ExportOptions::default()).unwrap();
    assert!(
        deck.text
            .contains("*CLOAD,AMPLITUDE=AM0_1\nREF0,2,-1.250000000000e1"),
        "no force on the reference node in\n{}",
        deck.text
    );
    // y is no longer prescribed on it; x (the slide) still is
    assert!(!deck.text.contains("*BOUNDARY,AMPLITUDE=AM0_1\n"));
    assert!(deck.text.contains("*BOUNDARY,AMPLITUDE=AM0_0\nREF0,1,1,"));
}

#[test]
fn what_calculix_cannot_be_told_is_a_typed_error() {
    let mut scene = indentation(2, 4);
    scene.bodies[0].formulation = Some(Formulation::FBar);
    let model = scene.build().unwrap();
    assert!(matches!(
        export(&model, &ExportOptions::default()),
        Err(CcxError::Unsupported(_))
    ));
    let model = indentation(2, 4).build().unwrap();
    let bad = ExportOptions {
        normal_factor: -1.0,
        ..ExportOptions::default()
    };
    assert!(matches!(export(&model, &bad), Err(CcxError::Option(_))));
}

#[test]
fn dat_force_blocks_are_read_and_summed() {
    let dat = "
 forces (fx,fy,fz) for set REF0 and time  0.5000000E+00

      3343  2.666108E+00 -8.218465E+02 -1.570823E-16

 displacements (vx,vy,vz) for set REF0 and time  0.5000000E+00

      3343  0.000000E+00 -5.000000E-03  0.000000E+00

 forces (fx,fy,fz) for set REF0 and time  0.1000000E+01

      3343  5.0E+00 -1.0E+03 0.0
      3344  1.0E+00 -1.0E+00 0.0
";
    let f = parse_dat_forces(dat, "REF0", Path::new("x.dat")).unwrap();
    assert_eq!(f.len(), 2);
    assert_eq!(f[0].0, 0.5);
    assert_eq!(f[0].1[1], -821.8465);
    assert_eq!(f[1].1, [6.0, -1001.0, 0.0]);
    assert!(matches!(
        parse_dat_forces(dat, "REF1", Path::new("x.dat")),
        Err(CcxError::Parse { .. })
    ));
    assert_eq!(variation(&[0.0, 2.0, 1.0, 1.0]), (3.0, 2.0));
}

#[test]
fn the_cli_skips_cleanly_without_ccx() {
    let out = scratch_path("ccx-skip");
    let run = fricsens()
        .args(["ccx", "indentation", "--out"])
        .arg(&out)
        .env("PATH", "")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{stdout}");
    assert!(stdout.contains("ccx not found: skipping"), "{stdout}");
    assert!(!out.exists(), "nothing is written when skipping");
}

/// A reduced indentation (2 pressing and 4 sliding increments) solved by both codes.
#[test]
#[ignore = "runs CalculiX three times (about a minute); skips without ccx"]
fn reduced_indentation_against_calculix() {
    let model = indentation(2, 4).build().unwrap();
    let Some(c) = against_calculix(&model, "indentation-reduced", "ccx-test", 1) else {
        return;
    };
    assert_eq!(c.times.len(), 6);
    assert!(c.rigid);
    let labels: Vec<&str> = c.quantities.iter().map(|q| q.label.as_str()).collect();
    assert_eq!(labels, ["Fx", "Fy"]);
    // forces: penalty vs multiplier and the element implementations differ by well under 2 %
    let fmax = |v: &[Vec<f64>], k: usize| v.iter().map(|f| f[k].abs()).fold(0.0, f64::max);
    for k in [0, 1] {
        let scale = fmax(&c.fricsens, k);
        for (a, b) in c.fricsens.iter().zip(&c.ccx) {
            assert!((a[k] - b[k]).abs() < 0.02 * scale, "F[{k}]: {a:?} vs {b:?}");
        }
    }
    // dFx/dmu while sliding: ccx's central difference and fricsens' DDM within 3 %
    let scale = fmax(&c.ddm, 0);
    assert!(scale > 0.0);
    for (a, b) in c.ddm.iter().zip(&c.fd) {
        assert!(
            (a[0] - b[0]).abs() < 0.03 * scale,
            "dFx/dmu: {a:?} vs {b:?}"
        );
    }
    let dir = scratch_path("ccx-report");
    c.write(&dir).unwrap();
    let md = std::fs::read_to_string(dir.join("ccx.md")).unwrap();
    assert!(md.starts_with("## Against CalculiX"));
    assert!(dir.join("ccx.svg").exists() && dir.join("ccx.csv").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn punch_deck_pairs_the_punch_faces_with_the_slab_faces_surface_to_surface() {
    let model = scene("meshes/punch-on-slab.toml").build().unwrap();
    let deck = export(&model, &ExportOptions::default()).unwrap();
    let kw = keyword_counts(&deck.text);
    for (k, n) in [
        ("ELEMENT", 2), // punch and slab, no rigid body
        ("MATERIAL", 2),
        ("ELASTIC", 2),
        ("SURFACE", 2), // slave and master
        ("SURFACE INTERACTION", 1),
        ("SURFACE BEHAVIOR", 1),
        ("FRICTION", 1),
        ("CONTACT PAIR", 1),
        ("STEP", 2),       // press (2 x 0.5) and slide (8 x 0.125)
        ("NODE PRINT", 4), // the reactions Fx and Fy, in each step
        ("BOUNDARY", 6),   // base x, y; press; slide; plane strain of each body
        ("AMPLITUDE", 2),  // press and slide
        ("CLOAD", 0),
    ] {
        assert_eq!(kw.get(k).copied().unwrap_or(0), n, "*{k} in\n{kw:?}");
    }
    assert!(!kw.contains_key("RIGID BODY"));
    assert_eq!(deck.reference_nodes, vec![None]);
    assert_eq!(deck.element_types, vec!["C3D8I", "C3D8I"]);
    assert!(deck.nlgeom, "the punch scene is large kinematics");
    // surface to surface, no tension value, no ADJUST (both bodies are held by prescribed
    // displacements in every direction)
    assert!(deck
        .text
        .contains("*CONTACT PAIR,INTERACTION=SI0,TYPE=SURFACE TO SURFACE\nSLAVE0,MASTER0\n"));
    assert_eq!(deck.adjust, vec![0.0]);
    assert_eq!(deck.tension, vec![0.0]);
    let k_line = format!(
        "*SURFACE BEHAVIOR,PRESSURE-OVERCLOSURE=LINEAR\n{:.9e}\n*FRICTION\n",
        deck.normal_stiffness[0]
    );
    assert!(deck.text.contains(&k_line), "{k_line}");
    // the rigid case's constants: K = 10 k / A, stick slope eps_T / A
    let pair = &model.contacts[0];
    let a = deck.median_area[0];
    assert!((deck.normal_stiffness[0] * a / (10.0 * pair.constraint_scale) - 1.0).abs() < 1e-12);
    assert!((deck.stick_slope[0] * a / pair.tangential_stiffness - 1.0).abs() < 1e-12);
    // the prescribed motions of the punch's top with their amplitudes and nonzero values
    for (value, comp, amp) in [(-0.25, 1, [0.0, 1.0, 1.0]), (1.0, 0, [0.0, 0.0, 1.0])] {
        let i = model
            .prescribed
            .iter()
            .position(|p| p.value == value && p.component == comp)
            .unwrap();
        let bc = format!(
            "*BOUNDARY,AMPLITUDE=AP{i}\nP{i},{c},{c},{value:.12e}\n",
            c = comp + 1
        );
        assert!(deck.text.contains(&bc), "{bc}");
        let table = format!(
            "*AMPLITUDE,NAME=AP{i},TIME=TOTAL TIME\n0.000000000000e0,{:.12e}\n1.000000000000e0,{:.12e}\n2.000000000000e0,{:.12e}\n",
            amp[0], amp[1], amp[2]
        );
        assert!(deck.text.contains(&table), "{table}");
    }
    // the reaction responses' node sets are printed as totals
    assert_eq!(deck.printed, vec![0, 1]);
    assert!(deck.text.contains("*NODE PRINT,NSET=R0,TOTALS=ONLY\nRF\n"));

    // the surfaces, checked against the model independently of the exporter's side table
    let d = parse_deck(&deck.text);
    let owners = d.face_owners();
    let Target::Faces { faces } = &pair.target else {
        panic!("a deformable target")
    };
    let target: BTreeSet<[usize; 4]> = (0..faces.len())
        .map(|k| {
            let mut f = quad_nodes(faces, k);
            f.sort_unstable();
            f
        })
        .collect();
    let master = &d.surfaces["MASTER0"];
    assert_eq!(master.len(), faces.len());
    let mut seen = BTreeSet::new();
    for &(e, side) in master {
        // a slab element (body 1), a face of the target face set, on the slab's boundary
        assert_eq!(d.elements[&e].1, "B1", "master element {e}");
        let mut f = d.side_nodes(e, side);
        f.sort_unstable();
        assert!(target.contains(&f), "({e}, S{side}) is no target face");
        assert_eq!(owners[&f], 1, "({e}, S{side}) is an interior face");
        seen.insert(f);
    }
    assert_eq!(seen, target, "every target face once");
    // the label's face is outward: from the element's centre towards fricsens' outward normal
    for k in 0..faces.len() {
        let q = quad_nodes(faces, k);
        let n = cross(sub(d.x(q[2]), d.x(q[0])), sub(d.x(q[3]), d.x(q[1])));
        let mut f = q;
        f.sort_unstable();
        let &(e, side) = master
            .iter()
            .find(|&&(e, side)| {
                let mut g = d.side_nodes(e, side);
                g.sort_unstable();
                g == f
            })
            .unwrap();
        let elem: Vec<usize> = d.elements[&e].0.iter().map(|n| n - 1).collect();
        let out = sub(centroid(&d, &d.side_nodes(e, side)), centroid(&d, &elem));
        assert!(dot(out, n) > 0.0, "({e}, S{side}) faces inward");
    }
    // the slave surface: punch faces (body 0) made of hitting nodes, covering them all
    let hitting: BTreeSet<usize> = pair.hitting.iter().copied().collect();
    let mut covered = BTreeSet::new();
    for &(e, side) in &d.surfaces["SLAVE0"] {
        assert_eq!(d.elements[&e].1, "B0", "slave element {e}");
        let f = d.side_nodes(e, side);
        assert!(f.iter().all(|n| hitting.contains(n)), "({e}, S{side})");
        let mut g = f;
        g.sort_unstable();
        assert_eq!(owners[&g], 1, "slave ({e}, S{side}) is an interior face");
        covered.extend(f);
    }
    assert_eq!(covered, hitting);
}

#[test]
fn frictionless_pairs_several_of_them_and_a_body_held_by_contact() {
    // Hertz's two cylinders, with a second pair in the other direction: the upper cylinder is
    // held by contact alone along y, so both pairs get ADJUST
    let mut s = scene("meshes/hertz-cylinders.toml");
    let mut reverse = s.contacts[0].clone();
    reverse.name = "reverse".into();
    reverse.hitting = "lower.lower-contact".into();
    reverse.target = TargetSpec::Faces("upper.upper-contact".into());
    s.contacts.push(reverse);
    let model = s.build().unwrap();
    assert!(model.contacts.iter().all(|c| c.friction.is_none()));
    let deck = export(&model, &ExportOptions::default()).unwrap();
    let kw = keyword_counts(&deck.text);
    assert_eq!(kw.get("CONTACT PAIR"), Some(&2));
    assert_eq!(kw.get("SURFACE INTERACTION"), Some(&2));
    assert_eq!(kw.get("SURFACE"), Some(&4));
    assert_eq!(kw.get("FRICTION"), None);
    assert_eq!(kw.get("CLOAD"), Some(&1), "the load on the upper cylinder");
    assert!(!deck.nlgeom);
    assert_eq!(deck.stick_slope, vec![0.0, 0.0]);
    for c in 0..2 {
        let d = ExportOptions::default().adjust_fraction * deck.median_area[c].sqrt();
        assert!((deck.adjust[c] / d - 1.0).abs() < 1e-12);
        let line = format!(
            "*CONTACT PAIR,INTERACTION=SI{c},TYPE=SURFACE TO SURFACE,ADJUST={d:.6e}\nSLAVE{c},MASTER{c}\n"
        );
        assert!(deck.text.contains(&line), "{line}");
    }
    // each pair's master faces are its target's, on the other cylinder
    let d = parse_deck(&deck.text);
    for (c, body) in [(0, "B1"), (1, "B0")] {
        let Target::Faces { faces } = &model.contacts[c].target else {
            panic!()
        };
        let master = &d.surfaces[&format!("MASTER{c}")];
        assert_eq!(master.len(), faces.len());
        assert!(master.iter().all(|(e, _)| d.elements[e].1 == body));
    }
}

#[test]
fn pressure_loads_are_the_consistent_nodal_forces() {
    // the Lamé octant's bore: a pressure p on the inner octant of a sphere of radius a pushes
    // it with p pi a^2 / 4 along each axis (the projected quarter disc), up to the faceting
    let model = scene("meshes/lame-octant.toml").build().unwrap();
    let deck = export(&model, &ExportOptions::default()).unwrap();
    let text = &deck.text;
    let start = text.find("*CLOAD,AMPLITUDE=APR0\n").unwrap();
    let mut total = [0.0; 3];
    for l in text[start..]
        .lines()
        .skip(1)
        .take_while(|l| !l.starts_with('*'))
    {
        let f: Vec<&str> = l.split(',').collect();
        total[f[1].parse::<usize>().unwrap() - 1] += f[2].parse::<f64>().unwrap();
    }
    let expected = std::f64::consts::PI / 4.0;
    for t in total {
        assert!((t / expected - 1.0).abs() < 5e-3, "{total:?} vs {expected}");
    }
}

#[test]
fn what_calculix_cannot_be_told_names_what_and_where() {
    let mut s = scene("meshes/punch-on-slab.toml");
    s.bodies[1].material = Material::J2(J2Plasticity::linear(1000.0, 0.3, 10.0, 100.0));
    let model = s.build().unwrap();
    match export(&model, &ExportOptions::default()) {
        Err(CcxError::Unsupported(m)) => assert!(m.contains("'slab'") && m.contains("J2"), "{m}"),
        other => panic!("{other:?}"),
    }
    // a rigid cylinder (the built-in Hertz) is not meshed
    let model = fricsens::scene::Scene::load("hertz")
        .unwrap()
        .build()
        .unwrap();
    match export(&model, &ExportOptions::default()) {
        Err(CcxError::Unsupported(m)) => assert!(m.contains("rounded box"), "{m}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn dat_totals_and_displacements_are_read() {
    let dat = "
 total force (fx,fy,fz) for set R0 and time  0.5000000E+00

       -9.188995E-03 -3.080528E+01  2.715606E-13

 displacements (vx,vy,vz) for set R1 and time  0.5000000E+00

        12  1.000000E-03 -2.000000E-02  0.000000E+00
        13  3.000000E-03 -4.000000E-02  0.000000E+00
";
    let t = parse_dat_blocks(dat, DatBlock::TotalForce, "R0", Path::new("x.dat")).unwrap();
    assert_eq!(t, vec![(0.5, [-9.188995e-3, -30.80528, 2.715606e-13], 1)]);
    let u = parse_dat_blocks(dat, DatBlock::Displacements, "R1", Path::new("x.dat")).unwrap();
    assert_eq!(u.len(), 1);
    assert_eq!(u[0].2, 2);
    assert!((u[0].1[1] - -0.06).abs() < 1e-15);
    assert!(parse_dat_blocks(dat, DatBlock::Forces, "R0", Path::new("x.dat")).is_err());
}

/// The punch pressed into and slid along the slab, solved by both codes.
#[test]
#[ignore = "runs CalculiX three times (about two minutes); skips without ccx"]
fn punch_on_slab_against_calculix() {
    let model = scene("meshes/punch-on-slab.toml").build().unwrap();
    let Some(c) = against_calculix(&model, "meshes/punch-on-slab.toml", "ccx-punch-test", 2) else {
        return;
    };
    assert!(!c.rigid);
    assert_eq!(c.symbol, "mu");
    assert_eq!(c.times.len(), 10);
    let labels: Vec<&str> = c.quantities.iter().map(|q| q.label.as_str()).collect();
    assert_eq!(labels, ["Fx", "Fy"]);
    assert!(matches!(
        c.quantities[1].source,
        Source::ReactionTotal { component: 1, .. }
    ));
    // The final press reaction Fy within 2 %. Why 2 %: (a) the penalty overlap p / K, at
    // most 64 MPa / 3.5e5 MPa/mm = 1.8e-4 mm, is 0.07 % of the 0.25 mm indentation; (b)
    // CalculiX's surface-to-surface contact sees the punch's facets at their integration
    // points, which lie inside the arc by about h^2 / (12 R) = 0.47^2 / 120 = 1.8e-3 mm where
    // fricsens' node-to-segment contact sees the nodes on it: 0.7 % of the indentation, at
    // most 1.1 % of the force for a contact force growing like the indentation to the power
    // 1.5; (c) the two incompatible-mode bricks differ by about 0.5 % on the indentation
    // scene. Together 1.7 %.
    let (f, g) = (c.fricsens.last().unwrap()[1], c.ccx.last().unwrap()[1]);
    assert!(f < -60.0, "the punch is pressed down: {f}");
    assert!(
        (g - f).abs() < 0.02 * f.abs(),
        "Fy: fricsens {f}, CalculiX {g}"
    );
    let dir = scratch_path("ccx-punch-report");
    c.write(&dir).unwrap();
    let md = std::fs::read_to_string(dir.join("ccx.md")).unwrap();
    assert!(md.starts_with("## Against CalculiX"));
    assert!(md.contains("### Responses") && md.contains("Branch check"));
    assert!(dir.join("ccx.svg").exists() && dir.join("ccx.csv").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A rerun that stops early, played by a stand-in for `ccx` (a shell script that prints the
/// punch's two reaction totals and stops the mu (1 + beta) rerun after five increments with
/// CalculiX's divergence message): the comparison completes, the quotient is NaN from there on
/// and the report says why. Needs no CalculiX.
#[cfg(unix)]
#[test]
fn a_rerun_that_stops_early_leaves_nan_quotients_and_a_note() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch_path("ccx-stand-in");
    std::fs::create_dir_all(&dir).unwrap();
    let program = dir.join("ccx");
    std::fs::write(
        &program,
        r#"#!/bin/sh
if [ "$1" = "-v" ]; then echo " This is Version 0.0"; exit 0; fi
job=$2; n=10; [ "$job" = mu-plus ] && n=5
: > "$job.dat"
i=1
for t in 0.5 1.0 1.125 1.25 1.375 1.5 1.625 1.75 1.875 2.0; do
  [ $i -gt $n ] && break
  for set in R0 R1; do
    printf ' total force (fx,fy,fz) for set %s and time  %s\n\n  1.0E+00 -7.0E+01 0.0E+00\n\n' $set $t >> "$job.dat"
  done
  i=$((i+1))
done
if [ $n -lt 10 ]; then echo ' *ERROR: solution seems to diverge; please try'; exit 201; fi
echo ' iteration 1'
"#,
    )
    .unwrap();
    std::fs::set_permissions(&program, std::fs::Permissions::from_mode(0o755)).unwrap();
    let model = scene("meshes/punch-on-slab.toml").build().unwrap();
    let c = compare(&model, "punch", &options(program, dir.join("work"), 1)).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(c.ccx_rerun_failures[1].is_none());
    let f = c.ccx_rerun_failures[0].as_deref().unwrap();
    assert!(f.contains("t = 1.375") && f.contains("diverge"), "{f}");
    for k in 0..10 {
        // Fx: the stand-in prints 1 N in every run
        assert_eq!(c.ccx[k][0], 1.0);
        if k < 5 {
            assert_eq!(c.fd[k][0], 0.0, "increment {}", k + 1);
        } else {
            assert!(c.fd[k][0].is_nan(), "increment {}", k + 1);
        }
    }
    let md = c.markdown();
    assert!(
        md.contains("The rerun at mu (1 + beta) did not reach the end"),
        "{md}"
    );
    assert!(
        md.contains("over the 5 unflagged increments with both reruns"),
        "{md}"
    );
}

/// A CalculiX run that never ends (a stand-in that sleeps) is stopped at the time limit and
/// reported as such, instead of the comparison waiting for ever. Needs no CalculiX.
#[cfg(unix)]
#[test]
fn a_calculix_run_past_its_time_limit_is_stopped_and_reported() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch_path("ccx-sleeper");
    std::fs::create_dir_all(&dir).unwrap();
    let program = dir.join("ccx");
    std::fs::write(
        &program,
        "#!/bin/sh\nif [ \"$1\" = \"-v\" ]; then echo ' This is Version 0.0'; exit 0; fi\necho ' iteration 1'\nexec sleep 60\n",
    )
    .unwrap();
    std::fs::set_permissions(&program, std::fs::Permissions::from_mode(0o755)).unwrap();
    let model = scene("meshes/lame-octant.toml").build().unwrap();
    let opts = CompareOptions {
        time_limit: Some(0.5),
        ..options(program, dir.join("work"), 1)
    };
    let t = std::time::Instant::now();
    let e = compare(&model, "lame", &opts).unwrap_err().to_string();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(t.elapsed().as_secs_f64() < 30.0, "waited for the sleeper");
    assert!(e.contains("time limit"), "{e}");
    assert!(
        e.contains("iteration 1"),
        "the output's tail is not shown: {e}"
    );
}

/// Sides S1.. of each CalculiX solid type as 1-based corners, from the Abaqus / CalculiX
/// manuals (written out here rather than taken from the importer, as [`C3D8_SIDES`]).
fn manual_sides(ty: &str) -> Vec<Vec<usize>> {
    let tet: &[&[usize]] = &[&[1, 2, 3], &[1, 4, 2], &[2, 4, 3], &[3, 4, 1]];
    let wedge: &[&[usize]] = &[
        &[1, 2, 3],
        &[4, 6, 5],
        &[1, 4, 5, 2],
        &[2, 5, 6, 3],
        &[3, 6, 4, 1],
    ];
    let t: Vec<Vec<usize>> = if ty.starts_with("C3D4") || ty.starts_with("C3D10") {
        tet.iter().map(|s| s.to_vec()).collect()
    } else if ty.starts_with("C3D6") || ty.starts_with("C3D15") {
        wedge.iter().map(|s| s.to_vec()).collect()
    } else {
        C3D8_SIDES.iter().map(|s| s.to_vec()).collect()
    };
    t
}

#[test]
fn slave_surfaces_of_every_solid_shape_are_its_sides_on_the_contact_face() {
    // The sliding block with its slider (the hitting body) made of each solid shape, the base
    // hex8 (quad4 target faces): the slave surface is element-based, each (element, Sn) names
    // by the manuals' tables a boundary face of corners among the hitting nodes on the
    // slider's bottom y = 0, and together they cover the bottom once (their areas sum to its
    // 1.5 x 0.5); the master sides are the base's top faces (areas summing to 8 x 0.5)
    use fricsens::element::Shape;
    use fricsens::scene::{sliding_block, BodyGeometry};
    for (shape, ty) in [
        (Shape::Hex20, "C3D20R"),
        (Shape::Tet4, "C3D4"),
        (Shape::Tet10, "C3D10"),
        (Shape::Wedge6, "C3D6"),
        (Shape::Wedge15, "C3D15"),
    ] {
        let mut s = sliding_block(Some(0.3));
        let BodyGeometry::Block(b) = &mut s.bodies[1].geometry else {
            panic!("a generated slider")
        };
        b.element = shape;
        s.bodies[1].formulation = None;
        let model = s.build().unwrap_or_else(|e| panic!("{shape:?}: {e}"));
        let deck = export(&model, &ExportOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(deck.element_types, vec!["C3D8I", ty], "{shape:?}");
        assert!(
            deck.text.contains("TYPE=SURFACE TO SURFACE"),
            "{shape:?}: no element-based slave surface"
        );
        let d = parse_deck(&deck.text);
        // every side of every element of the model, by sorted corners, and its owners
        let corners = |e: usize, side: usize| -> Vec<usize> {
            let (c, set) = &d.elements[&e];
            let ty = if set == "B0" { "C3D8I" } else { ty };
            let mut f: Vec<usize> = manual_sides(ty)[side - 1]
                .iter()
                .map(|&l| c[l - 1] - 1)
                .collect();
            f.sort_unstable();
            f
        };
        let mut owners: HashMap<Vec<usize>, usize> = HashMap::new();
        for e in 1..=model.mesh.n_elements() {
            let set = &d.elements[&e].1;
            let ty = if set == "B0" { "C3D8I" } else { ty };
            for side in 1..=manual_sides(ty).len() {
                *owners.entry(corners(e, side)).or_insert(0) += 1;
            }
        }
        // the area of a planar face of three or four corners (in any order) in the plane
        // y = const: the convex hull's area in x, z
        let area = |f: &[usize]| -> f64 {
            let mut p: Vec<[f64; 2]> = f.iter().map(|&n| [d.x(n)[0], d.x(n)[2]]).collect();
            let c = p.iter().fold([0.0, 0.0], |a, q| [a[0] + q[0], a[1] + q[1]]);
            let c = [c[0] / p.len() as f64, c[1] / p.len() as f64];
            p.sort_by(|a, b| {
                let t = |q: &[f64; 2]| (q[1] - c[1]).atan2(q[0] - c[0]);
                t(a).total_cmp(&t(b))
            });
            (0..p.len())
                .map(|k| {
                    let (a, b) = (p[k], p[(k + 1) % p.len()]);
                    0.5 * (a[0] * b[1] - b[0] * a[1])
                })
                .sum::<f64>()
                .abs()
        };
        let pair = &model.contacts[0];
        let hitting: BTreeSet<usize> = pair.hitting.iter().copied().collect();
        for (surface, body, y, want) in [("SLAVE0", "B1", 0.0, 0.75), ("MASTER0", "B0", 0.0, 4.0)] {
            let mut seen = BTreeSet::new();
            let mut total = 0.0;
            for &(e, side) in &d.surfaces[surface] {
                assert_eq!(d.elements[&e].1, body, "{shape:?} {surface} element {e}");
                let f = corners(e, side);
                assert_eq!(
                    owners[&f], 1,
                    "{shape:?} {surface} ({e}, S{side}) is interior"
                );
                assert!(
                    f.iter().all(|&n| d.x(n)[1] == y),
                    "{shape:?} {surface} ({e}, S{side}) is not on y = {y}"
                );
                if surface == "SLAVE0" {
                    assert!(
                        f.iter().all(|n| hitting.contains(n)),
                        "{shape:?} ({e}, S{side})"
                    );
                }
                assert!(seen.insert(f.clone()), "{shape:?} {surface}: a face twice");
                total += area(&f);
            }
            assert!(
                (total - want).abs() < 1e-12,
                "{shape:?} {surface}: area {total}"
            );
        }
    }
}

#[test]
fn quadratic_indentations_write_their_elements_on_continuation_lines() {
    // the shipped quadratic indentations: C3D20R and C3D10 with every element's id and nodes,
    // no data line over CalculiX's 16 entries (it stops at a longer one)
    for (file, ty, nodes) in [
        ("indentation-hex20.toml", "C3D20R", 20),
        ("indentation-tet10.toml", "C3D10", 10),
    ] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(file);
        let model = Scene::from_file(&path).unwrap().build().unwrap();
        let deck = export(&model, &ExportOptions::default()).unwrap();
        assert_eq!(deck.element_types, vec![ty], "{file}");
        let header = format!("*ELEMENT,TYPE={ty}");
        let data: Vec<&str> = (deck.text.lines())
            .skip_while(|l| !l.starts_with(&header))
            .skip(1)
            .take_while(|l| !l.starts_with('*'))
            .collect();
        for l in &data {
            assert!(
                l.split(',').filter(|e| !e.trim().is_empty()).count() <= 16,
                "{file}: {l}"
            );
        }
        // the entries, continuation lines joined: an id and its nodes per element
        let entries: Vec<usize> = (data.join(",").split(','))
            .filter(|e| !e.trim().is_empty())
            .map(|e| e.trim().parse().unwrap())
            .collect();
        assert_eq!(
            entries.len(),
            model.mesh.n_elements() * (nodes + 1),
            "{file}"
        );
        for (k, element) in entries.chunks(nodes + 1).enumerate() {
            let want: Vec<usize> = (model.mesh.element_nodes(k).iter())
                .map(|n| n + 1)
                .collect();
            assert_eq!(element[0], k + 1);
            assert_eq!(&element[1..], &want[..], "{file}: element {}", k + 1);
        }
    }
}
