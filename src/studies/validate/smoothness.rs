//! How smooth the sensitivities of a contact pressure are along the surface, for hex8, hex20
//! and tet10 meshes of a curved punch slid on a slab: `dp/dmu` at every station of the slab's
//! surface by DDM, central SDM and central FDM, its total variation, its largest jump and its
//! largest second difference between neighbouring stations.
//!
//! The scene (written out as `punch-FAMILY-hSIZE-on-FAMILY-hSIZE.toml` beside its punch mesh
//! `punch-FAMILY-hSIZE.inp`, so that `fricsens run` reruns it): an elastic punch, the region
//! between a circular arc of radius [`RADIUS`] (lowest at the origin) and a flat top at height
//! [`HEIGHT`], `|x| <=` [`HALF_WIDTH`], E = 10 000, nu = 0.3, is pressed [`PRESS`] into an
//! elastic slab 16 x 4 (E = 1000, nu = 0.3; finely meshed for `|x| <= 4`) and then slid
//! [`SLIDE`] along x with Coulomb friction mu = 0.3, plane strain (one element through the
//! thickness), large kinematics. The punch's arc is the **target** (master) surface, the
//! slab's top the hitting (slave) one: the pressure is read at the slab's stations (the
//! hitting nodes at one x, their normal forces over their pressure areas). The punch is the
//! block generator's grid mapped onto the region, mid-edge nodes at their fractions' middle,
//! so a quadratic punch's arc faces lie on the circle to interpolation order while a hex8
//! punch's arc is faceted.
//!
//! The meshings ([`COMBINATIONS`]): one family on both sides at about equal unknowns (12 000:
//! hex8 0.2, its incompatible modes counted; hex20 0.25; tet10 1/3); a hex20 punch on a hex8
//! slab at about one slab node per punch face; and a hex8 or hex20 punch of 0.5 on a hex8 slab
//! of 0.1 at equal unknowns (32 000), the slab finer than the punch. One element of
//! [`THICKNESS`] through the thickness.

use super::ValidateError;
use crate::element::{ElementFamily, Shape};
use crate::mesh::{Axis, BlockSpec, Mesh, NodePlace};
use crate::response::ResponseKind;
use crate::scene::Scene;
use crate::sensitivity::{run_fdm_sweep, run_inline_sweep, Method, Parameter, Settings};
use std::path::Path;

/// Radius of the punch's arc.
pub const RADIUS: f64 = 10.0;
/// Half-width of the punch.
pub const HALF_WIDTH: f64 = 3.0;
/// Height of the punch's flat top above the arc's lowest point.
pub const HEIGHT: f64 = 2.0;
/// The punch's top is pressed down by this (first step).
pub const PRESS: f64 = 0.2;
/// ... and slid along x by this (second step).
pub const SLIDE: f64 = 0.5;
/// Thickness of both bodies (one element).
pub const THICKNESS: f64 = 0.25;
/// The folder of the report's data the scenes are written to.
pub const FOLDER: &str = "smoothness";
/// Relative perturbation of the central SDM and FDM.
pub const BETA: f64 = 1e-4;

/// A body's element shape and size.
pub type Meshing = (Shape, f64);

/// The combinations of the study: the punch's and the slab's meshing.
pub const COMBINATIONS: [(Meshing, Meshing); 6] = [
    ((Shape::Hex8, 0.2), (Shape::Hex8, 0.2)),
    ((Shape::Hex20, 0.25), (Shape::Hex20, 0.25)),
    ((Shape::Tet10, 1.0 / 3.0), (Shape::Tet10, 1.0 / 3.0)),
    ((Shape::Hex20, 0.25), (Shape::Hex8, 0.2)),
    ((Shape::Hex8, 0.5), (Shape::Hex8, 0.1)),
    ((Shape::Hex20, 0.5), (Shape::Hex8, 0.1)),
];

