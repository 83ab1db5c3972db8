//! A reverse-mode scalar: [`Rev`].
//!
//! Every operation on `Rev` numbers that depend on an input appends its local partial
//! derivatives to a tape kept per thread; one backward sweep over the tape ([`sweep`]) then
//! gives the derivative of a weighted sum of outputs with respect to every input: a
//! vector-Jacobian product for the cost of the recording and one sweep, whatever the number of
//! inputs. Forward duals give a Jacobian-vector product per direction instead, so a
//! vector-Jacobian product over an element's 24 unknowns and 56 history scalars costs them
//! ten 8-wide evaluations.
//!
//! The kernels are the same generic code ([`Scalar`]): branch decisions are taken on real
//! parts, constants carry no tape entry, and the partial derivatives of every function other
//! than the four arithmetic operations come from [`Dual64`], so nothing here is a derivative
//! written by hand; comparisons, `abs` and `is_zero` behave as the dual numbers' do, so both
//! modes take the same branches. The adjoint ([`crate::sensitivity`]) records the elements of
//! a parallel task one after the other on its thread's tape, and each colour of hitting
//! nodes in one evaluation; it moves the tapes out ([`take`]) and sweeps each recording's
//! part of them ([`Recording::sweep_part`]) on any thread, once per column.
//!
//! A recording must be made on one thread, between a [`clear`] and a [`take`], with nothing
//! in between that could run another recording on that thread (no parallel work inside a
//! kernel): a `Rev` made on another thread's tape or before the last `clear` names a wrong
//! entry. The inputs of one recording must be constants again before the next begins on the
//! same tape, so that each recording's part is self-contained.

use super::Scalar;
use num_dual::{Dual64, DualNum, DualStruct, Mappable};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};
use std::cell::UnsafeCell;
use std::fmt;
use std::iter::{Product, Sum};
use std::mem::ManuallyDrop;
use std::ops::{
    Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Rem, RemAssign, Sub, SubAssign,
};
use std::sync::Mutex;

/// The index of a number that depends on no input (a constant).
const NONE: u32 = u32::MAX;

/// A reverse-mode number: its value and its entry on this thread's tape (none for a
/// constant).
#[derive(Clone, Copy)]
pub struct Rev {
    v: f64,
    i: u32,
}

/// One tape entry: the entry's parents and its partial derivatives with respect to them.
#[derive(Clone, Copy)]
struct Node {
    a: u32,
    b: u32,
    da: f64,
    db: f64,
}

thread_local! {
    /// This thread's tape. No destructor (`ManuallyDrop`), so that every operation reaches it
    /// by a plain thread-local access, not through the lazy registration a destructor needs:
    /// the recordings end with [`take`], which leaves it empty, and what a thread still holds
    /// when it exits is not freed.
    static TAPE: UnsafeCell<ManuallyDrop<Vec<Node>>> =
        const { UnsafeCell::new(ManuallyDrop::new(Vec::new())) };
}

/// Runs `f` on this thread's tape. Sound because every use is one of this module's
/// functions, none of which runs other code (no `Rev` operation, no callback) while it holds
/// the reference: there is never a second one.
#[inline(always)]
fn with_tape<R>(f: impl FnOnce(&mut Vec<Node>) -> R) -> R {
    TAPE.with(|t| {
        // SAFETY: see above; the reference does not outlive `f`, and `f` never reaches the
        // tape again.
        let t = unsafe { &mut *t.get() };
        f(t)
    })
}

#[inline(always)]
fn push(node: Node) -> u32 {
    with_tape(|t| {
        let i = t.len();
        if i >= NONE as usize {
            too_long();
        }
        t.push(node);
        i as u32
    })
}

/// A tape as long as `u32` indices reach: out of the hot path of [`push`].
#[cold]
#[inline(never)]
fn too_long() -> ! {
    panic!("tape longer than u32 indices");
}

/// Empties this thread's tape; every `Rev` recorded before names nothing now.
pub fn clear() {
    with_tape(|t| t.clear());
}

/// Tapes of dropped recordings, kept for the next recordings to grow into: an adjoint sweep
/// records and drops tapes of about the same lengths at every increment, and a fresh tape of
/// a few MiB costs its page faults and zeroing again each time (on the leaf spring's sweep a
/// fifth of the recordings' time).
static SPARE: Mutex<Vec<Vec<Node>>> = Mutex::new(Vec::new());

