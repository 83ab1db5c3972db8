//! Face families: the shapes of boundary faces as contact and surface loads see them
//! (bilinear and serendipity quadrilaterals, linear and quadratic triangles), with their
//! interpolation on the face's natural coordinates `(s, t)`, a Gauss rule, and the share of a
//! face's area each node carries.
//!
//! ## How corner and mid-side nodes share a face's area
//! A node-to-segment contact weighs each hitting node by its tributary area. The consistent
//! weights `int N_a dA` are negative at the corners of a quad8 (`-1/12` of the area) and zero
//! at those of a tri6: a corner node would press with a negative or no area. The shares here
//! are the row-sum-free HRZ lumping (Hinton, Rock & Zienkiewicz 1976) of the face's mass
//! matrix, `int N_a^2 dA / sum_b int N_b^2 dA`, positive at every node:
//!
//! | family | corner | mid-side |
//! |---|---|---|
//! | quad4 | 1/4 | - |
//! | tri3 | 1/3 | - |
//! | quad8 | 3/76 | 4/19 |
//! | tri6 | 1/19 | 16/57 |
//!
//! (exact on an undistorted face; the tests integrate `N_a^2` to check them). A pressure load
//! keeps the consistent weights, which are what the virtual work of a pressure is.
//!
//! ## How a contact pressure is read from the nodes' forces
//! The shares above scale the penalty laws; the contact *pressure* of a hitting node is its
//! normal force over another area, its **pressure share** ([`FaceFamily::pressure_share`]):
//! the share of a uniform pressure's load that a node-to-segment contact transmits to the
//! node. On quad4, tri3 and tri6 faces that is the consistent weight (`1/4`, `1/3`; on a tri6
//! `0` at the corners and `1/3` at the mid-sides), so a uniform pressure on an undistorted
//! face is read exactly. On a quad8 the consistent corner weight `-1/12` is a pull, which a contact cannot exert: the
//! corners open (by a fraction of the elastic approach) and the four mid-sides carry the face's
//! load, a quarter each on a face of even aspect (measured on the Hertz block: every corner
//! open, the mid-sides within 1 % of `p A / 4`). The pressure shares are therefore:
//!
//! | family | corner | mid-side |
//! |---|---|---|
//! | quad4 | 1/4 | - |
//! | tri3 | 1/3 | - |
//! | quad8 | 0 | 1/4 |
//! | tri6 | 0 | 1/3 |
//!
//! A corner node of a quadratic face carries no pressure share; its pressure is the mean of
//! its faces' mid-side nodes' ([`crate::contact::ContactPair::nodal_pressures`]). The HRZ
//! shares would misread a uniform pressure by the ratio of the two tables (mid-sides of a
//! tri6 by 57/48, of a quad8 by 19/16).

// the Gauss rules' digits as published (rounded to f64 on reading)
#![allow(clippy::excessive_precision)]

use crate::scalar::{safe_norm, Scalar};
use nalgebra::Vector3;

/// Most nodes of any face family.
pub const MAX_FACE_NODES: usize = 8;

/// A face's shape functions at a point: values `n`, first derivatives `d` (`[d/ds, d/dt]`)
/// and second derivatives `dd` (`[d2/ds2, d2/dsdt, d2/dt2]`), the first `n_nodes` entries.
#[derive(Clone, Copy, Debug)]
pub struct FaceShape<S> {
    /// `N_a`.
    pub n: [S; MAX_FACE_NODES],
    /// `[N_a,s, N_a,t]`.
    pub d: [[S; 2]; MAX_FACE_NODES],
    /// `[N_a,ss, N_a,st, N_a,tt]`.
    pub dd: [[S; 3]; MAX_FACE_NODES],
}

/// The shape of a boundary face as contact and surface loads see it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum FaceFamily {
    /// Four-node bilinear quadrilateral, nodes counter-clockwise seen from outside.
    Quad4,
    /// Three-node triangle, counter-clockwise seen from outside.
    Tri3,
    /// Six-node quadratic triangle: the corners, then the middles of edges `01, 12, 20`.
    Tri6,
    /// Eight-node serendipity quadrilateral: the corners, then the middles of edges `01, 12,
    /// 23, 30`.
    Quad8,
}

