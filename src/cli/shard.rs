//! `radbake shard`: a bake split into jobs for a batch scheduler
//! ([`radbake::pipeline::shard`]). `plan` prepares the work folder; `run` and
//! `merge` are the jobs; `local`, `slurm` and `k8s` run the plan or print
//! it for a scheduler. Every job sees the work folder at the same path
//! (shared storage) and writes only its own file there, atomically.

use super::bake::BakeArgs;
use super::{classify, lib_err, Outcome};
use clap::{Args, Subcommand};
use radbake::pipeline::shard::{Job, Sharding};
use radbake::BakeConfig;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand)]
pub enum ShardCommand {
    /// Prepare the work folder (`--out`): the scene, the settings and `shards/plan.json`.
    Plan(PlanArgs),
    /// Run one job of a phase: its slice, written to `<dir>/shards/`.
    Run(RunArgs),
    /// Merge a phase: check its slices; phase 1 solves, phase 2 writes the outputs into `<dir>`.
    Merge(MergeArgs),
    /// Run the whole plan here, K jobs at a time.
    Local(LocalArgs),
    /// Print a Slurm batch script: a job array per phase, `--dependency=afterok` between them.
    Slurm(SchedulerArgs),
    /// Print Kubernetes Indexed Jobs (`completionMode: Indexed`) over a shared volume.
    K8s(SchedulerArgs),
}

#[derive(Args)]
pub struct PlanArgs {
    /// Jobs per phase.
    #[arg(long, default_value_t = 4)]
    pub shards: u32,
    /// The bake's scene and settings, as `radbake bake` takes them; `--out` is the work folder.
    #[command(flatten)]
    pub bake: Box<BakeArgs>,
}

#[derive(Args)]
pub struct RunArgs {
    /// The work folder.
    pub dir: PathBuf,
    /// 1 (form-factor rows and direct light) or 2 (the final gather).
    #[arg(long)]
    pub phase: u8,
    /// This job's slice, 0-based (Slurm: `$SLURM_ARRAY_TASK_ID`; Kubernetes: `$JOB_COMPLETION_INDEX`).
    #[arg(long)]
    pub index: u32,
}

#[derive(Args)]
pub struct MergeArgs {
    /// The work folder.
    pub dir: PathBuf,
    /// 1 (the solve) or 2 (the outputs).
    #[arg(long)]
    pub phase: u8,
}

#[derive(Args)]
pub struct LocalArgs {
    /// The work folder.
    pub dir: PathBuf,
    /// Jobs at once.
    #[arg(long, default_value_t = 2)]
    pub jobs: u32,
    /// Threads per job (`RAYON_NUM_THREADS`) [default: the cores divided among --jobs].
    #[arg(long)]
    pub threads: Option<u32>,
}

#[derive(Args)]
pub struct SchedulerArgs {
    /// The work folder.
    pub dir: PathBuf,
    /// The radbake command the jobs run.
    #[arg(long, default_value = "radbake")]
    pub radbake: String,
    /// Kubernetes: the container image.
    #[arg(long, default_value = "radbake:latest")]
    pub image: String,
    /// Kubernetes: the PersistentVolumeClaim holding the work folder (mounted at its path).
    #[arg(long, default_value = "radbake-work")]
    pub claim: String,
}

pub fn run(cmd: &ShardCommand) -> Outcome {
    match cmd {
        ShardCommand::Plan(a) => plan(a),
        ShardCommand::Run(a) => job(&a.dir, |count| Job::Run {
            phase: a.phase,
            index: a.index,
            count,
        }),
        ShardCommand::Merge(a) => job(&a.dir, |_| Job::Merge { phase: a.phase }),
        ShardCommand::Local(a) => local(a),
        ShardCommand::Slurm(a) => {
            print!("{}", slurm(&read_plan(&a.dir)?, &a.radbake));
            Ok(())
        }
        ShardCommand::K8s(a) => {
            print!("{}", k8s(&read_plan(&a.dir)?, a));
            Ok(())
        }
    }
}

/// The plan's phases: name, jobs (None: one merge), arguments after `radbake`.
fn phases(dir: &str, shards: u32) -> Vec<(String, Option<u32>, String)> {
    vec![
        (
            "phase1".into(),
            Some(shards),
            format!("shard run {dir} --phase 1 --index {{index}}"),
        ),
        (
            "merge1".into(),
            None,
            format!("shard merge {dir} --phase 1"),
        ),
        (
            "phase2".into(),
            Some(shards),
            format!("shard run {dir} --phase 2 --index {{index}}"),
        ),
        (
            "merge2".into(),
            None,
            format!("shard merge {dir} --phase 2"),
        ),
    ]
}

