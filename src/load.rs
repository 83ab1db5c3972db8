//! Loads in pseudo-time: the amplitudes that scale prescribed displacements, nodal loads and
//! rigid motions.

/// Piecewise-linear amplitude of pseudo-time, constant beyond its ends.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Amplitude {
    /// `(time, value)` pairs with increasing times.
    pub points: Vec<(f64, f64)>,
}

impl Amplitude {
    /// Linear ramp from 0 at t = 0 to 1 at t = 1.
    pub fn ramp() -> Self {
        Amplitude {
            points: vec![(0.0, 0.0), (1.0, 1.0)],
        }
    }

    /// Value at time `t`.
    pub fn at(&self, t: f64) -> f64 {
        let p = &self.points;
        if p.is_empty() {
            return 0.0;
        }
        if t <= p[0].0 {
            return p[0].1;
        }
        for w in p.windows(2) {
            let (t0, v0) = w[0];
            let (t1, v1) = w[1];
            if t <= t1 {
                if t1 == t0 {
                    return v1;
                }
                return v0 + (v1 - v0) * (t - t0) / (t1 - t0);
            }
        }
        p[p.len() - 1].1
    }
}
