//! Convergence orders of every element family on Lamé's thick cylinder: the displacement and
//! its DDM derivatives with respect to Young's modulus and to a shape parameter, against the
//! closed form.
//!
//! The problem: a quarter of a thick-walled cylinder, inner radius `a = 1`, outer `b = 2`,
//! internal pressure `p = 1`, plane strain (`u_z = 0`), symmetry planes `x = 0` and `y = 0`,
//! linear elasticity (small kinematics, `E = 1000`, `nu = 0.3`). Its solution is radial,
//!
//! `u_r(r) = (1 + nu) p a^2 / (E (b^2 - a^2)) ((1 - 2 nu) r + b^2 / r)`,
//!
//! not a polynomial, so no family represents it and every mesh has an error. Its derivatives
//! have closed forms too: `du/dE = -u/E`; and for the shape parameter `b` that scales the
//! cross-section about the axis (every length of the problem with it, `p` fixed), the
//! displacement of a material point scales with it, `du/db = u/b`. The mesh is the block
//! generator's (radius, angle, thickness) grid, `n` elements through the wall, `2n` around,
//! one through the thickness, mapped onto the annulus, mid-edge nodes on the arcs.
//!
//! The error is the relative L2 norm over the body, `|u_h - u| / |u|`, integrated with each
//! shape's finest rule ([`crate::element::ElementFamily::fine_quadrature`]); the order is the
//! least-squares slope of `log error` against `log h`, `h = 1/n`. Linear families are expected
//! at about 2, quadratic ones at about 3.

use super::ValidateError;
use crate::element::{ElementFamily, Kinematics, Shape};
use crate::load::{Amplitude, PressureLoad};
use crate::material::StVenantKirchhoff;
use crate::mesh::shape_map::{MapKind, ShapeMap};
use crate::mesh::{Axis, BlockSpec, Mesh, NodePlace};
use crate::model::{Body, Material, Model, Prescribed};
use crate::sensitivity::{run_sensitivity, Method, Parameter, Settings};
use nalgebra::Vector3;

/// Inner radius.
const A: f64 = 1.0;
/// Outer radius (the shape parameter's reference value).
const B: f64 = 2.0;
/// Internal pressure.
const P: f64 = 1.0;
/// Young's modulus.
const E: f64 = 1000.0;
/// Poisson's ratio.
const NU: f64 = 0.3;
/// Thickness (one element).
const T: f64 = 0.25;

/// Elements through the wall of the report's meshes.
pub const LEVELS: [usize; 4] = [2, 4, 8, 16];

/// The families: every solid shape with its standard formulation.
pub const SHAPES: [Shape; 6] = Shape::SOLIDS;

/// One mesh of one family.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ConvergenceRow {
    /// The family's name.
    pub family: String,
    /// Elements through the wall.
    pub n: usize,
    /// Unknowns.
    pub unknowns: usize,
    /// Relative L2 error of the displacement.
    pub displacement: f64,
    /// Relative L2 error of its DDM derivative with respect to E.
    pub d_young: f64,
    /// Relative L2 error of its DDM derivative with respect to the outer radius.
    pub d_radius: f64,
}

/// The exact radial displacement at radius `r`.
fn radial(r: f64) -> f64 {
    (1.0 + NU) * P * A * A / (E * (B * B - A * A)) * ((1.0 - 2.0 * NU) * r + B * B / r)
}

/// The exact displacement at `x`.
pub fn exact(x: &Vector3<f64>) -> Vector3<f64> {
    let r = (x.x * x.x + x.y * x.y).sqrt();
    Vector3::new(x.x / r, x.y / r, 0.0) * radial(r)
}

