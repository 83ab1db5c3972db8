//! The two contact pressures: nominal (normal force over the reference tributary area) and
//! current (over the deformed one, the Cauchy pressure CalculiX and Abaqus report), on the
//! paper's rigid flat block sliding over an elastic half-space.

use crate::common;
use fricsens::prelude::*;
use fricsens::response::{PressureMeasure, ResponseKind};
use fricsens::scene::{Component, ResponseSpec};

#[test]
fn the_current_pressure_integrates_to_the_normal_force_and_ddm_equals_central_fdm() {
    let mut s = builtin::indentation(2, 3);
    s.responses
        .retain(|r| !matches!(r, ResponseSpec::PressureProfile { .. }));
    for (name, area) in [
        ("p_nominal", PressureMeasure::Nominal),
        ("p_current", PressureMeasure::Current),
    ] {
        s.responses.push(ResponseSpec::PressureProfile {
            name: name.into(),
            pair: "block".into(),
            along: Component::X,
            area,
            per: fricsens::scene::ProfilePoints::Node,
        });
    }
    let model = s.build().unwrap();
    let (ps, ddm, fdm) = common::ddm_and_central_fdm(&model, &["mu", "E"]);
    let res = Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    let pair = &model.contacts[0];
    let faces = pair.hitting_faces.as_ref().expect("a face-set pair");
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let kind = |r: usize| match model.responses[r].kind {
        ResponseKind::ContactPressure {
            ref nodes, measure, ..
        } => Some((nodes[0], measure)),
        _ => None,
    };
    let mut closed = 0;
    for (k, inc) in ddm.increments.iter().enumerate() {
        // the deformed tributary areas of this increment, from its displacements
        let z = &res.states[k + 1];
        let at = |n: usize| x[n] + nalgebra::Vector3::new(z[3 * n], z[3 * n + 1], z[3 * n + 2]);
        // each face's area by the cross product of its diagonals (exact for a planar quad, and
        // not the code's two-triangle split), a quarter to each of its nodes
        let index = |n: usize| pair.hitting.iter().position(|h| *h == n);
        let mut current = vec![0.0; pair.hitting.len()];
        for f in 0..faces.len() {
            let q = faces.nodes(f);
            let area = 0.5 * (at(q[2]) - at(q[0])).cross(&(at(q[3]) - at(q[1]))).norm();
            for n in q {
                if let Some(i) = index(*n) {
                    current[i] += 0.25 * area;
                }
            }
        }
        let normal = &res.contact[k + 1].normal_force;
        let (mut integral, mut total) = (0.0, 0.0);
        for r in 0..model.responses.len() {
            let Some((node, measure)) = kind(r) else {
                continue;
            };
            match measure {
                PressureMeasure::Current => {
                    integral += inc.values[r] * current[node];
                    total += normal[node];
                }
                PressureMeasure::Nominal => {
                    // the two measures differ by the area ratio, and do differ where closed
                    let twin = (0..model.responses.len())
                        .find(|q| kind(*q) == Some((node, PressureMeasure::Current)))
                        .unwrap();
                    let ratio = current[node] / pair.area[node];
                    let (pn, pc) = (inc.values[r], inc.values[twin]);
                    assert!((pn - pc * ratio).abs() <= 1e-11 * pn.abs().max(1e-300));
                    if pn > 0.0 {
                        closed += 1;
                        assert!(pn != pc, "node {node}: the measures coincide");
                    }
                }
            }
        }
        // the faces stay planar to round-off here (plane strain: the two rows of a face move
        // alike), so the diagonal formula and the code's split agree to about 1e-15
        assert!(
            (integral - total).abs() <= 1e-12 * total.abs(),
            "increment {}: {integral} vs {total}",
            k + 1
        );
    }
    assert!(closed > 0);
    // DDM against central FDM for every pressure, both measures
    let pressures: Vec<usize> = (0..model.responses.len())
        .filter(|r| kind(*r).is_some())
        .collect();
    // relative to the largest derivative of any response (the forces')
    let every: Vec<usize> = (0..model.responses.len()).collect();
    for (p, param) in ps.iter().enumerate() {
        let (worst, scale) = common::worst_difference(&ddm, &fdm, &pressures, &every, p);
        println!(
            "{}: DDM vs central FDM {worst:.2e} of {scale:.4e}",
            param.name
        );
        // central FDM, beta = 1e-6: truncation of order beta^2; the reruns converge to a
        // relative force tolerance of 1e-9, which over 2 beta can reach 5e-4 of a response per
        // unit, but Newton's last step leaves far less: 3e-8 measured; 1e-7 leaves a margin of 3
        assert!(worst < 1e-7, "{}: {worst:.2e}", param.name);
    }
}

