//! Shape maps (translate, rotate, scale about a point and an axis, a boundary-driven field by
//! Laplace and elastic smoothing) and a pressure load, differentiated along a frictional load
//! path: DDM equals central FDM of reruns (an independent method: reruns of the primal at
//! perturbed designs, no derivative code involved).

use crate::common;
use fricsens::prelude::*;
use fricsens::scene::{Component, MapSpec, PressureSpec, ShapeSpec, SurfaceMotion};

/// The built-in sliding block (mu = 0.3, face-to-face, frictional slide across target faces),
/// its slider moved a quarter face off the base's face edges, shortened to a press and a slide of 0.6 in 6 increments, its normal load given as a
/// pressure on the slider's top, and one shape map.
fn scene(map: ShapeSpec) -> Scene {
    let mut s = builtin::sliding_block(Some(0.3));
    // the slider's nodes off the base's face edges (at x = 1, 2, ...): a node exactly on an
    // edge makes the response kink in a shape parameter that moves it across
    s.bodies[1].block_mut().unwrap().origin[0] = 1.25;
    s.steps[1].end = 1.2;
    s.steps[1].increments = 6;
    s.prescribed[3].value = 3.0;
    s.loads.clear();
    s.pressures.push(PressureSpec {
        name: "N".into(),
        faces: "slider.ymax".into(),
        // the built-in's total -1 over the top face (1.5 x 0.5), pushing down
        value: 1.0 / 0.75,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
    });
    s.shapes.push(map);
    s
}

fn shape(name: &str, nodes: &str, value: Option<f64>, map: MapSpec) -> ShapeSpec {
    ShapeSpec {
        name: name.into(),
        nodes: nodes.into(),
        value,
        map,
    }
}

fn maps() -> Vec<ShapeSpec> {
    // centres on the contact face (y = 0): a scale with a centre above it would push the
    // slider's bottom into the base at one of the FDM reruns' designs
    let centre = [2.0, 0.0, 0.25];
    vec![
        shape(
            "shift",
            "slider.all",
            None,
            MapSpec::Translate {
                direction: [1.0, 0.0, 0.0],
            },
        ),
        shape(
            "tilt",
            "slider.all",
            None,
            // about the vertical axis through the front face (a tilt about z would push a
            // corner into the base; an axis through the middle gives zero by symmetry)
            MapSpec::Rotate {
                centre: [2.0, 0.0, 0.0],
                axis: [0.0, 1.0, 0.0],
            },
        ),
        shape(
            "size",
            "slider.all",
            Some(1.5),
            MapSpec::Scale { centre, axis: None },
        ),
        shape(
            "girth",
            "slider.all",
            None,
            MapSpec::Scale {
                centre,
                axis: Some([0.0, 0.0, 1.0]),
            },
        ),
        shape(
            "height",
            "slider",
            None,
            MapSpec::Boundary {
                surface: "slider.ymax".into(),
                motion: SurfaceMotion::Translate {
                    direction: [0.0, 1.0, 0.0],
                },
                fixed: vec!["slider.ymin".into()],
                slide: vec![],
                smoothing: fricsens::mesh::Smoothing::Laplace,
            },
        ),
        shape(
            "bulge",
            "slider",
            None,
            MapSpec::Boundary {
                surface: "slider.xmax".into(),
                motion: SurfaceMotion::Radial {
                    centre: [2.0, 0.0, 0.0],
                    axis: Some([0.0, 0.0, 1.0]),
                },
                fixed: vec!["slider.xmin".into()],
                slide: vec![("slider.ymin".into(), Component::Y)],
                smoothing: fricsens::mesh::Smoothing::Elastic,
            },
        ),
    ]
}

