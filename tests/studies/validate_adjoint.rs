//! The adjoint in the validation's comparison tables: every response at the last increment of
//! each scene, by one backward sweep, against DDM (an independent method: forward, per
//! parameter), and its row in the report's cost table.

use crate::common::scratch_path;

use fricsens::studies::validate::{default_scenes, validate, ValidateOptions};

#[test]
fn the_adjoint_at_the_last_increment_equals_ddm_in_the_report() {
    let out = scratch_path("validate-adjoint");
    let _ = std::fs::remove_dir_all(&out);
    let keep = [
        "uniaxial-j2",
        "jenkins",
        "klarbring-2dof",
        "cantilever-small",
    ];
    let scenes: Vec<_> = default_scenes(false)
        .into_iter()
        .filter(|s| keep.contains(&s.name.as_str()))
        .collect();
    assert_eq!(scenes.len(), keep.len());
    let opts = ValidateOptions {
        out: out.clone(),
        betas: vec![1e-4],
        friction_laws: None,
        imported: None,
        ..ValidateOptions::default()
    };
    let v = validate(&scenes, &opts).expect("validation runs");
    for s in &v.scenes {
        let a = &s.adjoint;
        assert!(a.failure.is_none(), "{}: {:?}", s.scene, a.failure);
        assert_eq!(a.errors.len(), s.params.len(), "{}", s.scene);
        for (p, e) in s.params.iter().zip(&a.errors) {
            // the README's claim: the adjoint equals DDM to 1e-10 of each sensitivity's scale
            assert!(
                *e <= 1e-10,
                "{}: d/d {p}: adjoint against DDM {e:e}",
                s.scene
            );
        }
        assert!(a.cost_ratio.is_finite() && a.cost_ratio > 0.0);
        assert!(a.stored_bytes > 0, "{}", s.scene);
    }
    let md = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(md.contains("| adjoint (last increment, every response) (error) |"));
    assert!(md.contains("**Adjoint.** Every response at the last increment"));
}
