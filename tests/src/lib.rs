//! Helpers for the end-to-end tests in `tests/tests/`: they start the real
//! binaries (`sim-core`, `world-server`, `cosim`) over real sockets.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// The repository's root (the workspace).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The directory cargo puts binaries in for the profile this test was
/// built with (`target/debug` or `target/release`, or under
/// `CARGO_TARGET_DIR`).
fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test>-<hash>
    exe.parent()
        .and_then(Path::parent)
        .expect("test executable lives in target/<profile>/deps")
        .to_path_buf()
}

/// The environment variable naming a directory that holds `cosim`,
/// `sim-core` and `world-server` already built (the test command builds
/// them once, in the same cargo invocation as the tests, and sets it; the
/// Python tests read the same variable): the tests then start those and
/// build nothing.
pub const BIN_DIR_ENV: &str = "COSIM_BIN_DIR";

/// The packages and binaries the end-to-end tests start.
const BINARIES: [(&str, &str); 3] = [
    ("scenarios", "cosim"),
    ("sim-core", "sim-core"),
    ("world-server", "world-server"),
];

static BUILT: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// The directory with the three binaries: `$COSIM_BIN_DIR`, or this test's
/// profile directory after one `cargo build` of all three (a test of
/// `e2e-tests` alone does not make cargo build other packages' binaries).
/// The build prints cargo's progress: the first test of a fresh checkout
/// waits for it, and says why.
fn built_bin_dir() -> PathBuf {
    let result = BUILT.get_or_init(|| {
        if let Some(dir) = std::env::var_os(BIN_DIR_ENV) {
            return Ok(PathBuf::from(dir));
        }
        let dir = bin_dir();
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let release = dir.file_name().is_some_and(|n| n == "release");
        let mut cmd = Command::new(cargo);
        cmd.current_dir(repo_root()).arg("build");
        for (package, name) in BINARIES {
            cmd.args(["-p", package, "--bin", name]);
        }
        if release {
            cmd.arg("--release");
        }
        // Build into the same target directory as this test.
        if let Some(target) = dir.parent() {
            cmd.env("CARGO_TARGET_DIR", target);
        }
        eprintln!(
            "e2e-tests: building cosim, sim-core and world-server into {} \
             (set {BIN_DIR_ENV} to use binaries built already)",
            dir.display()
        );
        match cmd.status() {
            Ok(s) if s.success() => Ok(dir),
            Ok(s) => Err(format!("cargo build of the binaries failed: {s}")),
            Err(e) => Err(format!("cannot run cargo: {e}")),
        }
    });
    match result {
        Ok(dir) => dir.clone(),
        Err(e) => panic!("{e}"),
    }
}

/// The path of a workspace binary (`package` is the package that builds
/// it): from `$COSIM_BIN_DIR`, or built first, once per test process.
pub fn binary(package: &str, name: &str) -> PathBuf {
    assert!(
        BINARIES.contains(&(package, name)),
        "{package}/{name} is not one of the binaries the tests build"
    );
    let path = built_bin_dir().join(name);
    assert!(path.exists(), "{} was not built", path.display());
    path
}

/// A committed firmware ELF (`sim-core/firmware/bin/NAME.elf`).
pub fn firmware(name: &str) -> PathBuf {
    let p = repo_root()
        .join("sim-core/firmware/bin")
        .join(format!("{name}.elf"));
    assert!(p.exists(), "{} is missing", p.display());
    p
}

/// A world file in `scenarios/worlds/`.
pub fn world_file(name: &str) -> PathBuf {
    repo_root()
        .join("scenarios/worlds")
        .join(format!("{name}.toml"))
}