/// At most this many tapes are kept ([`SPARE`]); the rest are freed.
const SPARE_MAX: usize = 16;

/// Makes room on this thread's tape for `additional` more entries at once (a recording of
/// known length grows without reallocating): an empty tape with less room takes a kept one of
/// a dropped [`Recording`] with enough (else the longest) before growing.
pub fn reserve(additional: usize) {
    let short = with_tape(|t| t.is_empty() && t.capacity() < additional);
    let spare = short
        .then(|| {
            let mut spare = SPARE.lock().unwrap_or_else(|e| e.into_inner());
            let pick = (spare.iter().enumerate())
                .filter(|(_, v)| v.capacity() >= additional)
                .min_by_key(|(_, v)| v.capacity())
                .or_else(|| spare.iter().enumerate().max_by_key(|(_, v)| v.capacity()))
                .map(|(i, _)| i);
            pick.map(|i| spare.swap_remove(i))
        })
        .flatten();
    let old = with_tape(|t| {
        let old = spare.map(|v| std::mem::replace(t, v));
        t.reserve(additional);
        old
    });
    // the thread's own empty tape, kept in turn (dropped outside the tape's borrow)
    if let Some(old) = old {
        keep(old);
    }
}

/// Keeps an emptied tape for a later recording ([`SPARE`]), or frees it.
fn keep(mut v: Vec<Node>) {
    if v.capacity() == 0 {
        return;
    }
    v.clear();
    let mut spare = SPARE.lock().unwrap_or_else(|e| e.into_inner());
    if spare.len() < SPARE_MAX {
        spare.push(v);
    }
}

/// Frees the tapes kept from dropped recordings (the end of a sweep).
pub fn free_kept() {
    let kept = std::mem::take(&mut *SPARE.lock().unwrap_or_else(|e| e.into_inner()));
    drop(kept);
}

/// Calls [`free_kept`] when dropped: a sweep holds one, so that the kept tapes are freed on
/// its errors too.
pub struct FreeKept;

impl Drop for FreeKept {
    fn drop(&mut self) {
        free_kept();
    }
}

/// The number of entries on this thread's tape.
pub fn len() -> usize {
    with_tape(|t| t.len())
}

/// The backward sweep: `adjoint` receives, for every entry of this thread's tape, the
/// derivative of `sum w * output` over `seeds` (`(output, w)`); read an input's with
/// [`Rev::adjoint`]. The tape is left as it is, for more sweeps with other seeds.
pub fn sweep(seeds: impl IntoIterator<Item = (Rev, f64)>, adjoint: &mut Vec<f64>) {
    // the seeds are collected first: iterating them runs the caller's code
    let seeds: Vec<(Rev, f64)> = seeds.into_iter().collect();
    with_tape(|t| sweep_nodes(t, 0..t.len(), seeds, adjoint));
}

/// A tape taken from its thread ([`take`]): swept later, on any thread, as often as needed,
/// whole or a part at a time. Dropped, its memory is kept for the next recording
/// ([`reserve`]) until [`free_kept`].
pub struct Recording(Vec<Node>);

impl Drop for Recording {
    fn drop(&mut self) {
        keep(std::mem::take(&mut self.0));
    }
}

/// This thread's tape, moved out (the thread's is empty again): the `Rev` numbers recorded on
/// it name entries of the [`Recording`] now.
pub fn take() -> Recording {
    Recording(with_tape(std::mem::take))
}

impl Recording {
    /// [`sweep`] over this recording.
    pub fn sweep(&self, seeds: impl IntoIterator<Item = (Rev, f64)>, adjoint: &mut Vec<f64>) {
        sweep_nodes(&self.0, 0..self.0.len(), seeds, adjoint);
    }

    /// [`sweep`] over the entries `part` alone, a self-contained recording: every entry in
    /// it depends on inputs made in it (several recordings one after the other on a tape
    /// not cleared between them, the inputs of the earlier ones made constants again). The
    /// adjoint of entry `k` is `adjoint[k - part.start]` ([`Rev::adjoint_in`]).
    pub fn sweep_part(
        &self,
        part: std::ops::Range<usize>,
        seeds: impl IntoIterator<Item = (Rev, f64)>,
        adjoint: &mut Vec<f64>,
    ) {
        sweep_nodes(&self.0, part, seeds, adjoint);
    }