/// Natural coordinates of the quadrilaterals' nodes.
const QUAD_ST: [[f64; 2]; 8] = [
    [-1.0, -1.0],
    [1.0, -1.0],
    [1.0, 1.0],
    [-1.0, 1.0],
    [0.0, -1.0],
    [1.0, 0.0],
    [0.0, 1.0],
    [-1.0, 0.0],
];

/// Triangle edges in the order of tri6's mid-side nodes.
const TRI_EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];

const G2: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)
const G3: f64 = 0.774_596_669_241_483_4; // sqrt(3/5)
const W5: f64 = 5.0 / 9.0;
const W8: f64 = 8.0 / 9.0;
const DA: f64 = 0.445_948_490_915_964_886;
const DWA: f64 = 0.5 * 0.223_381_589_678_011_466;
const DB: f64 = 0.091_576_213_509_770_743;
const DWB: f64 = 0.5 * 0.109_951_743_655_321_868;

/// Gauss points `(s, t)` and weights on the bilinear quad (2x2).
static QUAD_2X2: [([f64; 2], f64); 4] = [
    ([-G2, -G2], 1.0),
    ([G2, -G2], 1.0),
    ([G2, G2], 1.0),
    ([-G2, G2], 1.0),
];

/// Gauss points on the serendipity quad (3x3).
static QUAD_3X3: [([f64; 2], f64); 9] = [
    ([-G3, -G3], W5 * W5),
    ([0.0, -G3], W8 * W5),
    ([G3, -G3], W5 * W5),
    ([-G3, 0.0], W5 * W8),
    ([0.0, 0.0], W8 * W8),
    ([G3, 0.0], W5 * W8),
    ([-G3, G3], W5 * W5),
    ([0.0, G3], W8 * W5),
    ([G3, G3], W5 * W5),
];

/// The centroid of the unit triangle (exact for tri3's constant Jacobian).
static TRI_1: [([f64; 2], f64); 1] = [([1.0 / 3.0, 1.0 / 3.0], 0.5)];

/// Dunavant's 6-point rule of degree 4 on the unit triangle (tri6's `N_a (x_s x x_t)`).
static TRI_6: [([f64; 2], f64); 6] = [
    ([DA, DA], DWA),
    ([1.0 - 2.0 * DA, DA], DWA),
    ([DA, 1.0 - 2.0 * DA], DWA),
    ([DB, DB], DWB),
    ([1.0 - 2.0 * DB, DB], DWB),
    ([DB, 1.0 - 2.0 * DB], DWB),
];

impl FaceFamily {
    /// Every face family.
    pub const ALL: [FaceFamily; 4] = [
        FaceFamily::Quad4,
        FaceFamily::Tri3,
        FaceFamily::Tri6,
        FaceFamily::Quad8,
    ];

