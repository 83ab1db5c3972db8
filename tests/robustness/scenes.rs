//! Scenes: every built-in scene round-trips through TOML, bad files name the field, and the
//! paper's indentation example behaves as the physics says.

use crate::common::solve;

use fricsens::scene::{builtin, builtin_list, indentation, Scene};

#[test]
fn every_builtin_scene_round_trips_through_toml() {
    for (name, _) in builtin_list() {
        let scene = builtin(name).unwrap();
        let text = scene.to_toml().unwrap();
        let back = Scene::from_toml(&text, name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(back, scene, "{name}: TOML round trip changed the scene");
        // the same analysis: identical models (node count, unknowns, increments)
        let (a, b) = (scene.build().unwrap(), back.build().unwrap());
        assert_eq!(a.dof_map().n_total, b.dof_map().n_total, "{name}");
        assert_eq!(a.times, b.times, "{name}");
    }
}

#[test]
fn malformed_scene_files_name_the_file_and_the_field() {
    let good = builtin("cantilever-small").unwrap().to_toml().unwrap();
    // an impossible value
    let bad = good.replace("E = 100000.0", "E = -1.0");
    let err = Scene::from_toml(&bad, "beam.toml")
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("bodies[0].material.E") && err.contains("> 0"),
        "{err}"
    );
    // an unknown key
    let bad = good.replacen("[[bodies]]", "[[bodies]]\nyoung = 3.0", 1);
    let err = Scene::from_toml(&bad, "beam.toml").unwrap_err().to_string();
    assert!(
        err.starts_with("beam.toml") && err.contains("young"),
        "{err}"
    );
    // a set that does not exist
    let bad = good.replace("set = \"beam.xmin\"", "set = \"beam.nowhere\"");
    let err = Scene::from_toml(&bad, "beam.toml")
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("prescribed[0].set") && err.contains("beam.nowhere"),
        "{err}"
    );
}

#[test]
fn indentation_slides_at_the_coulomb_limit_with_an_asymmetric_pressure() {
    let model = indentation(2, 4).build().unwrap();
    let res = solve(&model);
    let fx = model
        .responses
        .iter()
        .position(|r| r.name == "block-force-x")
        .unwrap();
    let fy = model
        .responses
        .iter()
        .position(|r| r.name == "block-force-y")
        .unwrap();
    let last = res.states.len() - 1;
    let (x, y) = (
        res.response_value(&model, fx, last),
        res.response_value(&model, fy, last),
    );
    println!("sliding: Fx {x:.4}, Fy {y:.4}, ratio {:.6}", x / y);
    // every contact node slips under a sliding rigid punch: |Fx| = mu Fy, opposing the motion
    assert!(y > 0.0 && x < 0.0);
    assert!((x.abs() / y - 0.5).abs() < 1e-6, "ratio {}", x.abs() / y);
    // after pressing alone the pressure is symmetric about the block's centre (x = -10 mm);
    // sliding with friction makes it asymmetric
    let pressures = |k: usize| -> Vec<f64> {
        (0..model.responses.len())
            .filter(|r| model.responses[*r].name.starts_with("p["))
            .map(|r| res.response_value(&model, r, k))
            .collect()
    };
    let p_press = pressures(2);
    let p_slide = pressures(last);
    let moment = |p: &[f64]| -> f64 {
        let pair = &model.contacts[0];
        let xs = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
        let mut nodes: Vec<usize> = (0..pair.hitting.len()).collect();
        nodes.sort_by(|a, b| xs[pair.hitting[*a]][0].total_cmp(&xs[pair.hitting[*b]][0]));
        let total: f64 = p.iter().sum();
        let centroid: f64 = nodes
            .iter()
            .zip(p)
            .map(|(n, q)| xs[pair.hitting[*n]][0] * q)
            .sum::<f64>()
            / total;
        centroid
    };
    let (c_press, c_slide) = (moment(&p_press), moment(&p_slide));
    println!("pressure centroid: pressed {c_press:.4} mm, sliding {c_slide:.4} mm (block centre moved -10 -> -6.67)");
    assert!((c_press + 10.0).abs() < 0.05, "pressed centroid {c_press}");
    // the block has moved 3.33 mm: the centroid follows it but is shifted by the friction couple
    assert!(
        (c_slide - (-10.0 + 3.33)).abs() > 0.01,
        "sliding pressure still symmetric"
    );
}

