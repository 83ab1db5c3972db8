//! A finite-difference sweep split into shares run as separate processes (`fricsens
//! sensitivity --shard K/N`) and merged (`fricsens merge`) gives the unsharded run's
//! sensitivities bit for bit; shares that do not make one sweep are refused, naming why.

use crate::common::{fricsens, scratch_path, succeeds};
use std::path::Path;

fn run(args: &[&str]) -> std::process::Output {
    succeeds(fricsens().args(args))
}

fn increments(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("sensitivity.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["increments"].clone()
}

#[test]
fn shards_run_apart_and_merged_equal_the_unsharded_sweep_bit_for_bit() {
    let root = scratch_path("shards");
    let _ = std::fs::remove_dir_all(&root);
    let (full, parts, merged) = (root.join("full"), root.join("parts"), root.join("merged"));
    let scene = "leaf-spring-coarse";
    let common = [
        "--method",
        "fdm-central",
        "--beta",
        "1e-5",
        "--param",
        "mu",
        "--param",
        "E",
    ];
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let mut args: Vec<&str> = vec!["sensitivity", scene];
    args.extend(common);
    let full_s = s(&full);
    run(&[&args[..], &["--out", &full_s]].concat());
    // four reruns (two parameters, both signs) over three shares: 2 + 1 + 1
    let parts_s = s(&parts);
    for k in ["1/3", "2/3", "3/3"] {
        run(&[&args[..], &["--shard", k, "--out", &parts_s]].concat());
    }
    let files: Vec<String> = (1..=3)
        .map(|k| s(&parts.join(format!("partial-{k}-of-3.json"))))
        .collect();
    let merged_s = s(&merged);
    let mut m: Vec<&str> = vec!["merge"];
    m.extend(files.iter().map(|f| f.as_str()));
    m.extend(["--out", &merged_s]);
    run(&m);
    let (a, b) = (increments(&full), increments(&merged));
    assert_eq!(a.as_array().unwrap().len(), 18);
    // serde_json writes each double as the shortest text that reads back as it: equal
    // values are equal bits
    assert_eq!(a, b);
    // a share missing, and a share of another sweep
    let out = fricsens()
        .args(["merge", &files[0], &files[1]])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("run by no share"));
    let other = s(&root.join("other"));
    let mut a2: Vec<&str> = vec!["sensitivity", scene, "--method", "fdm-central"];
    a2.extend(["--beta", "1e-4", "--param", "mu", "--param", "E"]);
    run(&[&a2[..], &["--shard", "3/3", "--out", &other]].concat());
    let foreign = s(&root.join("other").join("partial-3-of-3.json"));
    let out = fricsens()
        .args(["merge", &files[0], &files[1], &foreign])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("not of the same sweep: their betas differ"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&root);
}
