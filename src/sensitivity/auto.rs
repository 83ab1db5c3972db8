//! `--beta auto` for SDM and SDM central: each parameter's step chosen at every increment, and
//! an error bar on every derivative.
//!
//! **Step.** At each converged increment SDM is evaluated at every step of a ladder (relative
//! steps a decade apart: [`FORWARD_LADDER`], [`CENTRAL_LADDER`]), all from the same incoming
//! history derivative: the probes cost residual evaluations at the fixed state and solves with
//! the factor at hand, no reruns. Along the ladder a difference first converges, its
//! truncation falling with the step, then diverges as round-off grows. Where neighbours agree
//! to the round-off they expect ([`NOISE_AGREEMENT`]) and their differences stop shrinking, the
//! step taken is the larger of the largest such pair: truncation is below round-off there, and
//! a larger step has less. Else it is one of the two adjacent probes that agree best, the
//! plateau between the two regimes (the rule of Stepleman & Winarsky, *Adaptive numerical
//! differentiation*, Math. Comp. 33, 1979: the sequence of differences is followed while
//! successive differences shrink): the larger, as they take it, or the smaller where the
//! pair's difference is the larger's truncation (`better_of_pair`). The
//! disagreement is measured over the responses sensitive to the parameter, each relative to
//! its largest probe, so that one parameter gets one step for all its responses.
//!
//! **The history's step.** The history derivative the increment carries on is chosen by the
//! same rule on its own differences (`HistoryProbes`), and taken from a smaller step than the
//! responses' where it asks for one: the responses at an increment do not show a truncation
//! only the history carries (the strip's stick anchors for mu). Where the history agrees at a
//! larger step than the responses, the responses' step is kept for both: the history's norm
//! weighs its entries by their size, not by what they do to later responses, and taking it
//! there cost the leaf spring's length its bars (82 of 102 bounded instead of 101).
//!
//! **Error bar.** A shadow SDM run goes along with the chosen one at a tenth of each chosen
//! step (the responses' and the history's), with its own history derivative. Where
//! truncation dominates, the shadow's error is a tenth (forward) or a hundredth (central) of
//! the chosen one's, so their difference is at
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
//! derivatives on every scene tested. An error that does not change between the step and a
//! tenth of it escapes the shadow's difference, so the expected round-off has to carry it: on
//! the Klarbring oscillator the stick force's quantization (its penalty times the ulp of the
//! anchor's position) is that error, and the bars bounded 142 of 150 while the round-off
//! counted the reference force alone.

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

/// Two neighbouring probes above their round-off that agree to this fraction of the larger
/// are a plateau: the derivative is not zero. A zero derivative's probes are truncation, which
/// falls a decade (forward) or two (central) from one step to the next down the ladder.
pub const PLATEAU: f64 = 0.1;

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

/// Of the pair of neighbouring steps that agrees best (`j` and `j + 1`, a decade apart), the
/// one with the smaller expected error: `difference(i)` is pair `i`'s disagreement (infinite
/// where a probe failed), `pairs` their number, `order` the method's (1 forward, 2 central),
/// `last_roundoff` the round-off expected of the ladder's last step (relative as the
/// differences are).
///
/// Stepleman & Winarsky take the larger step, whose error is the pair's difference where
/// truncation dominates. Where the differences shrink into pair `j` at the method's order (the
/// pair above differs by at least a third of `10^order` times as much), the difference is the
/// larger step's truncation, and the smaller step carries a `10^-order`-th of it plus its own
/// round-off. That round-off grows as the inverse of the step, so the pair below, which
/// differs by at least as much as pair `j` (it agrees best), differs by about 11 times it; the
/// ladder's last step has no pair below, and its expected round-off stands in. The smaller step
/// is taken where the sum of the two is below the larger's error (FDM central on the stacked
/// leaves' E: 1.0e-8 at 1e-4, where 1e-5 has 6.1e-10). A pair above whose difference is not a
/// number (a probe that failed, or for FDM a rerun across a switch) proves nothing: the
/// larger step is kept.
pub(super) fn better_of_pair(
    difference: impl Fn(usize) -> f64,
    j: usize,
    pairs: usize,
    order: i32,
    last_roundoff: f64,
) -> usize {
    if j == 0 || j >= pairs {
        return j;
    }
    let (above, here) = (difference(j - 1), difference(j));
    let roundoff = if j + 1 < pairs {
        difference(j + 1) / 11.0
    } else {
        last_roundoff
    };
    let rate = 10f64.powi(order);
    let truncation = here > 0.0 && above.is_finite() && above >= rate / 3.0 * here;
    if truncation && here / rate + roundoff < here {
        j + 1
    } else {
        j
    }
}

