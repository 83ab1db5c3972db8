//! Imported geometry against closed forms and independent values: Hertz between two elastic
//! cylinders meshed in Gmsh (both master/slave directions), the Lamé sphere (an octant, its
//! inner radius a shape parameter through a boundary-driven design velocity field), a
//! generated scene written to `.msh` and `.inp` and read back, and a morph between two Gmsh
//! meshes against the affine map that describes the same change.

use crate::common;
use fricsens::prelude::*;
use fricsens::response::ResponseKind;
use fricsens::scene::{BodyGeometry, MapSpec, MeshSource, ShapeSpec};
use fricsens::sensitivity::Method;
use fricsens::studies::validate::imported;
use fricsens::studies::validate::OracleRow;
use std::path::Path;

fn scene(file: &str) -> Scene {
    Scene::from_file(Path::new(file)).unwrap()
}

// The closed forms and their tolerances live in the library, where `fricsens validate` puts
// the same rows into the report's "Imported geometry" section
// (`fricsens::studies::validate::imported`, whose docs derive each one).

fn meshes() -> &'static Path {
    Path::new("meshes")
}

fn assert_rows(rows: &[OracleRow]) {
    for o in rows {
        println!(
            "{}: {}: {:.6e} vs {:.6e} ({:.2e}, tolerance {:.0e})",
            o.scene, o.quantity, o.got, o.expected, o.rel_error, o.tolerance
        );
    }
    for o in rows {
        assert!(o.pass, "{}: {}: {:.2e}", o.scene, o.quantity, o.rel_error);
    }
}

#[test]
fn hertz_between_two_elastic_cylinders_both_master_slave_directions() {
    // half-width and peak within 3 %, d p0 / d E1 within 4 % (the limits), the
    // nodal forces in equilibrium with the load to 7e-4 (the curvature's share)
    for reverse in [false, true] {
        assert_rows(&imported::hertz_cylinders(meshes(), reverse).unwrap());
    }
}

#[test]
fn lame_sphere_bore_displacement_and_its_derivatives_including_the_inner_radius() {
    // u(a), du/dE, du/dnu and du/da (a boundary-driven field) within 1 % of Lamé's closed
    // form, and du/da within 1e-6 of central FDM of reruns
    assert_rows(&imported::lame_sphere(meshes()).unwrap());
}

#[test]
fn a_morph_and_the_affine_map_of_the_same_change_give_the_same_ddm_sensitivity() {
    // lame-octant-scaled.msh is lame-octant.msh scaled by 1.05 about the origin (same
    // topology): the morph X_A + b (X_B - X_A) moves the nodes by 0.05 X_A per unit b, the
    // scale about the origin by X_A per unit factor: d/db = 0.05 d/ds, to 1e-10
    assert_rows(&imported::morph_against_scale(meshes()).unwrap());
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
    let u = imported::lame_bore(1.0, 1.0, 2.0, 1000.0, 0.3);
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
