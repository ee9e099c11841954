//! Helpers shared by the end-to-end tests (`mod common;`); each file uses a part of them.
#![allow(dead_code)]

use std::process::Command;

/// Whether the tests run in CI (`CI` set and not `false` or `0`): there a missing tool, adapter
/// or display fails a test instead of skipping it.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !v.is_empty() && v != "false" && v != "0")
}

/// Whether `tool` is on the PATH. Missing, it fails the test in CI (naming the apt `package`)
/// and otherwise prints a loud note that `what` is not tested, for the test to skip.
pub fn have(tool: &str, package: &str, what: &str) -> bool {
    let found = Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            !in_ci(),
            "CI=true but {tool} is missing: apt-get install {package}"
        );
        eprintln!("\n!!!!! SKIPPED: {tool} not found, {what} is NOT tested\n");
    }
    found
}