/// One method on one combination: its profile at the end of the slide, and the worst
/// measures of the interior over the slide.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct SmoothnessRow {
    /// `punch family, size / slab family, size`.
    pub combination: String,
    /// Whether the slab's (the hitting surface's) faces are quadratic.
    pub slave_quadratic: bool,
    /// Unknowns of the model.
    pub unknowns: usize,
    /// DDM, SDM central or FDM central.
    pub method: String,
    /// The stations' reference x, in contact at the end.
    pub x: Vec<f64>,
    /// Their pressures.
    pub p: Vec<f64>,
    /// Their `dp/dmu`.
    pub dp: Vec<f64>,
    /// `max |dp/dmu|` over them.
    pub max_abs: f64,
    /// The measures of `dp/dmu` over the interior stations (those bearing at least half the
    /// peak pressure: `dp/dmu` is singular at the contact's edges, which move with mu), the
    /// worst of each over the increments of the slide (the slab's nodes passing every place
    /// of the punch's faces).
    pub worst: Variation,
    /// The largest `|dp/dmu - DDM's|` at the end (zero for DDM).
    pub max_deviation: f64,
}

fn bad(what: String) -> ValidateError {
    ValidateError::Study {
        study: "smoothness",
        what,
    }
}

fn shape_of(element: Shape) -> &'static str {
    element.name()
}

/// Elements of size `size` over `length`, at least one.
fn count(length: f64, size: f64) -> usize {
    ((length / size).round() as usize).max(1)
}

/// The punch of `shape` elements of about `size`: the generator's grid mapped onto the region
/// between the arc and the flat top; node and face sets `punch.ymin` (the arc), `punch.ymax`
/// (the top), `punch.all`.
pub fn punch_mesh(shape: Shape, size: f64) -> Result<Mesh, ValidateError> {
    let mut mesh = Mesh::default();
    mesh.add_block(BlockSpec {
        element: shape,
        name: "punch".into(),
        origin: [0.0; 3],
        x: Axis::uniform(1.0, count(2.0 * HALF_WIDTH, size)),
        y: Axis::uniform(1.0, count(HEIGHT, size)),
        z: Axis::uniform(1.0, 1),
    })
    .map_err(|e| bad(e.to_string()))?;
    for p in mesh.places.iter_mut() {
        if let NodePlace::Block { t, .. } = *p {
            let x = -HALF_WIDTH + 2.0 * HALF_WIDTH * t[0];
            let arc = RADIUS - (RADIUS * RADIUS - x * x).sqrt();
            let y = arc + (HEIGHT - arc) * t[1];
            *p = NodePlace::Free([x, y, THICKNESS * t[2]]);
        }
    }
    Ok(mesh)
}

/// The scene's TOML around the punch mesh file `mesh`, the slab of `slab` elements of `size`.
fn scene_text(punch: Shape, (slab, size): Meshing, mesh: &str) -> String {
    let fine = count(8.0, size);
    let deep = count(1.0, size);
    let coarse = (fine / 8).max(2);
    format!(
        r#"# A curved elastic punch pressed {PRESS} into an elastic slab and slid {SLIDE} along x with
# Coulomb friction, plane strain: the sensitivity-smoothness study of the verification report
# (src/studies/validate/smoothness.rs). The punch ({punch}, mesh {mesh}) is the target
# surface, the slab's top ({slab}) the hitting one.
name = "punch-{punch}-on-{slab}"
description = "Curved punch (R = {RADIUS}, {punch}) pressed {PRESS} and slid {SLIDE} on a slab ({slab}), mu = 0.3, plane strain."

[[bodies]]
name = "punch"
mesh = "{mesh}"
kinematics = "large"
material = {{ law = "svk", E = 10000.0, nu = 0.3 }}

[[bodies]]
name = "slab"
element = "{slab_name}"
origin = [-8.0, -4.0, 0.0]
kinematics = "large"
material = {{ law = "svk", E = 1000.0, nu = 0.3 }}
x = {{ length = 16.0, zones = [{{ fraction = 0.25, elements = {coarse}, ratio = 0.25 }}, {{ fraction = 0.5, elements = {fine} }}, {{ fraction = 0.25, elements = {coarse}, ratio = 4.0 }}] }}
y = {{ length = 4.0, zones = [{{ fraction = 0.75, elements = {coarse}, ratio = 0.25 }}, {{ fraction = 0.25, elements = {deep} }}] }}
z = {{ length = {THICKNESS:?}, zones = [{{ fraction = 1.0, elements = 1 }}] }}

[[prescribed]]
name = "base"
set = "slab.ymin"
components = ["x", "y"]

[[prescribed]]
name = "press"
set = "punch.ymax"
components = ["y"]
value = -{PRESS:?}
amplitude = [[0.0, 0.0], [1.0, 1.0], [2.0, 1.0]]

[[prescribed]]
name = "slide"
set = "punch.ymax"
components = ["x"]
value = {SLIDE:?}
amplitude = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]]