const WHAT: [&str; 4] = [
    "form-factor rows of a slice of patches and direct light of a slice of texels",
    "every phase-1 slice read back; the radiosity solve",
    "the final gather of a slice of texels (slices of equal cost)",
    "every slice read back; denoising, lightmaps, probes and the outputs, written into the work folder",
];

fn plan(a: &PlanArgs) -> Outcome {
    let t = Instant::now();
    let args = &a.bake;
    if a.shards == 0 || a.shards > 10_000 {
        return Err((
            1,
            format!("--shards {}: must be between 1 and 10000", a.shards),
        ));
    }
    for (set, flag) in [
        (args.snapshot_every.is_some(), "--snapshot-every"),
        (args.timeout.is_some(), "--timeout"),
    ] {
        if set {
            return Err((
                2,
                format!("{flag} is a `radbake bake` option; a sharded bake does not use it"),
            ));
        }
    }
    let mut config = args
        .config()
        .map_err(|e| (classify(&e), format!("{e:#}")))?;
    refuse_unsupported(&config)?;
    let dir = absolute(&args.out)?;
    let shell_safe = |c: char| c.is_ascii_alphanumeric() || "/._-+,:@".contains(c);
    if !dir.to_string_lossy().chars().all(shell_safe) {
        return Err((
            1,
            format!(
                "{}: the work folder's path goes through schedulers' shells: use letters, digits and / . _ - + , : @ only",
                dir.display()
            ),
        ));
    }
    let io = |p: &Path, e: std::io::Error| (3, format!("{}: {e}", p.display()));
    std::fs::create_dir_all(dir.join("shards")).map_err(|e| io(&dir, e))?;
    // A new plan: slices of an earlier one must not be read by mistake.
    for entry in std::fs::read_dir(dir.join("shards"))
        .map_err(|e| io(&dir, e))?
        .flatten()
    {
        if entry.path().extension().is_some_and(|e| e == "bin") {
            std::fs::remove_file(entry.path()).map_err(|e| io(&entry.path(), e))?;
        }
    }
    // The scene's files, byte for byte, so every job imports the same scene.
    let name = args
        .scene
        .file_name()
        .ok_or_else(|| (1, format!("{}: not a file", args.scene.display())))?;
    let scene_dir = dir.join("scene");
    copy_scene(&args.scene, &scene_dir).map_err(|e| (1, format!("{e:#}")))?;
    if let Some(map) = &config.sky_map {
        let copy = scene_dir.join(format!(
            "sky_map.{}",
            map.extension().and_then(|e| e.to_str()).unwrap_or("exr")
        ));
        std::fs::copy(map, &copy).map_err(|e| io(map, e))?;
        config.sky_map = Some(copy);
    }
    let toml =
        toml::to_string(&config).map_err(|e| (3, format!("cannot write the settings: {e}")))?;
    radbake::output::write_bytes_atomic(&dir.join("bake.toml"), toml.as_bytes())
        .map_err(lib_err)?;
    let scene_path = scene_dir.join(name);
    let scene = load(&scene_path, &config)?;
    let hash = radbake::pipeline::incremental::content_hash(&scene, &config);
    let d = dir.display().to_string();
    let phases: Vec<Value> = phases(&d, a.shards)
        .into_iter()
        .zip(WHAT)
        .enumerate()
        .map(|(k, ((name, jobs, command), what))| {
            let commands: Vec<String> = match jobs {
                Some(n) => (0..n)
                    .map(|i| format!("radbake {}", command.replace("{index}", &i.to_string())))
                    .collect(),
                None => vec![format!("radbake {command}")],
            };
            json!({
                "name": name,
                "what": what,
                "jobs": jobs.unwrap_or(1),
                "array": jobs.is_some(),
                "after": (k > 0).then(|| ["phase1", "merge1", "phase2"][k - 1]),
                "command": format!("radbake {command}"),
                "commands": commands,
            })
        })
        .collect();
    let plan = json!({
        "radbake": env!("CARGO_PKG_VERSION"),
        "work": d,
        "storage": "every job must see the work folder at this same path (shared storage); each writes only its own file under shards/, atomically",
        "scene": Path::new("scene").join(name),
        "config": "bake.toml",
        "hash": hash,
        "shards": a.shards,
        "phases": phases,
    });
    let text = serde_json::to_vec_pretty(&plan).unwrap_or_default();
    radbake::output::write_bytes_atomic(&dir.join("shards/plan.json"), &text).map_err(lib_err)?;
    // The stages before the sliced ones, once, for every job to read.
    job(&dir, |_| Job::Prepare)?;
    if !args.quiet {
        eprintln!(
            "planned {} × 2 jobs + 2 merges in {} ({:.2} s); run them with `radbake shard local {}` or print them for `sbatch` (`shard slurm`) or `kubectl` (`shard k8s`)",
            a.shards,
            dir.display(),
            t.elapsed().as_secs_f64(),
            dir.display()
        );
    }
    Ok(())
}

