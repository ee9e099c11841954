//! The window app end to end: `cloth view drape --frames 30` under a virtual X display opens a
//! window, draws 30 frames and exits with status 0.
//!
//! Needs `xvfb-run` (apt package `xvfb` + `xauth`) and a graphics adapter (Mesa's software
//! renderer will do). Outside CI a missing `xvfb-run` skips loudly; in CI (`CI=true`) it fails.

mod common;

use std::process::Command;

#[test]
fn view_drape_runs_thirty_frames_under_xvfb_and_exits_cleanly() {
    if !common::have("xvfb-run", "xvfb xauth", "the window app") {
        return;
    }
    let xdg = std::env::temp_dir().join("cloth-test-xdg-view");
    let _ = std::fs::create_dir_all(&xdg);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = std::fs::set_permissions(&xdg, std::fs::Permissions::from_mode(0o700));
    }
    let out = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x800x24"])
        .arg(env!("CARGO_BIN_EXE_cloth"))
        .args([
            "view",
            "drape",
            "--frames",
            "30",
            "--resolution",
            "24",
            "--size",
            "640x400",
        ])
        .env("XDG_RUNTIME_DIR", &xdg)
        .output()
        .expect("run xvfb-run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "stderr: {stderr}");
    assert!(stderr.contains("cloth view: drape on"), "{stderr}");
}
