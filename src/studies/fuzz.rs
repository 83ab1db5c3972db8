//! A physics fuzzer: random *valid* contact scenes, run with default settings and checked.
//!
//! *Why one file of over 1,000 lines:* the generator and the checks share one vocabulary of
//! generated scenes (target kinds, paths, size classes); splitting them would put each change to
//! that vocabulary in two files.
//!
//! [`generate`] turns a seed into a [`Scene`] a user could have written: a deformable block
//! (random size, aspect, grading, element formulation and kinematics; St Venant-Kirchhoff,
//! Neo-Hookean or J2 with linear or saturation hardening; `E` over six decades and `nu` up to
//! 0.49) pressed by a rigid cylinder, sphere, rounded punch or plane, or by a second deformable
//! block, with every normal law (Lagrange, penalty, augmented Lagrangian) and friction law
//! (none, Coulomb, regularised, pressure-dependent; `mu` in [0, 1.5]), along a random path of
//! press, slide (either way), unload (partly, or to lift-off) and reload phases with random
//! increment counts, in plane strain or 3D. Every setting a user may leave out (tangential
//! stiffness, constraint scale, search radius, solver settings) is left out.
//!
//! [`run_case`] runs a scene and checks every converged increment against physics rather than
//! against the code's own output ([`IncrementCheck`]):
//! * global equilibrium: the reactions at the supports, the loads and the forces of the rigid
//!   targets add up to zero in every direction (to [`EQUILIBRIUM_TOL`] of the largest of them);
//! * the Coulomb inequality at every closed hitting node, `|t| <= mu(p_n) p_n` (the law's own
//!   slip limit, to [`COULOMB_TOL`]), no tensile normal force, no friction force on an open
//!   node;
//! * no penetration of a Lagrange-multiplier pair beyond round-off ([`PENETRATION_TOL`] of the
//!   smallest element); an augmented-Lagrangian pair's constraint within its own tolerance: no
//!   node carrying a normal force pressed in, or held off, by more than it.
//!
//! A run that fails either to complete or a check is a failure with a class
//! ([`FailureClass`]); `fricsens fuzz` runs thousands of seeds, writes the table of the
//! report's robustness section and keeps every failing scene as TOML, the regression corpus
//! (`tests/corpus/robustness/`) whose scenes the default test suite runs.

use crate::contact::friction::{
    Coulomb, FrictionLaw, PressureDependentCoulomb, RegularizedCoulomb,
};
use crate::contact::{Friction, Target};
use crate::element::Shape;
use crate::material::{J2Plasticity, Material, NeoHookean, StVenantKirchhoff};
use crate::mesh::{Axis, BlockSpec, Zone};
use crate::scene::{
    BodySpec, Component, ContactSpec, MotionSpec, PrescribedSpec, ResponseSpec, RigidSpec, Scene,
    StepSpec, TargetSpec,
};
use crate::solver::{AnalysisError, Converged, Observer, RunOptions, Solver};
use std::time::Instant;

/// A small, fast, deterministic generator (SplitMix64): the same seed gives the same scene on
/// every machine.
#[derive(Clone, Debug)]
pub(crate) struct Rng(u64);