#[test]
fn every_shape_map_and_the_pressure_ddm_equals_central_fdm_along_a_frictional_slide() {
    for map in maps() {
        let name = map.name.clone();
        let model = scene(map).build().unwrap();
        let names = [name.as_str(), "pressure.N"];
        let (ps, ddm, fdm) = common::ddm_and_central_fdm(&model, &names);
        assert_eq!(ddm.increments.len(), fdm.increments.len());
        for (p, param) in ps.iter().enumerate() {
            // the scale of the comparison: the largest sensitivity over the path, or the
            // largest response per unit of the parameter when that is larger (central FDM's
            // round-off, about 1e-13 of the response over the step, is then what is left)
            let largest = |f: &dyn Fn(&fricsens::sensitivity::IncrementSensitivity) -> f64| {
                ddm.increments.iter().fold(0.0f64, |m, i| m.max(f(i).abs()))
            };
            let sensitivity = largest(&|i| i.derivatives[0][p]);
            let per_unit = largest(&|i| i.values[0]) / param.value.abs().max(1.0);
            assert!(
                sensitivity > 1e-6 * per_unit,
                "{name}: {} has no effect",
                param.name
            );
            let scale = sensitivity.max(per_unit);
            let mut worst: f64 = 0.0;
            for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
                worst = worst.max((a.derivatives[0][p] - b.derivatives[0][p]).abs() / scale);
            }
            println!(
                "{name}: d(pull)/d({}) DDM vs central FDM: {worst:.2e} of {scale:.4e} (largest sensitivity {sensitivity:.4e})",
                param.name
            );
            // central FDM's truncation (beta^2) and round-off are below 1e-6 on this path
            assert!(worst < 1e-6, "{name} / {}: {worst:.2e}", param.name);
        }
    }
}

#[test]
fn a_shape_map_at_its_reference_value_leaves_the_analysis_bit_for_bit() {
    // the identity at b_ref: the same primal path with or without a map
    let plain = {
        let mut s = scene(maps().remove(0));
        s.shapes.clear();
        s.build().unwrap()
    };
    let x0 = plain.mesh.coordinates::<f64>(&plain.mesh.block_geometry());
    for map in maps() {
        let m = scene(map).build().unwrap();
        let x = m.mesh.coordinates::<f64>(&m.mesh.block_geometry());
        assert_eq!(x, x0);
        let l = m.lifted::<f64>(&[]);
        assert_eq!(l.coords, x0);
    }
}

#[test]
fn contact_areas_follow_a_shape_parameter_as_geometry_says() {
    // the slider scaled about a point by s / s_ref: every face's area scales by (s / s_ref)^2
    // (3-D similarity), so each hitting node's tributary area is A_ref (s / s_ref)^2 with the
    // derivative 2 A_ref / s_ref at s_ref; a translation leaves every area alone
    use num_dual::Dual64;
    for (map, exponent) in [(2usize, 2.0), (0, 0.0)] {
        let spec = maps().remove(map);
        let name = spec.name.clone();
        let model = scene(spec).build().unwrap();
        let p = fricsens::sensitivity::Parameter::by_name(&model, &name).unwrap();
        let (b, db) = (p.value, 0.1 * p.value.abs().max(1.0));
        let seeded: Vec<_> = (p.targets.iter())
            .map(|t| (*t, Dual64::new(b, 1.0)))
            .collect();
        let moved: Vec<_> = (p.targets.iter()).map(|t| (*t, b + db)).collect();
        let (at, perturbed) = (model.lifted(&seeded), model.lifted::<f64>(&moved));
        let ratio = if exponent == 0.0 {
            1.0
        } else {
            ((b + db) / b).powf(exponent)
        };
        let pair = &model.contacts[0];
        assert!(pair.hitting_faces.is_some());
        for (i, a) in pair.area.iter().enumerate() {
            // every map is the identity bit for bit at its reference value
            assert_eq!(at.area[0][i].re, *a, "{name}: area at b_ref");
            // (the translation's reference is 0: its derivative is 0, not 0 / 0; and exactly
            // 0, since it moves every node of a face alike)
            if exponent == 0.0 {
                assert_eq!(at.area[0][i].eps, 0.0, "{name}: dA/db");
            }
            let derivative = if exponent == 0.0 {
                0.0
            } else {
                exponent * a / b
            };
            assert!(
                (at.area[0][i].eps - derivative).abs() <= 1e-13 * a / b.abs().max(1.0),
                "{name}: dA/db {} vs {derivative}",
                at.area[0][i].eps
            );
            assert!(
                (perturbed.area[0][i] - a * ratio).abs() <= 1e-13 * a * ratio,
                "{name}: A at b + db {} vs {}",
                perturbed.area[0][i],
                a * ratio
            );
        }
    }
}

