//! The one scalar bound every kernel is generic over.
//!
//! A kernel written once as `fn kernel<S: Scalar>(..)` serves four uses:
//!
//! * `S = f64`: the primal analysis, SDM's finite-perturbation unbalance forces and FDM's reruns;
//! * `S = Dual64`: one design parameter seeded, the derivative part is the exact partial (DDM);
//! * `S = DualSVec64<N>`: N design parameters at once (batched DDM), or N element DOFs at once
//!   (a tangent by forward AD);
//! * `S = `[`Rev`]: reverse mode on a tape, a vector-Jacobian product of an element or a
//!   hitting node in one sweep (the adjoint's local derivatives).
//!
//! Rules every kernel follows (see `shared/style.md`):
//! * branch decisions (elastic/plastic, stick/slip, open/closed) are taken on real parts, with
//!   [`re`] written out, never through `PartialOrd` on the dual itself;
//! * square roots of quantities that may be exactly zero (a zero deviator, a zero slip) go
//!   through [`safe_sqrt`] or [`safe_norm`], whose derivative at zero is taken as zero instead of
//!   the NaN that `sqrt` gives.

use nalgebra::{Matrix3, SVector, Vector3};
use num_dual::{Derivative, Dual64, DualNum, DualSVec64};

pub mod tape;
pub use tape::Rev;

/// Scalar type of every kernel: `f64`, [`Dual64`], [`DualSVec64<N>`] or [`Rev`].
///
/// Beyond `DualNum<Primitive = f64>` it gives uniform access to the derivative parts, which the
/// sensitivity engine needs to seed parameters and to read results, whatever the dual width.
pub trait Scalar: DualNum<Primitive = f64> + Copy + Send + Sync + 'static {
    /// Number of derivative directions carried (0 for `f64` and [`Rev`]).
    const NPARTS: usize;

    /// Whether the scalar carries derivatives at all (forward parts or a tape): `false` for
    /// `f64` alone, where a kernel may take a plain-value shortcut.
    const DIFFERENTIATES: bool = Self::NPARTS > 0 || Self::RECORDS;

    /// Whether operations record on a thread's tape ([`Rev`]): an evaluation in it must run
    /// on one thread, the one whose tape it records on (the assembler then evaluates its
    /// elements on the calling thread).
    const RECORDS: bool = false;

    /// The real part (value).
    fn value(&self) -> f64;

    /// Whether the number depends on nothing differentiated: every forward part zero, no
    /// tape entry. A kernel may then compute with its value in `f64` and lift the result:
    /// the same value to the bit where the `f64` operations round as the scalar's do (sums,
    /// differences, products, `recip`; not a quotient of two scalars, which the dual
    /// numbers and [`Rev`] take as a product by the reciprocal), no tape entry either way,
    /// and derivative parts of `+0` where the scalar's arithmetic may have left a `-0`.
    fn is_constant(&self) -> bool;

    /// Derivative part number `k` (`k < NPARTS`); `0.0` when out of range.
    fn part(&self, k: usize) -> f64;

    /// A scalar with value `re` and the given derivative parts; missing parts are zero and
    /// surplus parts are ignored.
    fn with_parts(re: f64, parts: &[f64]) -> Self;

    /// A constant: value `re`, every derivative part zero.
    #[inline]
    fn lift(re: f64) -> Self {
        Self::from(re)
    }

    /// The independent variable number `k`: value `re`, derivative part `k` equal to one.
    /// For `f64` (no parts) this is the plain value.
    #[inline]
    fn seeded(re: f64, k: usize) -> Self {
        let mut parts = [0.0; 64];
        let n = Self::NPARTS.min(64);
        if k < n {
            parts[k] = 1.0;
        }
        Self::with_parts(re, &parts[..n])
    }

    /// `self + a * b`, rounded as written (a product, then a sum: no fused multiply-add),
    /// so that every scalar's value is the `f64` one. A [`Rev`] records it as one tape entry
    /// where a factor is a constant (the sums of products with constant coefficients of the
    /// kinematics and of the nodal forces) instead of two, with the same adjoints to the bit
    /// (the product's entry would have passed its adjoint on, in the same place of the
    /// sweep).
    #[inline]
    fn add_mul(self, a: Self, b: Self) -> Self {
        self + a * b
    }

    /// All derivative parts, written into `out` (length `NPARTS`).
    #[inline]
    fn parts_into(&self, out: &mut [f64]) {
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.part(k);
        }
    }
}