[[prescribed]]
name = "plane-strain-punch"
set = "punch.all"
components = ["z"]

[[prescribed]]
name = "plane-strain-slab"
set = "slab.all"
components = ["z"]

[[contacts]]
name = "interface"
hitting = "slab.ymax"
target = {{ faces = "punch.ymin" }}
normal = {{ law = "lagrange" }}
friction = {{ law = "coulomb", mu = 0.3 }}

[[steps]]
end = 1.0
increments = 4

[[steps]]
end = 2.0
increments = 10

[[responses]]
kind = "pressure-profile"
name = "p"
pair = "interface"
along = "x"
per = "station"

[study]
params = ["mu"]
"#,
        punch = ElementFamily::standard(punch).name(),
        slab = ElementFamily::standard(slab).name(),
        slab_name = shape_of(slab),
    )
}

/// Write the scene of `(punch, slab)` and its punch mesh into `dir`; the scene file's path.
pub fn write_scene(
    (punch, size): Meshing,
    slab: Meshing,
    dir: &Path,
) -> Result<std::path::PathBuf, ValidateError> {
    std::fs::create_dir_all(dir).map_err(|e| bad(format!("{}: {e}", dir.display())))?;
    let mesh = punch_mesh(punch, size)?;
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    let file = format!("punch-{}-h{size:.3}.inp", shape_of(punch));
    crate::mesh::abaqus::write(&mesh, &x, &[("punch".into(), 0)], &dir.join(&file))
        .map_err(|e| bad(e.to_string()))?;
    let path = dir.join(format!(
        "punch-{}-h{size:.3}-on-{}-h{:.3}.toml",
        shape_of(punch),
        shape_of(slab.0),
        slab.1
    ));
    std::fs::write(&path, scene_text(punch, slab, &file))
        .map_err(|e| bad(format!("{}: {e}", path.display())))?;
    Ok(path)
}

/// The measures of a profile `d` over neighbouring entries.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Variation {
    /// `sum |d[j+1] - d[j]|`.
    pub total: f64,
    /// `max |d[j+1] - d[j]|`.
    pub jump: f64,
    /// `max |d[j+1] - 2 d[j] + d[j-1]|`.
    pub second: f64,
    /// `max |d[j]|`.
    pub max_abs: f64,
    /// The total variation over the range `max d - min d`: one for a monotone profile.
    pub excess: f64,
}

impl Variation {
    /// Each measure the larger of `self`'s and `other`'s.
    pub fn worst(&self, other: &Variation) -> Variation {
        Variation {
            total: self.total.max(other.total),
            jump: self.jump.max(other.jump),
            second: self.second.max(other.second),
            max_abs: self.max_abs.max(other.max_abs),
            excess: self.excess.max(other.excess),
        }
    }
}

/// The [`Variation`] of `d`.
pub fn variation(d: &[f64]) -> Variation {
    let jumps = d.windows(2).map(|w| (w[1] - w[0]).abs());
    let mut v = Variation {
        total: jumps.clone().sum(),
        jump: jumps.fold(0.0, f64::max),
        second: (d.windows(3))
            .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
            .fold(0.0, f64::max),
        max_abs: d.iter().fold(0.0f64, |m, v| m.max(v.abs())),
        excess: 1.0,
    };
    let (lo, hi) = (d.iter()).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(*v), h.max(*v))
    });
    if hi > lo {
        v.excess = v.total / (hi - lo);
    }
    v
}

