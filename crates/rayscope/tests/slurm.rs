//! The Slurm batch script on a real one-node Slurm cluster: `deploy/slurm/test-cluster.sh` starts
//! munged, slurmctld and slurmd on this machine (as root, no systemd), submits
//! `deploy/slurm/render.sbatch` as a job array of parts plus a merge job that depends on it, and
//! checks that each merged image is byte for byte the local render; it stops the daemons and
//! removes its files whatever happens.
//!
//! Without root or Debian's `slurmctld`, `slurmd`, `slurm-client` and `munge` the test fails when
//! `CI=true` and otherwise says on the terminal that it did not run.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn on_path(exe: &str) -> bool {
    let dirs = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&dirs)
        .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/sbin")])
        .any(|d| d.join(exe).is_file())
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

#[test]
fn job_array_on_a_one_node_slurm_cluster_merges_into_the_local_render() {
    let missing: Vec<&str> = ["munged", "slurmctld", "slurmd", "sbatch", "squeue", "sinfo", "scontrol"]
        .into_iter()
        .filter(|e| !on_path(e))
        .collect();
    if !missing.is_empty() || !is_root() {
        rayscope_testkit::not_run(
            "needs Slurm, MUNGE and root",
            &format!(
                "Missing: {}{}.",
                missing.join(", "),
                if is_root() { "" } else { " (and this is not root)" }
            ),
            "To run it, as root: apt-get install slurm-wlm munge (the test starts and stops the daemons itself).",
        );
        return;
    }
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let root = rayscope_testkit::workspace();
    let script = root.join("deploy/slurm/test-cluster.sh");
    let cases = [
        // A course scene with its OBJ bunny, and our path-traced glossy scene at -q 2.
        format!("{}|3|-w 64 -h 48 -x 2", course.scene("sample_scene_obj.txt").display()),
        format!(
            "{}|4|-w 72 -h 40 -q 2 -l",
            rayscope_testkit::scene("glossy.txt").display()
        ),
    ];
    let out = Command::new("bash")
        .arg(&script)
        .arg(Path::new(env!("CARGO_BIN_EXE_rayscope")))
        .args(&cases)
        .env_remove("SLURM_CONF")
        .output()
        .expect("run deploy/slurm/test-cluster.sh");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "test-cluster.sh failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    for i in 0..cases.len() {
        assert!(
            stdout.contains(&format!("case {i}: ")) && stdout.contains("identical to the local render"),
            "{stdout}\n{stderr}"
        );
    }
    assert_eq!(
        stdout.matches("merged image identical to the local render").count(),
        cases.len(),
        "{stdout}"
    );
}