impl Scalar for f64 {
    const NPARTS: usize = 0;
    #[inline]
    fn value(&self) -> f64 {
        *self
    }
    #[inline]
    fn is_constant(&self) -> bool {
        true
    }
    #[inline]
    fn part(&self, _k: usize) -> f64 {
        0.0
    }
    #[inline]
    fn with_parts(re: f64, _parts: &[f64]) -> Self {
        re
    }
}

impl Scalar for Dual64 {
    const NPARTS: usize = 1;
    #[inline]
    fn value(&self) -> f64 {
        self.re
    }
    #[inline]
    fn is_constant(&self) -> bool {
        self.eps == 0.0
    }
    #[inline]
    fn part(&self, k: usize) -> f64 {
        if k == 0 {
            self.eps
        } else {
            0.0
        }
    }
    #[inline]
    fn with_parts(re: f64, parts: &[f64]) -> Self {
        Dual64::new(re, parts.first().copied().unwrap_or(0.0))
    }
}

impl<const N: usize> Scalar for DualSVec64<N> {
    const NPARTS: usize = N;
    #[inline]
    fn value(&self) -> f64 {
        self.re
    }
    #[inline]
    fn is_constant(&self) -> bool {
        self.eps
            .0
            .as_ref()
            .is_none_or(|m| m.iter().all(|p| *p == 0.0))
    }
    #[inline]
    fn part(&self, k: usize) -> f64 {
        match &self.eps.0 {
            Some(m) if k < N => m[k],
            _ => 0.0,
        }
    }
    #[inline]
    fn with_parts(re: f64, parts: &[f64]) -> Self {
        if parts.iter().all(|p| *p == 0.0) {
            return DualSVec64::from_re(re);
        }
        let mut v = SVector::<f64, N>::zeros();
        for (k, p) in parts.iter().take(N).enumerate() {
            v[k] = *p;
        }
        DualSVec64::new(re, Derivative::some(v))
    }
}

/// The real part of any scalar (free-function form, reads well in branch conditions).
#[inline]
pub fn re<S: Scalar>(x: S) -> f64 {
    x.value()
}

/// Lift a plain value to a constant of the scalar type.
#[inline]
pub fn lift<S: Scalar>(x: f64) -> S {
    S::lift(x)
}

/// `sqrt(x)` whose derivative parts are zero (not NaN) where `x` is exactly zero.
#[inline]
pub fn safe_sqrt<S: Scalar>(x: S) -> S {
    if x.re() <= 0.0 {
        S::zero()
    } else {
        x.sqrt()
    }
}

/// Euclidean norm of a 3-vector, zero-safe (see [`safe_sqrt`]).
#[inline]
pub fn safe_norm<S: Scalar>(v: &Vector3<S>) -> S {
    safe_sqrt(v.dot(v))
}

/// Frobenius norm of a 3x3 tensor, zero-safe.
#[inline]
pub fn safe_norm_tensor<S: Scalar>(a: &Matrix3<S>) -> S {
    safe_sqrt(a.component_mul(a).sum())
}

/// Lift a plain vector to the scalar type.
#[inline]
pub fn lift_vec<S: Scalar>(v: &Vector3<f64>) -> Vector3<S> {
    v.map(S::lift)
}

/// Real parts of a vector.
#[inline]
pub fn re_vec<S: Scalar>(v: &Vector3<S>) -> Vector3<f64> {
    v.map(|x| x.value())
}

/// Real parts of a tensor.
#[inline]
pub fn re_mat<S: Scalar>(a: &Matrix3<S>) -> Matrix3<f64> {
    a.map(|x| x.value())
}

/// Determinant of a 3x3 matrix by cofactors (generic; no `RealField` needed).
#[inline]
pub fn det3<S: Scalar>(a: &Matrix3<S>) -> S {
    a[(0, 0)] * (a[(1, 1)] * a[(2, 2)] - a[(1, 2)] * a[(2, 1)])
        - a[(0, 1)] * (a[(1, 0)] * a[(2, 2)] - a[(1, 2)] * a[(2, 0)])
        + a[(0, 2)] * (a[(1, 0)] * a[(2, 1)] - a[(1, 1)] * a[(2, 0)])
}

/// Inverse and determinant of a 3x3 matrix by cofactors; `None` when the real part of the
/// determinant is zero or not finite.
#[inline]
pub fn inv3<S: Scalar>(a: &Matrix3<S>) -> Option<(Matrix3<S>, S)> {
    let d = det3(a);
    let dr = d.re();
    if dr == 0.0 || !dr.is_finite() {
        return None;
    }
    let c = |i: usize, j: usize, k: usize, l: usize| a[(i, j)] * a[(k, l)] - a[(i, l)] * a[(k, j)];
    let cof = Matrix3::new(
        c(1, 1, 2, 2),
        -c(0, 1, 2, 2),
        c(0, 1, 1, 2),
        -c(1, 0, 2, 2),
        c(0, 0, 2, 2),
        -c(0, 0, 1, 2),
        c(1, 0, 2, 1),
        -c(0, 0, 2, 1),
        c(0, 0, 1, 1),
    );
    // `cof` as written is already the adjugate (transpose of the cofactor matrix).
    let inv_d = d.recip();
    Some((cof * inv_d, d))
}