/// The three methods' profiles on one combination, its scene written into `dir`.
pub fn rows(
    punch: Meshing,
    slab: Meshing,
    dir: &Path,
) -> Result<Vec<SmoothnessRow>, ValidateError> {
    let path = write_scene(punch, slab, dir)?;
    let scene = Scene::from_file(&path).map_err(|e| bad(e.to_string()))?;
    let model = scene.build().map_err(|e| bad(e.to_string()))?;
    let mu = Parameter::by_name(&model, "mu").map_err(|e| bad(e.to_string()))?;
    let params = [mu];
    let analysis = |source| ValidateError::Analysis {
        scene: scene.name.clone(),
        source,
    };
    let settings = |method, beta| Settings {
        method,
        beta,
        ..Settings::default()
    };
    let (res, inline) = run_inline_sweep(
        &model,
        &params,
        &[
            settings(Method::Ddm, 0.0),
            settings(Method::SdmCentral, BETA),
        ],
    )
    .map_err(analysis)?;
    let (_, mut fdm) = run_fdm_sweep(&model, &params, &[BETA], true).map_err(analysis)?;
    let fdm = fdm.pop().ok_or_else(|| bad("no FDM run".into()))?;
    let unknowns = res.states.last().map_or(0, |z| z.len());
    // the stations, in order along x, and their reference x
    let x0 = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let stations: Vec<(usize, f64)> = (model.responses.iter().enumerate())
        .filter_map(|(r, resp)| match &resp.kind {
            ResponseKind::ContactPressure { pair, nodes, .. } => {
                Some((r, x0[model.contacts[*pair].hitting[nodes[0]]][0]))
            }
            _ => None,
        })
        .collect();
    let ddm = &inline[0];
    let last = ddm
        .increments
        .last()
        .ok_or_else(|| bad("no increment".into()))?;
    let closed: Vec<&(usize, f64)> = (stations.iter())
        .filter(|(r, _)| last.values[*r] > 0.0)
        .collect();
    let reference: Vec<f64> = closed
        .iter()
        .map(|(r, _)| last.derivatives[*r][0])
        .collect();
    let mut out = Vec::new();
    for (name, s) in [
        ("DDM", ddm),
        ("SDM central", &inline[1]),
        ("FDM central", &fdm),
    ] {
        if let Some(why) = &s.failure {
            return Err(bad(format!("{name}: {why}")));
        }
        if s.increments.len() != ddm.increments.len() {
            return Err(bad(format!("{name}: other increments than DDM's")));
        }
        // the measures over the interior (the stations bearing at least half the peak
        // pressure) at every increment of the slide, the worst of each
        let mut worst = Variation::default();
        for (inc, nominal) in s.increments.iter().zip(&ddm.increments) {
            if inc.time <= 1.0 {
                continue;
            }
            let peak = (stations.iter()).fold(0.0f64, |m, (r, _)| m.max(nominal.values[*r]));
            let interior: Vec<f64> = (stations.iter())
                .filter(|(r, _)| peak > 0.0 && nominal.values[*r] >= 0.5 * peak)
                .map(|(r, _)| inc.derivatives[*r][0])
                .collect();
            worst = worst.worst(&variation(&interior));
        }
        let inc = s
            .increments
            .last()
            .ok_or_else(|| bad("no increment".into()))?;
        let dp: Vec<f64> = closed.iter().map(|(r, _)| inc.derivatives[*r][0]).collect();
        let max_deviation = (dp.iter().zip(&reference))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        out.push(SmoothnessRow {
            combination: combination_name(punch, slab),
            slave_quadratic: slab.0.is_quadratic(),
            unknowns,
            method: name.into(),
            x: closed.iter().map(|(_, x)| *x).collect(),
            p: closed.iter().map(|(r, _)| last.values[*r]).collect(),
            max_abs: dp.iter().fold(0.0f64, |m, v| m.max(v.abs())),
            dp,
            worst,
            max_deviation,
        });
    }
    Ok(out)
}

/// `punch family size / slab family size`, as the report names a combination.
fn combination_name(punch: Meshing, slab: Meshing) -> String {
    format!(
        "{} {} / {} {}",
        ElementFamily::standard(punch.0).name(),
        size_label(punch.1),
        ElementFamily::standard(slab.0).name(),
        size_label(slab.1)
    )
}