/// The step along a ladder of `rungs + 1` probes by the rule of the module docs, from the
/// relative `disagreement(j)` of probes `j` and `j + 1` (infinite where one failed), the
/// round-off `noise(j)` they expect, the method's `order` and the last probe's expected
/// round-off: the largest pair that agrees to its round-off where the differences stop
/// shrinking, else the better of the pair that agrees best; `None` where no pair ran.
fn choose_step(
    disagreement: impl Fn(usize) -> f64,
    noise: impl Fn(usize) -> f64,
    rungs: usize,
    order: i32,
    last_roundoff: f64,
) -> Option<usize> {
    let pairs: Vec<(usize, f64)> = (0..rungs)
        .map(|j| (j, disagreement(j)))
        .filter(|(_, d)| d.is_finite())
        .collect();
    // the largest pair that agrees to the round-off it expects: truncation is below
    // round-off there already, and the larger step has the less round-off (on a plateau of
    // agreement at the round-off floor the smallest disagreement falls anywhere, often at a
    // step with a thousand times the round-off); else the better of the pair that agrees best
    (pairs.iter().enumerate())
        .find(|(i, (j, d))| {
            // and the differences stop shrinking there (Stepleman & Winarsky): an
            // overestimated round-off does not stop the descent early
            let next = pairs.get(i + 1).map_or(f64::INFINITY, |p| p.1);
            *d <= NOISE_AGREEMENT * noise(*j) && next >= *d
        })
        .map(|(_, p)| p.0)
        .or_else(|| {
            let best = pairs.iter().min_by(|a, b| a.1.total_cmp(&b.1))?.0;
            Some(better_of_pair(
                disagreement,
                best,
                rungs,
                order,
                last_roundoff,
            ))
        })
}

/// One parameter's history derivative along the ladder, the outgoing `dh_n/db` of each probe,
/// whose differences choose the history's step.
///
/// The responses at an increment do not show a truncation that only the history carries on:
/// on the strip pull-out, forward SDM for mu, the responses' probes agree exactly from 1e-1
/// on through the stick increments, while the anchors' derivatives differ a decade per decade
/// of step (7.1e-5 of their size between 1e-1 and 1e-2) down to their round-off at 1e-6, and
/// the truncation taken at 1e-1 reached the pull-out's displacement later as an error of
/// 2.9e-7 (the sweep's best, at 1e-6: 3.3e-10). The history's round-off is machine precision
/// times the history itself (each perturbed entry is rounded to its own ulp) over the step,
/// plus the unbalance's relative round-off carried through the solve; measured there, the
/// first is where the differences stop falling. Without the second the strip's E took its
/// history from 1e-6 where the responses' 1e-1 to 1e-3 was better (an error of 4.1e-10
/// against 1.2e-13, both measured by the CLI against DDM).
struct HistoryProbes<'p> {
    probes: &'p [Option<Step>],
    /// The parameter's entries of `dhist`.
    range: std::ops::Range<usize>,
    /// The absolute step of each probe.
    steps: Vec<f64>,
    /// Each probe's `|dh_n/db|` (`None` where it failed).
    norms: Vec<Option<f64>>,
    /// Each probe's round-off carried through the solve: the unbalance's relative round-off
    /// times `|dh_n/db|`.
    carried: Vec<f64>,
    /// `|h_n|`.
    size: f64,
    /// The largest probe's `|dh_n/db|`; `None` where no two neighbouring probes above their
    /// round-off agree (no plateau): the history is then left out of the choice.
    scale: Option<f64>,
}

