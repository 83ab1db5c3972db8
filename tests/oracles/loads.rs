//! What `[[loads]]` means: a total force shared by tributary area over a face set (a uniform
//! traction), equally over a node set. The patch test tells them apart.

use fricsens::prelude::*;

/// A block graded along y and z (ratios 5 and 3), held on its x = 0 face in x, on y = 0 in
/// y and on z = 0 in z, pulled along x by a total force F = 12 on the set `set` of its x = 2
/// face: uniaxial stress F / A = 12 / (1 x 0.5) = 24 when the force is a uniform traction.
fn pulled(set: &str) -> Scene {
    let text = format!(
        r#"
name = "patch"
[[bodies]]
name = "b"
origin = [0.0, 0.0, 0.0]
kinematics = "small"
material = {{ law = "svk", E = 1000.0, nu = 0.3 }}
x = {{ length = 2.0, zones = [{{ fraction = 1.0, elements = 4, ratio = 1.0 }}] }}
y = {{ length = 1.0, zones = [{{ fraction = 1.0, elements = 5, ratio = 5.0 }}] }}
z = {{ length = 0.5, zones = [{{ fraction = 1.0, elements = 3, ratio = 3.0 }}] }}

[[prescribed]]
name = "x0"
set = "b.xmin"
components = ["x"]

[[prescribed]]
name = "y0"
set = "b.ymin"
components = ["y"]

[[prescribed]]
name = "z0"
set = "b.zmin"
components = ["z"]

[[loads]]
name = "F"
set = "{set}"
component = "x"
value = 12.0

[[steps]]
end = 1.0
increments = 1
"#
    );
    Scene::from_toml(&text, "patch.toml").unwrap()
}

/// Largest relative deviation of the elements' sigma_xx from F / A, and of the other
/// components from zero.
fn deviation(set: &str) -> f64 {
    let model = pulled(set).build().unwrap();
    let res = Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    let stress = res.stresses.last().unwrap();
    assert_eq!(stress.len(), 4 * 5 * 3);
    let nominal = 12.0 / 0.5;
    stress.iter().fold(0.0f64, |m, s| {
        let mut d: f64 = (s[(0, 0)] - nominal).abs();
        for (i, j) in [(1, 1), (2, 2), (0, 1), (1, 2), (0, 2)] {
            d = d.max(s[(i, j)].abs());
        }
        m.max(d / nominal)
    })
}

#[test]
fn a_load_on_a_face_set_is_a_uniform_traction_and_on_a_node_set_equal_forces() {
    // on the face set: consistent nodal forces of a uniform traction on parallelogram quads
    // (a quarter of each face's area per node), so the patch test holds to round-off
    let traction = deviation("b.xmax");
    // the same nodes as a node set (an intersection is a node set): equal forces per node,
    // too much on the small faces' nodes and too little on the large ones
    let equal = deviation("b.xmax & b.all");
    println!("face set: {traction:.2e}; node set: {equal:.2e}");
    assert!(traction < 1e-10, "{traction:.2e}");
    assert!(equal > 1e-2, "{equal:.2e}");
}