/// An element size as the report writes it (1/3 as such).
fn size_label(size: f64) -> String {
    if (size - 1.0 / 3.0).abs() < 1e-12 {
        "h 1/3".into()
    } else {
        format!("h {size}")
    }
}

/// Every combination, the scenes written into `dir`.
pub fn study(dir: &Path) -> Result<Vec<SmoothnessRow>, ValidateError> {
    let mut out = Vec::new();
    for (punch, slab) in COMBINATIONS {
        out.extend(rows(punch, slab, dir)?);
    }
    Ok(out)
}

/// The figures' file names: every combination's `dp/dmu` by DDM, and the three methods on
/// the roughest.
pub const FIGURE: &str = "smoothness-dp-dmu.svg";
/// See [`FIGURE`].
pub const FIGURE_METHODS: &str = "smoothness-methods.svg";

/// `dp/dmu` along the surface after the slide, DDM, one line per combination.
pub fn figure(rows: &[SmoothnessRow]) -> crate::studies::plot::Figure {
    use crate::studies::plot::{Figure, Style};
    let mut f = Figure::new(
        "dp/dmu along the slab's surface after the slide, DDM (punch / slab)",
        "x",
        "dp/dmu",
    );
    for r in rows.iter().filter(|r| r.method == "DDM") {
        let points = r.x.iter().copied().zip(r.dp.iter().copied()).collect();
        f = f.series(r.combination.clone(), points, Style::LinePoints);
    }
    f
}

/// The three methods on the combination of the roughest DDM profile (the largest worst
/// second difference).
pub fn figure_methods(rows: &[SmoothnessRow]) -> crate::studies::plot::Figure {
    use crate::studies::plot::{Figure, Style};
    let roughest = (rows.iter().filter(|r| r.method == "DDM"))
        .max_by(|a, b| a.worst.second.total_cmp(&b.worst.second))
        .map(|r| r.combination.clone())
        .unwrap_or_default();
    let mut f = Figure::new(
        format!("dp/dmu after the slide by three methods: {roughest}"),
        "x",
        "dp/dmu",
    );
    for r in rows.iter().filter(|r| r.combination == roughest) {
        let style = match r.method.as_str() {
            "DDM" => Style::Line,
            "SDM central" => Style::Dashed,
            _ => Style::Points,
        };
        let points = r.x.iter().copied().zip(r.dp.iter().copied()).collect();
        f = f.series(r.method.clone(), points, style);
    }
    f
}