    /// Its number of entries.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether it has none.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// The sweep over the entries `part` of `t`, `adjoint` indexed from `part.start`.
fn sweep_nodes(
    t: &[Node],
    part: std::ops::Range<usize>,
    seeds: impl IntoIterator<Item = (Rev, f64)>,
    adjoint: &mut Vec<f64>,
) {
    let start = part.start;
    adjoint.clear();
    adjoint.resize(part.len(), 0.0);
    for (x, w) in seeds {
        if x.i != NONE {
            assert!(
                part.contains(&(x.i as usize)),
                "seed outside the swept part"
            );
            adjoint[x.i as usize - start] += w;
        }
    }
    for k in part.rev() {
        let g = adjoint[k - start];
        if g == 0.0 {
            continue;
        }
        let n = t[k];
        // a parent before `start` would belong to another recording (`sweep_part`)
        if n.a != NONE {
            adjoint[n.a as usize - start] += n.da * g;
        }
        if n.b != NONE {
            adjoint[n.b as usize - start] += n.db * g;
        }
    }
}

impl Rev {
    /// A constant: no tape entry.
    #[inline]
    pub const fn constant(v: f64) -> Self {
        Rev { v, i: NONE }
    }

    /// An input (an independent variable): a tape entry of its own.
    pub fn input(v: f64) -> Self {
        let i = push(Node {
            a: NONE,
            b: NONE,
            da: 0.0,
            db: 0.0,
        });
        Rev { v, i }
    }

    /// The value.
    #[inline]
    pub fn value(&self) -> f64 {
        self.v
    }

    /// Whether the number depends on an input.
    #[inline]
    pub fn is_recorded(&self) -> bool {
        self.i != NONE
    }

    /// This number's entry of a [`sweep`]'s adjoints (zero for a constant).
    #[inline]
    pub fn adjoint(&self, adjoint: &[f64]) -> f64 {
        self.adjoint_in(adjoint, 0)
    }

    /// This number's entry of a [`Recording::sweep_part`]'s adjoints, the part starting at
    /// entry `start` (zero for a constant).
    #[inline]
    pub fn adjoint_in(&self, adjoint: &[f64], start: usize) -> f64 {
        if self.i == NONE {
            0.0
        } else {
            adjoint[self.i as usize - start]
        }
    }

    /// `v = f(x)` with `df/dx = d`. No entry where none is needed: a zero derivative makes
    /// a constant, a unit one passes `x`'s adjoint on unchanged, so `v` can share `x`'s entry
    /// (an element's sums start from zero, its shape derivatives hold zeros and ones).
    #[inline]
    fn unary(v: f64, x: Rev, d: f64) -> Rev {
        if x.i == NONE || d == 0.0 {
            return Rev::constant(v);
        }
        if d == 1.0 {
            return Rev { v, i: x.i };
        }
        let i = push(Node {
            a: x.i,
            b: NONE,
            da: d,
            db: 0.0,
        });
        Rev { v, i }
    }

    /// `v = f(x, y)` with partials `dx`, `dy`.
    #[inline]
    fn binary(v: f64, x: Rev, dx: f64, y: Rev, dy: f64) -> Rev {
        match (x.i == NONE || dx == 0.0, y.i == NONE || dy == 0.0) {
            (true, true) => Rev::constant(v),
            (false, true) => Rev::unary(v, x, dx),
            (true, false) => Rev::unary(v, y, dy),
            (false, false) => {
                let i = push(Node {
                    a: x.i,
                    b: y.i,
                    da: dx,
                    db: dy,
                });
                Rev { v, i }
            }
        }
    }

    /// A function of one argument, its value and derivative taken from [`Dual64`].
    #[inline]
    fn through_dual(self, f: impl Fn(Dual64) -> Dual64) -> Rev {
        let d = f(Dual64::new(self.v, 1.0));
        Rev::unary(d.re, self, d.eps)
    }
}

impl fmt::Debug for Rev {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.i == NONE {
            write!(f, "{:?}", self.v)
        } else {
            write!(f, "{:?} @{}", self.v, self.i)
        }
    }
}