/// What a sharded bake cannot do yet, refused at plan time in one line.
fn refuse_unsupported(c: &BakeConfig) -> Outcome {
    use radbake::config::{Device, Method};
    if c.method != Method::Radiosity {
        return Err((
            1,
            "radbake shard splits the radiosity bake only (method = \"radiosity\")".into(),
        ));
    }
    if c.device == Device::Gpu {
        return Err((
            1,
            "radbake shard runs its jobs on the CPU (device = \"cpu\")".into(),
        ));
    }
    Ok(())
}

fn absolute(p: &Path) -> Result<PathBuf, (u8, String)> {
    std::fs::create_dir_all(p).map_err(|e| (3, format!("{}: {e}", p.display())))?;
    std::fs::canonicalize(p).map_err(|e| (3, format!("{}: {e}", p.display())))
}

/// Copies the scene file and, for a `.gltf`, every file its buffers and
/// images name (relative URIs, kept relative).
fn copy_scene(scene: &Path, to: &Path) -> anyhow::Result<()> {
    use anyhow::Context as _;
    std::fs::create_dir_all(to).with_context(|| to.display().to_string())?;
    let name = scene.file_name().context("the scene is not a file")?;
    std::fs::copy(scene, to.join(name)).with_context(|| scene.display().to_string())?;
    let is_gltf = scene
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
    if !is_gltf {
        return Ok(());
    }
    let from = scene.parent().unwrap_or(Path::new("."));
    let doc: Value = serde_json::from_slice(&std::fs::read(scene)?)
        .with_context(|| format!("{}: not JSON", scene.display()))?;
    for key in ["buffers", "images"] {
        for item in doc[key].as_array().into_iter().flatten() {
            let Some(uri) = item["uri"].as_str() else {
                continue;
            };
            if uri.starts_with("data:") {
                continue;
            }
            let rel = percent_encoding::percent_decode_str(uri).decode_utf8_lossy();
            let rel = Path::new(rel.as_ref());
            if rel.is_absolute()
                || rel
                    .components()
                    .any(|c| c == std::path::Component::ParentDir)
            {
                anyhow::bail!(
                    "{}: {key} uri `{uri}` leaves the scene's folder",
                    scene.display()
                );
            }
            let dst = to.join(rel);
            if let Some(parent) = dst.parent() {
                std::fs::create_dir_all(parent)?;
            }
            std::fs::copy(from.join(rel), &dst)
                .with_context(|| format!("{}: {key} `{uri}`", scene.display()))?;
        }
    }
    Ok(())
}

fn read_plan(dir: &Path) -> Result<Value, (u8, String)> {
    let path = dir.join("shards/plan.json");
    let bytes = std::fs::read(&path).map_err(|e| {
        (
            1,
            format!("{}: {e} (run `radbake shard plan` first)", path.display()),
        )
    })?;
    serde_json::from_slice(&bytes).map_err(|e| (1, format!("{}: {e}", path.display())))
}

fn load(scene: &Path, config: &BakeConfig) -> Result<radbake::scene::Scene, (u8, String)> {
    let mut s = radbake::scene::load(scene, &Default::default()).map_err(lib_err)?;
    config.light_modes.apply(&mut s).map_err(|e| {
        let (code, message) = lib_err(e);
        (code, format!("{}: {message}", scene.display()))
    })?;
    Ok(s)
}