/// The report's section.
pub fn write_smoothness(s: &mut String, rows: &[SmoothnessRow]) {
    use std::fmt::Write;
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Smoothness of the sensitivities along a contact surface\n"
    );
    let _ = writeln!(
        s,
        "A curved elastic punch (arc radius {RADIUS}, half-width {HALF_WIDTH}, E = 10 000) pressed {PRESS} into an elastic slab (E = 1000) and slid {SLIDE} with Coulomb friction mu = 0.3, plane strain, large kinematics; the punch's arc is the target (master) surface, the slab's top the hitting (slave) one ([`smoothness`](../src/studies/validate/smoothness.rs)). The scenes and punch meshes are written to `data/{FOLDER}/` (`fricsens run validation/data/{FOLDER}/punch-hex20-h0.500-on-hex8-h0.100.toml` reruns one). `dp/dmu` at every station of the slab's surface (its hitting nodes at one x), by DDM, central SDM and central FDM (relative step {BETA:e}). A quadratic punch's arc faces are curved (mid-side nodes on the circle), a hex8 punch's are flat facets, meeting at an angle of element size over radius, seen by default through smoothed nodal normals (`contacts[].smoothing = \"normals\"` on linear faces: the normal turns continuously across a facet's edge, at a rate that jumps there). The first three combinations are of one family on both sides at about equal unknowns (hex8 0.2, hex20 0.25, tet10 1/3); the last three a hex8 slab under a hex20 or hex8 punch, the last two at equal unknowns with a slab finer than the punch, as node-to-segment contact is meant to be used.\n\nThe measures are taken over the interior (the stations bearing at least half the peak pressure: at the contact's edges, which move with mu, `dp/dmu` is singular) at every increment of the slide, so that the slab's nodes pass every place of the punch's faces, and the worst of each is given: the total variation, the total variation over the range (one for a monotone profile), the largest jump between neighbouring stations, and the largest second difference `|d[j+1] - 2 d[j] + d[j-1]|` (a spike's or an odd-even oscillation's signature; a smooth profile's falls with the spacing squared). Deviation: the largest difference from DDM after the slide, over the largest `|dp/dmu|`.\n\n![{FIGURE}](figures/{FIGURE})\n\n![{FIGURE_METHODS}](figures/{FIGURE_METHODS})\n"
    );
    let _ = writeln!(
        s,
        "| punch / slab | unknowns | method | total variation | variation / range | largest jump | largest second difference | deviation from DDM |\n|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.2} | {:.1e} |",
            r.combination,
            r.unknowns,
            r.method,
            r.worst.total,
            r.worst.excess,
            r.worst.jump,
            r.worst.second,
            r.max_deviation / r.max_abs.max(f64::MIN_POSITIVE)
        );
    }
    let ddm: Vec<&SmoothnessRow> = rows.iter().filter(|r| r.method == "DDM").collect();
    let agree = (rows.iter())
        .map(|r| r.max_deviation / r.max_abs.max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    let rank = |a: &&SmoothnessRow, b: &&SmoothnessRow| a.worst.excess.total_cmp(&b.worst.excess);
    let mut order = ddm.clone();
    order.sort_by(rank);
    let names: Vec<String> = (order.iter())
        .map(|r| format!("{} ({:.2})", r.combination, r.worst.excess))
        .collect();
    let _ = writeln!(
        s,
        "\nThe three methods agree on every profile to {agree:.1e} of its largest value: the roughness is the discrete problem's derivative, which every method computes, not a method's error. From smoothest to roughest by the variation over the range of DDM's profile: {}.",
        names.join(", ")
    );
    // the combinations the explanation compares, by their place in COMBINATIONS
    let excess = |k: usize| -> String {
        let name = combination_name(COMBINATIONS[k].0, COMBINATIONS[k].1);
        ddm.iter()
            .find(|r| r.combination == name)
            .map_or("-".into(), |r| format!("{:.2}", r.worst.excess))
    };
    let _ = writeln!(
        s,
        "\nWhy. A node-to-segment contact constrains each slave node against the master face under it, and the profile is as regular as that pairing is along the surface. (1) **Faceted master, finer slave** (hex8 punch 0.5 on hex8 slab 0.1: {}): a slave node crossing a facet's kink meets a jump of the normal (with `smoothing = \"none\"`; 4.95 in the report before smoothing was the default) or of its rate of turn (smoothed), so the pressure and above all its derivative spike at the kinks — the effect the CalculiX measurement saw. The smoothed normals, which make Newton converge where faceted ones cycle (*Robustness*), do not smooth this roughness ({} against 4.95). (2) **Curved master** (hex20 punch 0.5 on the same slab, at the same unknowns: {}): the quadratic faces follow the circle, so the normal barely turns at their edges, and most of the spikes go. With about one slave node per master face (hex20 punch 0.25 on hex8 slab 0.2: {}) the profile is rougher again: a serendipity face's corner shape functions are negative over most of the face, so a slave node pressing on it pulls the face's corners, by how much depending on where on the face it sits. (3) **Quadratic slave** (hex20 on hex20: {}, tet10 on tet10: {}): the corner and mid-side nodes of a quad8 or tri6 face do not share its load evenly (a pressure's consistent load is a pull at a quad8's corners and nothing at a tri6's), and a change of mu shifts load between them, a mode the node-wise constraints leave free: `dp/dmu` alternates between the stations of corners and of mid-sides. The smoothest sensitivities therefore come from a curved (quadratic) master over a finer linear slave; quadratic elements belong on the master side of a node-to-segment pair. Remedies for quadratic slaves, not built here: a mortar (segment-to-segment) contact, which integrates the constraint over the slave faces, or faces with a mid-face node (quad9, whose consistent loads are all positive).",
        excess(4),
        excess(4),
        excess(5),
        excess(3),
        excess(1),
        excess(2)
    );
    let _ = writeln!(s);
}
