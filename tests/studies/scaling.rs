//! The scaling study (issue 7): the reduced path of the command line end to end (two small
//! sizes per scene, each in its own child process), the power-law fits against synthetic
//! laws (oracle), and bad input. The study itself is `fricsens scaling` (tens of minutes).

use crate::common::{fricsens, scratch_path, succeeds};

use fricsens::studies::scaling::{fit_all, Measurement, ScalingScene, Study, QUANTITIES};
use std::path::PathBuf;

#[test]
fn quick_study_writes_csv_svg_and_markdown_with_finite_exponents() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("scaling-quick");
    let _ = std::fs::remove_dir_all(&dir);
    succeeds(fricsens().args(["scaling", "--quick", "--out"]).arg(&dir));

    // CSV: a header and two sizes per scene, each with its own peak memory
    let csv = std::fs::read_to_string(dir.join("scaling.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    assert_eq!(lines.len(), 1 + 2 * ScalingScene::ALL.len(), "{csv}");
    let peak = header.iter().position(|h| *h == "peak_mib").unwrap();
    let dofs = header.iter().position(|h| *h == "dofs").unwrap();
    for l in &lines[1..] {
        let f: Vec<&str> = l.split(',').collect();
        assert_eq!(f.len(), header.len(), "{l}");
        let mib: f64 = f[peak].parse().expect("peak memory measured in the child");
        assert!(mib > 1.0 && mib < 4096.0, "{l}");
        let n: usize = f[dofs].parse().unwrap();
        assert!((1000..5000).contains(&n), "{l}");
    }

    // the JSON record gives back the study, every fit finite
    let json = std::fs::read_to_string(dir.join("scaling.json")).unwrap();
    let study: Study = serde_json::from_str(&json).unwrap();
    let study = study.fitted();
    assert_eq!(study.fits.len(), ScalingScene::ALL.len() * QUANTITIES.len());
    for f in &study.fits {
        let law = f.law.unwrap_or_else(|| panic!("{f:?}"));
        assert!(law.exponent.is_finite() && law.coefficient > 0.0, "{f:?}");
    }

    // markdown: the section heading, the table, the exponents, the verdict
    let md = std::fs::read_to_string(dir.join("scaling.md")).unwrap();
    assert!(md.starts_with("## Scaling\n"), "{md}");
    for part in [
        "| scene | DOFs |",
        "### Fitted exponents",
        "### Where the sparse direct solver stops being the right tool",
        "**Verdict.**",
        "scaling.svg",
    ] {
        assert!(md.contains(part), "missing {part}");
    }
    assert!(!md.contains("NaN") && !md.contains(" inf"), "{md}");

    // SVG: three panels (primal, sensitivity, memory)
    let svg = std::fs::read_to_string(dir.join("scaling.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("Peak resident memory"));

    // --rewrite reproduces the markdown from the record alone
    std::fs::remove_file(dir.join("scaling.md")).unwrap();
    succeeds(fricsens().args(["scaling", "--rewrite", "--out"]).arg(&dir));
    assert_eq!(std::fs::read_to_string(dir.join("scaling.md")).unwrap(), md);
}

/// A measurement whose every fitted quantity follows an exact power law of its DOFs.
fn synthetic(scene: ScalingScene, dofs: usize) -> Measurement {
    let n = dofs as f64;
    Measurement {
        scene,
        refinement: 1.0,
        elements: dofs / 13,
        unknowns: dofs + dofs / 5,
        dofs,
        increments: 2,
        newton_iterations: 4,
        factorizations: Some(4),
        setup_seconds: 1e-6 * n,
        primal_seconds: 3e-8 * n.powf(1.5),
        assembly_seconds: 1e-7 * n,
        factor_seconds: 2e-8 * n.powf(1.8),
        solve_seconds: 1e-8 * n,
        parameters: 2,
        ddm_seconds: 5e-7 * n.powf(1.1),
        ddm_factorizations: 0,
        sdm_seconds: 4e-7 * n.powf(1.05),
        sdm_factorizations: 0,
        peak_mib: Some(0.02 * n.powf(4.0 / 3.0)),
        threads: Some(2),
        separate: false,
    }
}

#[test]
fn a_size_measured_on_its_own_replaces_its_not_measured_entry() {
    use fricsens::studies::scaling::{merge_measurements, write_outputs, Skipped};
    let dir = scratch_path("merge");
    let _ = std::fs::remove_dir_all(&dir);
    let rows: Vec<Measurement> = [1_000usize, 4_000, 16_000]
        .iter()
        .map(|&n| synthetic(ScalingScene::LeafSpring, n))
        .collect();
    let study = Study {
        rows,
        skipped: vec![Skipped {
            scene: ScalingScene::LeafSpring,
            refinement: 10.4,
            dofs: 64_000,
            reason: "wall time extrapolated above the budget".into(),
        }],
        fits: Vec::new(),
        machine_mib: 24_000.0,
        cpus: 2,
        wall_seconds: 1.0,
        quick: false,
        time_budget_seconds: Some(300.0),
    }
    .fitted();
    write_outputs(&study, &dir).unwrap();
    let mut big = synthetic(ScalingScene::LeafSpring, 64_000);
    big.refinement = 10.4;
    big.threads = Some(1);
    // measured before the factorizations were recorded
    big.factorizations = None;
    let merged = merge_measurements(&dir, vec![big]).unwrap();
    assert!(merged.skipped.is_empty());
    assert_eq!(merged.rows.len(), 4);
    let last = merged.rows.last().unwrap();
    assert!(
        last.separate && last.dofs == 64_000,
        "sorted by DOFs, marked"
    );
    // the fits now reach the merged size: the synthetic law's exponent is exact
    let fit = merged
        .fit(ScalingScene::LeafSpring, QUANTITIES[0].0)
        .unwrap();
    assert_eq!(fit.x_range.1, 64_000.0, "{fit:?}");
    // ... except those per Newton iteration, which need every iteration counted
    let lu = merged
        .fit(ScalingScene::LeafSpring, "factorization")
        .unwrap();
    assert_eq!(lu.x_range.1, 16_000.0, "{lu:?}");
    assert!((lu.exponent - 1.8).abs() < 1e-9, "{lu:?}");
    let md = std::fs::read_to_string(dir.join("scaling.md")).unwrap();
    assert!(md.contains("| leaf-spring (*) | 64000 |"), "{md}");
    assert!(
        md.contains("on one thread") && !md.contains("Not measured"),
        "{md}"
    );
    // a second merge of the same size replaces it rather than adding a row
    let again = merge_measurements(&dir, vec![merged.rows[3].clone()]).unwrap();
    assert_eq!(again.rows.len(), 4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fits_recover_synthetic_power_laws_over_the_largest_half() {
    // the smallest sizes break the law: the fit must use the largest half only
    let mut rows = Vec::new();
    for (k, n) in [1_000usize, 3_000, 9_000, 27_000, 81_000, 243_000]
        .into_iter()
        .enumerate()
    {
        let mut m = synthetic(ScalingScene::LeafSpring3d, n);
        if k < 3 {
            m.primal_seconds *= 7.0 + k as f64;
            m.peak_mib = m.peak_mib.map(|p| p + 500.0);
        }
        rows.push(m);
    }
    let fits = fit_all(&rows);
    let get = |q: &str| {
        fits.iter()
            .find(|f| f.quantity == q)
            .and_then(|f| f.law)
            .unwrap()
    };
    let expect = [
        ("primal-increment", 1.5),
        ("primal-iteration", 1.5),
        ("factorization", 1.8),
        ("ddm", 1.1),
        ("sdm", 1.05),
        ("memory", 4.0 / 3.0),
    ];
    for (q, a) in expect {
        let l = get(q);
        assert!((l.exponent - a).abs() < 1e-9, "{q}: {l:?}");
        assert_eq!(l.points, 3, "{q}");
        assert_eq!(l.x_range, (27_000.0, 243_000.0), "{q}");
    }
    // the memory law's coefficient, and where it reaches a budget
    let m = get("memory");
    assert!((m.coefficient / 0.02 - 1.0).abs() < 1e-9);
    let n = m.reaches(24.0 * 1024.0).unwrap();
    assert!((0.02 * n.powf(4.0 / 3.0) / (24.0 * 1024.0) - 1.0).abs() < 1e-9);
}

#[test]
fn bad_scene_and_refinement_fail_with_a_message() {
    for args in [
        ["--scene", "cantilever", "--refinement", "1"],
        ["--scene", "indentation", "--refinement", "-1"],
        ["--scene", "leaf-spring", "--refinement", "NaN"],
        ["--scene", "leaf-spring-3d", "--refinement", "1e9"],
    ] {
        let out = fricsens().arg("scaling-one").args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.starts_with("error: "), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
