//! `--beta auto` for SDM and SDM central: each parameter's step chosen at every increment, and
//! an error bar on every derivative.
//!
//! **Step.** At each converged increment SDM is evaluated at every step of a ladder (relative
//! steps a decade apart: [`FORWARD_LADDER`], [`CENTRAL_LADDER`]), all from the same incoming
//! history derivative: the probes cost residual evaluations at the fixed state and solves with
//! the factor at hand, no reruns. Along the ladder a difference first converges, its
//! truncation falling with the step, then diverges as round-off grows; the step taken is the
//! larger of the two adjacent probes that agree best, the plateau between the two regimes
//! (the rule of Stepleman & Winarsky, *Adaptive numerical differentiation*, Math. Comp. 33,
//! 1979: the sequence of differences is followed while successive differences shrink), or,
//! where neighbours already agree to the round-off they expect ([`NOISE_AGREEMENT`]), the
//! largest such pair: truncation is below round-off there, and a larger step has less. The
//! disagreement is measured over the responses sensitive to the parameter, each relative to
//! its largest probe, so that one parameter gets one step for all its responses.
//!
//! **Error bar.** A shadow SDM run goes along with the chosen one at a tenth of each chosen
//! step, with its own history derivative. Where truncation dominates, the shadow's error is
//! a tenth (forward) or a hundredth (central) of the chosen one's, so their difference is at
//! least 0.9 of the chosen error; where round-off dominates, the shadow's is expected ten
//! times larger, and so is the difference, if the round-off takes the size expected. The
//! bar is [`SAFETY`] times the sum of that difference and the round-off both runs expect
//! (machine precision times the forces that cancel in each unbalance, through the solve, and
//! in the response's own difference, over the step): the chosen error is at most the
//! difference plus the shadow's error, and the shadow's round-off, ten times the chosen
//! one's, is signed: it can cancel the truncation the difference should show (the J2 bar's stress
//! for E, forward: a truncation of 7.5 times the step against a shadow at 1e-8 deep in round-off, a
//! bar of 2.6e-11 under an error of 6.5e-11 before the shadow's round-off was counted). The
//! shadow's truncation is not in the sum: a tenth of the chosen one's (forward), it is what
//! [`SAFETY`] covers, so the bar is an estimate, not a proof. The bar includes what the history
//! carries in from earlier increments, as both runs carry their own. A bar that is not a number is
//! infinite.
//!
//! Measured against DDM (`tests/methods/beta_auto.rs`): the bars bound at least 95 % of the
//! derivatives on most scenes, not on all: an error that does not change between the step
//! and a tenth of it escapes the shadow's difference (the Klarbring oscillator's reactions).

use super::*;
use crate::solver::{AnalysisError, Converged};

/// Relative steps probed by forward SDM.
pub const FORWARD_LADDER: [f64; 10] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];

/// Relative steps probed by central SDM.
pub const CENTRAL_LADDER: [f64; 7] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7];

/// The shadow run's step is the chosen one over this.
pub const SHADOW_RATIO: f64 = 10.0;

/// The error bar is this times the difference from the shadow run and both runs' expected
/// round-off: the difference is at least 0.9 of the chosen error where the error is
/// asymptotic, and the factor covers the shadow's truncation and a truncation that is not
/// yet asymptotic (a higher order adding to the first).
pub const SAFETY: f64 = 2.0;

/// Two neighbouring probes whose difference is within this times the round-off they expect
/// agree to round-off: the expectation (machine precision times the forces that cancel) is an
/// estimate, and the factor leaves it room.
pub const NOISE_AGREEMENT: f64 = 2.0;

/// The error bar of a derivative: [`SAFETY`] times the sum of its difference from the shadow
/// run's and the round-off (or noise) both runs expect; infinite where that is not a number
/// (a probe or rerun that failed).
pub(super) fn bar(gap: f64, noise: f64) -> f64 {
    let bar = SAFETY * (gap + noise);
    if bar.is_nan() {
        f64::INFINITY
    } else {
        bar
    }
}

/// A step taken, its derivatives' error bars `[r][p]`.
type Chosen = (Step, Vec<f64>, Vec<Vec<f64>>);