/// Waits until `path` exists (a server's socket), for at most `secs`
/// seconds of wall time; returns whether it appeared.
pub fn wait_for_path(path: &Path, secs: u64) -> bool {
    let until = std::time::Instant::now() + std::time::Duration::from_secs(secs);
    while !path.exists() {
        if std::time::Instant::now() >= until {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    true
}

/// The three binaries the `cosim` launcher drives, built for this test's
/// profile; `cosim` is run from the repository's root with the other two
/// named explicitly.
pub struct CosimBins {
    pub cosim: PathBuf,
    pub sim_core: PathBuf,
    pub world: PathBuf,
}

impl CosimBins {
    pub fn new() -> CosimBins {
        CosimBins {
            cosim: binary("scenarios", "cosim"),
            sim_core: binary("sim-core", "sim-core"),
            world: binary("world-server", "world-server"),
        }
    }

    /// `cosim ARGS --sim-core … --world-server …`, not started yet.
    pub fn command(&self, args: &[&str]) -> Command {
        let mut c = Command::new(&self.cosim);
        c.args(args)
            .arg("--sim-core")
            .arg(&self.sim_core)
            .arg("--world-server")
            .arg(&self.world)
            .current_dir(repo_root());
        c
    }

    /// Runs `cosim ARGS` to the end.
    pub fn cosim(&self, args: &[&str]) -> Output {
        self.command(args).output().expect("run cosim")
    }
}

impl Default for CosimBins {
    fn default() -> Self {
        Self::new()
    }
}

/// The platform's outputs that are the same bytes whatever carries the
/// frames (transport, image encoding, polling): the power network's four
/// CSVs and the firmware's console.
pub const PLATFORM_FILES: [&str; 5] = [
    "power.csv",
    "motor_empirical.csv",
    "motor_dandrea.csv",
    "motor_stolaroff.csv",
    "console.log",
];

/// A finished process's status and output, for assertion messages.
pub fn output_text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The file that holds a series named by its CSV name (`out/power.csv` is
/// `out/power.csv.zst` when the run compressed its series); any other path
/// as it is.
pub fn series_file(path: &Path) -> PathBuf {
    protocol::series::resolve(path)
}

/// The text of a series or CSV file, in either form; a file torn by a
/// writer that died fails the test.
pub fn read_series(path: &Path) -> String {
    let text = protocol::series::read(path).unwrap_or_else(|e| panic!("{e}"));
    if let Some(w) = text.warning() {
        panic!("{w}");
    }
    String::from_utf8(text.bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Asserts that each of `files` (paths relative to `a` and `b`; a series by
/// its CSV name, in whichever form the runs wrote it) has the same bytes in
/// both directories: the byte-identical-outputs check of every end-to-end
/// test. `what` ends the message ("between two runs").
pub fn assert_same_files<S: AsRef<str>>(a: &Path, b: &Path, files: &[S], what: &str) {
    for f in files {
        let f = f.as_ref();
        let read = |dir: &Path| {
            let p = series_file(&dir.join(f));
            std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        };
        // Not assert_eq!: a mismatch would print two whole files.
        assert!(read(a) == read(b), "{f} differs {what}");
    }
}

/// A run's `summary.json` in `dir`, parsed.
pub fn summary(dir: &Path) -> serde_json::Value {
    let path = dir.join("summary.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A running process as `/proc` shows it (Linux): what the end-to-end tests
/// look for when they pick a child of `cosim` to kill or check that none
/// outlived it.
#[derive(Debug, Clone)]
pub struct Process {
    pub pid: u32,
    /// The parent's pid (`/proc/PID/stat`'s fourth field).
    pub ppid: Option<u32>,
    /// The command line, one element per argument.
    pub args: Vec<String>,
}

impl Process {
    /// The command line as one string (arguments joined by spaces).
    pub fn cmdline(&self) -> String {
        self.args.join(" ")
    }

    /// Whether the command line has `flag` immediately followed by `path`
    /// (compared as paths: `a//b` is `a/b`).
    pub fn has_path_arg(&self, flag: &str, path: &Path) -> bool {
        self.args
            .windows(2)
            .any(|w| w[0] == flag && Path::new(&w[1]) == path)
    }

    /// Whether the command line has `flag` immediately followed by `value`.
    pub fn has_arg(&self, flag: &str, value: &str) -> bool {
        self.args.windows(2).any(|w| w[0] == flag && w[1] == value)
    }
}

/// Every process this user can read in `/proc` (those that ended while it
/// was read are left out).
pub fn processes() -> Vec<Process> {
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let mut found = Vec::new();
    for entry in dir.flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(raw) = std::fs::read(entry.path().join("cmdline")) else {
            continue;
        };
        let args = raw
            .split(|b| *b == 0)
            .filter(|a| !a.is_empty())
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        // "PID (COMM) STATE PPID ...": COMM may hold spaces and parentheses.
        let ppid = std::fs::read_to_string(entry.path().join("stat"))
            .ok()
            .and_then(|stat| {
                let (_, rest) = stat.rsplit_once(") ")?;
                rest.split_whitespace().nth(1)?.parse().ok()
            });
        found.push(Process { pid, ppid, args });
    }
    found
}
