//! The CalculiX exporter and comparison (`src/ccx.rs`).
//!
//! The deck tests need no CalculiX. The comparison itself is `#[ignore]`d (it runs `ccx` three
//! times and fricsens twice) and skips with a message when `ccx` is not on PATH:
//! `cargo test --release --test studies -- --ignored ccx::`.

use crate::common::{fricsens, scratch_path};

use fricsens::element::Hex8Formulation;
use fricsens::scene::{indentation, Scene};
use fricsens::studies::ccx::{
    compare, export, find_ccx, keyword_counts, parse_dat_forces, variation, CcxError,
    CompareOptions, ExportOptions,
};
use std::path::Path;

fn scene(file: &str) -> Scene {
    Scene::from_file(Path::new(file)).unwrap()
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
fn what_calculix_cannot_be_told_is_a_typed_error() {
    let mut scene = indentation(2, 4);
    scene.bodies[0].formulation = Hex8Formulation::FBar;
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
    let Some(ccx) = find_ccx() else {
        println!(
            "ccx not found: skipping the CalculiX comparison (install Debian package calculix-ccx)"
        );
        return;
    };
    let model = indentation(2, 4).build().unwrap();
    let work = scratch_path("ccx-test");
    let opts = CompareOptions {
        ccx,
        work: work.clone(),
        beta: 1e-2,
        threads: 1,
        export: ExportOptions::default(),
    };
    let c = compare(&model, "indentation-reduced", &opts);
    let _ = std::fs::remove_dir_all(&work);
    let c = c.unwrap();
    assert_eq!(c.times.len(), 6);
    // forces: penalty vs multiplier and the element implementations differ by well under 2 %
    let fmax = |v: &[[f64; 3]], k: usize| v.iter().map(|f| f[k].abs()).fold(0.0, f64::max);
    for k in [0, 1] {
        let scale = fmax(&c.force_fricsens, k);
        for (a, b) in c.force_fricsens.iter().zip(&c.force_ccx) {
            assert!((a[k] - b[k]).abs() < 0.02 * scale, "F[{k}]: {a:?} vs {b:?}");
        }
    }
    // dFx/dmu while sliding: ccx's central difference and fricsens' DDM within 3 %
    let scale = fmax(&c.dforce_ddm, 0);
    assert!(scale > 0.0);
    for (a, b) in c.dforce_ddm.iter().zip(&c.dforce_fd) {
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