impl Rng {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x5851_f42d_4c95_7f2d)
    }

    /// The next 64 random bits.
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[a, b)`.
    pub fn uniform(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }

    /// Log-uniform in `[a, b)` (`0 < a < b`).
    pub(crate) fn log_uniform(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.unit()).exp()
    }

    /// Uniform integer in `[a, b]`.
    pub fn int(&mut self, a: usize, b: usize) -> usize {
        a + (self.next_u64() % (b - a + 1) as u64) as usize
    }

    /// True with probability `p`.
    pub(crate) fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    /// Index chosen with the given weights.
    pub fn weighted(&mut self, weights: &[f64]) -> usize {
        let total: f64 = weights.iter().sum();
        let mut x = self.unit() * total;
        for (i, w) in weights.iter().enumerate() {
            if x < *w {
                return i;
            }
            x -= w;
        }
        weights.len() - 1
    }
}

/// What presses the block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Indenter {
    Cylinder,
    Sphere,
    Punch,
    Plane,
    Block,
}

/// An axis of `n` elements over `length`, uniform or graded.
fn axis(r: &mut Rng, length: f64, n: usize, fine: Option<bool>) -> Axis {
    // fine: None uniform-ish; Some(true) fine in the middle; Some(false) fine at the end
    match fine {
        Some(true) if n >= 6 && r.chance(0.7) => {
            let side = r.int(1, (n / 3).max(1));
            let middle = n - 2 * side;
            let ratio = r.log_uniform(1.5, 8.0);
            let fm = r.uniform(0.2, 0.6);
            Axis {
                length,
                zones: vec![
                    Zone {
                        fraction: (1.0 - fm) / 2.0,
                        elements: side,
                        ratio: 1.0 / ratio,
                    },
                    Zone {
                        fraction: fm,
                        elements: middle,
                        ratio: 1.0,
                    },
                    Zone {
                        fraction: (1.0 - fm) / 2.0,
                        elements: side,
                        ratio,
                    },
                ],
            }
        }
        Some(false) if n >= 4 && r.chance(0.7) => {
            let coarse = r.int(1, n / 2);
            let ratio = r.log_uniform(1.5, 8.0);
            let fc = r.uniform(0.3, 0.8);
            Axis {
                length,
                zones: vec![
                    Zone {
                        fraction: fc,
                        elements: coarse,
                        ratio: 1.0 / ratio,
                    },
                    Zone {
                        fraction: 1.0 - fc,
                        elements: n - coarse,
                        ratio: 1.0,
                    },
                ],
            }
        }
        _ => Axis::uniform(length, n),
    }
}

fn material(r: &mut Rng, e: f64) -> Material {
    let nu = if r.chance(0.15) {
        r.uniform(0.45, 0.49)
    } else {
        r.uniform(0.0, 0.45)
    };
    match r.weighted(&[0.35, 0.2, 0.45]) {
        0 => Material::Svk(StVenantKirchhoff::new(e, nu)),
        1 => Material::NeoHookean(NeoHookean::new(e, nu)),
        _ => {
            let sigma_y = e * r.log_uniform(3e-4, 1e-2);
            let hardening = if r.chance(0.2) {
                0.0
            } else {
                e * r.log_uniform(1e-3, 0.2)
            };
            Material::J2(if r.chance(0.25) {
                let sigma_inf = sigma_y * r.uniform(1.1, 3.0);
                let delta = r.log_uniform(5.0, 500.0);
                J2Plasticity::saturation(e, nu, sigma_y, hardening, sigma_inf, delta)
            } else {
                J2Plasticity::linear(e, nu, sigma_y, hardening)
            })
        }
    }
}

fn body(r: &mut Rng, block: BlockSpec, e: f64) -> BodySpec {
    use crate::element::{Formulation, Kinematics};
    BodySpec {
        geometry: crate::scene::BodyGeometry::Block(block),
        material: material(r, e),
        kinematics: if r.chance(0.3) {
            Kinematics::Small
        } else {
            Kinematics::Large
        },
        formulation: match r.weighted(&[0.2, 0.5, 0.3]) {
            0 => Some(Formulation::Full),
            1 => Some(Formulation::IncompatibleModes),
            _ => Some(Formulation::FBar),
        },
    }
}

fn friction(r: &mut Rng, force_scale: f64) -> Option<Friction> {
    let mu = if r.chance(0.1) {
        0.0
    } else {
        r.uniform(0.0, 1.5)
    };
    match r.weighted(&[0.12, 0.55, 0.18, 0.15]) {
        0 => None,
        1 => Some(Friction::Coulomb(Coulomb::new(mu))),
        2 => Some(Friction::RegularizedCoulomb(RegularizedCoulomb::new(mu))),
        _ => Some(Friction::PressureDependent(PressureDependentCoulomb::new(
            mu,
            force_scale * r.log_uniform(0.1, 10.0),
            r.uniform(0.0, 0.3),
        ))),
    }
}

fn normal_law(r: &mut Rng, e: f64, h: f64, depth: f64) -> crate::contact::NormalLaw {
    use crate::contact::NormalLaw;
    // a penalty stiffness (pressure per unit penetration) of 1 to 100 times E over the
    // element size: penetrations of 1 to 1e-2 of the elastic strain's displacement
    let stiffness = e / h * r.log_uniform(1.0, 100.0);
    match r.weighted(&[0.6, 0.2, 0.2]) {
        0 => NormalLaw::Lagrange,
        1 => NormalLaw::Penalty { stiffness },
        _ => NormalLaw::Augmented {
            stiffness,
            tolerance: depth * r.log_uniform(1e-4, 1e-2),
        },
    }
}

/// One phase of the path: the target's displacement at its end, and its increments.
struct Phase {
    end: [f64; 3],
    increments: usize,
}

/// A random path: press, then a few of slide (either way), unload (partly, or to lift-off),
/// reload and press further. `depth` is the first press; `slide` a typical sliding distance.
fn path(r: &mut Rng, gap0: f64, depth: f64, slide: f64, three_d: bool) -> Vec<Phase> {
    let mut phases = Vec::new();
    let mut at = [0.0, -(gap0 + depth), 0.0];
    phases.push(Phase {
        end: at,
        increments: r.int(1, 8),
    });
    let n = r.int(0, 4);
    let mut lifted = false;
    for _ in 0..n {
        let mut next = at;
        match r.weighted(&[0.5, 0.2, 0.15, 0.15]) {
            0 if !lifted => {
                let s = slide * r.uniform(0.2, 1.5) * if r.chance(0.35) { -1.0 } else { 1.0 };
                if three_d && r.chance(0.4) {
                    let a = r.uniform(0.0, std::f64::consts::TAU);
                    next[0] += s * a.cos();
                    next[2] += s * a.sin();
                } else {
                    next[0] += s;
                }
            }
            1 => {
                // unload by a fraction of the press; above 1 the target lifts off
                let f = r.uniform(0.2, 1.3);
                next[1] = (at[1] + f * depth).min(gap0 + 0.5 * depth);
                lifted = next[1] > -gap0;
            }
            2 => {
                next[1] = -(gap0 + depth * r.uniform(0.5, 1.0));
                lifted = false;
            }
            _ => {
                next[1] = at[1] - depth * r.uniform(0.1, 0.5);
                lifted = false;
            }
        }
        if next == at {
            continue;
        }
        at = next;
        phases.push(Phase {
            end: at,
            increments: r.int(1, 10),
        });
    }
    phases
}

/// The random scene of `seed` (see the module docs).
pub fn generate(seed: u64) -> Scene {
    let mut r = Rng::new(seed);
    let three_d = r.chance(0.25);
    // units: a length scale over four decades, E over six
    let unit = r.log_uniform(1e-2, 1e2);
    let e = r.log_uniform(1.0, 1e6);
    let lx = unit * r.uniform(10.0, 60.0);
    let ly = lx * r.uniform(0.25, 0.8);
    let (nx, ny) = if three_d {
        (r.int(4, 10), r.int(2, 5))
    } else {
        (r.int(6, 28), r.int(3, 12))
    };
    let nz = if three_d { r.int(2, 6) } else { 1 };
    let indenter = if three_d {
        [
            Indenter::Cylinder,
            Indenter::Sphere,
            Indenter::Punch,
            Indenter::Plane,
            Indenter::Block,
        ][r.weighted(&[0.2, 0.3, 0.2, 0.1, 0.2])]
    } else {
        [
            Indenter::Cylinder,
            Indenter::Punch,
            Indenter::Plane,
            Indenter::Block,
        ][r.weighted(&[0.4, 0.2, 0.1, 0.3])]
    };
    // the contact region in the middle of x (and z): grade there unless a plane presses all
    let fine = indenter != Indenter::Plane;
    let x = axis(&mut r, lx, nx, Some(fine));
    let y = axis(&mut r, ly, ny, Some(false));
    // plane strain: one element as thick as a typical element in x
    let hx = lx / nx as f64;
    let lz = if three_d {
        lx * r.uniform(0.3, 1.0)
    } else {
        hx * r.uniform(0.5, 2.0)
    };
    let z = if three_d {
        axis(&mut r, lz, nz, Some(fine))
    } else {
        Axis::uniform(lz, 1)
    };
    // smallest element size of the base near its top
    let h = [&x, &y, &z]
        .iter()
        .map(|a| a.element_sizes().into_iter().fold(f64::INFINITY, f64::min))
        .fold(f64::INFINITY, f64::min);
    let origin = [-lx / 2.0, -ly, if three_d { -lz / 2.0 } else { 0.0 }];
    let base = BlockSpec {
        element: crate::element::Shape::Hex8,
        name: "base".into(),
        origin,
        x,
        y,
        z,
    };
    let mut bodies = vec![body(&mut r, base, e)];
    let mut prescribed = vec![PrescribedSpec {
        name: "support".into(),
        set: "base.ymin".into(),
        components: vec![Component::X, Component::Y, Component::Z],
        value: 0.0,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
    }];
    if !three_d {
        // plane strain; the support's z is prescribed by the support itself
        prescribed[0].components.pop();
        prescribed.push(PrescribedSpec {
            name: "plane-strain".into(),
            set: "base.all".into(),
            components: vec![Component::Z],
            value: 0.0,
            amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
        });
    }
    // press depth: 0.3 % to 5 % of the block's height, at least a tenth of an element
    let mut depth = ly * r.log_uniform(3e-3, 5e-2);
    let gap0 = if r.chance(0.6) {
        0.0
    } else {
        depth * r.uniform(0.0, 0.5)
    };
    let mut responses = Vec::new();
    let contacts;
    let slide;
    let force_scale = e * h * h * 1e-2;
    match indenter {
        Indenter::Block => {
            let w = lx * r.uniform(0.15, 0.5);
            let hgt = ly * r.uniform(0.15, 0.5);
            let n_sx = r.int(2, if three_d { 5 } else { 12 });
            let n_sy = r.int(1, if three_d { 3 } else { 6 });
            let (lzs, nzs) = if three_d {
                (lz * r.uniform(0.3, 0.8), r.int(1, 4))
            } else {
                (lz, 1)
            };
            let slider = BlockSpec {
                element: crate::element::Shape::Hex8,
                name: "slider".into(),
                origin: [
                    -w / 2.0 + lx * r.uniform(-0.1, 0.1),
                    gap0,
                    if three_d { -lzs / 2.0 } else { 0.0 },
                ],
                x: Axis::uniform(w, n_sx),
                y: Axis::uniform(hgt, n_sy),
                z: Axis::uniform(lzs, nzs),
            };
            // the slider's material: same or another stiffness (up to 100 times either way)
            let es = if r.chance(0.5) {
                e
            } else {
                e * r.log_uniform(1e-2, 1e2)
            };
            bodies.push(body(&mut r, slider, es));
            depth = depth.min(0.3 * hgt);
            slide = w * r.uniform(0.05, 0.5);
            let phases = path(&mut r, gap0, depth, slide, three_d);
            let mut comps = vec![Component::X, Component::Y];
            if three_d {
                comps.push(Component::Z);
            }
            for (c, comp) in comps.iter().enumerate() {
                let mut amp = vec![(0.0, 0.0)];
                for (k, p) in phases.iter().enumerate() {
                    amp.push(((k + 1) as f64, p.end[c]));
                }
                prescribed.push(PrescribedSpec {
                    name: format!("drive-{}", ["x", "y", "z"][c]),
                    set: "slider.ymax".into(),
                    components: vec![*comp],
                    value: 1.0,
                    amplitude: amp,
                });
            }
            if !three_d {
                prescribed.push(PrescribedSpec {
                    name: "slider-plane-strain".into(),
                    set: "slider.all".into(),
                    components: vec![Component::Z],
                    value: 0.0,
                    amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
                });
            }
            let (hitting, target) = if r.chance(0.8) {
                ("slider.ymin", "base.ymax")
            } else {
                ("base.ymax", "slider.ymin")
            };
            contacts = vec![ContactSpec {
                name: "interface".into(),
                hitting: hitting.into(),
                target: TargetSpec::Faces(target.into()),
                normal: normal_law(&mut r, e.min(es), h, depth),
                friction: friction(&mut r, force_scale),
                tangential_stiffness: None,
                constraint_scale: None,
                activation: None,
                search_radius: None,
                smoothing: None,
            }];
            for c in [Component::X, Component::Y] {
                responses.push(ResponseSpec::Reaction {
                    name: format!("drive-force-{c:?}").to_lowercase(),
                    set: "slider.ymax".into(),
                    component: c,
                });
            }
            return finish(
                seed,
                bodies,
                prescribed,
                contacts,
                steps(&phases),
                responses,
            );
        }
        Indenter::Cylinder | Indenter::Sphere => {
            let radius = lx * r.log_uniform(0.15, 10.0);
            // keep the contact half-width sqrt(2 R d) within a third of the block
            depth = depth.min((0.33 * lx).powi(2) / (2.0 * radius));
            let a = (2.0 * radius * depth).sqrt();
            slide = a.max(2.0 * h) * r.uniform(0.3, 2.0);
            let centre = [lx * r.uniform(-0.1, 0.1), gap0 + radius, 0.0];
            let surface = if indenter == Indenter::Cylinder {
                RigidSpec::Cylinder {
                    axis_point: centre,
                    axis: [0.0, 0.0, 1.0],
                    radius,
                }
            } else {
                RigidSpec::RoundedBox {
                    center: centre,
                    half_extents: [radius; 3],
                    radius,
                }
            };
            contacts = vec![rigid_contact(&mut r, surface, e, h, depth, force_scale)];
        }
        Indenter::Punch => {
            let w = lx * r.uniform(0.1, 0.3);
            let round = w * r.uniform(0.05, 0.9);
            let hz = if three_d {
                lz * r.uniform(0.2, 0.8)
            } else {
                lz
            };
            let half = [w, w.max(round), hz.max(round)];
            depth = depth.min(0.5 * round);
            slide = w * r.uniform(0.05, 0.6);
            let surface = RigidSpec::RoundedBox {
                center: [lx * r.uniform(-0.1, 0.1), gap0 + half[1], 0.0],
                half_extents: half,
                radius: round,
            };
            contacts = vec![rigid_contact(&mut r, surface, e, h, depth, force_scale)];
        }
        Indenter::Plane => {
            depth = ly * r.log_uniform(1e-3, 2e-2);
            slide = depth * r.uniform(0.5, 5.0);
            let surface = RigidSpec::Plane {
                point: [0.0, gap0, 0.0],
                normal: [0.0, -1.0, 0.0],
            };
            contacts = vec![rigid_contact(&mut r, surface, e, h, depth, force_scale)];
        }
    }
    let phases = path(&mut r, gap0, depth, slide, three_d);
    let mut contacts = contacts;
    if let TargetSpec::Rigid { motion, .. } = &mut contacts[0].target {
        for c in 0..if three_d { 3 } else { 2 } {
            let mut amp = vec![(0.0, 0.0)];
            for (k, p) in phases.iter().enumerate() {
                amp.push(((k + 1) as f64, p.end[c]));
            }
            if amp.iter().all(|(_, v)| *v == 0.0) {
                continue;
            }
            motion.push(MotionSpec {
                component: [Component::X, Component::Y, Component::Z][c],
                value: Some(1.0),
                force: None,
                amplitude: amp,
            });
        }
    }
    for c in [Component::X, Component::Y] {
        responses.push(ResponseSpec::TargetForce {
            name: format!("target-force-{c:?}").to_lowercase(),
            pair: "indenter".into(),
            component: c,
        });
    }
    finish(
        seed,
        bodies,
        prescribed,
        contacts,
        steps(&phases),
        responses,
    )
}

fn rigid_contact(
    r: &mut Rng,
    surface: RigidSpec,
    e: f64,
    h: f64,
    depth: f64,
    force_scale: f64,
) -> ContactSpec {
    ContactSpec {
        name: "indenter".into(),
        hitting: "base.ymax".into(),
        target: TargetSpec::Rigid {
            surface,
            motion: Vec::new(),
        },
        normal: normal_law(r, e, h, depth),
        friction: friction(r, force_scale),
        tangential_stiffness: None,
        constraint_scale: None,
        activation: None,
        search_radius: None,
        smoothing: None,
    }
}

/// One step per phase, phase `k` ending at pseudo-time `k + 1`.
fn steps(phases: &[Phase]) -> Vec<StepSpec> {
    phases
        .iter()
        .enumerate()
        .map(|(k, p)| StepSpec {
            end: (k + 1) as f64,
            increments: p.increments,
        })
        .collect()
}

fn finish(
    seed: u64,
    bodies: Vec<BodySpec>,
    prescribed: Vec<PrescribedSpec>,
    contacts: Vec<ContactSpec>,
    steps: Vec<StepSpec>,
    responses: Vec<ResponseSpec>,
) -> Scene {
    Scene {
        name: format!("fuzz-{seed}"),
        description: format!(
            "physics fuzzer scene, seed {seed} (fricsens::studies::fuzz::generate)"
        ),
        bodies,
        free_nodes: Vec::new(),
        springs: Vec::new(),
        prescribed,
        loads: Vec::new(),
        pressures: vec![],
        shapes: vec![],
        contacts,
        steps,
        responses,
        solver: Default::default(),
        study: Default::default(),
    }
}

/// Relative tolerance of the global equilibrium check: far above the residual Newton leaves
/// (1e-9 of the reference force), far below any missing or doubled force.
pub const EQUILIBRIUM_TOL: f64 = 1e-6;
/// Relative tolerance of the Coulomb inequality `|t| <= mu p_n`: the return map puts a
/// slipping node's force on the limit to round-off, and a stick within its round-off margin.
pub const COULOMB_TOL: f64 = 1e-6;
/// Penetration of a Lagrange pair allowed, as a fraction of the smallest element size: the
/// constraint `g = 0` holds to Newton's tolerance.
pub const PENETRATION_TOL: f64 = 1e-6;
/// An augmented-Lagrangian pair's largest `|g|` at a loaded node over its tolerance that is
/// accepted: the check reads the evaluation the solver accepted, at 1 at most.
pub const CONSTRAINT_TOL: f64 = 1.0;

/// The physics checks of one converged increment.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct IncrementCheck {
    /// `|sum of reactions, loads and rigid-target forces|` over the largest of them, the
    /// worst component.
    pub equilibrium: f64,
    /// Largest `|t| / limit - 1` over the closed hitting nodes with friction (negative when
    /// every node is inside its cone), or a friction force on an open node over the force
    /// scale.
    pub coulomb: f64,
    /// Largest tensile normal force over the force scale (0 when none).
    pub tension: f64,
    /// Largest penetration of a Lagrange pair over the smallest element size.
    pub penetration: f64,
    /// Largest violation of an augmented-Lagrangian pair's constraint over its tolerance (0
    /// without such pairs).
    pub constraint: f64,
}

impl IncrementCheck {
    /// Whether every check holds.
    pub fn passes(&self) -> bool {
        self.equilibrium <= EQUILIBRIUM_TOL
            && self.coulomb <= COULOMB_TOL
            && self.tension <= COULOMB_TOL
            && self.penetration <= PENETRATION_TOL
            && self.constraint <= CONSTRAINT_TOL
    }

    /// The worse of two checks, check by check.
    fn worst(&mut self, o: &IncrementCheck) {
        self.equilibrium = self.equilibrium.max(o.equilibrium);
        self.coulomb = self.coulomb.max(o.coulomb);
        self.tension = self.tension.max(o.tension);
        self.penetration = self.penetration.max(o.penetration);
        self.constraint = self.constraint.max(o.constraint);
    }
}

/// The physics checks of a converged increment (see the module docs). `scale` is the largest
/// force of the run so far (support reactions, loads, rigid-target forces, normal forces): the
/// imbalance and the tensile forces are measured against it and it is raised to this
/// increment's largest, so that an unloaded state's round-off is not measured against its own
/// vanishing forces.
pub(crate) fn check_increment(
    c: &Converged<'_>,
    element_size: f64,
    scale: &mut f64,
) -> IncrementCheck {
    let model = c.model;
    let r = &c.eval.residual;
    let n_nodal = c.assembler.dofs.n_nodal;
    let mut out = IncrementCheck {
        coulomb: f64::NEG_INFINITY,
        ..IncrementCheck::default()
    };
    // global equilibrium, per component, against the largest force of any component: the
    // residual at the supports (the reactions), the loads and the forces of the rigid targets
    // on the bodies add up to zero (the internal forces of every element add up to zero, and
    // so do the contact forces between deformable bodies)
    let mut imbalance = [0.0f64; 3];
    let mut largest: f64 = 0.0;
    for (comp, imb) in imbalance.iter_mut().enumerate() {
        let mut sum = 0.0;
        for d in (comp..n_nodal).step_by(3) {
            if c.constrained[d] {
                sum += r[d];
                largest = largest.max(r[d].abs());
            }
        }
        // springs to the ground are supports too: their force `K u` on the node is in the
        // residual as an internal force that does not add up to zero
        let grounded = model.springs.iter().flat_map(|sp| {
            let g = &model.mesh.groups[sp.group];
            let nodes = if g.shape == Shape::Point1 {
                &g.nodes[..]
            } else {
                &[]
            };
            nodes.iter().map(move |&a| (sp, a))
        });
        for (sp, a) in grounded {
            let f: f64 = (0..3)
                .map(|j| sp.stiffness[comp][j] * c.z[crate::model::node_dof(a, j)])
                .sum();
            sum -= f;
            largest = largest.max(f.abs());
        }
        for (l, load) in model.loads.iter().enumerate() {
            if load.component == comp {
                let f = c.lifted.loads[l] * load.amplitude.at(c.time);
                sum += f;
                largest = largest.max(f.abs());
            }
        }
        for (p, pair) in model.contacts.iter().enumerate() {
            if let Target::Rigid { .. } = pair.target {
                let f = c.eval.contact.pair_force[p][comp];
                sum += f;
                largest = largest.max(f.abs());
            }
        }
        *imb = sum.abs();
    }
    let ce = &c.eval.contact;
    *scale = ce
        .normal_force
        .iter()
        .fold(scale.max(largest), |a, f| a.max(f.abs()));
    if *scale > 0.0 {
        out.equilibrium = imbalance.iter().fold(0.0f64, |a, b| a.max(*b)) / *scale;
    }
    // contact: Coulomb, tension, penetration
    let force_scale = scale.max(f64::MIN_POSITIVE);
    let mut flat = 0;
    for (p, pair) in model.contacts.iter().enumerate() {
        let nodes = flat..flat + pair.hitting.len();
        if let Some((worst, tolerance)) = crate::contact::assembly::augmented_violation(
            pair,
            &ce.normal_force[nodes.clone()],
            &ce.gap[nodes],
        ) {
            out.constraint = out.constraint.max(worst / tolerance);
        }
        for k in 0..pair.hitting.len() {
            let i = flat + k;
            let state = ce.choice[i].state;
            let p_n = ce.normal_force[i];
            let t = ce.traction[i];
            if state == crate::contact::ContactState::Open {
                out.coulomb = out.coulomb.max(t.norm() / force_scale - 1.0);
                continue;
            }
            out.tension = out.tension.max(-p_n / force_scale);
            if pair.normal == crate::contact::NormalLaw::Lagrange {
                out.penetration = out.penetration.max(-ce.gap[i] / element_size);
            }
            if let Some(law) = &pair.friction {
                let tn = t.norm();
                // the law's slip limit at this normal force: its return of a trial force far
                // outside the cone along the node's friction force
                let dir = if tn > 0.0 {
                    t / tn
                } else {
                    nalgebra::Vector3::x()
                };
                let trial = dir * (1e12 * (p_n.abs() + tn) + 1.0);
                let params = c.lifted.friction_of(p, k);
                let limit = crate::with_friction!(law, f => f.return_map(params, &trial, p_n.max(0.0), 0.0, None))
                    .traction
                    .norm();
                let v = if limit > 0.0 {
                    tn / limit - 1.0
                } else if tn > 0.0 {
                    tn / force_scale
                } else {
                    -1.0
                };
                out.coulomb = out.coulomb.max(v);
            }
        }
        flat += pair.hitting.len();
    }
    if out.coulomb == f64::NEG_INFINITY {
        out.coulomb = 0.0;
    }
    out
}

/// Why a generated scene failed.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum FailureClass {
    /// The scene did not build (a generator bug: every generated scene should be valid).
    Build,
    /// A pre-check refused the scene before the first increment.
    Precheck,
    /// Newton did not converge; the reason of the last attempt.
    Diverged(String),
    /// The run exceeded its time budget.
    TimeLimit,
    /// A converged increment failed a physics check: equilibrium.
    Equilibrium,
    /// A converged increment failed a physics check: the Coulomb inequality or tension.
    Coulomb,
    /// A converged increment failed a physics check: penetration of a Lagrange pair, or an
    /// augmented-Lagrangian pair's constraint beyond its tolerance.
    Penetration,
    /// Another analysis error.
    Other(String),
}

impl std::fmt::Display for FailureClass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FailureClass::Build => write!(f, "does not build"),
            FailureClass::Precheck => write!(f, "refused by a pre-check"),
            FailureClass::Diverged(why) => write!(f, "diverged: {why}"),
            FailureClass::TimeLimit => write!(f, "time limit"),
            FailureClass::Equilibrium => write!(f, "wrong answer: equilibrium"),
            FailureClass::Coulomb => write!(f, "wrong answer: Coulomb inequality"),
            FailureClass::Penetration => write!(f, "wrong answer: contact constraint"),
            FailureClass::Other(why) => write!(f, "{why}"),
        }
    }
}

/// What one generated scene did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaseOutcome {
    /// The seed (the scene's name is `fuzz-SEED`).
    pub seed: u64,
    /// Unknowns of the model (0 if it did not build).
    pub unknowns: usize,
    /// Whether it is a 3D scene (else plane strain).
    pub three_d: bool,
    /// Load increments the scene asks for.
    pub increments: usize,
    /// Converged increments (cut-back sub-increments included).
    pub converged: usize,
    /// Whether the whole path completed and every check held.
    pub passed: bool,
    /// Newton iterations of each converged increment.
    pub iterations: Vec<usize>,
    /// Cutbacks over the run.
    pub cutbacks: usize,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Of [`CaseOutcome::seconds`], those in assemblies, factorizations and triangular
    /// solves (every attempt's, failed ones and line searches included:
    /// [`crate::solver::PrimalCost::work_seconds`]).
    pub work_seconds: f64,
    /// The price of one Newton iteration of this scene, one assembly, one factorization and
    /// one solve at its ledger's means ([`crate::solver::PrimalCost::iteration_seconds`],
    /// an upper estimate).
    pub iteration_seconds: f64,
    /// Linear solves, every one ([`crate::solver::PrimalCost::solves`]): those of the
    /// converged increments are their [`CaseOutcome::iterations`] (the predictor's and the
    /// active-set settling's included), the rest those of failed attempts and failed
    /// augmented-Lagrangian passes.
    pub solves: usize,
    /// Newton steps the penetration limiter shortened
    /// ([`crate::solver::PrimalCost::limited_steps`]).
    pub limited_steps: usize,
    /// Why it failed.
    pub failure: Option<FailureClass>,
    /// The error message, or the failed check.
    pub message: String,
    /// The worst of every increment's checks.
    pub check: IncrementCheck,
}

struct Checker {
    element_size: f64,
    /// The largest force of the run so far.
    scale: f64,
    worst: IncrementCheck,
    first_failure: Option<(usize, IncrementCheck)>,
}

impl Observer for Checker {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        let check = check_increment(c, self.element_size, &mut self.scale);
        if !check.passes() && self.first_failure.is_none() {
            self.first_failure = Some((c.index, check.clone()));
        }
        self.worst.worst(&check);
        Ok(())
    }
}

/// Run one scene with default settings and check it (see the module docs). `time_limit`
/// bounds the wall time (seconds).
pub fn run_case(seed: u64, scene: &Scene, time_limit: Option<f64>) -> CaseOutcome {
    let start = Instant::now();
    let mut out = CaseOutcome {
        seed,
        unknowns: 0,
        three_d: !scene.prescribed.iter().any(|p| p.name == "plane-strain"),
        increments: scene.steps.iter().map(|s| s.increments).sum(),
        converged: 0,
        passed: false,
        iterations: Vec::new(),
        cutbacks: 0,
        seconds: 0.0,
        work_seconds: 0.0,
        iteration_seconds: 0.0,
        solves: 0,
        limited_steps: 0,
        failure: None,
        message: String::new(),
        check: IncrementCheck::default(),
    };
    let model = match scene.build() {
        Ok(m) => m,
        Err(e) => {
            out.failure = Some(FailureClass::Build);
            out.message = e.to_string();
            out.seconds = start.elapsed().as_secs_f64();
            return out;
        }
    };
    let h = model
        .mesh
        .smallest_edge(&model.mesh.coordinates::<f64>(&model.mesh.block_geometry()));
    // the force a strain of 1e-6 carries over one element face of the stiffest body: the
    // smallest force scale of the checks, so that the round-off of an unloaded state is not
    // measured against its own vanishing forces
    let e_max = model
        .bodies
        .iter()
        .map(|b| b.material.young())
        .fold(0.0f64, f64::max);
    let mut checker = Checker {
        element_size: h,
        scale: 1e-6 * e_max * h * h,
        worst: IncrementCheck::default(),
        first_failure: None,
    };
    let result = Solver::new(&model).and_then(|mut s| {
        out.unknowns = s.assembler.dofs.n_total;
        s.run(
            &RunOptions {
                keep_states: false,
                time_limit,
            },
            &mut checker,
        )
    });
    out.seconds = start.elapsed().as_secs_f64();
    out.check = checker.worst.clone();
    let records = match &result {
        Ok(res) => Some(&res.records),
        Err(e) => e.partial().map(|p| &p.records),
    };
    let cost = match &result {
        Ok(res) => Some(&res.cost),
        Err(e) => e.partial().map(|p| &p.cost),
    };
    if let Some(c) = cost {
        out.work_seconds = c.work_seconds();
        out.iteration_seconds = c.iteration_seconds();
        out.solves = c.solves;
        out.limited_steps = c.limited_steps;
    }
    if let Some(records) = records {
        out.converged = records.len();
        out.iterations = records.iter().map(|r| r.iterations).collect();
        out.cutbacks = records.iter().map(|r| r.cutbacks).sum();
    }
    match result {
        Err(e) => {
            out.failure = Some(match &e {
                AnalysisError::Diverged { reason, .. } => {
                    FailureClass::Diverged(reason_class(reason))
                }
                AnalysisError::TimeLimit { .. } => FailureClass::TimeLimit,
                AnalysisError::Precheck(_) => FailureClass::Precheck,
                other => FailureClass::Other(first_words(&other.to_string())),
            });
            out.message = e.to_string();
        }
        Ok(_) => {
            if let Some((inc, check)) = checker.first_failure {
                out.failure = Some(if check.equilibrium > EQUILIBRIUM_TOL {
                    FailureClass::Equilibrium
                } else if check.penetration > PENETRATION_TOL || check.constraint > CONSTRAINT_TOL {
                    FailureClass::Penetration
                } else {
                    FailureClass::Coulomb
                });
                out.message = format!("increment {inc}: {check:?}");
            } else {
                out.passed = true;
            }
        }
    }
    out
}

/// The class of a divergence reason: its words up to the first number or parenthesis (of
/// the last failed attempt, where the attempt budget ran out).
fn reason_class(reason: &str) -> String {
    let reason = match reason.split_once("the last failed attempt, to t = ") {
        Some((_, rest)) => rest.split_once(": ").map(|(_, r)| r).unwrap_or(rest),
        None => reason,
    };
    if reason.starts_with("Newton cycles with the contact states and material branches unchanged") {
        "cycle, states unchanged".into()
    } else if reason.starts_with("Newton cycles") && reason.contains("hitting node(s)") {
        // hitting nodes and Gauss points flipping together count as a contact cycle
        "cycle, contact states flipping".into()
    } else if reason.starts_with("Newton cycles") {
        "cycle, material branches flipping".into()
    } else {
        first_words(reason)
    }
}

fn first_words(s: &str) -> String {
    s.split(|c: char| c == '(' || c == ':' || c == ';' || c.is_ascii_digit())
        .next()
        .unwrap_or(s)
        .trim()
        .to_string()
}

/// The figures of a fuzzing campaign: what the report's robustness section tabulates.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// Scenes tried.
    pub tried: usize,
    /// Scenes that completed their whole path with every check holding.
    pub passed: usize,
    /// Failures per class, most frequent first.
    pub classes: Vec<(String, usize)>,
    /// Median Newton iterations per converged increment over all scenes.
    pub median_iterations: f64,
    /// 90th percentile of the iterations per converged increment.
    pub p90_iterations: f64,
    /// Per size class (`unknowns` upper bound): scenes, median seconds, largest seconds, and
    /// the largest over the median.
    pub size_classes: Vec<SizeClass>,
    /// Scenes that completed with a check failing (wrong answers).
    #[serde(default)]
    pub wrong: usize,
    /// Where the linear solves went, in the scenes over 10 x their size class's median
    /// time and in the others.
    #[serde(default)]
    pub solves_over_ten: SolveShare,
    /// See [`Summary::solves_over_ten`].
    #[serde(default)]
    pub solves_within_ten: SolveShare,
}

/// Where a set of scenes' linear solves went ([`Summary::solves_over_ten`]).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SolveShare {
    /// Scenes.
    pub scenes: usize,
    /// Their linear solves ([`CaseOutcome::solves`]).
    pub solves: usize,
    /// Their converged increments' Newton iterations.
    pub iterations: usize,
    /// Their steps the penetration limiter shortened.
    pub limited_steps: usize,
}

impl SolveShare {
    fn add(&mut self, o: &CaseOutcome) {
        self.scenes += 1;
        self.solves += o.solves;
        self.iterations += o.iterations.iter().sum::<usize>();
        self.limited_steps += o.limited_steps;
    }

    /// Percentages of the solves: in converged increments' iterations, and shortened by
    /// the penetration limiter.
    fn shares(&self) -> (f64, f64) {
        let of = |n: usize| 100.0 * n as f64 / self.solves.max(1) as f64;
        (of(self.iterations), of(self.limited_steps))
    }
}

/// Wall times of the scenes of one size class.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SizeClass {
    /// Unknowns below this bound (and at or above the previous class's).
    pub below: usize,
    /// Scenes in the class.
    pub scenes: usize,
    /// Median wall time, seconds.
    pub median_seconds: f64,
    /// Largest wall time, seconds.
    pub max_seconds: f64,
    /// Seed of the slowest scene.
    pub slowest_seed: u64,
    /// Median wall time per increment the scene asks for, seconds.
    #[serde(default)]
    pub median_per_increment: f64,
    /// Largest wall time per increment asked for, seconds, and its seed.
    #[serde(default)]
    pub max_per_increment: (f64, u64),
    /// The time target's floor: the largest wall time, over the class's median, that a
    /// complete scene would take at the class's median Newton iterations per increment
    /// asked for (each iteration one assembly, one factorization and one solve at the
    /// scene's own means, [`CaseOutcome::iteration_seconds`], and no line search; the rest
    /// of its time as it was), and its seed; `None` without a complete scene. What is left
    /// of the time ratio at uniform difficulty: the scenes' own work per iteration and path
    /// lengths.
    #[serde(default)]
    pub floor: Option<(f64, u64)>,
}

impl SizeClass {
    /// The largest wall time over the median.
    pub(crate) fn time_ratio(&self) -> f64 {
        self.max_seconds / self.median_seconds.max(1e-9)
    }

    /// The largest wall time per increment asked for over the median.
    pub(crate) fn time_ratio_per_increment(&self) -> f64 {
        self.max_per_increment.0 / self.median_per_increment.max(1e-12)
    }
}

/// [`SizeClass::floor`] of the scenes `members`, whose median wall time is `median`.
fn time_floor(members: &[&CaseOutcome], median: f64) -> Option<(f64, u64)> {
    let complete: Vec<&&CaseOutcome> = members.iter().filter(|o| o.passed).collect();
    let mut per: Vec<f64> = (complete.iter())
        .map(|o| o.iterations.iter().sum::<usize>() as f64 / o.increments.max(1) as f64)
        .collect();
    let iterations = percentile(&mut per, 0.5);
    (complete.iter())
        .map(|o| {
            let uniform = o.increments as f64 * iterations * o.iteration_seconds;
            (
                (o.seconds - o.work_seconds + uniform) / median.max(1e-9),
                o.seed,
            )
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// Wall times per size class as a markdown table (totals and per increment asked for).
fn size_class_table(classes: &[SizeClass]) -> String {
    use std::fmt::Write;
    let mut s = String::from(
        "| unknowns | scenes | median (s) | largest (s) | largest / median | slowest seed | median per increment (s) | largest per increment / median | seed | floor: largest at the median iterations / median | seed |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut lower = 0;
    for c in classes {
        let range = if c.below == usize::MAX {
            format!(">= {lower}")
        } else {
            format!("{lower} - {}", c.below)
        };
        lower = c.below;
        let _ = writeln!(
            s,
            "| {range} | {} | {:.3} | {:.3} | {:.1} | {} | {:.4} | {:.1} | {} | {} |",
            c.scenes,
            c.median_seconds,
            c.max_seconds,
            c.time_ratio(),
            c.slowest_seed,
            c.median_per_increment,
            c.time_ratio_per_increment(),
            c.max_per_increment.1,
            c.floor
                .map_or("- | -".into(), |(r, seed)| format!("{r:.1} | {seed}"))
        );
    }
    s
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    v[k]
}

/// The time target: no scene over this many times its size class's median wall time.
pub(crate) const TIME_TARGET: f64 = 10.0;

/// Upper bounds (unknowns) of the size classes.
pub(crate) const SIZE_CLASSES: [usize; 5] = [500, 1_000, 2_000, 5_000, usize::MAX];

impl Summary {
    /// The figures of `outcomes`.
    pub fn of(outcomes: &[CaseOutcome]) -> Summary {
        let mut classes = std::collections::BTreeMap::<String, usize>::new();
        for o in outcomes {
            if let Some(f) = &o.failure {
                *classes.entry(f.to_string()).or_default() += 1;
            }
        }
        let mut classes: Vec<(String, usize)> = classes.into_iter().collect();
        classes.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let mut iters: Vec<f64> = outcomes
            .iter()
            .flat_map(|o| o.iterations.iter().map(|&i| i as f64))
            .collect();
        let median_iterations = percentile(&mut iters, 0.5);
        let p90_iterations = percentile(&mut iters, 0.9);
        let mut size_classes = Vec::new();
        let (mut solves_over_ten, mut solves_within_ten) =
            (SolveShare::default(), SolveShare::default());
        let mut lower = 0;
        for &below in &SIZE_CLASSES {
            let members: Vec<&CaseOutcome> = outcomes
                .iter()
                .filter(|o| o.unknowns >= lower && o.unknowns < below)
                .collect();
            lower = below;
            if members.is_empty() {
                continue;
            }
            let mut t: Vec<f64> = members.iter().map(|o| o.seconds).collect();
            let per = |o: &CaseOutcome| o.seconds / o.increments.max(1) as f64;
            let mut t_inc: Vec<f64> = members.iter().map(|o| per(o)).collect();
            let slowest = members
                .iter()
                .max_by(|a, b| a.seconds.total_cmp(&b.seconds))
                .expect("not empty");
            let slowest_inc = members
                .iter()
                .max_by(|a, b| per(a).total_cmp(&per(b)))
                .expect("not empty");
            let median_seconds = percentile(&mut t, 0.5);
            for o in &members {
                if o.seconds > TIME_TARGET * median_seconds {
                    solves_over_ten.add(o);
                } else {
                    solves_within_ten.add(o);
                }
            }
            size_classes.push(SizeClass {
                below,
                scenes: members.len(),
                median_seconds,
                floor: time_floor(&members, median_seconds),
                max_seconds: slowest.seconds,
                slowest_seed: slowest.seed,
                median_per_increment: percentile(&mut t_inc, 0.5),
                max_per_increment: (per(slowest_inc), slowest_inc.seed),
            });
        }
        Summary {
            solves_over_ten,
            solves_within_ten,
            tried: outcomes.len(),
            passed: outcomes.iter().filter(|o| o.passed).count(),
            classes,
            median_iterations,
            p90_iterations,
            size_classes,
            wrong: outcomes
                .iter()
                .filter(|o| {
                    matches!(
                        o.failure,
                        Some(
                            FailureClass::Equilibrium
                                | FailureClass::Coulomb
                                | FailureClass::Penetration
                        )
                    )
                })
                .count(),
        }
    }

    /// The summary as Markdown (the report's robustness tables).
    pub fn markdown(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} scenes tried, {} completed their whole path with every check holding ({:.1} %); Newton iterations per converged increment: median {}, 90th percentile {}.\n",
            self.tried,
            self.passed,
            100.0 * self.passed as f64 / self.tried.max(1) as f64,
            self.median_iterations,
            self.p90_iterations
        );
        if !self.classes.is_empty() {
            let _ = writeln!(s, "| failure class | scenes |\n|---|---|");
            for (c, n) in &self.classes {
                let _ = writeln!(s, "| {c} | {n} |");
            }
            s.push('\n');
        }
        s.push_str(&size_class_table(&self.size_classes));
        s
    }
}

/// The report's robustness section: the campaign `after` against the baseline `before` (the
/// same seeds run with the solver and defaults before the robustness work), with the targets.
pub fn report_section(after: &Summary, before: Option<&Summary>, notes: &str) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let pct = |x: &Summary| 100.0 * x.passed as f64 / x.tried.max(1) as f64;
    let _ = writeln!(s, "## Robustness\n");
    let _ = writeln!(
        s,
        "`fricsens fuzz` generates random valid contact scenes a user could write (`fricsens::studies::fuzz::generate`: rigid cylinders, spheres, rounded punches and planes, or a second deformable block, pressed into graded blocks in plane strain or 3D; St Venant-Kirchhoff, Neo-Hookean and J2 bodies, E over six decades, nu up to 0.49, mu in [0, 1.5]; every normal and friction law; press, slide, unload and reload paths with random increment counts) and runs each with default settings. After every converged increment it checks global equilibrium (reactions, loads and rigid-target forces add up to zero, to 1e-6 of the largest force), the Coulomb inequality at every closed node (to 1e-6 of its slip limit), tension, penetration of Lagrange pairs (1e-6 of the smallest element), and the constraint of augmented-Lagrangian pairs (no node carrying a normal force pressed in, or held off, by more than the pair's tolerance). A scene passes when its whole path completes with every check holding.\n"
    );
    let _ = writeln!(s, "| | before | after |\n|---|---|---|");
    let b = |f: &dyn Fn(&Summary) -> String| before.map(f).unwrap_or_else(|| "-".into());
    let _ = writeln!(
        s,
        "| scenes tried | {} | {} |",
        b(&|x| x.tried.to_string()),
        after.tried
    );
    let _ = writeln!(
        s,
        "| completed with every check holding | {} | {} ({:.1} %) |",
        b(&|x| format!("{} ({:.1} %)", x.passed, pct(x))),
        after.passed,
        pct(after)
    );
    let _ = writeln!(
        s,
        "| completed with a wrong answer | {} | {} |",
        b(&|x| x.wrong.to_string()),
        after.wrong
    );
    let _ = writeln!(
        s,
        "| Newton iterations per converged increment, median / 90th percentile | {} | {} / {} |",
        b(&|x| format!("{} / {}", x.median_iterations, x.p90_iterations)),
        after.median_iterations,
        after.p90_iterations
    );
    let mut classes: Vec<String> = after.classes.iter().map(|(c, _)| c.clone()).collect();
    if let Some(bf) = before {
        for (c, _) in &bf.classes {
            if !classes.contains(c) {
                classes.push(c.clone());
            }
        }
    }
    let count = |x: &Summary, c: &str| {
        x.classes
            .iter()
            .find(|(k, _)| k == c)
            .map(|(_, n)| *n)
            .unwrap_or(0)
    };
    for c in &classes {
        let _ = writeln!(
            s,
            "| failure: {c} | {} | {} |",
            b(&|x| count(x, c).to_string()),
            count(after, c)
        );
    }
    let _ = writeln!(s, "\nWall time per size class, after (two scenes at a time on two cores; \"per increment\" divides by the increments the scene asks for):\n");
    s.push_str(&size_class_table(&after.size_classes));
    s.push('\n');
    let worst = |f: fn(&SizeClass) -> f64| after.size_classes.iter().map(f).fold(0.0, f64::max);
    let ratio = worst(SizeClass::time_ratio);
    let ratio_inc = worst(SizeClass::time_ratio_per_increment);
    let met = |ok: bool| if ok { "met" } else { "**not met**" };
    let _ = writeln!(s, "| target | measured | |\n|---|---|---|");
    let _ = writeln!(
        s,
        "| at least 99 % complete their whole path | {:.1} % | {} |",
        pct(after),
        met(pct(after) >= 99.0)
    );
    let _ = writeln!(
        s,
        "| none finishes with a wrong answer | {} | {} |",
        after.wrong,
        met(after.wrong == 0)
    );
    let _ = writeln!(
        s,
        "| median Newton iterations per increment at most 6 | {} | {} |",
        after.median_iterations,
        met(after.median_iterations <= 6.0)
    );
    let _ = writeln!(
        s,
        "| no run over 10 x the median time of its size class | {ratio:.1} x ({ratio_inc:.1} x per increment asked for) | {} |\n",
        met(ratio <= TIME_TARGET)
    );
    let floor =
        (after.size_classes.iter().filter_map(|c| c.floor)).max_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((ratio, seed)) = floor {
        let _ = writeln!(
            s,
            "The time target's floor (the table's \"floor\" column): had every complete scene taken its size class's median Newton iterations per increment asked for, each iteration one assembly, one factorization and one solve at the scene's own mean cost of each (its ledger; the assemblies' time includes the penetration limiter's gap evaluations and the incompatible modes' relaxation, so this is an upper estimate) and no line search, and the rest of its time as it was, the largest ratio would be {ratio:.1} x (seed {seed}). {}\n",
            if ratio <= TIME_TARGET {
                "The target lies above this floor: what stands between is Newton iterations and failed attempts, not the scenes' size or their work per iteration."
            } else {
                "The target lies below this floor: the scenes' work per iteration and path lengths alone spread a size class's times by more than 10 x."
            }
        );
    }
    let (over, within) = (&after.solves_over_ten, &after.solves_within_ten);
    if over.scenes > 0 {
        let ((i_over, l_over), (i_within, l_within)) = (over.shares(), within.shares());
        let _ = writeln!(
            s,
            "Where the linear solves went (`fuzz.csv`'s `solves` and `limited_steps`): the {} scenes over 10 x made {} solves, {i_over:.0} % of them Newton iterations of the increments they converged (the rest in failed attempts and failed augmented-Lagrangian passes), and the penetration limiter shortened as many Newton steps as {l_over:.0} % of their solves; the other {} scenes: {i_within:.0} % and {l_within:.0} %.\n",
            over.scenes, over.solves, within.scenes
        );
    }
    s.push_str(notes);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(seed: u64, iterations: usize, iteration_seconds: f64, passed: bool) -> CaseOutcome {
        // ten increments asked for, a tenth of a second outside the iterations' work
        let work = iterations as f64 * iteration_seconds;
        CaseOutcome {
            seed,
            unknowns: 100,
            three_d: false,
            increments: 10,
            converged: 10,
            passed,
            iterations: vec![iterations / 10; 10],
            cutbacks: 0,
            seconds: 0.1 + work,
            work_seconds: work,
            iteration_seconds,
            solves: iterations,
            limited_steps: 0,
            failure: None,
            message: String::new(),
            check: IncrementCheck::default(),
        }
    }

    /// The floor puts every complete scene at the median iterations per increment asked for
    /// (4 here), at its own cost per iteration, with the rest of its time: scene 3's five
    /// times the iterations at three times the cost per iteration take 0.1 + 40 x 0.03 =
    /// 1.3 s against the median scene's 0.5 s. The failed scene counts in neither: with its
    /// 30 iterations per increment the median would be 20 of [4, 4, 20, 30] (scene 3 at
    /// 12.2 x), and at its 50 s per iteration its own floor would be the largest.
    #[test]
    fn the_time_floor_takes_the_median_iterations_at_each_scenes_own_cost() {
        let mut failed = outcome(4, 300, 1e-4, false);
        // its wall time 0.13 s (the median stays 0.5 s), its price per iteration huge
        failed.iteration_seconds = 50.0;
        let all = [
            outcome(1, 40, 0.01, true),
            outcome(2, 40, 0.01, true),
            outcome(3, 200, 0.03, true),
            failed,
        ];
        let members: Vec<&CaseOutcome> = all.iter().collect();
        let mut t: Vec<f64> = members.iter().map(|o| o.seconds).collect();
        let median = percentile(&mut t, 0.5);
        assert_eq!(median, 0.5);
        let (ratio, seed) = time_floor(&members, median).expect("complete scenes");
        assert_eq!(seed, 3);
        assert!((ratio - 2.6).abs() < 1e-12, "{ratio}");
        // no complete scene: no floor
        assert_eq!(time_floor(&members[3..], median), None);
    }

    /// The solves' shares split the scenes at 10 x their size class's median: of four scenes
    /// of one class whose median is 0.5 s (seconds 0.5, 0.5, 6.1, 0.13), scene 3 at 6.1 s is
    /// the one over; its 100 converged iterations of 400 solves are 25 %, its 100 limited
    /// steps 25 %; the others' 380 iterations of 400 solves 95 %, none limited.
    #[test]
    fn the_solves_split_at_ten_times_the_median() {
        let mut slow = outcome(3, 100, 0.06, true);
        slow.solves = 400;
        slow.limited_steps = 100;
        let mut failed = outcome(4, 300, 1e-4, false);
        failed.solves = 320;
        let summary = Summary::of(&[
            outcome(1, 40, 0.01, true),
            outcome(2, 40, 0.01, true),
            slow,
            failed,
        ]);
        assert_eq!(summary.size_classes[0].median_seconds, 0.5);
        let (over, within) = (&summary.solves_over_ten, &summary.solves_within_ten);
        assert_eq!((over.scenes, over.solves), (1, 400));
        assert_eq!(over.shares(), (25.0, 25.0));
        assert_eq!(
            (within.scenes, within.solves, within.iterations),
            (3, 400, 380)
        );
        assert_eq!(within.shares(), (95.0, 0.0));
    }
}
