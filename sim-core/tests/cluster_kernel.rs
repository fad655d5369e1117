//! The cluster on the full platform (DESIGN.md §12): the kernel runs FC +
//! cluster when the platform file has a `"cluster"` section
//! (`sim-core/platforms/crazyflie-aideck.json`), and `power.csv` gets the
//! cluster's columns; without the section nothing changes.

use std::path::PathBuf;

use protocol::ImageEncoding;
use sim_core::config::{PlatformConfig, RunConfig};
use sim_core::kernel::{simulate, KernelConfig};
use sim_core::peripherals::SoloWorld;
use sim_core::units::{Millis, Picos};

const FULL: f64 = sim_core::cluster::power::FULL_LOAD_W;

fn firmware(name: &str) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("firmware/bin")
        .join(format!("{name}.elf"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn aideck() -> PlatformConfig {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("platforms/crazyflie-aideck.json");
    PlatformConfig::from_path(&path).unwrap()
}

fn config(out: &std::path::Path, platform: PlatformConfig) -> KernelConfig {
    KernelConfig {
        platform,
        run: RunConfig::default(),
        image_encoding: ImageEncoding::Array,
        busy_poll_us: 0,
        drone: None,
        idle_skip: true,
        mmio_latency: 0,
        out_dir: Some(out.to_path_buf()),
        echo_console: false,
        progress: false,
        max_time: Some(Picos::from_ms(1_000)),
        gates_total: None,
    }
}

fn run(name: &str, platform: PlatformConfig) -> (tempfile::TempDir, sim_core::kernel::RunOutcome) {
    let dir = tempfile::tempdir().unwrap();
    let world = SoloWorld::new([0.0, 0.0, 0.015], Millis(2));
    let out = simulate(&firmware(name), &config(dir.path(), platform), world);
    (dir, out)
}

#[test]
fn the_kernel_runs_the_cluster_and_logs_its_power() {
    let (dir, out) = run("cluster_hw_repeat", aideck());
    assert!(out.error.is_none(), "{:?}", out.error);
    assert_eq!(out.summary.exit_code, 0);
    let console = std::fs::read_to_string(dir.path().join("console.log")).unwrap();
    assert!(
        console.contains("cluster: 8 cores, counter 4000"),
        "{console}"
    );
    let csv = series_text(&dir.path().join("power.csv"));
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (active, total) = (col("p_cluster_cores_active_w"), col("p_cluster_w"));
    assert_eq!(header.last(), Some(&"p_cluster_w"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    assert!(rows.len() >= 2, "{} rows", rows.len());
    // The first millisecond: the cluster is on and its cores work; its
    // power stays below the full-load figure (96 mW, 8 busy cores).
    let first = &rows[0];
    assert!(first[active] > 0.0 && first[total] > first[active]);
    assert!(first[total] < FULL);
    // summary.json's cluster energy is the sum of the logged samples'.
    let logged: f64 = rows.iter().map(|r| r[total] * 1e-3).sum();
    let e = out.summary.energy_j.cluster.unwrap();
    assert!((e - logged).abs() < 1e-9 * logged, "{e} vs {logged}");
}

#[test]
fn without_a_cluster_section_power_csv_keeps_its_columns() {
    let (dir, out) = run("hello", PlatformConfig::default_crazyflie());
    assert!(out.error.is_none(), "{:?}", out.error);
    assert_eq!(out.summary.energy_j.cluster, None);
    let csv = series_text(&dir.path().join("power.csv"));
    assert!(!csv.lines().next().unwrap().contains("cluster"));
    // And a cluster program on that platform is a clear failure, not a
    // hang: its first L1 access faults.
    let (_dir, out) = run("cluster_hw_test", PlatformConfig::default_crazyflie());
    let err = out.error.map(|e| e.to_string()).unwrap_or_default();
    assert!(
        err.contains("load access fault") && err.contains("mtval 0x10008000"),
        "{err}"
    );
}

/// A series file's text, in whichever form the run wrote it
/// (`power.csv` or `power.csv.zst`).
fn series_text(path: &std::path::Path) -> String {
    String::from_utf8(protocol::series::read(path).unwrap().bytes).unwrap()
}