impl fmt::Display for Rev {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.v, f)
    }
}

// Comparisons are of values, as the dual numbers' are.
impl PartialEq for Rev {
    fn eq(&self, other: &Self) -> bool {
        self.v == other.v
    }
}

impl PartialEq<f64> for Rev {
    fn eq(&self, other: &f64) -> bool {
        self.v == *other
    }
}

impl PartialOrd for Rev {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        self.v.partial_cmp(&other.v)
    }
}

impl PartialOrd<f64> for Rev {
    fn partial_cmp(&self, other: &f64) -> Option<std::cmp::Ordering> {
        self.v.partial_cmp(other)
    }
}

impl From<f64> for Rev {
    fn from(v: f64) -> Self {
        Rev::constant(v)
    }
}

impl Neg for Rev {
    type Output = Rev;
    #[inline]
    fn neg(self) -> Rev {
        Rev::unary(-self.v, self, -1.0)
    }
}

impl Add for Rev {
    type Output = Rev;
    #[inline]
    fn add(self, y: Rev) -> Rev {
        Rev::binary(self.v + y.v, self, 1.0, y, 1.0)
    }
}

impl Sub for Rev {
    type Output = Rev;
    #[inline]
    fn sub(self, y: Rev) -> Rev {
        Rev::binary(self.v - y.v, self, 1.0, y, -1.0)
    }
}

impl Mul for Rev {
    type Output = Rev;
    #[inline]
    fn mul(self, y: Rev) -> Rev {
        Rev::binary(self.v * y.v, self, y.v, y, self.v)
    }
}

impl Div for Rev {
    type Output = Rev;
    #[inline]
    fn div(self, y: Rev) -> Rev {
        let inv = 1.0 / y.v;
        let v = self.v * inv;
        Rev::binary(v, self, inv, y, -v * inv)
    }
}

impl Rem for Rev {
    type Output = Rev;
    fn rem(self, y: Rev) -> Rev {
        // x - trunc(x / y) y, the quotient piecewise constant
        Rev::binary(self.v % y.v, self, 1.0, y, -(self.v / y.v).trunc())
    }
}

impl Add<f64> for Rev {
    type Output = Rev;
    #[inline]
    fn add(self, y: f64) -> Rev {
        Rev::unary(self.v + y, self, 1.0)
    }
}

impl Sub<f64> for Rev {
    type Output = Rev;
    #[inline]
    fn sub(self, y: f64) -> Rev {
        Rev::unary(self.v - y, self, 1.0)
    }
}

impl Mul<f64> for Rev {
    type Output = Rev;
    #[inline]
    fn mul(self, y: f64) -> Rev {
        Rev::unary(self.v * y, self, y)
    }
}

impl Div<f64> for Rev {
    type Output = Rev;
    #[inline]
    fn div(self, y: f64) -> Rev {
        Rev::unary(self.v / y, self, 1.0 / y)
    }
}

impl Rem<f64> for Rev {
    type Output = Rev;
    fn rem(self, y: f64) -> Rev {
        Rev::unary(self.v % y, self, 1.0)
    }
}

/// The by-reference and compound-assignment forms, through the by-value ones.
macro_rules! forward_ops {
    ($($op:ident $f:ident $opa:ident $fa:ident),*) => {$(
        impl<'r> $op<&'r Rev> for Rev {
            type Output = Rev;
            #[inline]
            fn $f(self, y: &'r Rev) -> Rev {
                $op::$f(self, *y)
            }
        }
        impl $opa for Rev {
            #[inline]
            fn $fa(&mut self, y: Rev) {
                *self = $op::$f(*self, y);
            }
        }
        impl $opa<f64> for Rev {
            #[inline]
            fn $fa(&mut self, y: f64) {
                *self = $op::$f(*self, y);
            }
        }
    )*};
}

forward_ops!(
    Add add AddAssign add_assign,
    Sub sub SubAssign sub_assign,
    Mul mul MulAssign mul_assign,
    Div div DivAssign div_assign,
    Rem rem RemAssign rem_assign
);

impl Zero for Rev {
    fn zero() -> Self {
        Rev::constant(0.0)
    }
    /// A zero value, as the dual numbers' `is_zero` (the derivative is not looked at), so
    /// that code branching on it takes the same branch in every mode.
    fn is_zero(&self) -> bool {
        self.v == 0.0
    }
}