#[test]
fn a_penalty_law_follows_the_design_area_ddm_equals_central_fdm() {
    // the penalty force eps_N A <-g> takes the tributary area A at the design's geometry: on
    // the Gmsh punch with a penalty normal law, the radius R (a scale of the punch, whose arc
    // is the hitting surface) moves A, and DDM must match central FDM of reruns for every
    // response (forces and pressures)
    let mut s = Scene::from_file(std::path::Path::new("meshes/punch-on-slab.toml")).unwrap();
    // a stiff penalty per unit area: 20 times the slab's E per unit length
    s.contacts[0].normal = fricsens::contact::NormalLaw::Penalty { stiffness: 2e4 };
    let model = s.build().unwrap();
    let (ps, ddm, fdm) = common::ddm_and_central_fdm(&model, &["R"]);
    let scale = (ddm.increments.iter())
        .flat_map(|i| i.derivatives.iter().map(|d| d[0].abs()))
        .fold(0.0f64, f64::max);
    let mut worst: f64 = 0.0;
    for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
        for (x, y) in a.derivatives.iter().zip(&b.derivatives) {
            worst = worst.max((x[0] - y[0]).abs() / scale);
        }
    }
    println!(
        "{}: DDM vs central FDM {worst:.2e} of {scale:.4e}",
        ps[0].name
    );
    // central FDM, beta = 1e-6: truncation of order beta^2 and the reruns' convergence
    // noise, measured below 1e-7 in this file's other comparisons
    assert!(worst < 1e-6, "{worst:.2e}");
}

/// A centre or direction with a non-finite coordinate is an error naming the map and what
/// is wrong (found by an audit of bad input: a NaN centre passed, and the run failed later
/// on a tangential stiffness of NaN, or in a contact projection).
#[test]
fn a_non_finite_centre_or_direction_is_an_error_naming_the_map() {
    for bad in [f64::NAN, f64::INFINITY] {
        for mut map in maps() {
            let name = map.name.clone();
            let v = [bad, 0.0, 0.0];
            let needle = match &mut map.map {
                MapSpec::Translate { direction } => {
                    *direction = v;
                    "direction"
                }
                MapSpec::Rotate { centre, .. } | MapSpec::Scale { centre, .. } => {
                    *centre = v;
                    "centre"
                }
                MapSpec::Boundary { motion, .. } => match motion {
                    SurfaceMotion::Translate { direction } => {
                        *direction = v;
                        "map.motion.direction"
                    }
                    SurfaceMotion::Radial { centre, .. } => {
                        *centre = v;
                        "map.motion.centre"
                    }
                },
                other => panic!("a map the test does not edit: {other:?}"),
            };
            let err = match scene(map).build() {
                Ok(_) => panic!("{name}: a non-finite {needle} ({bad}) was accepted"),
                Err(e) => e.to_string(),
            };
            assert!(err.contains(needle), "{name}: {err}");
            assert!(err.contains("shapes[0]"), "{name}: {err}");
        }
    }
    // a boundary translated along no direction
    let mut map = (maps().into_iter())
        .find(|m| m.name == "height")
        .expect("the boundary translated map");
    if let MapSpec::Boundary { motion, .. } = &mut map.map {
        *motion = SurfaceMotion::Translate {
            direction: [0.0; 3],
        };
    }
    let err = scene(map).build().unwrap_err().to_string();
    assert!(err.contains("map.motion.direction"), "{err}");
}
