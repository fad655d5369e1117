//! `cosim run`, `cosim world` (and `world perturb`), `cosim list`: one scenario.

use crate::{BinArgs, PerturbArgs, RunArgs};
use anyhow::{bail, Context};
use scenarios::launch::LaunchOptions;
use scenarios::scenario::{find_repo_file, resolve_scenario, SCENARIO_KEYS};
use scenarios::world::World;
use scenarios::{run_scenario, Scenario};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

impl RunArgs {
    /// The `--set` assignments, then `--world` and `--no-mcap`.
    pub(crate) fn sets(&self) -> Vec<String> {
        let mut sets = self.set.clone();
        if let Some(w) = &self.world {
            sets.push(format!("world={}", w.display()));
        }
        if self.no_mcap {
            sets.push("mcap=false".into());
        }
        sets
    }
}

pub(crate) fn cmd_perturb(
    PerturbArgs {
        from,
        seed,
        max_offset,
        out,
    }: PerturbArgs,
) -> anyhow::Result<ExitCode> {
    let out = out.as_path();
    let from = match from {
        Some(p) => p,
        None => scenarios::scenario::find_repo_file("scenarios/worlds/thesis-course.toml")
            .context("cannot find scenarios/worlds/thesis-course.toml: pass --from FILE")?,
    };
    let text = std::fs::read_to_string(&from)
        .with_context(|| format!("cannot read {}", from.display()))?;
    let (world, offsets) =
        scenarios::perturb::perturb(&text, &from.display().to_string(), seed, max_offset)
            .with_context(|| format!("{}", from.display()))?;
    // The result must be a world the server accepts.
    world_server::world_file::WorldDesc::parse(&world, out)
        .map_err(|e| anyhow::anyhow!("the perturbed world is not valid: {e}"))?;
    std::fs::write(out, world).with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "cosim: {} gates moved (seed {seed}, max offset {max_offset} m) -> {}",
        offsets.len(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The scenario with `sets` applied, checked, and its world file (read
/// once, DESIGN.md §19).
pub(crate) fn load_scenario(
    arg: Option<&str>,
    sets: &[String],
) -> anyhow::Result<(Scenario, World)> {
    let path = resolve_scenario(arg)?;
    let mut s = Scenario::load(&path)?;
    for a in sets {
        s.set(a)?;
    }
    let world = s.check_files()?;
    Ok((s, world))
}

pub(crate) fn launch_options(run: &RunArgs, echo: bool) -> anyhow::Result<LaunchOptions> {
    let timeout = match run.timeout {
        Some(t) if t.is_finite() && t > 0.0 => Some(Duration::from_secs_f64(t)),
        Some(_) => bail!("--timeout must be a positive number of seconds"),
        None => None,
    };
    Ok(LaunchOptions {
        echo,
        traces: !run.no_trace,
        trace_images: run.trace_images,
        frames: run.frames,
        timeout,
        sim_core_args: Vec::new(),
        world_cmd: run.world_cmd.clone(),
        world_endpoint: None,
    })
}

pub(crate) fn cmd_run(
    scenario: Option<String>,
    out: Option<PathBuf>,
    run: RunArgs,
    no_plots: bool,
    quiet: bool,
    world_endpoint: Option<protocol::Endpoint>,
    bins: BinArgs,
) -> anyhow::Result<ExitCode> {
    let (s, world) = load_scenario(scenario.as_deref(), &run.sets())?;
    let out = out.unwrap_or_else(|| Path::new("out").join(&s.name));
    let bins = bins.locate()?;
    eprintln!("cosim: {} — {} -> {}", s.name, s.description, out.display());
    let opts = LaunchOptions {
        world_endpoint: world_endpoint.clone(),
        ..launch_options(&run, !quiet)?
    };
    let o = run_scenario(&s, &world, &bins, &out, &opts, !no_plots)?;
    println!("{}", o.text);
    // A world started by hand elsewhere may not be this scenario's: the
    // platform learns the world's timestep in GET_INIT_DATA, so a mismatch
    // shows in the summary.
    if let (Some(ep), Some(sum)) = (&world_endpoint, &o.summary) {
        if sum.timestep_ms != s.timestep_ms.get() {
            eprintln!(
                "cosim: the world at {ep} ran at {} ms, the scenario says {} ms: start it with `cosim world {} --listen ...` and the same --set",
                sum.timestep_ms, s.timestep_ms, s.name
            );
            return Ok(ExitCode::FAILURE);
        }
    }
    Ok(if o.ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

pub(crate) struct WorldArgs {
    pub(crate) scenario: Option<String>,
    pub(crate) listen: protocol::Endpoint,
    pub(crate) out: Option<PathBuf>,
    pub(crate) set: Vec<String>,
    pub(crate) no_trace: bool,
    pub(crate) trace_images: bool,
    pub(crate) frames: bool,
}

pub(crate) fn cmd_world(a: WorldArgs, bins: BinArgs) -> anyhow::Result<ExitCode> {
    let (s, world) = load_scenario(a.scenario.as_deref(), &a.set)?;
    let out = a
        .out
        .unwrap_or_else(|| Path::new("out").join(format!("{}-world", s.name)));
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let bins = bins.locate()?;
    let opts = LaunchOptions {
        traces: !a.no_trace,
        trace_images: a.trace_images,
        frames: a.frames,
        ..LaunchOptions::default()
    };
    let mut cmd = scenarios::launch::world_command(&s, &world, &bins, &a.listen, &out, &opts)?;
    // What the platform's host connects to: this host's name in place of
    // an any-interface address.
    let connect = match &a.listen {
        protocol::Endpoint::Tcp(addr) => match addr.rsplit_once(':') {
            Some((host, port)) if ["0.0.0.0", "[::]", "::"].contains(&host) => {
                format!("tcp:THIS-HOST:{port}")
            }
            _ => a.listen.to_string(),
        },
        unix => unix.to_string(),
    };
    eprintln!(
        "cosim world: {} ({} ms) on {}, outputs in {}; on the platform's host: cosim run {}{} --world-endpoint {connect}",
        s.name,
        s.timestep_ms,
        a.listen,
        out.display(),
        s.name,
        s.overrides
            .iter()
            .map(|(k, v)| format!(" --set {k}={v}"))
            .collect::<String>(),
    );
    let status = scenarios::signals::run_to_end(&mut cmd, scenarios::signals::Role::First)
        .with_context(|| format!("cannot start {}", bins.world_server.display()))?;
    Ok(if status.success() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

pub(crate) fn cmd_list() -> anyhow::Result<ExitCode> {
    let dir = find_repo_file("scenarios/thesis-race.toml")
        .and_then(|p| p.parent().map(Path::to_path_buf))
        .context("scenarios/ not found")?;
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        // The crate's own manifest shares the directory with the scenarios.
        .filter(|p| p.file_name().is_some_and(|n| n != "Cargo.toml"))
        .collect();
    names.sort();
    for p in names {
        match Scenario::load(&p) {
            Ok(s) => println!("{:<18} {}", s.name, s.description),
            Err(e) => println!("{:<18} (invalid: {e})", p.display()),
        }
    }
    println!("\n--set keys: {}", SCENARIO_KEYS.map(|(k, _)| k).join(", "));
    println!("run keys:   {}", sim_core::config::run_key_names());
    Ok(ExitCode::SUCCESS)
}
