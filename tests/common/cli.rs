//! The command-line program and scratch paths.

use std::path::PathBuf;
use std::process::Command;

/// The `fricsens` executable of this build.
pub fn fricsens() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fricsens"))
}

/// `fricsens-NAME-PID` in the system's temporary directory (not created): distinct per test
/// process, and per test as long as the names differ.
pub fn scratch_path(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("fricsens-{name}-{}", std::process::id()))
}

/// Runs `cmd` and returns its output, failing with the command and its standard error
/// unless it succeeded.
pub fn succeeds(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}
