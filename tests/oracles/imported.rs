//! Imported geometry against closed forms and independent values: Hertz between two elastic
//! cylinders meshed in Gmsh (both master/slave directions), the Lamé sphere (an octant, its
//! inner radius a shape parameter through a boundary-driven design velocity field), a
//! generated scene written to `.msh` and `.inp` and read back, and a morph between two Gmsh
//! meshes against the affine map that describes the same change.

use crate::common;
use fricsens::prelude::*;
use fricsens::response::ResponseKind;
use fricsens::scene::{BodyGeometry, MapSpec, MeshSource, ShapeSpec, TargetSpec};
use fricsens::sensitivity::Method;
use std::path::Path;

fn scene(file: &str) -> Scene {
    Scene::from_file(Path::new(file)).unwrap()
}

/// Two-body Hertz (shared/oracles.md section 4 with 1/R = 1/R1 + 1/R2 and
/// 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2): the parameters of meshes/hertz-cylinders.toml.
struct TwoCylinders {
    r1: f64,
    r2: f64,
    e1: f64,
    nu1: f64,
    e2: f64,
    nu2: f64,
    /// Load per unit length (the half model carries half of it over its thickness).
    p: f64,
}

impl TwoCylinders {
    fn e_star(&self) -> f64 {
        1.0 / ((1.0 - self.nu1 * self.nu1) / self.e1 + (1.0 - self.nu2 * self.nu2) / self.e2)
    }
    fn radius(&self) -> f64 {
        1.0 / (1.0 / self.r1 + 1.0 / self.r2)
    }
    fn half_width(&self) -> f64 {
        (4.0 * self.p * self.radius() / (std::f64::consts::PI * self.e_star())).sqrt()
    }
    fn peak(&self) -> f64 {
        2.0 * self.p / (std::f64::consts::PI * self.half_width())
    }
    /// d p0 / d E1 at fixed P: p0 = sqrt(P E* / (pi R)), dE*/dE1 = E*^2 (1 - nu1^2) / E1^2.
    fn dpeak_de1(&self) -> f64 {
        let es = self.e_star();
        self.peak() / (2.0 * es) * es * es * (1.0 - self.nu1 * self.nu1) / (self.e1 * self.e1)
    }
}

#[test]
fn hertz_between_two_elastic_cylinders_both_master_slave_directions() {
    let h = TwoCylinders {
        r1: 8.0,
        r2: 12.0,
        e1: 2e5,
        nu1: 0.3,
        e2: 1e5,
        nu2: 0.25,
        p: 13.21875 * 2.0 / 0.025,
    };
    for reverse in [false, true] {
        let mut s = scene("meshes/hertz-cylinders.toml");
        if reverse {
            s.contacts[0].hitting = "lower.lower-contact".into();
            s.contacts[0].target = TargetSpec::Faces("upper.upper-contact".into());
        }
        let model = s.build().unwrap();
        let res = common::sens(&model, &["upper.E"], Method::Ddm, 0.0);
        let last = res.increments.last().unwrap();
        let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
        // nodal normal forces f = p A at the hitting nodes, their x, the peak pressure
        let (mut force, mut moment2) = (0.0, 0.0);
        let mut peak = (0.0f64, 0.0f64);
        for (r, resp) in model.responses.iter().enumerate() {
            if let ResponseKind::ContactPressure { pair, node } = resp.kind {
                let n = model.contacts[pair].hitting[node];
                let f = last.values[r] * model.contacts[pair].area[node];
                force += f;
                moment2 += f * x[n].x * x[n].x;
                if last.values[r] > peak.0 {
                    peak = (last.values[r], last.derivatives[r][0]);
                }
            }
        }
        // the smooth measure of oracles.md: M2 = integral p x^2 = P a^2 / 4 (the half model's
        // sums over x >= 0 have the same ratio)
        let a_eff = 2.0 * (moment2 / force).sqrt();
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
        println!(
            "reverse {reverse}: total force {force:.5} (half model {:.5}), a_eff {a_eff:.5} vs {:.5} ({:.2} %), p0 {:.2} vs {:.2} ({:.2} %), dp0/dE1 {:.4e} vs {:.4e} ({:.2} %)",
            0.5 * h.p * 0.025,
            h.half_width(),
            100.0 * rel(a_eff, h.half_width()),
            peak.0,
            h.peak(),
            100.0 * rel(peak.0, h.peak()),
            peak.1,
            h.dpeak_de1(),
            100.0 * rel(peak.1, h.dpeak_de1())
        );
        // equilibrium: the normal forces' y components carry the load exactly; their sum
        // exceeds it by the curvature, 1 - cos(a / R1) = 7e-4 at the edge of the zone
        assert!(rel(force, 0.5 * h.p * 0.025) < 7e-4);
        assert!(rel(a_eff, h.half_width()) < 0.03);
        assert!(rel(peak.0, h.peak()) < 0.03);
        assert!(rel(peak.1, h.dpeak_de1()) < 0.04);
    }
}