impl<'p> HistoryProbes<'p> {
    fn new(
        c: &Converged<'_>,
        probes: &'p [Option<Step>],
        k: usize,
        step: impl Fn(usize) -> f64,
    ) -> Self {
        let nh = c.hist_prev.len();
        let range = k * nh..(k + 1) * nh;
        let norms: Vec<Option<f64>> = (probes.iter())
            .map(|p| p.as_ref().map(|p| norm(&p.dhist[range.clone()])))
            .collect();
        let carried = (probes.iter().zip(&norms))
            .map(|(p, n)| {
                let unbalance = p.as_ref().and_then(|p| p.unbalance_noise.get(k).copied());
                unbalance.unwrap_or(0.0) * n.unwrap_or(0.0)
            })
            .collect();
        let mut h = HistoryProbes {
            probes,
            range,
            steps: (0..probes.len()).map(step).collect(),
            norms,
            carried,
            size: norm(&c.eval.hist_new),
            scale: None,
        };
        // sensitive where two neighbouring probes above their round-off agree (a plateau,
        // as for the responses)
        let finite = |j: usize| h.norms.get(j).copied().flatten().filter(|v| v.is_finite());
        let (mut largest, mut plateau) = (0.0f64, false);
        for j in 0..probes.len() {
            let Some(v) = finite(j) else { continue };
            largest = largest.max(v);
            let Some(w) = finite(j + 1) else { continue };
            plateau |= v > NOISE_AGREEMENT * h.noise_abs(j)
                && w > NOISE_AGREEMENT * h.noise_abs(j + 1)
                && h.difference(j) <= PLATEAU * v.max(w);
        }
        h.scale = (plateau && largest > 0.0).then_some(largest);
        h
    }

    /// The history's own step on the ladder of `rungs + 1` probes ([`choose_step`]); `None`
    /// where it is left out.
    fn step(&self, rungs: usize, order: i32) -> Option<usize> {
        let scale = self.scale?;
        let noise = |j: usize| self.noise_abs(j) / scale;
        choose_step(
            |j| {
                let d = self.difference(j) / scale;
                if d.is_nan() {
                    f64::INFINITY
                } else {
                    d
                }
            },
            |j| noise(j) + noise(j + 1),
            rungs,
            order,
            noise(rungs),
        )
    }

    /// The round-off of probe `j`'s history derivative (absolute, infinite where the probe
    /// failed): the history's own rounding over the step, and the unbalance's round-off
    /// carried through the solve.
    fn noise_abs(&self, j: usize) -> f64 {
        match self.norms[j] {
            Some(_) => f64::EPSILON * self.size / self.steps[j] + self.carried[j],
            None => f64::INFINITY,
        }
    }

