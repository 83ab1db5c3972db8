//! Shares of a sweep (`--shard K/N`): what a share writes, how the shares are checked against
//! each other, and the exact JSON their results travel in.
//!
//! A sweep is a fixed list of independent jobs; share `K` of `N` runs the jobs whose position
//! is `K - 1` modulo `N` ([`crate::sensitivity::Shard`]) and writes
//! `OUT/partial-K-of-N.json`: a JSON object tagged by `kind` (`validate`, `scaling`; an FDM
//! sweep's partial has no `kind`), the sweep it belongs to (everything its jobs depend on),
//! and its jobs' results. `fricsens merge` refuses shares of different sweeps, a missing or a
//! doubled share ([`ShardError`]) and hands the results, in job order, to the code that the
//! unsharded run ends with, so that the merged outputs are the unsharded run's.
//!
//! **Exact JSON.** A result may hold NaN (a method that gave no value) or an infinity, which
//! JSON has no number for (`serde_json` writes `null` and cannot read it back as a float).
//! [`to_exact_json`] writes every non-finite float as `{"f64_bits": "0x..."}` (its bits) and
//! every finite one as the shortest decimal that reads back to the same bits;
//! [`from_exact_json`] reads both back. The results go through [`toml::Value`], whose floats
//! are plain `f64`, on the way; it keeps every float's bits but a NaN's sign and payload (a
//! NaN comes back as the positive quiet NaN; every output prints any NaN alike).

use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The key of a non-finite float in [`to_exact_json`]'s output.
const BITS_KEY: &str = "f64_bits";

/// Why shares do not merge, or a partial result cannot be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    /// No partial results given.
    #[error("no partial results to merge")]
    Empty,
    /// A file that is not a partial result of the expected kind.
    #[error("{path}: {why}")]
    Read {
        /// The file.
        path: String,
        /// What is wrong with it.
        why: String,
    },
    /// Two shares of different sweeps.
    #[error("{a} and {b} are not shares of the same sweep: their {what} differ")]
    Mismatch {
        /// One share's file.
        a: String,
        /// The other's.
        b: String,
        /// What differs.
        what: String,
    },
    /// A share no file holds.
    #[error("share {index} of {count} is missing (given: {given})")]
    Missing {
        /// `K`.
        index: usize,
        /// `N`.
        count: usize,
        /// The shares given.
        given: String,
    },
    /// A share given twice.
    #[error("share {index} of {count} is given twice: {a} and {b}")]
    Doubled {
        /// `K`.
        index: usize,
        /// `N`.
        count: usize,
        /// One file.
        a: String,
        /// The other.
        b: String,
    },
    /// A share holds a job that is not its own, or a job no share ran.
    #[error("job {job} of {of} ({name}): {why}")]
    Coverage {
        /// The job's position in the sweep.
        job: usize,
        /// The sweep's number of jobs.
        of: usize,
        /// The job's name.
        name: String,
        /// What is wrong.
        why: &'static str,
    },
    /// A scene that is not the one the shares ran (its file changed since).
    #[error("scene '{0}' is not the one the shares ran (its definition changed since): run the shares again")]
    SceneChanged(String),
}

/// `value` as JSON that [`from_exact_json`] reads back bit for bit, infinities and signed
/// zeros included, and NaN as NaN (module docs).
pub fn to_exact_json<T: Serialize>(value: &T) -> Result<serde_json::Value, String> {
    let v = toml::Value::try_from(value).map_err(|e| e.to_string())?;
    Ok(toml_to_json(v))
}

/// The value [`to_exact_json`] wrote.
pub fn from_exact_json<T: DeserializeOwned>(json: serde_json::Value) -> Result<T, String> {
    let v = json_to_toml(json)?;
    T::deserialize(v).map_err(|e| e.to_string())
}