/// Runs one job or merge of the plan in `dir`.
fn job(dir: &Path, job: impl FnOnce(u32) -> Job) -> Outcome {
    let t = Instant::now();
    let plan = read_plan(dir)?;
    let work = PathBuf::from(plan["work"].as_str().unwrap_or_default());
    let shards = plan["shards"].as_u64().unwrap_or(1) as u32;
    let job = job(shards);
    match job {
        Job::Run { phase, index, .. } if !(1..=2).contains(&phase) || index >= shards => {
            return Err((2, format!("--phase {phase} --index {index}: the plan has phases 1 and 2 of {shards} jobs (0..{})", shards - 1)));
        }
        Job::Merge { phase } if !(1..=2).contains(&phase) => {
            return Err((2, format!("--phase {phase}: the plan has merges 1 and 2")));
        }
        _ => {}
    }
    let config_path = work.join(plan["config"].as_str().unwrap_or("bake.toml"));
    let text = std::fs::read_to_string(&config_path)
        .map_err(|e| (1, format!("{}: {e}", config_path.display())))?;
    let config =
        BakeConfig::from_toml(&text).map_err(|e| (1, format!("{}: {e}", config_path.display())))?;
    let scene_path = work.join(plan["scene"].as_str().unwrap_or_default());
    let scene = load(&scene_path, &config)?;
    let hash = radbake::pipeline::incremental::content_hash(&scene, &config);
    if plan["hash"].as_str() != Some(hash.as_str()) {
        return Err((
            1,
            format!(
                "{}: the scene or settings changed since the plan; plan again",
                work.display()
            ),
        ));
    }
    let sharding = Sharding {
        job,
        dir: work.join("shards"),
        shards: [shards, shards],
        hash: hash.clone(),
    };
    let stem = scene_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    match radbake::bake_with(&scene, &config, &radbake::Silent, &sharding) {
        Err(radbake::Error::ShardDone) => {
            if job != Job::Prepare {
                eprintln!("{job:?} done in {:.2} s", t.elapsed().as_secs_f64());
            }
            Ok(())
        }
        Err(e) => {
            let (code, message) = lib_err(e);
            Err((code, format!("{}: {message}", scene_path.display())))
        }
        Ok(bake) => {
            let mut report = bake.report(&scene_path.display().to_string());
            let written = super::bake::write_outputs(&work, &stem, &bake, &mut report)?;
            radbake::pipeline::incremental::record(&work, &hash).map_err(lib_err)?;
            eprintln!(
                "merged: {} files in {} ({:.2} s)",
                written.len(),
                work.display(),
                t.elapsed().as_secs_f64()
            );
            Ok(())
        }
    }
}