#[test]
fn the_per_node_contact_csv_reads_back_equal_to_the_vtk_files() {
    // the paper's sliding block, shortened: contact.csv's last increment against the last
    // .vtu: node numbers index the VTK points, reference and current positions, the normal
    // force and both pressures agree to the CSV's 13 digits
    use fricsens::output::{write_run, VtkOutput};
    use vtkio::model::{Attribute, DataSet};
    let model = builtin::indentation(1, 2).build().unwrap();
    let res = Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    let dir = common::scratch_path("contact-csv");
    write_run(&dir, &model, &res, VtkOutput::Every(100)).unwrap();
    let last = res.times.len() - 1;
    let csv = std::fs::read_to_string(dir.join("contact.csv")).unwrap();
    let vtk = vtkio::Vtk::import(dir.join("vtk").join(format!("step_{last:04}.vtu"))).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid")
    };
    let piece = pieces[0].load_piece_data(None).unwrap();
    let points: Vec<f64> = piece.points.cast_into().unwrap();
    let field = |name: &str| -> Vec<f64> {
        (piece.data.point.iter())
            .find_map(|a| match a {
                Attribute::DataArray(d) if d.name == name => d.data.clone().cast_into(),
                _ => None,
            })
            .unwrap_or_else(|| panic!("no {name}"))
    };
    let (u, normal) = (field("displacement"), field("normal_force"));
    let (nominal, current) = (
        field("contact_pressure_nominal"),
        field("contact_pressure_current"),
    );
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1e-30);
    let mut rows = 0;
    let mut pressed = 0;
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        if f[col("increment")].parse::<usize>().unwrap() != last {
            continue;
        }
        rows += 1;
        let n: usize = f[col("node")].parse().unwrap();
        let v = |name: &str| f[col(name)].parse::<f64>().unwrap();
        for (a, c) in ["X", "Y", "Z"].iter().enumerate() {
            assert!(close(v(c), points[3 * n + a]), "node {n}: {c}");
            let current = ["x", "y", "z"][a];
            assert!(
                close(v(current), points[3 * n + a] + u[3 * n + a]),
                "node {n}: {current}"
            );
        }
        assert!(
            close(v("normal_force"), normal[n]),
            "node {n}: normal force"
        );
        assert!(close(v("p_nominal"), nominal[n]), "node {n}: p_nominal");
        assert!(close(v("p_current"), current[n]), "node {n}: p_current");
        if v("normal_force") > 0.0 {
            pressed += 1;
        }
    }
    assert_eq!(rows, model.contacts[0].hitting.len());
    assert!(pressed > 0);
}

#[test]
fn the_current_pressure_of_a_large_deformation_contact_ddm_equals_central_fdm() {
    // the Gmsh punch pressed 0.25 into the slab and slid (large kinematics): the deformed
    // areas differ from the reference ones by per cents, so the current pressure's derivative
    // carries the area's dependence on the displacements; DDM against central FDM of reruns
    let mut s = Scene::from_file(std::path::Path::new("meshes/punch-on-slab.toml")).unwrap();
    for r in &mut s.responses {
        if let ResponseSpec::PressureProfile { area, .. } = r {
            *area = PressureMeasure::Current;
        }
    }
    let model = s.build().unwrap();
    let (ps, ddm, fdm) = common::ddm_and_central_fdm(&model, &["mu", "slab.E"]);
    let res = Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    // how far the two measures are apart here: the largest |A_ref / A_cur - 1| of a pressed node
    let c = res.contact.last().unwrap();
    let spread = (0..c.area.len())
        .filter(|f| c.normal_force[*f] > 0.0)
        .map(|f| (c.area[f] / c.current_area[f] - 1.0).abs())
        .fold(0.0f64, f64::max);
    println!("largest area change of a pressed node: {spread:.3e}");
    assert!(spread > 1e-3);
    let pressures: Vec<usize> = (0..model.responses.len())
        .filter(|r| {
            matches!(
                model.responses[*r].kind,
                ResponseKind::ContactPressure { .. }
            )
        })
        .collect();
    for (p, param) in ps.iter().enumerate() {
        let (worst, scale) = common::worst_difference(&ddm, &fdm, &pressures, &pressures, p);
        println!(
            "{}: DDM vs central FDM {worst:.2e} of {scale:.4e}",
            param.name
        );
        // central FDM, beta = 1e-6: truncation of order beta^2; the reruns converge to a
        // relative force tolerance of 1e-9, which over 2 beta can reach 5e-4 of a response per
        // unit, but Newton's last step leaves far less: 3e-8 measured; 1e-7 leaves a margin of 3
        assert!(worst < 1e-7, "{}: {worst:.2e}", param.name);
    }
    // the adjoint's backward sweep reads the current areas' dependence on the displacements
    // through its own pass (each face node seeded once): exact like DDM, so round-off apart
    let adjoint = common::sensitivities(&model, &ps, Method::Adjoint, 0.0);
    for (p, param) in ps.iter().enumerate() {
        let (worst, scale) = common::worst_difference(&ddm, &adjoint, &pressures, &pressures, p);
        println!("{}: DDM vs adjoint {worst:.2e} of {scale:.4e}", param.name);
        assert!(worst < 1e-9, "{}: {worst:.2e}", param.name);
    }
}

