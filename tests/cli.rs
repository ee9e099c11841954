//! The `cloth` binary, run as a user would: good input runs a scene and reports it, bad input
//! gets an error naming the flag and its allowed range, with exit status 2 and no panic.

use std::process::Command;

fn cloth(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args(args)
        .output()
        .expect("run cloth");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn sim_runs_the_drape_and_reports_it() {
    let (code, stdout, stderr) = cloth(&["sim", "drape", "--frames", "20", "--resolution", "12"]);
    assert_eq!(code, 0, "stderr: {stderr}");
    assert!(
        stdout.contains("scene drape 12x12 particles=144"),
        "{stdout}"
    );
    assert!(stdout.contains("particle-substeps/s"), "{stdout}");
    assert!(
        !stdout.contains("NaN") && !stdout.contains("inf"),
        "{stdout}"
    );
}

#[test]
fn bad_flags_name_the_flag_and_the_allowed_range() {
    for (args, needle) in [
        (vec!["--frames", "0"], "`--frames`"),
        (vec!["--resolution", "1"], "2 ..= 4096"),
        (vec!["--integrator", "rk4"], "symplectic-euler"),
        (vec!["no-such-scene"], "allowed drape, hanging, peer-ball"),
        (vec!["--bogus"], "unknown option `--bogus`"),
        (vec!["--frames"], "needs a value"),
    ] {
        let (code, _, stderr) = cloth(&args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}