fn toml_to_json(v: toml::Value) -> serde_json::Value {
    use serde_json::Value as J;
    match v {
        toml::Value::String(s) => J::String(s),
        toml::Value::Integer(i) => J::from(i),
        toml::Value::Float(f) => match serde_json::Number::from_f64(f) {
            Some(n) => J::Number(n),
            None => {
                let mut m = serde_json::Map::new();
                m.insert(BITS_KEY.into(), J::String(format!("{:#018x}", f.to_bits())));
                J::Object(m)
            }
        },
        toml::Value::Boolean(b) => J::Bool(b),
        toml::Value::Datetime(d) => J::String(d.to_string()),
        toml::Value::Array(a) => J::Array(a.into_iter().map(toml_to_json).collect()),
        toml::Value::Table(t) => {
            J::Object(t.into_iter().map(|(k, v)| (k, toml_to_json(v))).collect())
        }
    }
}

fn json_to_toml(v: serde_json::Value) -> Result<toml::Value, String> {
    use serde_json::Value as J;
    Ok(match v {
        J::Null => return Err("a null where a value was written".into()),
        J::Bool(b) => toml::Value::Boolean(b),
        J::Number(n) => {
            if let Some(i) = n.as_i64() {
                toml::Value::Integer(i)
            } else if n.is_f64() {
                toml::Value::Float(n.as_f64().expect("an f64"))
            } else {
                return Err(format!("integer {n} out of range"));
            }
        }
        J::String(s) => toml::Value::String(s),
        J::Array(a) => {
            toml::Value::Array(a.into_iter().map(json_to_toml).collect::<Result<_, _>>()?)
        }
        J::Object(m) => {
            if m.len() == 1 {
                if let Some(J::String(bits)) = m.get(BITS_KEY) {
                    let b = u64::from_str_radix(bits.trim_start_matches("0x"), 16)
                        .map_err(|e| format!("{BITS_KEY} `{bits}`: {e}"))?;
                    return Ok(toml::Value::Float(f64::from_bits(b)));
                }
            }
            let mut t = toml::Table::new();
            for (k, v) in m {
                t.insert(k, json_to_toml(v)?);
            }
            toml::Value::Table(t)
        }
    })
}

/// `DIR/partial-K-of-N.json`.
pub fn partial_path(dir: &Path, shard: crate::sensitivity::Shard) -> PathBuf {
    dir.join(format!("partial-{}-of-{}.json", shard.index, shard.count))
}