    /// `|dh_n/db|` of probe `j` less that of probe `j + 1` (infinite where one failed).
    fn difference(&self, j: usize) -> f64 {
        let (Some(a), Some(b)) = (&self.probes[j], &self.probes[j + 1]) else {
            return f64::INFINITY;
        };
        diff_norm(&a.dhist[self.range.clone()], &b.dhist[self.range.clone()])
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn diff_norm(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
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
        // each parameter's step for the responses, and for the history it carries on
        let chosen: Vec<(usize, usize)> = (0..np)
            .map(|k| {
                let b = self.params[k].value.abs().max(1.0);
                // each sensitive response's largest probe (a response insensitive to the
                // parameter has a round-off derivative: left out, as in the report). A
                // response is insensitive too where a probe is within the round-off it
                // expects of zero and no two neighbouring probes above their round-off agree
                // (to PLATEAU): where the derivative is zero (a reaction fixed by
                // equilibrium) the large steps' truncation is all the probes have, shrinking
                // down the ladder a decade a step into the round-off, and it would pull the
                // step down with it. A derivative that is not zero has its plateau, and the
                // small steps' round-off can exceed it (a stiff stick penalty: the Klarbring
                // oscillator's friction force), which must not leave it out
                let scales: Vec<Option<f64>> = (0..nr)
                    .map(|r| {
                        let probe = |j: usize| {
                            let p = probes.get(j)?.as_ref()?;
                            let v = p.dresp[r][k];
                            v.is_finite().then_some((v, p.noise[r][k]))
                        };
                        let (mut s, mut zero, mut plateau) = (0.0f64, false, false);
                        for j in 0..ladder.len() {
                            let Some((v, noise)) = probe(j) else { continue };
                            s = s.max(v.abs());
                            zero |= v.abs() <= NOISE_AGREEMENT * noise;
                            if let Some((w, next)) = probe(j + 1) {
                                plateau |= v.abs() > NOISE_AGREEMENT * noise
                                    && w.abs() > NOISE_AGREEMENT * next
                                    && (v - w).abs() <= PLATEAU * v.abs().max(w.abs());
                            }
                        }
                        let zero = zero && !plateau;
                        (s > 0.0 && !zero && b * s >= 1e-9 * values[r].abs()).then_some(s)
                    })
                    .collect();
                let history =
                    HistoryProbes::new(c, &probes, k, |j| self.params[k].step(ladder[j]).abs());
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
                let order = if central { 2 } else { 1 };
                let last = ladder.len() - 1;
                let last_roundoff = probes[last].as_ref().map_or(f64::INFINITY, |p| {
                    (scales.iter().enumerate())
                        .filter_map(|(r, s)| Some(p.noise[r][k] / (*s)?))
                        .fold(0.0, f64::max)
                });
                let responses = choose_step(disagreement, noise, last, order, last_roundoff)
                    // no two neighbours agree: the largest probe that ran
                    .unwrap_or_else(|| probes.iter().position(Option::is_some).unwrap_or(0));
                // the history's own step, by the same rule on its own differences, where it
                // is the smaller
                let own = history.step(last, order).unwrap_or(responses);
                (responses, own.max(responses))
            })
            .collect();
        let betas: Vec<f64> = chosen.iter().map(|&(jr, _)| ladder[jr]).collect();
        let mut step = Step {
            dresp: vec![vec![0.0; np]; nr],
            dhist: vec![0.0; nh * np],
            dz: Vec::with_capacity(np),
            roundoff: vec![vec![false; np]; nr],
            noise: vec![vec![0.0; np]; nr],
            unbalance_noise: vec![0.0; np],
        };
        for (k, &(jr, jh)) in chosen.iter().enumerate() {
            let p = probes[jr].as_ref().expect("a probe that ran");
            for r in 0..nr {
                step.dresp[r][k] = p.dresp[r][k];
                step.roundoff[r][k] = p.roundoff[r][k];
                step.noise[r][k] = p.noise[r][k];
            }
            step.unbalance_noise[k] = p.unbalance_noise[k];
            let h = probes[jh].as_ref().expect("a probe that ran");
            step.dhist[k * nh..(k + 1) * nh].copy_from_slice(&h.dhist[k * nh..(k + 1) * nh]);
            step.dz.push(p.dz[k].clone());
        }
        // the shadow run, on its own history derivative, at a tenth of each step: the
        // responses', and the history's where it differs
        let tenth = |j: usize| ladder[j] / SHADOW_RATIO;
        let shadow_betas: Vec<f64> = chosen.iter().map(|&(jr, _)| tenth(jr)).collect();
        let history_betas: Vec<f64> = chosen.iter().map(|&(_, jh)| tenth(jh)).collect();
        std::mem::swap(&mut self.dhist, &mut self.shadow_dhist);
        let shadow = self.sdm(c, central, &shadow_betas).map(|mut shadow| {
            // (where that evaluation fails, the shadow keeps the history of the responses'
            // tenth: a bar, not the analysis, depends on it)
            if history_betas != shadow_betas {
                if let Ok(h) = self.sdm(c, central, &history_betas) {
                    for k in (0..np).filter(|&k| chosen[k].0 != chosen[k].1) {
                        shadow.dhist[k * nh..(k + 1) * nh]
                            .copy_from_slice(&h.dhist[k * nh..(k + 1) * nh]);
                    }
                }
            }
            shadow
        });
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A model ladder of differences, `D(h) = d + C h^p + s N / h` (truncation of order `p`,
    /// round-off growing as `1 / h` with alternating sign `s`): of the best-agreeing pair,
    /// [`better_of_pair`] takes the step whose true error (known here) is the smaller.
    fn model(p: i32, c: f64, noise: f64, steps: usize) -> (Vec<f64>, Vec<f64>) {
        let d = 1.0;
        let values: Vec<f64> = (0..steps)
            .map(|i| {
                let h = 10f64.powi(-(i as i32) - 1);
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                d + c * h.powi(p) + sign * noise / h
            })
            .collect();
        let errors = values.iter().map(|v| (v - d).abs()).collect();
        (values, errors)
    }

    fn choose(values: &[f64], order: i32, last_roundoff: f64) -> usize {
        let difference = |i: usize| (values[i] - values[i + 1]).abs();
        let pairs = values.len() - 1;
        let best = (0..pairs)
            .min_by(|a, b| difference(*a).total_cmp(&difference(*b)))
            .unwrap();
        better_of_pair(difference, best, pairs, order, last_roundoff)
    }

    #[test]
    fn the_smaller_step_where_the_best_pair_differs_by_truncation() {
        // central, truncation 1e-8 at 1e-4 and noise 1e-14 / h: the best pair is 1e-4 / 1e-5
        // (a difference of 8.8e-9, against 1.1e-8 below and 1e-6 above), and 1e-5 has the
        // smaller error (1.1e-9 against 9.9e-9)
        let (values, errors) = model(2, 1.0, 1e-14, 8);
        let j = choose(&values, 2, f64::INFINITY);
        let best = (0..values.len())
            .min_by(|a, b| errors[*a].total_cmp(&errors[*b]))
            .unwrap();
        assert_eq!(j, best, "errors {errors:?}");
        assert_eq!(j, 4); // 1e-5
    }

    #[test]
    fn the_larger_step_where_round_off_dominates_the_pair() {
        // forward, a tiny truncation: the pairs differ by round-off, which shrinks up the
        // ladder, and the largest step is the best
        let (values, errors) = model(1, 1e-12, 1e-14, 6);
        let j = choose(&values, 1, f64::INFINITY);
        assert_eq!(j, 0, "errors {errors:?}");
    }

    #[test]
    fn the_larger_step_where_round_off_dominates_a_pair_within_the_ladder() {
        // central, truncation 1e-8 h^2 and noise 1e-13 / h: the best pair is 1e-2 / 1e-3
        // (differences 1.10e-10, 1.09e-10, 1.1e-9, ... down from 1e-1 / 1e-2), whose
        // difference is 1e-3's round-off: 1e-2 has the smaller error (9e-12 against 1e-10),
        // and the pair above shows no truncation to move for
        let (values, errors) = model(2, 1e-8, 1e-13, 6);
        let j = choose(&values, 2, f64::INFINITY);
        assert_eq!(j, 1, "errors {errors:?}");
        assert!(errors[1] < errors[2]);
    }

    #[test]
    fn a_pair_above_that_failed_proves_no_truncation() {
        // the truncation case of the test above with the pair above made not a number: the
        // larger step is kept
        let (values, _) = model(2, 1.0, 1e-14, 8);
        let difference = |i: usize| {
            if i == 2 {
                f64::INFINITY
            } else {
                (values[i] - values[i + 1]).abs()
            }
        };
        assert_eq!(
            better_of_pair(difference, 3, values.len() - 1, 2, f64::INFINITY),
            3
        );
        let finite = |i: usize| (values[i] - values[i + 1]).abs();
        assert_eq!(
            better_of_pair(finite, 3, values.len() - 1, 2, f64::INFINITY),
            4
        );
    }

    #[test]
    fn the_step_where_the_differences_reach_their_round_off() {
        // forward, truncation h and round-off 1e-14 / h, each probe expecting its round-off
        // (the history's rule, `HistoryProbes`): the differences fall to 7.9e-7 at the pair
        // 1e-6 / 1e-7 and rise to 1.2e-6 at 1e-7 / 1e-8, the first pair within its expected
        // round-off (1.1e-6), and 1e-7 is the step of the smallest error (2e-7)
        let (values, errors) = model(1, 1.0, 1e-14, 10);
        let h = |j: usize| 10f64.powi(-(j as i32) - 1);
        let last = values.len() - 1;
        let j = choose_step(
            |j| (values[j] - values[j + 1]).abs(),
            |j| 1e-14 / h(j) + 1e-14 / h(j + 1),
            last,
            1,
            1e-14 / h(last),
        )
        .unwrap();
        let best = (0..values.len())
            .min_by(|a, b| errors[*a].total_cmp(&errors[*b]))
            .unwrap();
        assert_eq!(j, best, "errors {errors:?}");
        assert_eq!(j, 6);
    }

    #[test]
    fn the_last_step_on_its_expected_round_off() {
        // central, the best pair the ladder's last: the smaller step is taken only where its
        // expected round-off is below the larger's error
        let (values, _) = model(2, 1.0, 1e-17, 5);
        let last = values.len() - 1;
        assert_eq!(choose(&values, 2, 1e-13), last);
        assert_eq!(choose(&values, 2, 1e-2), last - 1);
    }
}