#[test]
fn single_nodes_by_number_or_by_the_nearest_point_make_sets_for_responses_and_springs() {
    use fricsens::response::ResponseKind;
    use fricsens::scene::{Component, ResponseSpec};
    let file = std::path::Path::new("meshes/punch-on-slab.toml");
    let with = |set: &str| {
        let mut s = Scene::from_file(file).unwrap();
        s.responses = vec![ResponseSpec::Displacement {
            name: "u".into(),
            set: set.into(),
            component: Component::Y,
        }];
        s
    };
    let nodes_of = |s: Scene| match s.build().map(|m| m.responses[0].kind.clone()) {
        Ok(ResponseKind::Displacement { nodes, .. }) => Ok(nodes),
        Ok(other) => panic!("{other:?}"),
        Err(e) => Err(e.to_string()),
    };
    // the contact point (20, 0, 0) holds a punch node and a slab node (the bodies are not
    // merged): the nearest node of the slab is the slab's, and it is at the point
    let model = with("slab.all").build().unwrap();
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let slab = nodes_of(with("slab.all & near 20 0 0")).unwrap();
    assert_eq!(slab.len(), 1);
    assert!(model.mesh.node_sets["slab.all"].contains(&slab[0]));
    assert_eq!(x[slab[0]], nalgebra::Vector3::new(20.0, 0.0, 0.0));
    let punch = nodes_of(with("punch.all & near 20, 0, 0")).unwrap();
    assert!(model.mesh.node_sets["punch.all"].contains(&punch[0]) && punch[0] != slab[0]);
    // by number, as messages and VTK files number nodes
    assert_eq!(nodes_of(with(&format!("node {}", slab[0]))).unwrap(), slab);
    // the whole mesh has two nearest nodes there: refused, naming both
    let e = nodes_of(with("near 20 0 0")).unwrap_err();
    for needle in [
        "responses[0].set",
        "both nearest",
        &slab[0].to_string(),
        &punch[0].to_string(),
    ] {
        assert!(e.contains(needle), "{needle:?} not in {e}");
    }
    // malformed
    for (bad, needle) in [
        ("node x", "a node number"),
        ("node 99999999", "the mesh has nodes 0 to"),
        ("near 1 2", "three coordinates"),
        ("slab.all & near 1 nan 0", "three coordinates"),
    ] {
        let e = nodes_of(with(bad)).unwrap_err();
        assert!(e.contains(needle), "{bad}: {needle:?} not in {e}");
    }
    // a spring takes the same expressions: the punch's contact node tied to the ground
    let mut s = with("slab.all");
    s.springs.push(fricsens::scene::SpringSpec {
        a: "punch.all & near 20 0 0".into(),
        b: None,
        stiffness: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    });
    assert_eq!(s.build().unwrap().springs.len(), 1);
}

#[test]
fn a_scene_file_is_told_which_settings_it_left_to_their_defaults() {
    // meshes/punch-on-slab.toml gives kinematics but not formulation, the press's value but
    // not the base's, no [solver] table; empty lists (no loads) are nothing defaulted
    let text = std::fs::read_to_string("meshes/punch-on-slab.toml").unwrap();
    let d = Scene::defaulted(&text, "punch-on-slab.toml").unwrap();
    // its bodies are read from a mesh file: hex8, whose standard is the incompatible modes
    for body in ["bodies[0]", "bodies[1]"] {
        assert!(
            d.iter()
                .any(|l| l.starts_with(&format!("{body}.formulation = "))
                    && l.contains("hex8 \"incompatible-modes\"")),
            "{body}'s formulation not in {d:#?}"
        );
    }
    for want in ["prescribed[0].value = 0.0", "solver.max_iterations = 30"] {
        assert!(d.iter().any(|l| l == want), "{want:?} not in {d:#?}");
    }
    for absent in [
        "kinematics",
        "loads",
        "prescribed[1].value",
        "contacts[0].friction",
    ] {
        assert!(
            !d.iter().any(|l| l.contains(absent)),
            "{absent:?} in {d:#?}"
        );
    }
    // a complete scene has nothing left to default but what only its mesh file tells (the
    // formulation of each shape in it)
    let full = Scene::from_toml(&text, "x").unwrap().to_toml().unwrap();
    let left: Vec<String> = Scene::defaulted(&full, "full.toml")
        .unwrap()
        .into_iter()
        .filter(|l| !l.contains(".formulation = each shape's standard"))
        .collect();
    assert_eq!(left, Vec::<String>::new());
}

/// `fricsens scenes --show` prints short arrays inline (`origin = [0.0, -1.0, 0.0]`, an
/// amplitude as `[[0.0, 0.0], [1.0, 1.0]]`), never one number per line.
#[test]
fn shown_scenes_print_short_arrays_inline() {
    for (name, _) in builtin_list() {
        let text = builtin(name).unwrap().to_toml().unwrap();
        for line in text.lines() {
            let t = line.trim().trim_end_matches(',');
            assert!(
                t.parse::<f64>().is_err() && t != "[" && t != "]",
                "{name}: a line of its own: `{line}`"
            );
        }
        let reread = Scene::from_toml(&text, name).unwrap();
        assert_eq!(reread.to_toml().unwrap(), text, "{name}");
    }
    let jenkins = builtin("jenkins").unwrap().to_toml().unwrap();
    assert!(jenkins.contains("amplitude = [[0.0, 0.0], [1.0, 1.0], [3.0, -1.0], [5.0, 1.0]]"));
}
