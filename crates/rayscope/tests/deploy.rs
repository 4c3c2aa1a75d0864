//! The Kubernetes manifests in deploy/kubernetes: parsed, their fields checked against what
//! docs/farm.md promises, and their commands run here, pod by pod, with `/work` in a temporary
//! folder: the parts the Indexed Job writes merge, with the merge Job's command, into the local
//! render. (No cluster: kubeconform is not packaged for Debian, PyPI or npm.)

mod common;

use std::fs;
use std::path::Path;
use std::process::Command;

use yaml_rust2::{Yaml as Value, YamlLoader};

fn manifest(name: &str) -> Value {
    let path = rayscope_testkit::workspace().join("deploy/kubernetes").join(name);
    let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut docs = YamlLoader::load_from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(docs.len(), 1, "{}: one YAML document", path.display());
    docs.remove(0)
}

fn get<'a>(v: &'a Value, path: &str) -> &'a Value {
    path.split('.').fold(v, |v, k| match k.parse::<usize>() {
        Ok(i) => &v[i],
        Err(_) => &v[k],
    })
}

fn text(v: &Value, path: &str) -> String {
    get(v, path)
        .as_str()
        .unwrap_or_else(|| panic!("{path} is not text: {:?}", get(v, path)))
        .to_owned()
}

fn num(v: &Value, path: &str) -> u64 {
    get(v, path)
        .as_i64()
        .and_then(|n| u64::try_from(n).ok())
        .unwrap_or_else(|| panic!("{path} is not a whole number: {:?}", get(v, path)))
}

fn env(container: &Value, name: &str) -> String {
    container["env"]
        .as_vec()
        .expect("env list")
        .iter()
        .find(|e| e["name"].as_str() == Some(name))
        .and_then(|e| e["value"].as_str())
        .unwrap_or_else(|| panic!("no env {name}"))
        .to_owned()
}

/// Checks a Job's pod template: restartPolicy Never, one container mounting the claim
/// `rayscope-work` at /work; returns the container.
fn pod(job: &Value) -> Value {
    assert_eq!(text(job, "apiVersion"), "batch/v1");
    assert_eq!(text(job, "kind"), "Job");
    let spec = get(job, "spec.template.spec");
    assert_eq!(text(spec, "restartPolicy"), "Never");
    let volumes = spec["volumes"].as_vec().expect("volumes");
    assert_eq!(volumes.len(), 1);
    assert_eq!(text(&volumes[0], "persistentVolumeClaim.claimName"), "rayscope-work");
    let containers = spec["containers"].as_vec().expect("containers");
    assert_eq!(containers.len(), 1);
    let c = containers[0].clone();
    let mounts = c["volumeMounts"].as_vec().expect("volumeMounts");
    assert_eq!(text(&mounts[0], "mountPath"), "/work");
    assert_eq!(text(&mounts[0], "name"), text(&volumes[0], "name"));
    c
}

/// The shell command of a container (`sh -c ARG`).
fn shell(c: &Value) -> String {
    let cmd: Vec<&str> = c["command"]
        .as_vec()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(cmd, ["/bin/sh", "-c"]);
    let args = c["args"].as_vec().unwrap();
    assert_eq!(args.len(), 1);
    args[0].as_str().unwrap().to_owned()
}

#[test]
fn the_indexed_job_maps_the_completion_index_to_the_part() {
    let job = manifest("render-job.yaml");
    assert_eq!(text(&job, "spec.completionMode"), "Indexed");
    let completions = num(&job, "spec.completions");
    let parallelism = num(&job, "spec.parallelism");
    assert!(parallelism >= 1 && parallelism <= completions);
    assert!(
        num(&job, "spec.backoffLimitPerIndex") >= 1,
        "a failed part is retried on its own"
    );
    let c = pod(&job);
    assert_eq!(
        env(&c, "PARTS"),
        completions.to_string(),
        "PARTS must equal completions"
    );
    let cmd = shell(&c);
    assert!(cmd.contains(r#"--part "${JOB_COMPLETION_INDEX}/${PARTS}""#), "{cmd}");
    assert!(
        cmd.contains(r#"-o "/work/parts/part_${JOB_COMPLETION_INDEX}.exr""#),
        "{cmd}"
    );

    let merge = manifest("merge-job.yaml");
    assert_eq!(num(&merge, "spec.completions"), 1);
    let m = shell(&pod(&merge));
    assert!(
        m.contains("rayscope merge /work/parts/part_*.exr -o /work/final.png"),
        "{m}"
    );

    let claim = manifest("volume.yaml");
    assert_eq!(text(&claim, "kind"), "PersistentVolumeClaim");
    assert_eq!(text(&claim, "metadata.name"), "rayscope-work");
    assert_eq!(text(&claim, "spec.accessModes.0"), "ReadWriteMany");
}

#[test]
fn the_pods_commands_render_parts_that_merge_into_the_local_render() {
    let job = manifest("render-job.yaml");
    let c = pod(&job);
    let parts = num(&job, "spec.completions");
    let merge = shell(&pod(&manifest("merge-job.yaml")));
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path().join("work");
    let bin = dir.path().join("bin");
    fs::create_dir_all(work.join("scene")).unwrap();
    fs::create_dir_all(&bin).unwrap();
    // `rayscope` on PATH, as in the container image.
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_rayscope"), bin.join("rayscope")).unwrap();
    fs::copy(rayscope_testkit::scene("glossy.txt"), work.join("scene/scene.txt")).unwrap();
    // The manifest's own command with a small image: its 16 parts need 16 tiles at least.
    let flags = "-w 64 -h 64 -q 1 -l";
    let work_s = work.to_str().unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let run = |cmd: &str, index: Option<u64>| {
        let mut p = Command::new("/bin/sh");
        p.arg("-c")
            .arg(cmd.replace("/work", work_s))
            .env("PATH", &path)
            .env("PARTS", env(&c, "PARTS"))
            .env("SCENE", env(&c, "SCENE").replace("/work", work_s))
            .env("FLAGS", flags);
        if let Some(i) = index {
            p.env("JOB_COMPLETION_INDEX", i.to_string());
        }
        let out = p.output().unwrap();
        assert!(out.status.success(), "{cmd}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let render = shell(&c);
    for i in 0..parts {
        run(&render, Some(i));
    }
    run(&merge, None);
    let local = dir.path().join("local.png");
    common::rayscope()
        .arg("-f")
        .arg(work.join("scene/scene.txt"))
        .arg("-o")
        .arg(&local)
        .arg("--quiet")
        .args(flags.split(' '))
        .assert()
        .success();
    assert!(
        fs::read(work.join("final.png")).unwrap() == fs::read(Path::new(&local)).unwrap(),
        "the merged image differs from the local render"
    );
}