impl One for Rev {
    fn one() -> Self {
        Rev::constant(1.0)
    }
}

impl Num for Rev {
    type FromStrRadixErr = <f64 as Num>::FromStrRadixErr;
    fn from_str_radix(s: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        f64::from_str_radix(s, radix).map(Rev::constant)
    }
}

impl Signed for Rev {
    /// `x` or `-x` by the sign of the value, as the dual numbers' `abs` (derivative one at
    /// +0).
    fn abs(&self) -> Self {
        if self.is_positive() {
            *self
        } else {
            -*self
        }
    }
    fn abs_sub(&self, other: &Self) -> Self {
        if self.v <= other.v {
            Rev::zero()
        } else {
            *self - *other
        }
    }
    fn signum(&self) -> Self {
        Rev::constant(Signed::signum(&self.v))
    }
    fn is_positive(&self) -> bool {
        self.v.is_sign_positive()
    }
    fn is_negative(&self) -> bool {
        self.v.is_sign_negative()
    }
}

impl Inv for Rev {
    type Output = Rev;
    fn inv(self) -> Rev {
        DualNum::recip(&self)
    }
}

impl Sum for Rev {
    fn sum<I: Iterator<Item = Rev>>(iter: I) -> Rev {
        iter.fold(Rev::zero(), |a, b| a + b)
    }
}

impl<'a> Sum<&'a Rev> for Rev {
    fn sum<I: Iterator<Item = &'a Rev>>(iter: I) -> Rev {
        iter.fold(Rev::zero(), |a, b| a + *b)
    }
}

impl Product for Rev {
    fn product<I: Iterator<Item = Rev>>(iter: I) -> Rev {
        iter.fold(Rev::one(), |a, b| a * b)
    }
}

impl FromPrimitive for Rev {
    fn from_i64(n: i64) -> Option<Self> {
        f64::from_i64(n).map(Rev::constant)
    }
    fn from_u64(n: u64) -> Option<Self> {
        f64::from_u64(n).map(Rev::constant)
    }
    fn from_f64(n: f64) -> Option<Self> {
        Some(Rev::constant(n))
    }
}

impl DualStruct for Rev {
    type Real = f64;
    type Inner = f64;
    fn re(&self) -> f64 {
        self.v
    }
    fn from_inner(inner: &f64) -> Self {
        Rev::constant(*inner)
    }
}

impl Mappable<Rev> for Rev {
    type Output<O> = O;
    fn map_dual<M: Fn(Rev) -> O, O>(self, f: M) -> O {
        f(self)
    }
}

/// Functions of one argument whose value and derivative come from [`Dual64`].
macro_rules! through_dual {
    ($($f:ident),*) => {$(
        #[inline]
        fn $f(&self) -> Self {
            self.through_dual(|d| d.$f())
        }
    )*};
}

impl DualNum for Rev {
    type Primitive = f64;
    const NDERIV: usize = 1;
    type InnerDual = f64;

    fn from_re(re: f64) -> Self {
        Rev::constant(re)
    }

    fn scale(self, factor: &f64) -> Self {
        self * *factor
    }

    #[inline]
    fn recip(&self) -> Self {
        let v = 1.0 / self.v;
        Rev::unary(v, *self, -v * v)
    }

    fn powi(&self, n: i32) -> Self {
        self.through_dual(|d| d.powi(n))
    }

    fn powf(&self, n: f64) -> Self {
        self.through_dual(|d| d.powf(n))
    }

    #[inline]
    fn sqrt(&self) -> Self {
        let v = self.v.sqrt();
        Rev::unary(v, *self, 0.5 / v)
    }

    fn log(&self, base: f64) -> Self {
        self.through_dual(|d| d.log(base))
    }

    fn sin_cos(&self) -> (Self, Self) {
        (DualNum::sin(self), DualNum::cos(self))
    }

    fn atan2(&self, other: Self) -> Self {
        // atan2(y, x): d/dy = x / r^2, d/dx = -y / r^2
        let r2 = self.v * self.v + other.v * other.v;
        Rev::binary(
            self.v.atan2(other.v),
            *self,
            other.v / r2,
            other,
            -self.v / r2,
        )
    }