/// `a x` as nalgebra's product makes it, a column of `a` at a time (every row's first term,
/// then every row's second, ...), through [`Scalar::add_mul`]: the same values (and, for a
/// [`Rev`], the same tape order, so the same adjoints) to the bit, but the derivative parts
/// of a [`Dual64`], whose zeros may keep a sign nalgebra's `1 * a` turns to `+0`. nalgebra's
/// generic product of small matrices is a chain of calls that a recording's scalars keep the
/// compiler from inlining, and two tape entries a term where one entry does.
#[inline(always)]
pub fn mat_vec<S: Scalar>(a: &Matrix3<S>, x: &Vector3<S>) -> Vector3<S> {
    let mut y = Vector3::new(a[(0, 0)] * x[0], a[(1, 0)] * x[0], a[(2, 0)] * x[0]);
    for j in 1..3 {
        for i in 0..3 {
            y[i] = y[i].add_mul(a[(i, j)], x[j]);
        }
    }
    y
}

/// `a b`, a column at a time as nalgebra makes it, each by [`mat_vec`].
#[inline(always)]
pub fn mat_mat<S: Scalar>(a: &Matrix3<S>, b: &Matrix3<S>) -> Matrix3<S> {
    let c = [0, 1, 2].map(|j| mat_vec(a, &b.column(j).into_owned()));
    Matrix3::from_columns(&c)
}

/// `a^T b`, as [`mat_mat`] of the transpose.
#[inline(always)]
pub fn tr_mat_mat<S: Scalar>(a: &Matrix3<S>, b: &Matrix3<S>) -> Matrix3<S> {
    mat_mat(&a.transpose(), b)
}

/// The derivative parts of a vector dual as a nalgebra vector (helper for tests and the
/// sensitivity engine).
#[inline]
pub fn parts_of<const N: usize>(x: &DualSVec64<N>) -> SVector<f64, N> {
    match &x.eps.0 {
        Some(m) => m.clone_owned(),
        None => SVector::<f64, N>::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn parts_round_trip() {
        let x = DualSVec64::<3>::with_parts(2.0, &[1.0, -2.0, 3.0]);
        assert_eq!(x.value(), 2.0);
        assert_eq!(x.part(1), -2.0);
        let y = Dual64::seeded(4.0, 0);
        assert_eq!(y.eps, 1.0);
        assert_eq!(f64::seeded(4.0, 0), 4.0);
    }

    #[test]
    fn safe_sqrt_at_zero_has_finite_derivative() {
        let z = Dual64::new(0.0, 1.0);
        let s = safe_sqrt(z);
        assert_eq!(s.re, 0.0);
        assert_eq!(s.eps, 0.0);
        let v = Vector3::new(Dual64::new(0.0, 1.0), Dual64::from(0.0), Dual64::from(0.0));
        assert!(safe_norm(&v).eps.is_finite());
    }

    #[test]
    fn inverse_by_cofactors_matches_nalgebra() {
        let a = Matrix3::new(2.0, 0.3, -0.1, 0.2, 1.5, 0.4, -0.3, 0.1, 0.9);
        let (ai, d) = inv3(&a).unwrap();
        assert_relative_eq!(d, a.determinant(), max_relative = 1e-14);
        assert_relative_eq!(ai, a.try_inverse().unwrap(), max_relative = 1e-13);
    }

    #[test]
    fn dual_determinant_derivative_is_jacobi_formula() {
        // d det(A + t B)/dt at t=0 = det(A) tr(A^-1 B)
        let a = Matrix3::new(2.0, 0.3, -0.1, 0.2, 1.5, 0.4, -0.3, 0.1, 0.9);
        let b = Matrix3::new(0.1, 0.2, 0.3, -0.4, 0.5, 0.6, 0.7, -0.8, 0.9);
        let ad = Matrix3::from_fn(|i, j| Dual64::new(a[(i, j)], b[(i, j)]));
        let expected = a.determinant() * (a.try_inverse().unwrap() * b).trace();
        assert_relative_eq!(det3(&ad).eps, expected, max_relative = 1e-13);
    }
}