/// Read a partial result's JSON and check its `kind`.
pub fn read_partial(path: &Path, kind: &str) -> Result<serde_json::Value, ShardError> {
    let bad = |why: String| ShardError::Read {
        path: path.display().to_string(),
        why,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    match v.get("kind").and_then(|k| k.as_str()) {
        Some(k) if k == kind => Ok(v),
        Some(k) => Err(bad(format!(
            "a partial result of a {k} sweep, not of a {kind} one"
        ))),
        None => Err(bad(format!(
            "not a partial result of a {kind} sweep (no `kind`)"
        ))),
    }
}

/// The `kind` of a partial result file (`None`: none, as an FDM sweep's share).
pub fn partial_kind(path: &Path) -> Result<Option<String>, ShardError> {
    let bad = |why: String| ShardError::Read {
        path: path.display().to_string(),
        why,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    Ok(v.get("kind").and_then(|k| k.as_str()).map(str::to_string))
}

/// Check that `shards` (with the files they came from) are every share of `1..=N` exactly
/// once, `N` the same for all.
pub fn check_coverage(shards: &[(crate::sensitivity::Shard, String)]) -> Result<(), ShardError> {
    let (first, first_file) = shards.first().ok_or(ShardError::Empty)?;
    let count = first.count;
    let mut seen: Vec<Option<&str>> = vec![None; count];
    for (s, file) in shards {
        if s.index == 0 || s.index > s.count {
            return Err(ShardError::Read {
                path: file.clone(),
                why: format!("share {} of {}: not a share", s.index, s.count),
            });
        }
        if s.count != count {
            return Err(ShardError::Mismatch {
                a: first_file.clone(),
                b: file.clone(),
                what: format!("share counts ({} and {})", count, s.count),
            });
        }
        let slot = &mut seen[s.index - 1];
        if let Some(a) = slot {
            return Err(ShardError::Doubled {
                index: s.index,
                count,
                a: a.to_string(),
                b: file.clone(),
            });
        }
        *slot = Some(file);
    }
    if let Some(k) = seen.iter().position(|s| s.is_none()) {
        let mut given: Vec<usize> = shards.iter().map(|(s, _)| s.index).collect();
        given.sort_unstable();
        return Err(ShardError::Missing {
            index: k + 1,
            count,
            given: given
                .iter()
                .map(|k| k.to_string())
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    Ok(())
}

/// Put each share's `(job, result)` in its place among `names.len()` jobs: every job once,
/// each from the share it belongs to.
pub fn collect_jobs<T>(
    names: &[String],
    shares: Vec<(crate::sensitivity::Shard, Vec<(usize, T)>)>,
) -> Result<Vec<T>, ShardError> {
    let of = names.len();
    let mut slots: Vec<Option<T>> = (0..of).map(|_| None).collect();
    for (shard, jobs) in shares {
        for (j, out) in jobs {
            let name = names.get(j).cloned().unwrap_or_else(|| "?".into());
            let coverage = |why| ShardError::Coverage {
                job: j,
                of,
                name: name.clone(),
                why,
            };
            if j >= of || !shard.takes(j) {
                return Err(coverage("not a job of the share that holds it"));
            }
            if slots[j].is_some() {
                return Err(coverage("run by two shares"));
            }
            slots[j] = Some(out);
        }
    }
    slots
        .into_iter()
        .enumerate()
        .map(|(j, s)| {
            s.ok_or_else(|| ShardError::Coverage {
                job: j,
                of,
                name: names[j].clone(),
                why: "run by no share",
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Sample {
        a: f64,
        v: Vec<Vec<f64>>,
        o: Option<String>,
        n: usize,
        t: (f64, f64),
    }

    #[test]
    fn floats_round_trip_bit_for_bit_and_nan_as_nan() {
        let s = Sample {
            a: f64::NAN,
            v: vec![
                vec![f64::INFINITY, f64::NEG_INFINITY, -0.0, 0.1 + 0.2],
                vec![f64::MIN_POSITIVE, 1e300, 1.0],
            ],
            o: None,
            n: 7,
            t: (2.0, -f64::NAN),
        };
        let text = serde_json::to_string(&to_exact_json(&s).unwrap()).unwrap();
        let back: Sample = from_exact_json(serde_json::from_str(&text).unwrap()).unwrap();
        // a NaN's sign and payload are not kept: NaN as the positive quiet NaN
        let bits = |x: &Sample| -> Vec<u64> {
            std::iter::once(x.a)
                .chain(x.v.iter().flatten().copied())
                .chain([x.t.0, x.t.1])
                .map(|f| if f.is_nan() { f64::NAN } else { f }.to_bits())
                .collect()
        };
        assert_eq!(bits(&back), bits(&s));
        assert!(back.a.is_nan() && back.t.1.is_nan());
        assert_eq!((back.o, back.n), (None, 7));
    }

    #[test]
    fn shares_must_cover_one_to_n_once() {
        use crate::sensitivity::Shard;
        let sh = |index, count| Shard { index, count };
        let f = |k: usize| format!("p{k}");
        assert!(check_coverage(&[(sh(2, 2), f(2)), (sh(1, 2), f(1))]).is_ok());
        assert!(matches!(
            check_coverage(&[(sh(1, 3), f(1)), (sh(3, 3), f(3))]),
            Err(ShardError::Missing {
                index: 2,
                count: 3,
                ..
            })
        ));
        assert!(matches!(
            check_coverage(&[(sh(1, 2), f(1)), (sh(1, 2), f(3))]),
            Err(ShardError::Doubled { index: 1, .. })
        ));
        assert!(matches!(
            check_coverage(&[(sh(1, 2), f(1)), (sh(2, 3), f(2))]),
            Err(ShardError::Mismatch { .. })
        ));
    }
}
