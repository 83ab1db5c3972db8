//! Sharded studies (`--shard K/N`, `fricsens merge`): the shares of a validation run and of
//! the scaling study, each run as a process of its own and merged, give the unsharded run's
//! outputs: the validation's data bit for bit (its timings aside), the scaling study's sizes
//! and their counts. Shares of different runs, a missing and a doubled share are refused,
//! naming what is wrong.

use crate::common::{fricsens, scratch_path, succeeds};
use std::path::{Path, PathBuf};

/// Run `fricsens ARGS`, which must succeed.
fn run<S: AsRef<str>>(args: &[S]) {
    succeeds(fricsens().args(args.iter().map(|a| a.as_ref())));
}

/// Run `fricsens ARGS`, which must fail; its stderr.
fn refused<S: AsRef<str>>(args: &[S]) -> String {
    let args: Vec<&str> = args.iter().map(|a| a.as_ref()).collect();
    let out = fricsens().args(&args).output().expect("fricsens runs");
    assert!(
        !out.status.success(),
        "fricsens {} succeeded",
        args.join(" ")
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The files under `dir` (relative paths), partial results left out.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else if !p
                .file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("partial-")
            {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// A timing: a wall time, or a ratio of wall times. They differ between any two runs.
fn timing(key: &str) -> bool {
    key.contains("seconds") || key.ends_with("cost_ratio") || key == "cost" || key == "ratios"
}

/// `v` without its timings.
fn untimed(v: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(
            m.into_iter()
                .filter(|(k, _)| !timing(k))
                .map(|(k, v)| (k, untimed(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.into_iter().map(untimed).collect()),
        v => v,
    }
}

/// A CSV without the columns whose header is a timing.
fn untimed_csv(text: &str) -> String {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let keep: Vec<bool> = header.iter().map(|h| !timing(h)).collect();
    text.lines()
        .map(|l| {
            // the failure column is quoted text that may hold commas: it is the last
            let (fields, rest) = match l.find('"') {
                Some(q) => (&l[..q], &l[q..]),
                None => (l, ""),
            };
            let kept: Vec<&str> = fields
                .split(',')
                .zip(keep.iter().chain(std::iter::repeat(&true)))
                .filter(|(_, k)| **k)
                .map(|(f, _)| f)
                .collect();
            format!("{}{rest}", kept.join(","))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn validation_shards_merged_equal_the_unsharded_run_bit_for_bit() {
    let root = scratch_path("validate-shards");
    let _ = std::fs::remove_dir_all(&root);
    let (whole, shared, other) = (root.join("whole"), root.join("shared"), root.join("other"));
    let (whole_s, shared_s) = (whole.to_str().unwrap(), shared.to_str().unwrap());
    // five jobs (four scenes and the friction laws on a coarse strip), three shares
    let args = |out: &str| -> Vec<String> {
        [
            "validate",
            "uniaxial-j2",
            "jenkins",
            "klarbring-2dof",
            "cantilever-small",
            "--beta-max",
            "1e-2",
            "--beta-min",
            "1e-4",
            "--friction-laws",
            "20",
            "--out",
            out,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let with = |mut v: Vec<String>, more: &[&str]| {
        v.extend(more.iter().map(|s| s.to_string()));
        v
    };
    run(&args(whole_s));
    for k in 1..=3 {
        run(&with(args(shared_s), &["--shard", &format!("{k}/3")]));
    }
    let part = |k: usize| shared.join(format!("partial-{k}-of-3.json"));
    let merge = |parts: &[PathBuf]| -> Vec<String> {
        std::iter::once("merge".to_string())
            .chain(parts.iter().map(|p| p.display().to_string()))
            .collect()
    };

    // refused: a missing share, a doubled one, a share of another run (other betas)
    let e = refused(&merge(&[part(1), part(3)]));
    assert!(e.contains("share 2 of 3 is missing"), "{e}");
    let e = refused(&merge(&[part(1), part(2), part(2)]));
    assert!(e.contains("share 2 of 3 is given twice"), "{e}");
    let mut o = args(other.to_str().unwrap());
    let at = o.iter().position(|a| a == "--beta-min").unwrap() + 1;
    o[at] = "1e-3".into();
    run(&with(o, &["--shard", "3/3"]));
    let e = refused(&merge(&[
        part(1),
        part(2),
        other.join("partial-3-of-3.json"),
    ]));
    assert!(
        e.contains("not shares of the same sweep") && e.contains("betas"),
        "{e}"
    );

    run(&merge(&[part(3), part(1), part(2)]));
    assert_eq!(files(&whole), files(&shared));
    let mut sensitivities = 0;
    for f in files(&whole) {
        let name = f.to_string_lossy().into_owned();
        let (a, b) = (read(&whole.join(&f)), read(&shared.join(&f)));
        if name.ends_with("-sensitivities.csv") {
            sensitivities += 1;
            assert!(a == b, "{name} differs");
        } else if name.ends_with("-errors.csv") {
            assert!(a.starts_with("scene,method,beta,param,error,cost_ratio,"));
            assert!(untimed_csv(&a) == untimed_csv(&b), "{name} differs");
        } else if name.ends_with(".json") {
            let parse = |t: &str| untimed(serde_json::from_str(t).unwrap());
            assert!(parse(&a) == parse(&b), "{name} differs beyond its timings");
        }
    }
    assert_eq!(sensitivities, 4);
}

#[test]
fn scaling_shards_merged_measure_the_unsharded_sizes() {
    let root = scratch_path("scaling-shards");
    let _ = std::fs::remove_dir_all(&root);
    let (whole, shared) = (root.join("whole"), root.join("shared"));
    let (whole_s, shared_s) = (whole.to_str().unwrap(), shared.to_str().unwrap());
    run(&["scaling", "--quick", "--out", whole_s]);
    for k in ["1/2", "2/2"] {
        run(&["scaling", "--quick", "--out", shared_s, "--shard", k]);
    }
    let e = refused(&[
        "merge".to_string(),
        shared.join("partial-2-of-2.json").display().to_string(),
    ]);
    assert!(e.contains("share 1 of 2 is missing"), "{e}");
    run(&[
        "merge",
        shared.join("partial-1-of-2.json").to_str().unwrap(),
        shared.join("partial-2-of-2.json").to_str().unwrap(),
    ]);
    // the sizes and what does not depend on the clock: the same rows in the same order
    let sizes = |dir: &Path| -> Vec<String> {
        let csv = read(&dir.join("scaling.csv"));
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let cols: Vec<usize> = [
            "scene",
            "refinement",
            "dofs",
            "unknowns",
            "elements",
            "increments",
            "newton_iterations",
            "factorizations",
        ]
        .iter()
        .map(|c| header.iter().position(|h| h == c).expect(c))
        .collect();
        csv.lines()
            .skip(1)
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                cols.iter().map(|c| f[*c]).collect::<Vec<_>>().join(",")
            })
            .collect()
    };
    let (a, b) = (sizes(&whole), sizes(&shared));
    assert_eq!(a.len(), 6, "{a:?}");
    assert_eq!(a, b);
    assert!(shared.join("scaling.md").exists() && shared.join("scaling.svg").exists());
}
