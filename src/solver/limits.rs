//! The solver's limits and step controls: augmentation passes, line search, the limiters on
//! penetration and yield-surface crossing, increment growth and shrinkage, cycle detection.

/// Augmented-Lagrangian passes allowed per increment.
pub(super) const MAX_AUGMENTATIONS: usize = 50;

/// Times an increment's augmented-Lagrangian passes go back to the last converged pass after
/// one fails, each with the multiplier update shortened by [`AUGMENTATION_BACKTRACK_STEP`].
/// Measured on the fuzzer's seeds 0-999: seeds 291 and 836 (contact cycles while their
/// augmented pairs unload) complete, 254, 411 and 458 take 5 to 12 % fewer Newton iterations,
/// every other scene's iterations are unchanged.
pub(super) const AUGMENTATION_BACKTRACKS: usize = 3;

/// The factor a backtrack shortens the multiplier update by ([`AUGMENTATION_BACKTRACKS`]).
pub(super) const AUGMENTATION_BACKTRACK_STEP: f64 = 0.25;

/// Residual growth over one Newton step that triggers backtracking (contact models).
pub(super) const LINE_SEARCH_GROWTH: f64 = 4.0;

/// A Newton correction below this many ulps of what it corrects is round-off (the
/// round-off convergence criterion).
pub(super) const CORRECTION_ROUND_OFF: f64 = 64.0;

/// The step limiter acts on penetrations deeper than this fraction of the model's size (the
/// diagonal of its reference bounding box): well above round-off, far below any clearance a
/// scene resolves (leaf spring: 1e-4 mm against a 0.02 mm clearance).
pub(super) const PENETRATION_LIMIT_SCALE: f64 = 1e-6;

/// Diagonal of the bounding box of some points.
pub(super) fn bounding_diagonal(points: &[nalgebra::Vector3<f64>]) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    let (lo, hi) = points
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    (hi - lo).norm()
}

/// The line search halves a Newton step only while it is longer than this fraction of it
/// (so it ends between 1/64 and 1/32): backtracking a blow-up of the residual, and halving a
/// step whose end state cannot be evaluated (an inverted element, a degenerate target
/// segment) before the attempt fails.
pub(super) const SHORTEST_STEP: f64 = 1.0 / 32.0;

/// Shortest fraction of a Newton step the yield-surface crossing limiter keeps. Without a
/// floor, points that cross near the start of the step cut it to 1e-7 and Newton stalls (the
/// leaf spring refined 4 times ran out of time).
pub(super) const YIELD_CROSSING_FLOOR: f64 = 0.125;

/// A Newton iteration whose residual is above this fraction of the last one's stalls: the
/// slip-reversal remedy acts only then.
pub(super) const STALL_RATIO: f64 = 0.5;

/// Local Newton steps per element on the incompatible modes ([`Solver`]'s mode relaxation:
/// after an attempt of a nominal increment has failed, every later attempt of it holds the
/// modes of each incompatible-modes element with a history (J2) in equilibrium with its nodes
/// before each evaluation, [`crate::assembly::Assembler::relax_modes`]).
///
/// Why: the global Newton step moves the modes with the linearised element, and a J2 element
/// under large plastic strain can take a step of the modes that folds a Gauss point's branch
/// back and forth or inverts it; held at the local equilibrium of their element, they follow
/// the nodes. Measured on the physics fuzzer with default settings (scenes completing their
/// whole path): seeds 0-999, 989 -> 990 (931 completes, none fails; 918 scenes take the same
/// iterations, the other 82 differ after a failed attempt); held-out seeds 1000-1999,
/// 994 -> 996 (1186 and 1954 complete, none fails). The variants measured and not kept (at
/// every attempt; without the step halving; elastic elements too) are in the report's
/// robustness notes.
pub(super) const MODE_RELAXATION_STEPS: usize = 3;

/// Failed attempts allowed within one of the user's increments, per `max_cutbacks`.
pub(super) const FAILED_ATTEMPTS_PER_STEP: usize = 2;

/// Factor of the step after an increment harder than `SolverSettings::shrink_after` (CalculiX's
/// D_B), down to [`HARD_FLOOR`] of the user's increment.
pub(super) const HARD_SHRINK: f64 = 0.75;
/// See [`HARD_SHRINK`].
pub(super) const HARD_FLOOR: f64 = 0.25;

/// The energy and round-off convergence criteria accept a residual at most this many times
/// the force tolerance (the leaf spring's round-off floor, the reason for the round-off
/// criterion, is 11 times it on the finest mesh; the physics fuzzer found an increment
/// accepted with a tenth of its forces out of balance).
pub(super) const NEAR_TOLERANCE: f64 = 1e4;

/// Free evaluations over which a cycle is looked for ([`Solver`]'s attempt): the same contact
/// decisions twice among them, after at least twice as many iterations, with no residual
/// below half the best before them, end the attempt.
pub(super) const CYCLE_WINDOW: usize = 6;

/// Times a hitting node may be forced onto the stick branch per attempt when its slip
/// direction reverses between two Newton iterates ([`Solver`]'s attempt).
pub(super) const SLIP_REVERSALS: usize = 3;

/// Of the nodes a step would close, the first active-set prediction takes those whose
/// predicted penetration is at least this fraction of their pair's deepest.
pub(super) const ACTIVE_SET_ADD_FRACTION: f64 = 0.9;