    through_dual!(
        cbrt, exp, exp2, exp_m1, ln, log2, log10, ln_1p, sin, cos, tan, asin, acos, atan, sinh,
        cosh, tanh, asinh, acosh, atanh, sph_j0, sph_j1, sph_j2
    );
}

impl Scalar for Rev {
    /// No forward directions: a `Rev`'s derivatives come from a [`sweep`].
    const NPARTS: usize = 0;
    const RECORDS: bool = true;
    #[inline]
    fn value(&self) -> f64 {
        self.v
    }
    #[inline]
    fn is_constant(&self) -> bool {
        self.i == NONE
    }
    #[inline]
    fn part(&self, _k: usize) -> f64 {
        0.0
    }
    /// A constant: a `Rev` input is made with [`Rev::input`], not seeded.
    #[inline]
    fn with_parts(re: f64, _parts: &[f64]) -> Self {
        Rev::constant(re)
    }
    /// One entry with partials 1 and the constant factor where a factor is a constant:
    /// the product's entry would pass its adjoint `g` on unchanged, and `b g` from it is
    /// `b g` from this one, in the same place of the sweep, so the adjoints are those of
    /// `self + a * b` to the bit.
    #[inline(always)]
    fn add_mul(self, a: Rev, b: Rev) -> Rev {
        let v = self.v + a.v * b.v;
        if b.i == NONE {
            Rev::binary(v, self, 1.0, a, b.v)
        } else if a.i == NONE {
            Rev::binary(v, self, 1.0, b, a.v)
        } else {
            self + a * b
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scalar::{det3, inv3, parts_of, safe_norm};
    use approx::assert_relative_eq;
    use nalgebra::{Matrix3, Vector3};
    use num_dual::DualSVec64;

    /// A function of six inputs through most of what a kernel uses: matrix products, the
    /// cofactor inverse, a zero-safe norm, roots, logarithms, powers, a quotient.
    fn f<S: Scalar>(x: &[S; 6]) -> [S; 2] {
        let a = Matrix3::new(
            x[0] + S::from(2.0),
            x[1],
            x[2] * x[3],
            S::from(0.1),
            x[4] + S::from(1.5),
            x[5].sin(),
            x[0] * x[5],
            S::from(-0.2),
            x[3].exp() + S::from(0.3),
        );
        let (ai, d) = inv3(&a).expect("invertible");
        let b = a.transpose() * ai * a;
        let n = safe_norm(&Vector3::new(x[0], x[1], x[2]));
        let g = b.trace() * d.ln() + n.sqrt() * x[4].powi(3) / (x[5].cbrt() + S::from(2.0));
        let h = det3(&b).atan2(x[1]) - x[2].tanh() * x[3].abs() + x[4].powf(1.7);
        [g, h]
    }

    #[test]
    fn one_sweep_gives_the_vector_jacobian_product_forward_duals_give_a_column_at_a_time() {
        let x0 = [0.3, -0.7, 0.45, 0.2, 0.9, 0.6];
        let w = [1.3, -0.4];
        // forward: six directions at once, the Jacobian, weighed by w
        let xd: [DualSVec64<6>; 6] = std::array::from_fn(|k| DualSVec64::seeded(x0[k], k));
        let yd = f(&xd);
        let vjp_fwd: Vec<f64> = (0..6)
            .map(|k| w[0] * yd[0].part(k) + w[1] * yd[1].part(k))
            .collect();
        // reverse: one recording, one sweep
        clear();
        let xr: [Rev; 6] = std::array::from_fn(|k| Rev::input(x0[k]));
        let yr = f(&xr);
        assert_eq!(yr[0].value(), f(&x0)[0]);
        assert_eq!(yr[1].value(), f(&x0)[1]);
        let mut adj = Vec::new();
        sweep([(yr[0], w[0]), (yr[1], w[1])], &mut adj);
        for (x, v) in xr.iter().zip(&vjp_fwd) {
            assert_relative_eq!(x.adjoint(&adj), *v, max_relative = 1e-13);
        }
        // a second sweep on the same tape, the other output alone
        sweep([(yr[1], 1.0)], &mut adj);
        for (k, x) in xr.iter().enumerate() {
            assert_relative_eq!(x.adjoint(&adj), yd[1].part(k), max_relative = 1e-13);
        }
        // taken from the thread, the same sweep
        let taken = take();
        assert_eq!(len(), 0);
        assert!(!taken.is_empty());
        taken.sweep([(yr[0], w[0]), (yr[1], w[1])], &mut adj);
        for (x, v) in xr.iter().zip(&vjp_fwd) {
            assert_relative_eq!(x.adjoint(&adj), *v, max_relative = 1e-13);
        }
    }

    /// The products of [`crate::scalar::mat_vec`], [`crate::scalar::mat_mat`] and
    /// [`crate::scalar::tr_mat_mat`] are nalgebra's to the bit: the values in `f64` and in
    /// dual numbers, and in reverse mode the values and the adjoints of one sweep through
    /// them, on a tape with one entry a term fewer where a factor is constant.
    #[test]
    fn small_products_are_nalgebras_to_the_bit_on_a_shorter_tape() {
        use crate::scalar::{mat_mat, mat_vec, tr_mat_mat};
        let a0 = Matrix3::new(0.31, -1.7, 2.3e-3, 4.1, 0.52, -0.66, 1.0 / 3.0, 7.9, -2.2);
        let b0 = Matrix3::new(-0.8, 0.13, 5.5, 0.29, -3.1, 0.47, 2.9, -1.0 / 7.0, 0.61);
        let x0 = Vector3::new(0.17, -2.6, 1.0 / 9.0);
        let nalgebra_f = |a: &Matrix3<f64>, b: &Matrix3<f64>, x: &Vector3<f64>| {
            (a * x, a * b, a.transpose() * b)
        };
        let (v, m, t) = nalgebra_f(&a0, &b0, &x0);
        assert_eq!((mat_vec(&a0, &x0), mat_mat(&a0, &b0)), (v, m));
        assert_eq!(tr_mat_mat(&a0, &b0), t);
        // dual numbers: every entry of `a` seeded
        let ad = Matrix3::from_fn(|i, j| DualSVec64::<9>::seeded(a0[(i, j)], 3 * j + i));
        let (bd, xd) = (b0.map(DualSVec64::<9>::from), x0.map(DualSVec64::<9>::from));
        assert_eq!(mat_vec(&ad, &xd), ad * xd);
        assert_eq!(mat_mat(&ad, &bd), ad * bd);
        assert_eq!(tr_mat_mat(&ad, &bd), ad.transpose() * bd);
        for (got, want) in mat_mat(&ad, &bd).iter().zip((ad * bd).iter()) {
            assert_eq!(parts_of(got), parts_of(want));
        }
        // a deformation gradient of a simple shear, its first row (1, 0, c) exactly: products
        // of ones and zeros share their factors' entries, so that the tape's order decides
        // the order of the additions into an input's adjoint
        let f0 = Matrix3::new(1.0, 0.0, 0.37, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        // reverse mode: `a`, `x` and `f` inputs, `b` constant, every output weighed
        let record = |ours: bool| {
            clear();
            let a = a0.map(Rev::input);
            let x = x0.map(Rev::input);
            let f = f0.map(Rev::input);
            let b = b0.map(Rev::constant);
            let (v, m, t) = if ours {
                (mat_vec(&a, &x), mat_mat(&a, &b), tr_mat_mat(&a, &b))
            } else {
                (a * x, a * b, a.transpose() * b)
            };
            let entries = len() - 9;
            let (c, g) = if ours {
                (
                    tr_mat_mat(&f, &f),
                    mat_mat(&mat_mat(&f, &m), &f.transpose()),
                )
            } else {
                (f.transpose() * f, f * m * f.transpose())
            };
            let seeds = (v.iter().chain(&m).chain(&t).chain(&c).chain(&g).enumerate())
                .map(|(k, y)| (*y, 1.0 + 0.1 * k as f64))
                .collect::<Vec<_>>();
            let mut adj = Vec::new();
            sweep(seeds.iter().copied(), &mut adj);
            let values: Vec<f64> = seeds.iter().map(|(y, _)| y.value()).collect();
            let adjoints: Vec<f64> = (a.iter().chain(&x).chain(&f))
                .map(|z| z.adjoint(&adj))
                .collect();
            (values, adjoints, entries)
        };
        let (ours, theirs) = (record(true), record(false));
        assert_eq!(ours.0, theirs.0, "values");
        assert_eq!(ours.1, theirs.1, "adjoints");
        // 12 inputs; `a x`, both factors recorded: 3 entries of a product and two sums of
        // a product, 15 entries either way; `a b` and `a^T b` (no zero in `b`): 9 entries
        // of 3 terms each, the first a product, each later one a product and a sum (5
        // tape entries an entry of the result) or one fused entry (3)
        assert_eq!((ours.2, theirs.2), (12 + 15 + 2 * 27, 12 + 15 + 2 * 45));
    }

    /// A dropped recording's memory is kept and a later recording grows into it: that one
    /// starts empty, its entries numbered from zero, and sweeps to the forward duals' product
    /// as a fresh tape does; after `free_kept` recordings start from fresh memory again.
    #[test]
    fn a_kept_tape_starts_empty_and_records_as_a_fresh_one() {
        let x0 = [0.3, -0.7, 0.45, 0.2, 0.9, 0.6];
        let xd: [DualSVec64<6>; 6] = std::array::from_fn(|k| DualSVec64::seeded(x0[k], k));
        let yd = f(&xd);
        // on a thread of its own: its tape starts with no memory
        std::thread::spawn(move || {
            for round in 0..3 {
                clear();
                let xr: [Rev; 6] = std::array::from_fn(|k| Rev::input(x0[k]));
                let yr = f(&xr);
                let entries = len();
                let first = take();
                assert_eq!(first.len(), entries);
                drop(first);
                // the next recording takes a kept tape (this one's, or another's)
                reserve(entries);
                assert_eq!(len(), 0, "round {round}: a kept tape comes back empty");
                let xr: [Rev; 6] = std::array::from_fn(|k| Rev::input(x0[k]));
                assert_eq!(xr[0].i, 0, "entries numbered from zero");
                let yr2 = f(&xr);
                assert_eq!(len(), entries);
                assert_eq!(yr2[1].value(), yr[1].value());
                let mut adj = Vec::new();
                take().sweep([(yr2[1], 1.0)], &mut adj);
                for (k, x) in xr.iter().enumerate() {
                    assert_relative_eq!(x.adjoint(&adj), yd[1].part(k), max_relative = 1e-13);
                }
                if round == 1 {
                    free_kept();
                }
            }
        })
        .join()
        .unwrap();
    }

    #[test]
    fn recordings_one_after_the_other_sweep_apart() {
        clear();
        let x = Rev::input(0.5);
        let y = x.sin() * x;
        let start = len();
        let u = Rev::input(2.0);
        let v = u.ln() * u.sqrt();
        let end = len();
        let z = Rev::input(1.5);
        let w = z * z;
        let taken = take();
        let mut adj = Vec::new();
        taken.sweep_part(start..end, [(v, 1.0)], &mut adj);
        let du = 2.0f64.sqrt() * (1.0 / 2.0 + 2.0f64.ln() / 4.0);
        assert_relative_eq!(u.adjoint_in(&adj, start), du, max_relative = 1e-15);
        taken.sweep_part(0..start, [(y, 1.0)], &mut adj);
        assert_relative_eq!(x.adjoint_in(&adj, 0), 0.5f64.cos() * 0.5 + 0.5f64.sin());
        taken.sweep_part(end..taken.len(), [(w, 1.0)], &mut adj);
        assert_eq!(z.adjoint_in(&adj, end), 3.0);
    }

    #[test]
    fn constants_leave_no_tape_and_zero_adjoint() {
        clear();
        let c = Rev::constant(2.0);
        let y = (c * c).sqrt() + c.exp();
        assert!(!y.is_recorded());
        assert_eq!(len(), 0);
        let x = Rev::input(3.0);
        let z = x * c + c;
        // the input and the product; the sum with a constant shares the product's entry
        assert_eq!(len(), 2);
        // a unit or zero derivative makes no entry
        let one = x * Rev::constant(1.0) + Rev::constant(0.0);
        assert_eq!(len(), 2);
        assert!(one.is_recorded());
        assert!(!(x * Rev::constant(0.0)).is_recorded());
        let mut adj = Vec::new();
        sweep([(z, 1.0)], &mut adj);
        assert_eq!(x.adjoint(&adj), 2.0);
        assert_eq!(c.adjoint(&adj), 0.0);
        clear();
    }
}