/// Lamé's bore displacement of a thick sphere (inner a, outer b) under internal pressure p,
/// generic so that a dual number gives its derivatives exactly.
fn lame_bore<S: fricsens::scalar::Scalar>(p: f64, a: S, b: f64, e: S, nu: S) -> S {
    let l = S::lift;
    let a3 = a * a * a;
    let b3 = l(b * b * b);
    a * l(p) / (e * (b3 - a3)) * ((l(1.0) - nu * l(2.0)) * a3 + (nu + l(1.0)) * b3 * l(0.5))
}

#[test]
fn lame_sphere_bore_displacement_and_its_derivatives_including_the_inner_radius() {
    use num_dual::Dual64;
    let model = scene("meshes/lame-octant.toml").build().unwrap();
    let res = common::sens(&model, &["E", "nu", "a"], Method::Ddm, 0.0);
    let last = res.increments.last().unwrap();
    let (p, a, b, e, nu) = (1.0, 1.0, 2.0, 1000.0, 0.3);
    let u = lame_bore(p, a, b, e, nu);
    let d = Dual64::from;
    let s = Dual64::new;
    let du_de = lame_bore(p, d(a), b, s(e, 1.0), d(nu)).eps;
    let du_dnu = lame_bore(p, d(a), b, d(e), s(nu, 1.0)).eps;
    let du_da = lame_bore(p, s(a, 1.0), b, d(e), d(nu)).eps;
    let rel = |x: f64, y: f64| (x - y).abs() / y.abs();
    let got = [
        last.values[0],
        last.derivatives[0][0],
        last.derivatives[0][1],
        last.derivatives[0][2],
    ];
    let want = [u, du_de, du_dnu, du_da];
    for (what, (g, w)) in ["u(a)", "du/dE", "du/dnu", "du/da"]
        .iter()
        .zip(got.iter().zip(want))
    {
        println!(
            "{what}: {g:.6e} vs Lamé {w:.6e} ({:.3} %)",
            100.0 * rel(*g, w)
        );
    }
    // the 1 % for the displacement; the derivatives carry the same discretisation
    // error (du/dE = -u/E exactly), du/dnu and du/da a derivative of it: 1 % as well
    for (g, w) in got.iter().zip(want) {
        assert!(rel(*g, w) < 0.01);
    }
    // DDM against central FDM of reruns for the shape parameter (an independent method)
    let fdm = common::sens(&model, &["a"], Method::FdmCentral, 1e-6);
    let f = fdm.increments.last().unwrap().derivatives[0][0];
    assert!(
        rel(f, last.derivatives[0][2]) < 1e-6,
        "{f} vs {}",
        last.derivatives[0][2]
    );
}

#[test]
fn a_morph_and_the_affine_map_of_the_same_change_give_the_same_ddm_sensitivity() {
    // lame-octant-scaled.msh is lame-octant.msh scaled by 1.05 about the origin (same
    // topology): the morph X_A + b (X_B - X_A) moves the nodes by 0.05 X_A per unit b, the
    // scale about the origin by X_A per unit factor: d/db = 0.05 d/ds
    let mut s = scene("meshes/lame-octant.toml");
    s.study.params.clear();
    s.shapes = vec![
        ShapeSpec {
            name: "morph".into(),
            nodes: "shell".into(),
            value: None,
            map: MapSpec::Morph {
                mesh: "lame-octant-scaled.msh".into(),
                set: None,
            },
        },
        ShapeSpec {
            name: "scale".into(),
            nodes: "shell.all".into(),
            value: None,
            map: MapSpec::Scale {
                centre: [0.0; 3],
                axis: None,
            },
        },
    ];
    let model = s.build().unwrap();
    let res = common::sens(&model, &["morph", "scale"], Method::Ddm, 0.0);
    for inc in &res.increments {
        let (m, a) = (inc.derivatives[0][0], inc.derivatives[0][1]);
        println!("morph {m:.12e}, 0.05 x affine {:.12e}", 0.05 * a);
        assert!(
            (m - 0.05 * a).abs() <= 1e-10 * m.abs(),
            "{m} vs {}",
            0.05 * a
        );
    }
}