/// Lamé's quarter cylinder meshed with `shape` elements, `n` through the wall: its model,
/// with the shape map `b` (the outer radius, scaling the cross-section about the axis).
pub fn lame(shape: Shape, n: usize) -> Result<Model, ValidateError> {
    let bad = |what: String| ValidateError::Study {
        study: "convergence",
        what,
    };
    let mut mesh = Mesh::default();
    mesh.add_block(BlockSpec {
        element: shape,
        name: "cyl".into(),
        origin: [0.0; 3],
        x: Axis::uniform(1.0, n),
        y: Axis::uniform(1.0, 2 * n),
        z: Axis::uniform(1.0, 1),
    })
    .map_err(|e| bad(e.to_string()))?;
    // (radius, angle, thickness) fractions onto the annulus: mid-edge nodes are placed at
    // their fractions' middle, so they lie on the arcs
    for p in mesh.places.iter_mut() {
        if let NodePlace::Block { t, .. } = *p {
            let r = A + (B - A) * t[0];
            let theta = std::f64::consts::FRAC_PI_2 * t[1];
            *p = NodePlace::Free([r * theta.cos(), r * theta.sin(), T * t[2]]);
        }
    }
    let all: Vec<usize> = (0..mesh.n_nodes()).collect();
    let map = ShapeMap::new(
        "b",
        all,
        MapKind::Scale {
            centre: [0.0; 3],
            axis: Some([0.0, 0.0, 1.0]),
        },
        B,
    )
    .map_err(|e| bad(e.to_string()))?;
    mesh.shape_maps.push(map);
    let set = |name: &str| mesh.node_sets[&format!("cyl.{name}")].clone();
    let prescribed = |name: &str, nodes: Vec<usize>, component: usize| Prescribed {
        name: name.into(),
        nodes,
        component,
        value: 0.0,
        amplitude: Amplitude::ramp(),
    };
    let model = Model {
        bodies: vec![Body {
            name: "cyl".into(),
            group: 0,
            material: Material::Svk(StVenantKirchhoff::new(E, NU)),
            kinematics: Kinematics::Small,
            formulation: None,
        }],
        prescribed: vec![
            // theta = 0 is the plane y = 0, theta = pi/2 the plane x = 0
            prescribed("y-symmetry", set("ymin"), 1),
            prescribed("x-symmetry", set("ymax"), 0),
            prescribed("plane-strain", set("all"), 2),
        ],
        pressures: vec![PressureLoad {
            name: "p".into(),
            faces: mesh.face_sets["cyl.xmin"].clone(),
            value: P,
            amplitude: Amplitude::ramp(),
        }],
        times: vec![1.0],
        mesh,
        ..Model::default()
    };
    Ok(model)
}

/// `|field - exact| / |exact|` in L2 over the body, by each element's finest rule.
fn l2_error(
    model: &Model,
    field: &[f64],
    exact: impl Fn(&Vector3<f64>) -> Vector3<f64>,
) -> Result<f64, ValidateError> {
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let family = model.bodies[0]
        .family(&model.mesh)
        .map_err(|e| ValidateError::Study {
            study: "convergence",
            what: e.to_string(),
        })?;
    let (mut err, mut norm) = (0.0, 0.0);
    for e in model.mesh.group_elements(0) {
        let nodes = model.mesh.element_nodes(e);
        let xe: Vec<Vector3<f64>> = nodes.iter().map(|&n| x[n]).collect();
        let points = family
            .fine_quadrature(&xe)
            .map_err(|f| ValidateError::Study {
                study: "convergence",
                what: f.to_string(),
            })?;
        for (n_a, dv) in points {
            let mut p = Vector3::zeros();
            let mut u = Vector3::zeros();
            for (a, &node) in nodes.iter().enumerate() {
                p += x[node] * n_a[a];
                u += Vector3::from_column_slice(&field[3 * node..3 * node + 3]) * n_a[a];
            }
            let want = exact(&p);
            err += (u - want).norm_squared() * dv;
            norm += want.norm_squared() * dv;
        }
    }
    Ok((err / norm).sqrt())
}

/// The errors of one family on one mesh.
pub fn row(shape: Shape, n: usize) -> Result<ConvergenceRow, ValidateError> {
    let model = lame(shape, n)?;
    let family = ElementFamily::standard(shape);
    let params: Vec<Parameter> = ["E", "b"]
        .iter()
        .map(|name| Parameter::by_name(&model, name))
        .collect::<Result<_, _>>()
        .map_err(|e| ValidateError::Study {
            study: "convergence",
            what: e.to_string(),
        })?;
    let settings = Settings {
        method: Method::Ddm,
        fields: true,
        ..Settings::default()
    };
    let (res, sens) =
        run_sensitivity(&model, &params, &settings).map_err(|source| ValidateError::Analysis {
            scene: format!("lame-{}-{n}", family.name()),
            source,
        })?;
    let z = res.states.last().expect("a converged state");
    let fields = sens.fields.last().expect("field derivatives");
    let displacement = |p: usize| {
        fields.derivatives[p]
            .iter()
            .find(|f| f.name == "displacement")
            .map(|f| f.values.clone())
            .expect("a displacement field")
    };
    Ok(ConvergenceRow {
        family: family.name().to_string(),
        n,
        unknowns: z.len(),
        displacement: l2_error(&model, z, exact)?,
        d_young: l2_error(&model, &displacement(0), |x| -exact(x) / E)?,
        d_radius: l2_error(&model, &displacement(1), |x| exact(x) / B)?,
    })
}