    /// Short name (`quad4`, `tri3`, `tri6`, `quad8`).
    pub fn name(self) -> &'static str {
        match self {
            FaceFamily::Quad4 => "quad4",
            FaceFamily::Tri3 => "tri3",
            FaceFamily::Tri6 => "tri6",
            FaceFamily::Quad8 => "quad8",
        }
    }

    /// Number of nodes.
    pub fn n_nodes(self) -> usize {
        match self {
            FaceFamily::Quad4 => 4,
            FaceFamily::Tri3 => 3,
            FaceFamily::Tri6 => 6,
            FaceFamily::Quad8 => 8,
        }
    }

    /// Number of corner nodes (the first ones).
    pub fn n_corners(self) -> usize {
        match self {
            FaceFamily::Quad4 | FaceFamily::Quad8 => 4,
            FaceFamily::Tri3 | FaceFamily::Tri6 => 3,
        }
    }

    /// Whether its natural domain is the unit triangle (else the square `[-1, 1]^2`).
    pub fn is_triangle(self) -> bool {
        matches!(self, FaceFamily::Tri3 | FaceFamily::Tri6)
    }

    /// Whether its edges are curved (quadratic).
    pub fn is_quadratic(self) -> bool {
        matches!(self, FaceFamily::Tri6 | FaceFamily::Quad8)
    }

    /// Natural coordinates of node `a`.
    pub fn node_st(self, a: usize) -> [f64; 2] {
        if self.is_triangle() {
            const T: [[f64; 2]; 6] = [
                [0.0, 0.0],
                [1.0, 0.0],
                [0.0, 1.0],
                [0.5, 0.0],
                [0.5, 0.5],
                [0.0, 0.5],
            ];
            T[a]
        } else {
            QUAD_ST[a]
        }
    }

    /// Shape functions at `(s, t)` (the first `n_nodes` entries) and their derivatives
    /// `[dN/ds, dN/dt]`.
    pub fn shape(self, st: [f64; 2]) -> ([f64; MAX_FACE_NODES], [[f64; 2]; MAX_FACE_NODES]) {
        let f = self.interpolation(st);
        (f.n, f.d)
    }

    /// Shape functions, first and second derivatives at `(s, t)`, in any scalar (a contact
    /// point's `xi` carries the derivatives of the projection).
    // the node number addresses the natural coordinates and the three outputs alike
    #[allow(clippy::needless_range_loop)]
    pub fn interpolation<S: Scalar>(self, st: [S; 2]) -> FaceShape<S> {
        let (s, t) = (st[0], st[1]);
        let one = S::one();
        let z = S::zero();
        let mut f = FaceShape {
            n: [z; MAX_FACE_NODES],
            d: [[z; 2]; MAX_FACE_NODES],
            dd: [[z; 3]; MAX_FACE_NODES],
        };
        match self {
            FaceFamily::Quad4 => {
                for a in 0..4 {
                    let [sa, ta] = QUAD_ST[a];
                    let (fs, ft) = (one + s * sa, one + t * ta);
                    f.n[a] = fs * ft * 0.25;
                    f.d[a] = [ft * (0.25 * sa), fs * (0.25 * ta)];
                    f.dd[a] = [z, S::lift(0.25 * sa * ta), z];
                }
            }
            FaceFamily::Quad8 => {
                for a in 0..4 {
                    let [sa, ta] = QUAD_ST[a];
                    let (fs, ft) = (one + s * sa, one + t * ta);
                    f.n[a] = fs * ft * (s * sa + t * ta - 1.0) * 0.25;
                    f.d[a] = [
                        ft * (s * (2.0 * sa) + t * ta) * (0.25 * sa),
                        fs * (s * sa + t * (2.0 * ta)) * (0.25 * ta),
                    ];
                    f.dd[a] = [
                        ft * 0.5,
                        (s * (2.0 * sa) + t * (2.0 * ta) + 1.0) * (0.25 * sa * ta),
                        fs * 0.5,
                    ];
                }
                for a in 4..8 {
                    let [sa, ta] = QUAD_ST[a];
                    if sa == 0.0 {
                        let ft = one + t * ta;
                        f.n[a] = (one - s * s) * ft * 0.5;
                        f.d[a] = [-s * ft, (one - s * s) * (0.5 * ta)];
                        f.dd[a] = [-ft, -s * ta, z];
                    } else {
                        let fs = one + s * sa;
                        f.n[a] = fs * (one - t * t) * 0.5;
                        f.d[a] = [(one - t * t) * (0.5 * sa), -t * fs];
                        f.dd[a] = [z, -t * sa, -fs];
                    }
                }
            }
            FaceFamily::Tri3 | FaceFamily::Tri6 => {
                let l = [one - s - t, s, t];
                const DL: [[f64; 2]; 3] = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
                if self == FaceFamily::Tri3 {
                    f.n[..3].copy_from_slice(&l);
                    for (d, dl) in f.d.iter_mut().zip(DL) {
                        *d = dl.map(S::lift);
                    }
                } else {
                    for a in 0..3 {
                        let g = l[a] * 4.0 - 1.0;
                        f.n[a] = l[a] * (l[a] * 2.0 - 1.0);
                        f.d[a] = [g * DL[a][0], g * DL[a][1]];
                        f.dd[a] = [
                            4.0 * DL[a][0] * DL[a][0],
                            4.0 * DL[a][0] * DL[a][1],
                            4.0 * DL[a][1] * DL[a][1],
                        ]
                        .map(S::lift);
                    }
                    for (m, [a, b]) in TRI_EDGES.iter().enumerate() {
                        let (la, lb, da, db) = (l[*a], l[*b], DL[*a], DL[*b]);
                        f.n[3 + m] = la * lb * 4.0;
                        f.d[3 + m] = [
                            (lb * da[0] + la * db[0]) * 4.0,
                            (lb * da[1] + la * db[1]) * 4.0,
                        ];
                        f.dd[3 + m] = [
                            4.0 * 2.0 * da[0] * db[0],
                            4.0 * (da[0] * db[1] + db[0] * da[1]),
                            4.0 * 2.0 * da[1] * db[1],
                        ]
                        .map(S::lift);
                    }
                }
            }
        }
        f
    }

    /// Natural coordinates of the face's centre (`(0, 0)` on a quad, the centroid of a
    /// triangle).
    pub fn centre_st(self) -> [f64; 2] {
        if self.is_triangle() {
            [1.0 / 3.0, 1.0 / 3.0]
        } else {
            [0.0, 0.0]
        }
    }

    /// Whether `(s, t)` lies in the natural domain, widened by `tolerance`.
    pub fn contains(self, st: [f64; 2], tolerance: f64) -> bool {
        if self.is_triangle() {
            st[0] >= -tolerance && st[1] >= -tolerance && st[0] + st[1] <= 1.0 + tolerance
        } else {
            st[0].abs() <= 1.0 + tolerance && st[1].abs() <= 1.0 + tolerance
        }
    }

    /// How far `st` lies outside the natural domain (0 inside), in `ξ`: the largest amount by
    /// which one of the domain's bounding inequalities ([`FaceFamily::contains`]) fails.
    pub fn distance_outside(self, st: [f64; 2]) -> f64 {
        if self.is_triangle() {
            (-st[0]).max(-st[1]).max(st[0] + st[1] - 1.0).max(0.0)
        } else {
            (st[0].abs() - 1.0).max(st[1].abs() - 1.0).max(0.0)
        }
    }

    /// The edges of the natural domain as pairs of corner numbers (counter-clockwise), each a
    /// straight line in `(s, t)` from the first corner's coordinates to the second's.
    pub fn edges(self) -> &'static [[usize; 2]] {
        if self.is_triangle() {
            &TRI_EDGES
        } else {
            &[[0, 1], [1, 2], [2, 3], [3, 0]]
        }
    }

    /// A Gauss rule on the natural domain, `(point, weight)`: exact for the face's
    /// `N_a (x_s x x_t)` on an undistorted face (2x2 for quad4, 3x3 for quad8, the centroid
    /// for tri3, Dunavant's degree-4 rule for tri6).
    pub fn rule(self) -> &'static [([f64; 2], f64)] {
        match self {
            FaceFamily::Quad4 => &QUAD_2X2,
            FaceFamily::Quad8 => &QUAD_3X3,
            FaceFamily::Tri3 => &TRI_1,
            FaceFamily::Tri6 => &TRI_6,
        }
    }

    /// Position and covariant tangents `x_s`, `x_t` at `(s, t)` of the face with nodes `x`.
    pub fn point<S: Scalar>(
        self,
        x: &[Vector3<S>],
        st: [f64; 2],
    ) -> (Vector3<S>, Vector3<S>, Vector3<S>) {
        let (n, d) = self.shape(st);
        let mut p = Vector3::<S>::zeros();
        let mut ts = Vector3::<S>::zeros();
        let mut tt = Vector3::<S>::zeros();
        for (a, xa) in x.iter().enumerate().take(self.n_nodes()) {
            p += xa * S::lift(n[a]);
            ts += xa * S::lift(d[a][0]);
            tt += xa * S::lift(d[a][1]);
        }
        (p, ts, tt)
    }

    /// Area of a face with node coordinates `x` (in the family's node order): reference or
    /// deformed, whichever `x` holds. Quad4: the two triangles `(0, 1, 3)` and `(2, 3, 1)`,
    /// exact for a planar face; tri3 exact; the quadratic faces by their Gauss rule.
    /// Generic in the scalar, so that a shape parameter's dual part reaches the area.
    pub fn area<S: Scalar>(self, x: &[Vector3<S>]) -> S {
        match self {
            FaceFamily::Quad4 => {
                safe_norm(&(x[1] - x[0]).cross(&(x[3] - x[0]))) * 0.5
                    + safe_norm(&(x[3] - x[2]).cross(&(x[1] - x[2]))) * 0.5
            }
            FaceFamily::Tri3 => safe_norm(&(x[1] - x[0]).cross(&(x[2] - x[0]))) * 0.5,
            FaceFamily::Tri6 | FaceFamily::Quad8 => {
                let mut a = S::zero();
                for (st, w) in self.rule() {
                    let (_, ts, tt) = self.point(x, *st);
                    a += safe_norm(&ts.cross(&tt)) * S::lift(*w);
                }
                a
            }
        }
    }

    /// The share of a face's area `area` that node `a` of the face carries (tributary
    /// areas; the module docs' table).
    pub fn tributary_share<S: Scalar>(self, area: S, a: usize) -> S {
        let corner = a < self.n_corners();
        match self {
            FaceFamily::Quad4 => area / 4.0,
            FaceFamily::Tri3 => area / 3.0,
            FaceFamily::Quad8 if corner => area * (3.0 / 76.0),
            FaceFamily::Quad8 => area * (4.0 / 19.0),
            FaceFamily::Tri6 if corner => area * (1.0 / 19.0),
            FaceFamily::Tri6 => area * (16.0 / 57.0),
        }
    }

    /// The share of a face's area `area` a node `a` of the face reads its contact pressure over
    /// (the module docs' second table): the consistent weights where they are not a pull,
    /// the mid-sides' quarter on a quad8.
    pub fn pressure_share<S: Scalar>(self, area: S, a: usize) -> S {
        let corner = a < self.n_corners();
        match self {
            FaceFamily::Quad4 => area / 4.0,
            FaceFamily::Tri3 => area / 3.0,
            FaceFamily::Quad8 | FaceFamily::Tri6 if corner => S::zero(),
            FaceFamily::Quad8 => area / 4.0,
            FaceFamily::Tri6 => area / 3.0,
        }
    }

    /// The consistent nodal weights of a unit normal traction, `int N_a (x_s x x_t) ds dt`
    /// (the area vector each node carries; negative at quad8's corners, which is what the
    /// virtual work of a pressure is). Quad4 keeps its own 2x2 loop, bit for bit as before.
    pub fn normal_weights<S: Scalar>(self, x: &[Vector3<S>]) -> [Vector3<S>; MAX_FACE_NODES] {
        let mut out = [Vector3::<S>::zeros(); MAX_FACE_NODES];
        for (st, w) in self.rule() {
            let (n, _) = self.shape(*st);
            let (_, ts, tt) = self.point(x, *st);
            let nda = ts.cross(&tt) * S::lift(*w);
            for (o, na) in out.iter_mut().zip(&n).take(self.n_nodes()) {
                *o += nda * S::lift(*na);
            }
        }
        out
    }

    /// The largest distance across a face (quads: the longer diagonal of the corners;
    /// triangles: the longest corner edge): the face's size for contact search radii.
    pub fn diameter(self, x: &[Vector3<f64>]) -> f64 {
        if self.is_triangle() {
            (x[1] - x[0])
                .norm()
                .max((x[2] - x[1]).norm())
                .max((x[0] - x[2]).norm())
        } else {
            (x[2] - x[0]).norm().max((x[3] - x[1]).norm())
        }
    }

    /// The face's centre: the mean of its corner nodes.
    pub fn centre(self, x: &[Vector3<f64>]) -> Vector3<f64> {
        match self {
            FaceFamily::Quad4 | FaceFamily::Quad8 => (x[0] + x[1] + x[2] + x[3]) / 4.0,
            FaceFamily::Tri3 | FaceFamily::Tri6 => (x[0] + x[1] + x[2]) / 3.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact `int s^i t^j` over the natural domain.
    fn monomial(family: FaceFamily, i: u32, j: u32) -> f64 {
        let fact = |n: u32| (1..=n).map(f64::from).product::<f64>();
        if family.is_triangle() {
            fact(i) * fact(j) / fact(i + j + 2)
        } else {
            let one = |k: u32| {
                if k % 2 == 1 {
                    0.0
                } else {
                    2.0 / f64::from(k + 1)
                }
            };
            one(i) * one(j)
        }
    }

    #[test]
    fn rules_integrate_their_degree_exactly() {
        for (family, degree) in [
            (FaceFamily::Quad4, 3),
            (FaceFamily::Quad8, 5),
            (FaceFamily::Tri3, 1),
            (FaceFamily::Tri6, 4),
        ] {
            for i in 0..=degree {
                for j in 0..=degree - i {
                    let q: f64 = family
                        .rule()
                        .iter()
                        .map(|(st, w)| w * st[0].powi(i as i32) * st[1].powi(j as i32))
                        .sum();
                    let exact = monomial(family, i, j);
                    assert!(
                        (q - exact).abs() < 1e-15,
                        "{family:?} s^{i} t^{j}: {q} {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn shape_functions_interpolate_and_derivatives_are_their_slopes() {
        for family in FaceFamily::ALL {
            let nn = family.n_nodes();
            for a in 0..nn {
                let (n, _) = family.shape(family.node_st(a));
                for (b, v) in n.iter().enumerate().take(nn) {
                    let expected = if a == b { 1.0 } else { 0.0 };
                    assert!((v - expected).abs() < 1e-14, "{family:?} N_{b} at node {a}");
                }
            }
            let st = [0.21, 0.33];
            let h = 1e-6;
            let (n, d) = family.shape(st);
            assert!((n[..nn].iter().sum::<f64>() - 1.0).abs() < 1e-14);
            for k in 0..2 {
                let (mut p, mut m) = (st, st);
                p[k] += h;
                m[k] -= h;
                let (np, nm) = (family.shape(p).0, family.shape(m).0);
                for a in 0..nn {
                    let fd = (np[a] - nm[a]) / (2.0 * h);
                    // central difference of a quadratic: exact up to round-off 1e-16 / 1e-6
                    assert!((fd - d[a][k]).abs() < 1e-9, "{family:?} dN_{a}/d{k}");
                }
            }
        }
    }

    #[test]
    fn second_derivatives_are_the_slopes_of_the_first() {
        for family in FaceFamily::ALL {
            let st = [0.23, 0.31];
            let h = 1e-6;
            let f = family.interpolation(st);
            for k in 0..2 {
                let (mut p, mut m) = (st, st);
                p[k] += h;
                m[k] -= h;
                let (dp, dm) = (family.interpolation(p).d, family.interpolation(m).d);
                for a in 0..family.n_nodes() {
                    for j in 0..2 {
                        // d/d(st_k) of dN/d(st_j): entry k + j of [ss, st, tt]
                        let fd = (dp[a][j] - dm[a][j]) / (2.0 * h);
                        assert!(
                            (fd - f.dd[a][k + j]).abs() < 1e-8,
                            "{family:?} N_{a},{k}{j}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn tributary_shares_are_the_lumped_mass_ratios() {
        // HRZ: int N_a^2 over the undistorted face, normalised (module docs' table)
        for family in FaceFamily::ALL {
            let nn = family.n_nodes();
            let mut m = [0.0; MAX_FACE_NODES];
            for (st, w) in family.rule() {
                let (n, _) = family.shape(*st);
                for a in 0..nn {
                    m[a] += w * n[a] * n[a];
                }
            }
            // each rule is exact for its N_a^2 (quad8: degree 4 per axis, tri6: degree 4),
            // but tri3's centroid, where the three equal values give the exact shares
            let total: f64 = m[..nn].iter().sum();
            for (a, ma) in m.iter().enumerate().take(nn) {
                let share = family.tributary_share(1.0, a);
                assert!(share > 0.0);
                assert!(
                    (share - ma / total).abs() < 1e-12,
                    "{family:?} node {a}: {share} vs {}",
                    ma / total
                );
            }
            let sum: f64 = (0..nn).map(|a| family.tributary_share(1.0, a)).sum();
            assert!((sum - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn pressure_shares_are_the_transmissible_consistent_loads() {
        // the consistent load share int N_a dA / A of a uniform pressure on the undistorted
        // face: the pressure share wherever it is not a pull; a quad8's corners (-1/12) open
        // and its mid-sides take a quarter each
        for family in FaceFamily::ALL {
            let nn = family.n_nodes();
            let mut c = [0.0; MAX_FACE_NODES];
            let mut area = 0.0;
            for (st, w) in family.rule() {
                let (n, _) = family.shape(*st);
                area += w;
                for a in 0..nn {
                    c[a] += w * n[a];
                }
            }
            for (a, ca) in c.iter().enumerate().take(nn) {
                let consistent = ca / area;
                let share = family.pressure_share(1.0, a);
                let corner = a < family.n_corners();
                if family == FaceFamily::Quad8 {
                    let want = if corner { -1.0 / 12.0 } else { 1.0 / 3.0 };
                    assert!((consistent - want).abs() < 1e-14, "quad8 node {a}");
                    assert_eq!(share, if corner { 0.0 } else { 0.25 });
                } else {
                    assert!((share - consistent).abs() < 1e-14, "{family:?} node {a}");
                }
                if !family.is_quadratic() {
                    assert_eq!(share, family.tributary_share(1.0, a), "{family:?}");
                }
            }
            let sum: f64 = (0..nn).map(|a| family.pressure_share(1.0, a)).sum();
            assert!((sum - 1.0).abs() < 1e-15, "{family:?}");
        }
    }

    #[test]
    fn areas_and_normal_weights_of_flat_faces() {
        // a 2 x 3 rectangle and the right triangle of legs 2 and 3, with straight-edge
        // mid-side nodes, in the plane z = 1
        let corners = |family: FaceFamily| -> Vec<Vector3<f64>> {
            (0..family.n_nodes())
                .map(|a| {
                    let [s, t] = family.node_st(a);
                    if family.is_triangle() {
                        Vector3::new(2.0 * s, 3.0 * t, 1.0)
                    } else {
                        Vector3::new(1.0 + s, 1.5 * (1.0 + t), 1.0)
                    }
                })
                .collect()
        };
        for family in FaceFamily::ALL {
            let x = corners(family);
            let area = if family.is_triangle() { 3.0 } else { 6.0 };
            assert!((family.area(&x) - area).abs() < 1e-13, "{family:?}");
            let w = family.normal_weights(&x);
            let total: Vector3<f64> = w.iter().sum();
            assert!((total - Vector3::new(0.0, 0.0, area)).norm() < 1e-13);
            // consistent weights: quad8 corners -1/12, mid-sides 1/3; tri6 corners 0
            match family {
                FaceFamily::Quad8 => {
                    assert!((w[0].z + area / 12.0).abs() < 1e-13);
                    assert!((w[4].z - area / 3.0).abs() < 1e-13);
                }
                FaceFamily::Tri6 => {
                    assert!(w[0].z.abs() < 1e-13);
                    assert!((w[3].z - area / 3.0).abs() < 1e-13);
                }
                _ => {}
            }
        }
    }
}