#[test]
fn a_generated_scene_written_as_msh_and_inp_and_read_back_gives_its_results() {
    // the built-in sliding block (mu = 0.3, face-to-face, frictional slide), shortened; its
    // two generated blocks written by the Gmsh (ASCII, binary) and Abaqus writers, and the
    // same scene with the bodies read from those files: same responses and DDM sensitivities
    // (the importer numbers the nodes in its own order, so the sums run in another order:
    // equal to 1e-12 relative, not bit for bit)
    let mut s = builtin::sliding_block(Some(0.3));
    s.steps[1].end = 1.2;
    s.steps[1].increments = 6;
    let generated = s.build().unwrap();
    let names = ["E", "interface.mu"];
    let want = common::sens(&generated, &names, Method::Ddm, 0.0);
    let x = generated
        .mesh
        .coordinates::<f64>(&generated.mesh.block_geometry());
    let bodies: Vec<(String, usize)> = generated
        .bodies
        .iter()
        .map(|b| (b.name.clone(), b.group))
        .collect();
    let dir = common::scratch_path("round-trip");
    std::fs::create_dir_all(&dir).unwrap();
    for (file, kind) in [
        ("blocks.msh", 0),
        ("blocks-binary.msh", 1),
        ("blocks.inp", 2),
    ] {
        let path = dir.join(file);
        match kind {
            0 => fricsens::mesh::gmsh::write(&generated.mesh, &x, &bodies, &path, false),
            1 => fricsens::mesh::gmsh::write(&generated.mesh, &x, &bodies, &path, true),
            _ => fricsens::mesh::abaqus::write(&generated.mesh, &x, &bodies, &path),
        }
        .unwrap();
        let mut t = s.clone();
        for b in &mut t.bodies {
            let name = b.name().to_string();
            b.geometry = BodyGeometry::Mesh(MeshSource {
                name: name.clone(),
                file: path.clone(),
                set: Some(name),
                scale: 1.0,
                folder: None,
            });
        }
        let imported = t.build().unwrap();
        assert_eq!(imported.mesh.n_elements(), generated.mesh.n_elements());
        let got = common::sens(&imported, &names, Method::Ddm, 0.0);
        assert_eq!(got.increments.len(), want.increments.len());
        let mut worst: f64 = 0.0;
        for (a, b) in got.increments.iter().zip(&want.increments) {
            for (r, v) in b.values.iter().enumerate() {
                worst = worst.max((a.values[r] - v).abs() / v.abs().max(1e-300));
                for p in 0..names.len() {
                    let d = b.derivatives[r][p];
                    worst = worst.max((a.derivatives[r][p] - d).abs() / d.abs().max(1e-300));
                }
            }
        }
        println!("{file}: largest relative difference {worst:.2e}");
        assert!(worst < 1e-12, "{file}: {worst:.2e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `meshes/punch-on-slab.msh` with the punch's nodes (y > 0) moved by `(0, c (x - 20)^2, 0)`:
/// the same file, node for node, with a blunter nose (the arc's curvature at the contact point
/// falls from 1/R to 1/R - 2c per unit of the morph). The contact point (20, 0) stays, and for
/// a morph value b > -1 / (20 c) the arc stays above the slab.
fn blunter_punch(c: f64) -> std::path::PathBuf {
    let text = std::fs::read_to_string("meshes/punch-on-slab.msh").unwrap();
    let mut out = String::with_capacity(text.len());
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        out.push_str(line);
        out.push('\n');
        if line != "$Nodes" {
            continue;
        }
        // MSH 4.1: numEntityBlocks numNodes minTag maxTag; per block: dim tag parametric n,
        // n tags, n coordinate lines
        let head: Vec<usize> = (lines.next().unwrap().split_whitespace())
            .map(|v| v.parse().unwrap())
            .collect();
        out.push_str(&format!(
            "{} {} {} {}\n",
            head[0], head[1], head[2], head[3]
        ));
        for _ in 0..head[0] {
            let block = lines.next().unwrap();
            let f: Vec<usize> = block
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect();
            assert_eq!(
                f[2], 0,
                "the meshes are written without parametric coordinates"
            );
            out.push_str(block);
            out.push('\n');
            for _ in 0..f[3] {
                out.push_str(lines.next().unwrap());
                out.push('\n');
            }
            for _ in 0..f[3] {
                let x: Vec<f64> = (lines.next().unwrap().split_whitespace())
                    .map(|v| v.parse().unwrap())
                    .collect();
                let dy = if x[1] > 0.0 {
                    c * (x[0] - 20.0).powi(2)
                } else {
                    0.0
                };
                out.push_str(&format!("{:e} {:e} {:e}\n", x[0], x[1] + dy, x[2]));
            }
        }
    }
    let path = common::scratch_path("blunter-punch").with_extension("msh");
    std::fs::write(&path, out).unwrap();
    path
}

#[test]
fn a_morph_ddm_equals_central_fdm_along_a_frictional_slide_of_a_curved_punch() {
    // meshes/punch-on-slab.toml (an elastic punch from Gmsh pressed 0.25 into an elastic slab
    // and slid 1.0, mu = 0.3, large kinematics) with a morph of the punch towards a blunter
    // nose, and its radius as the scene's scale map: DDM against central FDM of reruns (each
    // rerun a new mesh at the perturbed design, areas and all) for the forces on the punch's
    // top and every contact pressure along the path
    let morph = blunter_punch(0.01);
    let mut s = scene("meshes/punch-on-slab.toml");
    s.shapes.push(ShapeSpec {
        name: "blunt".into(),
        nodes: "punch".into(),
        value: None,
        map: MapSpec::Morph {
            mesh: morph.clone(),
            set: Some("punch".into()),
        },
    });
    let model = s.build().unwrap();
    let (ps, ddm, fdm) = common::ddm_and_central_fdm(&model, &["blunt", "R"]);
    let _ = std::fs::remove_file(&morph);
    let force = |r: usize| {
        !matches!(
            model.responses[r].kind,
            ResponseKind::ContactPressure { .. }
        )
    };
    for (p, param) in ps.iter().enumerate() {
        // per kind (forces, pressures): the largest sensitivity over the path and the kind
        let scale = |f: bool| {
            (ddm.increments.iter())
                .flat_map(|i| (0..model.responses.len()).map(move |r| (i, r)))
                .filter(|(_, r)| force(*r) == f)
                .fold(0.0f64, |m, (i, r)| m.max(i.derivatives[r][p].abs()))
        };
        let (sf, sp) = (scale(true), scale(false));
        assert!(sf > 0.0 && sp > 0.0, "{} has no effect", param.name);
        let mut worst: f64 = 0.0;
        for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
            for r in 0..model.responses.len() {
                let s = if force(r) { sf } else { sp };
                worst = worst.max((a.derivatives[r][p] - b.derivatives[r][p]).abs() / s);
            }
        }
        println!(
            "{}: DDM vs central FDM over {} increments and {} responses: {worst:.2e} (largest force sensitivity {sf:.4e}, pressure {sp:.4e})",
            param.name,
            ddm.increments.len(),
            model.responses.len()
        );
        // central FDM (beta = 1e-6 relative; absolute for the morph's reference 0): truncation
        // of order beta^2 and the reruns' force tolerance 1e-9 over beta, 1e-3 of a response
        // per unit at most, far below the sensitivities here (1e-1 to 1e2)
        assert!(worst < 1e-5, "{}: {worst:.2e}", param.name);
    }
}

#[test]
fn the_vtk_output_of_an_imported_mesh_carries_its_cells_points_and_the_lame_field() {
    // meshes/lame-octant.toml run and written as VTK; the file read back: 6912 hexahedra (3 blocks of 12 x 12 x 16) on the
    // Gmsh mesh's points, and on every point of the inner surface (|X| = 1 by construction of
    // the mesh) the radial displacement of Lamé's closed form within 1 %
    use fricsens::output::{write_run, VtkOutput};
    use vtkio::model::{Attribute, CellType, DataSet, VertexNumbers};
    let model = scene("meshes/lame-octant.toml").build().unwrap();
    let res = fricsens::solver::Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    let dir = common::scratch_path("lame-vtk");
    write_run(&dir, &model, &res, VtkOutput::Every(1)).unwrap();
    let vtk = vtkio::Vtk::import(dir.join("vtk").join("step_0001.vtu")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid")
    };
    let piece = pieces[0].load_piece_data(None).unwrap();
    let points: Vec<f64> = piece.points.cast_into().unwrap();
    assert_eq!(piece.cells.types.len(), 3 * 12 * 12 * 16);
    assert!(piece.cells.types.iter().all(|t| *t == CellType::Hexahedron));
    let VertexNumbers::XML { connectivity, .. } = &piece.cells.cell_verts else {
        panic!("legacy cell numbering in an XML file")
    };
    let n = points.len() / 3;
    assert!(connectivity.iter().all(|v| (*v as usize) < n));
    let displacement: Vec<f64> = piece
        .data
        .point
        .iter()
        .find_map(|a| match a {
            Attribute::DataArray(d) if d.name == "displacement" => d.data.clone().cast_into(),
            _ => None,
        })
        .expect("a displacement field");
    let u = lame_bore(1.0, 1.0, 2.0, 1000.0, 0.3);
    let mut inner = 0;
    for k in 0..n {
        let x = nalgebra::Vector3::new(points[3 * k], points[3 * k + 1], points[3 * k + 2]);
        if (x.norm() - 1.0).abs() > 1e-9 {
            continue;
        }
        inner += 1;
        let d = nalgebra::Vector3::new(
            displacement[3 * k],
            displacement[3 * k + 1],
            displacement[3 * k + 2],
        );
        let radial = d.dot(&x);
        assert!((radial - u).abs() <= 0.01 * u, "point {k}: {radial} vs {u}");
    }
    // (12 x 12 on each of the three cube-sphere blocks, sharing their edges: 3 x 13^2 - 3 x 13 + 1)
    assert_eq!(inner, 469);
}