/// Least-squares slope of `log error` against `log (1/n)` over `rows` (one family's).
pub fn order(rows: &[&ConvergenceRow], error: impl Fn(&ConvergenceRow) -> f64) -> f64 {
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (-(r.n as f64).ln(), error(r).ln()))
        .collect();
    let m = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / m, sy / m);
    let (num, den) = pts.iter().fold((0.0, 0.0), |(n, d), (x, y)| {
        (n + (x - mx) * (y - my), d + (x - mx) * (x - mx))
    });
    num / den
}

/// Every family on every level.
pub fn study(levels: &[usize]) -> Result<Vec<ConvergenceRow>, ValidateError> {
    let mut rows = Vec::new();
    for shape in SHAPES {
        for &n in levels {
            rows.push(row(shape, n)?);
        }
    }
    Ok(rows)
}

/// The figure's file name.
pub const FIGURE: &str = "convergence-orders.svg";

/// Error against unknowns, per family and quantity.
pub fn figure(rows: &[ConvergenceRow]) -> crate::studies::plot::Figure {
    use crate::studies::plot::{Figure, Style};
    let mut f = Figure::new(
        "Lamé's cylinder: L2 error of the displacement and of its DDM derivatives",
        "unknowns",
        "relative L2 error",
    )
    .log_x()
    .log_y();
    for family in super::distinct(rows.iter().map(|r| r.family.as_str())) {
        let mine: Vec<&ConvergenceRow> = rows.iter().filter(|r| r.family == family).collect();
        let series = |e: fn(&ConvergenceRow) -> f64| -> Vec<(f64, f64)> {
            mine.iter().map(|r| (r.unknowns as f64, e(r))).collect()
        };
        f = f.series(
            format!("{family}: u"),
            series(|r| r.displacement),
            Style::LinePoints,
        );
        f = f.series(
            format!("{family}: du/db"),
            series(|r| r.d_radius),
            Style::Dashed,
        );
    }
    f
}

/// The report's section.
pub fn write_convergence(s: &mut String, rows: &[ConvergenceRow]) {
    use std::fmt::Write;
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## Convergence orders of the element families\n");
    let _ = writeln!(
        s,
        "Lamé's thick cylinder (inner radius 1, outer 2, internal pressure 1, plane strain, E = 1000, nu = 0.3, small strains; a quarter with its symmetry planes), meshed by the block generator's grid mapped onto the annulus, `n` elements through the wall, `2n` around, one through the thickness; the shape's standard formulation. Relative L2 errors against the closed form of the displacement, of its DDM derivative with respect to E (`-u/E`) and to the outer radius `b`, a shape parameter scaling the cross-section (`u/b` at a material point); the order is the least-squares slope against the element size over the meshes ([`convergence`](../src/studies/validate/convergence.rs)). Every solution here is linear in `1/E`, the discrete one too, so the E-derivative's error is the displacement's; the shape derivative's is its own (equal to it on the hexahedra and wedges, whose meshes of the scaled cylinder are the scaled meshes of the plane-strain problem; not quite on the tetrahedra, whose split is not invariant under scaling the cross-section alone).\n\n![{FIGURE}](figures/{FIGURE})\n"
    );
    let _ = writeln!(
        s,
        "| family | n | unknowns | error u | error du/dE | error du/db |\n|---|---|---|---|---|---|"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3e} | {:.3e} | {:.3e} |",
            r.family, r.n, r.unknowns, r.displacement, r.d_young, r.d_radius
        );
    }
    let _ = writeln!(
        s,
        "\n| family | order u | order du/dE | order du/db |\n|---|---|---|---|"
    );
    for family in super::distinct(rows.iter().map(|r| r.family.as_str())) {
        let mine: Vec<&ConvergenceRow> = rows.iter().filter(|q| q.family == family).collect();
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} | {:.2} |",
            family,
            order(&mine, |q| q.displacement),
            order(&mine, |q| q.d_young),
            order(&mine, |q| q.d_radius)
        );
    }
    let _ = writeln!(s);
}