#[test]
fn a_profile_of_a_plane_strain_slab_gives_one_pressure_per_station_with_its_coordinates() {
    // the Gmsh punch on the one-element-thick slab: each x holds two hitting nodes (its two
    // faces in z), which carry the same pressure by the plane-strain symmetry; the default profile
    // gives one value per x, named after its measure, and profile.csv its coordinates
    use fricsens::output::{write_run, VtkOutput};
    let s = Scene::from_file(std::path::Path::new("meshes/punch-on-slab.toml")).unwrap();
    let model = s.build().unwrap();
    let pair = &model.contacts[0];
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let mut xs: Vec<f64> = pair.hitting.iter().map(|n| x[*n][0]).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    assert_eq!(2 * xs.len(), pair.hitting.len(), "two node rows");
    let zs = pair.hitting.iter().map(|n| x[*n][2]);
    let z_mid =
        0.5 * (zs.clone().fold(f64::INFINITY, f64::min) + zs.fold(f64::NEG_INFINITY, f64::max));
    let stations: Vec<usize> = (0..model.responses.len())
        .filter(|r| model.responses[*r].name.starts_with("p_nominal["))
        .collect();
    assert_eq!(stations.len(), xs.len(), "one response per station");
    let res = Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    let dir = common::scratch_path("profile-csv");
    write_run(&dir, &model, &res, VtkOutput::None).unwrap();
    let profile = std::fs::read_to_string(dir.join("profile.csv")).unwrap();
    let contact = std::fs::read_to_string(dir.join("contact.csv")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let last = res.times.len() - 1;
    let rows = |text: &str| -> Vec<Vec<String>> {
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let mut out = vec![header];
        out.extend(lines.map(|l| l.split(',').map(String::from).collect()));
        out
    };
    let (p, c) = (rows(&profile), rows(&contact));
    let col = |t: &[Vec<String>], name: &str| t[0].iter().position(|h| h == name).unwrap();
    let num = |r: &[String], i: usize| r[i].parse::<f64>().unwrap();
    let at_last = |t: &[Vec<String>]| -> Vec<Vec<String>> {
        let i = col(t, "increment");
        (t[1..].iter())
            .filter(|r| r[i].parse::<usize>().unwrap() == last)
            .cloned()
            .collect()
    };
    let (pl, cl) = (at_last(&p), at_last(&c));
    assert_eq!(pl.len(), xs.len());
    let mut pressed = 0;
    for (k, row) in pl.iter().enumerate() {
        assert_eq!(row[col(&p, "response")], format!("p_nominal[{k}]"));
        assert_eq!(row[col(&p, "measure")], "nominal");
        assert_eq!(row[col(&p, "nodes")], "2");
        let (sx, sz) = (num(row, col(&p, "X")), num(row, col(&p, "Z")));
        // (the CSV's 13 digits)
        assert!(
            (sx - xs[k]).abs() <= 1e-12 * xs[k].abs(),
            "station {k}: its x"
        );
        // the mean of the two rows' z
        assert!((sz - z_mid).abs() <= 1e-12, "station {k}: Z = {sz}");
        let pressure = num(row, col(&p, "pressure"));
        // the station's nodes in contact.csv: each carries the station's pressure
        let nodes: Vec<&Vec<String>> = (cl.iter()).filter(|r| num(r, col(&c, "X")) == sx).collect();
        assert_eq!(nodes.len(), 2);
        for r in nodes {
            let pn = num(r, col(&c, "p_nominal"));
            assert!(
                (pn - pressure).abs() <= 1e-9 * pressure.abs().max(1e-9),
                "station {k}: node pressure {pn:e}, station {pressure:e}"
            );
        }
        if pressure > 0.0 {
            pressed += 1;
        }
    }
    assert!(pressed >= 3, "{pressed} pressed stations");
}