impl Engine<'_> {
    /// SDM at the steps chosen per parameter from the ladder, with the error bars
    /// (module docs).
    pub(super) fn sdm_auto(
        &mut self,
        c: &Converged<'_>,
        central: bool,
    ) -> Result<Chosen, AnalysisError> {
        let ladder: &[f64] = if central {
            &CENTRAL_LADDER
        } else {
            &FORWARD_LADDER
        };
        let np = self.params.len();
        let nr = c.model.responses.len();
        let nh = c.hist_prev.len();
        // a probe that fails (a step too large for the mesh: an inverted element, a face
        // search that fails) is left out of the ladder; only if every one fails does SDM
        let mut probes: Vec<Option<Step>> = Vec::with_capacity(ladder.len());
        let mut failure = None;
        for beta in ladder {
            match self.sdm(c, central, &vec![*beta; np]) {
                Ok(p) => probes.push(Some(p)),
                Err(e) => {
                    probes.push(None);
                    failure = Some(e);
                }
            }
        }
        if probes.iter().all(Option::is_none) {
            return Err(failure.expect("a probe failed"));
        }
        let values = response_values(c);
        let chosen: Vec<usize> = (0..np)
            .map(|k| {
                let b = self.params[k].value.abs().max(1.0);
                // each sensitive response's largest probe (a response insensitive to the
                // parameter has a round-off derivative: left out, as in the report). A
                // response is insensitive too where a probe is within the round-off it
                // expects of zero: where the derivative is zero (a reaction fixed by
                // equilibrium) the large steps' truncation is all the probes have, shrinking
                // down the ladder into the round-off, and it would pull the step down with it
                let scales: Vec<Option<f64>> = (0..nr)
                    .map(|r| {
                        let finite = (probes.iter().flatten())
                            .map(|p| (p.dresp[r][k].abs(), p.noise[r][k]))
                            .filter(|(v, _)| v.is_finite());
                        let (mut s, mut zero) = (0.0f64, false);
                        for (v, noise) in finite {
                            s = s.max(v);
                            zero |= v <= NOISE_AGREEMENT * noise;
                        }
                        (s > 0.0 && !zero && b * s >= 1e-9 * values[r].abs()).then_some(s)
                    })
                    .collect();
                // between two neighbouring probes that both ran; a value that is not finite
                // disagrees with everything
                let disagreement = |j: usize| {
                    let (Some(a), Some(b)) = (&probes[j], &probes[j + 1]) else {
                        return f64::INFINITY;
                    };
                    scales
                        .iter()
                        .enumerate()
                        .filter_map(|(r, s)| {
                            let s = (*s)?;
                            let d = (a.dresp[r][k] - b.dresp[r][k]).abs() / s;
                            Some(if d.is_nan() { f64::INFINITY } else { d })
                        })
                        .fold(0.0, f64::max)
                };
                // the round-off both neighbours expect, relative as the disagreement is
                let noise = |j: usize| {
                    let (Some(a), Some(b)) = (&probes[j], &probes[j + 1]) else {
                        return 0.0;
                    };
                    scales
                        .iter()
                        .enumerate()
                        .filter_map(|(r, s)| Some((a.noise[r][k] + b.noise[r][k]) / (*s)?))
                        .fold(0.0, f64::max)
                };
                let pairs: Vec<(usize, f64)> = (0..ladder.len() - 1)
                    .map(|j| (j, disagreement(j)))
                    .filter(|(_, d)| d.is_finite())
                    .collect();
                // the largest pair that agrees to the round-off it expects: truncation is
                // below round-off there already, and the larger step has the less round-off
                // (on a plateau of agreement at the round-off floor the smallest disagreement
                // falls anywhere, often at a step with a thousand times the round-off);
                // else the pair that agrees best
                (pairs.iter().enumerate())
                    .find(|(i, (j, d))| {
                        // and the differences stop shrinking there (Stepleman & Winarsky):
                        // an overestimated round-off does not stop the descent early
                        let next = pairs.get(i + 1).map_or(f64::INFINITY, |p| p.1);
                        *d <= NOISE_AGREEMENT * noise(*j) && next >= *d
                    })
                    .map(|(_, p)| p)
                    .or_else(|| pairs.iter().min_by(|a, b| a.1.total_cmp(&b.1)))
                    .map(|(j, _)| *j)
                    // no two neighbours agree: the largest probe that ran
                    .unwrap_or_else(|| probes.iter().position(Option::is_some).unwrap_or(0))
            })
            .collect();
        let betas: Vec<f64> = chosen.iter().map(|j| ladder[*j]).collect();
        let mut step = Step {
            dresp: vec![vec![0.0; np]; nr],
            dhist: vec![0.0; nh * np],
            dz: Vec::with_capacity(np),
            roundoff: vec![vec![false; np]; nr],
            noise: vec![vec![0.0; np]; nr],
        };
        for (k, &j) in chosen.iter().enumerate() {
            let p = probes[j].as_ref().expect("a probe that ran");
            for r in 0..nr {
                step.dresp[r][k] = p.dresp[r][k];
                step.roundoff[r][k] = p.roundoff[r][k];
                step.noise[r][k] = p.noise[r][k];
            }
            step.dhist[k * nh..(k + 1) * nh].copy_from_slice(&p.dhist[k * nh..(k + 1) * nh]);
            step.dz.push(p.dz[k].clone());
        }
        // the shadow run, on its own history derivative
        let shadow_betas: Vec<f64> = betas.iter().map(|b| b / SHADOW_RATIO).collect();
        std::mem::swap(&mut self.dhist, &mut self.shadow_dhist);
        let shadow = self.sdm(c, central, &shadow_betas);
        std::mem::swap(&mut self.dhist, &mut self.shadow_dhist);
        let shadow = shadow?;
        self.shadow_dhist = shadow.dhist;
        let bars = (0..nr)
            .map(|r| {
                (0..np)
                    .map(|k| {
                        let gap = (step.dresp[r][k] - shadow.dresp[r][k]).abs();
                        bar(gap, step.noise[r][k] + shadow.noise[r][k])
                    })
                    .collect()
            })
            .collect();
        Ok((step, betas, bars))
    }
}
