//! `radbake shard`: a bake split into jobs and merged must give exactly the
//! bytes of `radbake bake` (lightmaps, `.glb`, manifest, probes), for any
//! number of shards and any order of completion; a missing or corrupt
//! slice is named; a job run again writes the same bytes; the scheduler
//! adapters say what Slurm and Kubernetes need.

mod common;

use common::*;
use std::path::Path;
use std::process::{Command, Output};

fn radbake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(args)
        .output()
        .expect("radbake runs")
}

fn ok(args: &[&str]) -> Output {
    let out = radbake(args);
    assert!(
        out.status.success(),
        "radbake {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file of the one-process bake in `reference` (but the report, whose
/// stage times differ) is byte-identical in `work`.
fn assert_same_outputs(reference: &Path, work: &Path) {
    let mut compared = 0;
    for entry in std::fs::read_dir(reference).unwrap() {
        let name = entry.unwrap().file_name();
        if name == "report.json" {
            continue;
        }
        let a = std::fs::read(reference.join(&name)).unwrap();
        let b = std::fs::read(work.join(&name))
            .unwrap_or_else(|e| panic!("{}: {e}", work.join(&name).display()));
        assert!(a == b, "{name:?} differs from the one-process bake");
        compared += 1;
    }
    assert!(compared >= 8, "only {compared} files compared");
}

/// `radbake shard plan SCENE --out WORK --shards N -q`.
fn plan(scene: &Path, work: &Path, shards: u32) {
    let n = shards.to_string();
    ok(&[
        "shard",
        "plan",
        s(scene),
        "--out",
        s(work),
        "--shards",
        &n,
        "-q",
    ]);
}

/// Runs the plan in `work` job by job, each phase's jobs in `order`.
fn run_plan(work: &Path, shards: u32, order: &dyn Fn(u32) -> Vec<u32>) {
    for phase in ["1", "2"] {
        for i in order(shards) {
            ok(&[
                "shard",
                "run",
                s(work),
                "--phase",
                phase,
                "--index",
                &i.to_string(),
            ]);
        }
        ok(&["shard", "merge", s(work), "--phase", phase]);
    }
}

/// A scene, extra bake options, shards, and the order its jobs run in.
type Case<'a> = (&'a str, &'a [&'a str], u32, &'a dyn Fn(u32) -> Vec<u32>);

/// The Cornell box (with its probes) in 1, 3 and 4 shards, with ray-cast
/// and hemicube form factors, jobs completing in order, in reverse and interleaved: the
/// outputs are those of `radbake bake`, byte for byte.
#[test]
fn sharded_bakes_are_byte_identical() {
    let cases: [Case; 3] = [
        ("cornell_box.gltf", &[], 3, &|n| (0..n).rev().collect()),
        ("cornell_box.gltf", &["--texels-per-meter", "30"], 4, &|n| {
            (0..n).step_by(2).chain((1..n).step_by(2)).collect()
        }),
        (
            "cornell_box.gltf",
            &["--form-factors", "hemicube", "--texels-per-meter", "20"],
            1,
            &|n| (0..n).collect(),
        ),
    ];
    for (k, (scene, extra, shards, order)) in cases.into_iter().enumerate() {
        let dir = temp_dir(&format!("shards-{k}"));
        let (reference, work) = (dir.join("bake"), dir.join("work"));
        let scene = scene_path(scene);
        let mut args = vec!["bake", s(&scene), "--out", s(&reference), "-q"];
        args.extend_from_slice(extra);
        ok(&args);
        let n = shards.to_string();
        let mut plan = vec![
            "shard",
            "plan",
            s(&scene),
            "--out",
            s(&work),
            "--shards",
            &n,
            "-q",
        ];
        plan.extend_from_slice(extra);
        ok(&plan);
        run_plan(&work, shards, order);
        assert_same_outputs(&reference, &work);
    }
}

/// `shard local` runs the whole plan with local processes: the same bytes.
#[test]
fn shard_local_runs_the_plan() {
    let dir = temp_dir("shards-local");
    let (reference, work) = (dir.join("bake"), dir.join("work"));
    let scene = scene_path("cornell_box.gltf");
    ok(&["bake", s(&scene), "--out", s(&reference), "-q"]);
    plan(&scene, &work, 2);
    let out = ok(&["shard", "local", s(&work), "--jobs", "2"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("phase2: 2 job(s)"), "{err}");
    assert_same_outputs(&reference, &work);
}

/// A slice missing or corrupt stops the merge with one line naming its
/// file; a job run again (after a kill, say) writes the same bytes; a job
/// that is not in the plan is a usage error.
#[test]
fn bad_slices_are_named_and_jobs_rerun_identically() {
    let dir = temp_dir("shards-bad");
    let work = dir.join("work");
    let scene = scene_path("cornell_box.gltf");
    plan(&scene, &work, 2);
    for i in ["0", "1"] {
        ok(&["shard", "run", s(&work), "--phase", "1", "--index", i]);
    }
    let slice = work.join("shards/rows_0001.bin");
    let first = std::fs::read(&slice).unwrap();
    ok(&["shard", "run", s(&work), "--phase", "1", "--index", "1"]);
    assert!(
        std::fs::read(&slice).unwrap() == first,
        "a rerun changed the slice"
    );

    let merge = ["shard", "merge", s(&work), "--phase", "1"];
    let mut bad = first.clone();
    let mid = bad.len() - 10;
    bad[mid] ^= 0x40;
    std::fs::write(&slice, &bad).unwrap();
    let out = radbake(&merge);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("rows_0001.bin") && err.contains("corrupt"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");

    std::fs::remove_file(&slice).unwrap();
    let out = radbake(&merge);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("rows_0001.bin") && err.contains("missing"),
        "{err}"
    );

    let out = radbake(&["shard", "run", s(&work), "--phase", "1", "--index", "2"]);
    assert_eq!(out.status.code(), Some(2));
    // The settings a sharded bake cannot run are refused at plan time.
    let out = radbake(&[
        "shard",
        "plan",
        s(&scene),
        "--out",
        s(&dir.join("gpu")),
        "--device",
        "gpu",
    ]);
    assert_eq!(out.status.code(), Some(1));
    // A `bake` option a sharded bake would ignore is refused, not ignored.
    let out = radbake(&[
        "shard",
        "plan",
        s(&scene),
        "--out",
        s(&dir.join("t")),
        "--timeout",
        "5",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--timeout"));
}

/// The scheduler adapters: a Slurm script with a job array per phase and
/// `afterok` between phases; Kubernetes Indexed Jobs reading their index
/// from `JOB_COMPLETION_INDEX`, over the claim that holds the work folder.
#[test]
fn scheduler_adapters_follow_the_plan() {
    let dir = temp_dir("shards-sched");
    let work = dir.join("work");
    let scene = scene_path("cornell_box.gltf");
    plan(&scene, &work, 5);
    let slurm = String::from_utf8(ok(&["shard", "slurm", s(&work)]).stdout).unwrap();
    assert_eq!(slurm.matches("--array=0-4").count(), 2, "{slurm}");
    for after in ["afterok:$phase1", "afterok:$merge1", "afterok:$phase2"] {
        assert!(slurm.contains(after), "{slurm}");
    }
    assert!(
        slurm.contains("SLURM_ARRAY_TASK_ID") && slurm.contains("shard merge"),
        "{slurm}"
    );
    let k8s =
        String::from_utf8(ok(&["shard", "k8s", s(&work), "--claim", "bakes"]).stdout).unwrap();
    assert_eq!(k8s.matches("completionMode: Indexed").count(), 2, "{k8s}");
    assert_eq!(k8s.matches("kind: Job").count(), 4, "{k8s}");
    assert!(
        k8s.contains("$(JOB_COMPLETION_INDEX)") && k8s.contains("claimName: bakes"),
        "{k8s}"
    );
    assert!(k8s.contains("completions: 5"), "{k8s}");
}