/// Runs the plan with local processes, `jobs` at a time, phase by phase
/// (each phase once the one before succeeded), and prints each phase's
/// wall time and the sum of its jobs' times.
fn local(a: &LocalArgs) -> Outcome {
    use std::collections::VecDeque;
    use std::process::{Child, Command, Stdio};
    let plan = read_plan(&a.dir)?;
    let exe =
        std::env::current_exe().map_err(|e| (3, format!("cannot find radbake itself: {e}")))?;
    let start = Instant::now();
    // The machine's cores shared among the jobs at once, unless told.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    let threads = a.threads.unwrap_or((cores / a.jobs.max(1)).max(1));
    let spawn = |c: &str| -> Result<(String, Instant, Child), (u8, String)> {
        let mut cmd = Command::new(&exe);
        cmd.args(c.split_whitespace().skip(1));
        cmd.stdout(Stdio::null()).stderr(Stdio::piped());
        cmd.env("RAYON_NUM_THREADS", threads.to_string());
        let child = cmd.spawn().map_err(|e| (3, format!("{c}: {e}")))?;
        Ok((c.to_owned(), Instant::now(), child))
    };
    for phase in plan["phases"].as_array().into_iter().flatten() {
        let mut todo: VecDeque<String> = (phase["commands"].as_array().into_iter().flatten())
            .filter_map(|c| c.as_str().map(str::to_owned))
            .collect();
        let t = Instant::now();
        let (mut running, mut sum) = (VecDeque::new(), 0.0);
        while !todo.is_empty() || !running.is_empty() {
            while running.len() < a.jobs.max(1) as usize {
                let Some(c) = todo.pop_front() else { break };
                running.push_back(spawn(&c)?);
            }
            let Some((c, began, child)) = running.pop_front() else {
                break;
            };
            let out = child
                .wait_with_output()
                .map_err(|e| (3, format!("{c}: {e}")))?;
            sum += began.elapsed().as_secs_f64();
            if !out.status.success() {
                let err = String::from_utf8_lossy(&out.stderr);
                return Err((3, format!("`{c}` failed: {}", err.trim())));
            }
        }
        eprintln!(
            "{}: {} job(s), {:.2} s wall, {:.2} s summed",
            phase["name"].as_str().unwrap_or("?"),
            phase["jobs"],
            t.elapsed().as_secs_f64(),
            sum
        );
    }
    eprintln!("the plan ran in {:.2} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// The Slurm batch script of `plan`.
fn slurm(plan: &Value, radbake: &str) -> String {
    let dir = plan["work"].as_str().unwrap_or_default();
    let n = plan["shards"].as_u64().unwrap_or(1);
    let job = |name: &str, array: bool, after: Option<&str>, args: &str| {
        let mut s = format!("{name}=$(sbatch --parsable --job-name=radbake-{name}");
        if array {
            s += &format!(" --array=0-{}", n - 1);
        }
        if let Some(a) = after {
            s += &format!(" --dependency=afterok:${a}");
        }
        s += &format!(
            " --output=\"$WORK/shards/slurm-{name}-%a.log\" --wrap=\"{radbake} {args}\")\n"
        );
        s
    };
    let mut s = format!(
        "#!/bin/bash\n# radbake shard plan in {dir}: {n} jobs per phase, one job array per phase,\n# each phase after the one before succeeded (afterok). Every node must see\n# {dir} at this path (shared storage). Submit with: bash this-script\nset -euo pipefail\nWORK={dir}\n",
    );
    s += &job(
        "phase1",
        true,
        None,
        "shard run $WORK --phase 1 --index \\$SLURM_ARRAY_TASK_ID",
    );
    s += &job(
        "merge1",
        false,
        Some("phase1"),
        "shard merge $WORK --phase 1",
    );
    s += &job(
        "phase2",
        true,
        Some("merge1"),
        "shard run $WORK --phase 2 --index \\$SLURM_ARRAY_TASK_ID",
    );
    s += &job(
        "merge2",
        false,
        Some("phase2"),
        "shard merge $WORK --phase 2",
    );
    s += "echo \"$merge2\"\n";
    s
}

/// Kubernetes manifests of `plan`: an Indexed Job per phase and a Job per
/// merge, over a shared volume; applied in order, each after the one
/// before completed.
fn k8s(plan: &Value, a: &SchedulerArgs) -> String {
    let dir = plan["work"].as_str().unwrap_or_default();
    let n = plan["shards"].as_u64().unwrap_or(1);
    let job = |name: &str, indexed: bool, args: &[&str]| {
        let (mode, index_arg) = if indexed {
            (
                format!("  completionMode: Indexed\n  completions: {n}\n  parallelism: {n}\n"),
                ", \"--index\", \"$(JOB_COMPLETION_INDEX)\"",
            )
        } else {
            ("  completions: 1\n".to_string(), "")
        };
        let args: Vec<String> = args.iter().map(|x| format!("\"{x}\"")).collect();
        format!(
            "---\napiVersion: batch/v1\nkind: Job\nmetadata:\n  name: radbake-{name}\nspec:\n{mode}  backoffLimit: 3\n  template:\n    spec:\n      restartPolicy: Never\n      containers:\n        - name: radbake\n          image: {image}\n          command: [\"{radbake}\"]\n          args: [{args}{index_arg}]\n          volumeMounts:\n            - name: work\n              mountPath: {dir}\n      volumes:\n        - name: work\n          persistentVolumeClaim:\n            claimName: {claim}\n",
            image = a.image,
            radbake = a.radbake,
            args = args.join(", "),
            claim = a.claim,
        )
    };
    let mut s = format!(
        "# radbake shard plan in {dir}: {n} jobs per phase. Kubernetes Jobs have no\n# dependencies, so apply them one at a time, each after the one before completed:\n#   for j in phase1 merge1 phase2 merge2; do\n#     yq \"select(.metadata.name == \\\"radbake-$j\\\")\" this.yaml | kubectl apply -f -\n#     kubectl wait --for=condition=complete --timeout=24h job/radbake-$j\n#   done\n# The claim `{}` must hold the work folder and be mounted read-write by every pod.\n",
        a.claim
    );
    s += &job("phase1", true, &["shard", "run", dir, "--phase", "1"]);
    s += &job("merge1", false, &["shard", "merge", dir, "--phase", "1"]);
    s += &job("phase2", true, &["shard", "run", dir, "--phase", "2"]);
    s += &job("merge2", false, &["shard", "merge", dir, "--phase", "2"]);
    s
}
