//! Every element family with every sensitivity method: a block of each solid shape pressed and
//! slid under a rigid plate with Coulomb friction, large kinematics, its derivatives in the
//! friction coefficient, Young's modulus and a shape parameter (the block's height) by SDM
//! (forward and central), central FDM and the adjoint, each against DDM.

use crate::common::{params, sensitivities, worst_difference};
use fricsens::element::Shape;
use fricsens::sensitivity::Method;

/// A block of `shape` elements, 2 x 1 x 1 on 2 x 2 x 1 cells, held at its base, pressed 1 %
/// by a rigid plate that starts 0.001 above its top (so that the reruns of a taller block
/// start clear of it) and slid 0.05 along x with mu = 0.3.
fn plate_on_block(shape: Shape) -> fricsens::model::Model {
    let text = format!(
        r#"
name = "plate-on-block"
[[bodies]]
name = "b"
element = "{}"
origin = [0.0, 0.0, 0.0]
kinematics = "large"
x = {{ length = 2.0, zones = [ {{ fraction = 1.0, elements = 2 }} ] }}
y = {{ length = 1.0, zones = [ {{ fraction = 1.0, elements = 2 }} ] }}
z = {{ length = 1.0, zones = [ {{ fraction = 1.0, elements = 1 }} ] }}
material = {{ law = "svk", E = 1000.0, nu = 0.3 }}

[[prescribed]]
name = "base"
set = "b.ymin"
components = ["x", "y", "z"]

[[contacts]]
name = "plate"
hitting = "b.ymax"
[contacts.target.rigid.surface]
shape = "plane"
point = [0.0, 1.001, 0.0]
normal = [0.0, -1.0, 0.0]
[[contacts.target.rigid.motion]]
component = "y"
value = -0.011
amplitude = [[0.0, 0.0], [1.0, 1.0], [2.0, 1.0]]
[[contacts.target.rigid.motion]]
component = "x"
value = 0.05
amplitude = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]]
[contacts.friction]
law = "coulomb"
mu = 0.3

[[steps]]
end = 1.0
increments = 2
[[steps]]
end = 2.0
increments = 4

[[responses]]
kind = "target-force"
name = "Fx"
pair = "plate"
component = "x"
[[responses]]
kind = "target-force"
name = "Fy"
pair = "plate"
component = "y"
[[responses]]
kind = "pressure-profile"
name = "p"
pair = "plate"
along = "x"
"#,
        shape.name()
    );
    fricsens::scene::Scene::from_toml(&text, "plate-on-block.toml")
        .expect("the scene parses")
        .build()
        .expect("the scene builds")
}

#[test]
fn every_family_with_every_method_agrees_with_ddm() {
    let names = ["mu", "b.E", "b.length.y"];
    // (method, relative step, tolerance against DDM over the largest |derivative|). The
    // height's step beta h moves the block's top by 100 beta relative to the plate's press of
    // 0.01, so the truncation of a difference goes with 100 beta rather than beta
    let methods = [
        // forward: truncation of order 100 beta = 1e-4 (the response's curvature in the
        // press over its slope, times the step); measured at most 2.9e-5 (tet4, the height)
        (Method::Sdm, 1e-6, 1e-4),
        // central: of order (100 beta)^2 = 1e-8; measured at most 1.4e-8
        (Method::SdmCentral, 1e-6, 1e-6),
        // the reruns converge to a relative force tolerance of 1e-9: over 2 beta their noise
        // is about 1e-9 / 1e-4 = 1e-5 of the derivative; truncation (100 beta)^2 = 1e-4
        // times the third derivative's scale; measured at most 3.1e-5 (tet10, the height)
        (Method::FdmCentral, 1e-4, 1e-4),
        // exact, like DDM: round-off of the backward sweep
        (Method::Adjoint, 0.0, 1e-8),
    ];
    for shape in Shape::SOLIDS {
        let model = plate_on_block(shape);
        let ps = params(&model, &names);
        let ddm = sensitivities(&model, &ps, Method::Ddm, 0.0);
        let all: Vec<usize> = (0..model.responses.len()).collect();
        let forces = [0, 1];
        // the block slides: Coulomb bounds the friction force by mu times the press, node by
        // node (|Fx| <= sum |t| <= mu sum p_n), and the slip takes nearly all of it
        let last = ddm.increments.last().unwrap();
        let (fx, fy) = (last.values[0].abs(), last.values[1].abs());
        assert!(
            fx <= 0.3 * fy * (1.0 + 1e-9) && fx > 0.99 * 0.3 * fy,
            "{shape:?}: Fx {fx} Fy {fy}"
        );
        for (method, beta, tol) in methods {
            let other = sensitivities(&model, &ps, method, beta);
            assert_eq!(other.increments.len(), ddm.increments.len());
            for (p, name) in names.iter().enumerate() {
                let (worst, scale) = worst_difference(&ddm, &other, &all, &forces, p);
                println!("{shape:?} {name} {}: {worst:.2e}", method.name());
                assert!(scale > 0.0, "{shape:?} {name}: no derivative");
                assert!(
                    worst < tol,
                    "{shape:?} {name} {}: {worst:.2e} of {scale:.3e}",
                    method.name()
                );
            }
        }
    }
}
