//! CSV logs of the power network (DESIGN.md §6): `power.csv` with one row
//! per 1 ms sample, and one file per motor model as the thesis's three log
//! files (§4.5.3, `open_files`).
//!
//! `power.csv` has two more columns at the end, `i_uwb_a` and `i_p2p_a`, for
//! a platform that reports its radios (a swarm member, `--drone`, or a
//! platform file that lists them; see `kernel::KernelConfig::reports_radios`).
//! Without them a radio's current is counted in `i_other_a`, so the VCC
//! columns always add up; a run that never switches a radio on writes the
//! same bytes as before the radios existed.
//!
//! The files are series files ([`protocol::series`]): plain CSV or
//! zstd-compressed (`power.csv.zst`, run key `output.compress`).
//!
//! Every file gets its header when it is created and is flushed by
//! [`PowerLogger::flush`] and finished when the logger is dropped — on
//! normal exit, on an error return and while unwinding from a panic — so
//! the files are always valid (a row is handed to the buffer whole,
//! [`CsvLine`]); a process killed mid-run leaves a valid prefix, which the
//! readers take ([`protocol::series::read`]).

use std::collections::VecDeque;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use protocol::series::{SeriesFormat, SeriesWriter};

use super::csv_line::CsvLine;
use super::models::PowerModelKind;
use super::{PowerError, PowerSample};

/// Series name of the network log (its file: `power.csv` or
/// `power.csv.zst`, [`SeriesFormat::file_name`]).
pub const POWER_CSV: &str = "power.csv";

/// Series name of one motor model's log (`motor_empirical.csv`, …).
pub fn model_csv_name(kind: PowerModelKind) -> String {
    format!("motor_{}.csv", kind.name())
}

const POWER_HEADER: [&str; 16] = [
    "t_ps",
    "time_s",
    "i_core_a",
    "i_camera_a",
    "i_stm32_a",
    "i_other_a",
    "i_vcc_a",
    "ldo_efficiency",
    "i_vcc_battery_a",
    "i_motor_a",
    "i_battery_a",
    "v_oc_v",
    "v_battery_v",
    "soc",
    "low_battery",
    "power_model",
];

const RADIO_HEADER: [&str; 2] = ["i_uwb_a", "i_p2p_a"];

/// The cluster's columns (a platform with a cluster, `crate::cluster::power`):
/// mean power over the sample's interval, W.
const CLUSTER_HEADER: [&str; 6] = [
    "p_cluster_cores_active_w",
    "p_cluster_cores_gated_w",
    "p_cluster_l1_w",
    "p_cluster_dma_w",
    "p_cluster_leakage_w",
    "p_cluster_w",
];

const MODEL_HEADER: [&str; 10] = [
    "t_ps",
    "time_s",
    "mean_omega_rad_s",
    "horizontal_speed_m_s",
    "vertical_speed_m_s",
    "pitch_rad",
    "current_a",
    "power_w",
    "v_battery_v",
    "selected",
];

struct CsvFile {
    path: PathBuf,
    writer: SeriesWriter,
    line: CsvLine,
}

impl CsvFile {
    fn create(path: PathBuf, header: &[&str]) -> Result<CsvFile, PowerError> {
        let writer = SeriesWriter::create(&path).map_err(|source| PowerError::Io {
            path: path.clone(),
            source,
        })?;
        let mut f = CsvFile {
            path,
            writer,
            line: CsvLine::new(),
        };
        for h in header {
            f.line.ident(h);
        }
        f.end_row()?;
        f.flush()?;
        Ok(f)
    }

    /// Appends the row built in `self.line`.
    fn end_row(&mut self) -> Result<(), PowerError> {
        self.line
            .finish(&mut self.writer)
            .map_err(|source| PowerError::Io {
                path: self.path.clone(),
                source,
            })
    }

    fn flush(&mut self) -> Result<(), PowerError> {
        self.writer.flush().map_err(|source| PowerError::Io {
            path: self.path.clone(),
            source,
        })
    }

    fn finish(&mut self) -> Result<(), PowerError> {
        self.writer.finish().map_err(|source| PowerError::Io {
            path: self.path.clone(),
            source,
        })
    }
}

/// The four files.
struct Files {
    power: CsvFile,
    models: [CsvFile; 3],
    radio_columns: bool,
    cluster_columns: bool,
}

/// Samples queued before [`PowerLogger::log`] writes them itself (a
/// simulation whose link never waits: an in-process world). About 1.3 MB.
const QUEUE_MAX: usize = 4096;
/// Samples written per slice of idle work: 8 rows, a few µs, so that a
/// reply that arrives meanwhile is noticed at once.
const SLICE: usize = 2;

/// What the logger and its idle work share.
struct Shared {
    files: Files,
    /// Samples logged, not yet formatted, oldest first.
    queue: VecDeque<PowerSample>,
    /// The first write error: reported by every later log and flush.
    error: Option<PowerError>,
}

impl Shared {
    /// Formats and writes up to `n` queued samples, in order.
    fn write_some(&mut self, n: usize) {
        for _ in 0..n {
            if self.error.is_some() {
                self.queue.clear();
                return;
            }
            let Some(s) = self.queue.pop_front() else {
                return;
            };
            if let Err(e) = self.files.log(&s) {
                self.error = Some(e);
            }
        }
    }

    fn result(&self) -> Result<(), PowerError> {
        self.error.as_ref().map_or(Ok(()), |e| Err(again(e)))
    }
}

/// Writers for `power.csv` and the three model files.
///
/// About 96 MB of CSV per race is formatted and written while the
/// platform waits for the world rather than when a sample is taken: the
/// samples are queued and [`PowerLogger::idle_work`], handed to the link
/// ([`crate::peripherals::WorldLink::add_idle_work`]), writes a few at a
/// time between polls of the socket. The next request to the world does
/// not wait for them (docs/COSIM.md "Performance"). The bytes are the same,
/// in the same order; [`PowerLogger::flush`] writes what is still queued.
/// A write error is reported by the next `log` or `flush` after it.
pub struct PowerLogger {
    shared: Arc<Mutex<Shared>>,
    paths: Vec<PathBuf>,
}

fn lock(shared: &Mutex<Shared>) -> std::sync::MutexGuard<'_, Shared> {
    // A panic while formatting leaves whole rows behind (a row reaches the
    // buffer whole), so the files can still be flushed.
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

impl PowerLogger {
    /// Creates (truncates) the four files in `dir` as plain CSV, headers
    /// written; `radio_columns` adds the radios' columns to `power.csv`.
    pub fn create(dir: &Path, radio_columns: bool) -> Result<PowerLogger, PowerError> {
        Self::create_with_cluster(dir, radio_columns, false, SeriesFormat::Plain)
    }

    /// As [`PowerLogger::create`], in the form `format`; `cluster_columns`
    /// adds the cluster's columns after all others.
    pub fn create_with_cluster(
        dir: &Path,
        radio_columns: bool,
        cluster_columns: bool,
        format: SeriesFormat,
    ) -> Result<PowerLogger, PowerError> {
        let mut header: Vec<&str> = POWER_HEADER.to_vec();
        if radio_columns {
            header.extend(RADIO_HEADER);
        }
        if cluster_columns {
            header.extend(CLUSTER_HEADER);
        }
        let power = CsvFile::create(dir.join(format.file_name(POWER_CSV)), &header)?;
        let model = |k: PowerModelKind| {
            CsvFile::create(
                dir.join(format.file_name(&model_csv_name(k))),
                &MODEL_HEADER,
            )
        };
        let files = Files {
            power,
            models: [
                model(PowerModelKind::Empirical)?,
                model(PowerModelKind::DAndrea)?,
                model(PowerModelKind::Stolaroff)?,
            ],
            radio_columns,
            cluster_columns,
        };
        let paths = std::iter::once(&files.power)
            .chain(files.models.iter())
            .map(|f| f.path.clone())
            .collect();
        Ok(PowerLogger {
            shared: Arc::new(Mutex::new(Shared {
                files,
                queue: VecDeque::with_capacity(QUEUE_MAX),
                error: None,
            })),
            paths,
        })
    }

    /// Paths of the four files (power first, then the models in order).
    pub fn paths(&self) -> Vec<PathBuf> {
        self.paths.clone()
    }

    /// Appends one sample to every file (queued; written by the idle work,
    /// by this call once [`QUEUE_MAX`] are queued, or by `flush`).
    pub fn log(&mut self, s: &PowerSample) -> Result<(), PowerError> {
        let mut g = lock(&self.shared);
        g.queue.push_back(*s);
        if g.queue.len() >= QUEUE_MAX {
            let n = g.queue.len();
            g.write_some(n);
        }
        g.result()
    }

    /// The work the link does while it waits for the world: writes
    /// [`SLICE`] queued samples per call, returns whether more are queued.
    pub fn idle_work(&self) -> protocol::busy_poll::IdleWork {
        let shared = Arc::clone(&self.shared);
        Box::new(move || {
            let mut g = lock(&shared);
            g.write_some(SLICE);
            g.error.is_none() && !g.queue.is_empty()
        })
    }

    /// Writes every queued sample and flushes every file.
    pub fn flush(&mut self) -> Result<(), PowerError> {
        self.write_all_then(Files::flush)
    }

    /// Writes every queued sample and ends every file (a compressed file's
    /// frame); later logs fail. The end of a run.
    pub fn finish(&mut self) -> Result<(), PowerError> {
        self.write_all_then(Files::finish)
    }

    fn write_all_then(
        &mut self,
        then: fn(&mut Files) -> Result<(), PowerError>,
    ) -> Result<(), PowerError> {
        let mut g = lock(&self.shared);
        let n = g.queue.len();
        g.write_some(n);
        g.result()?;
        if let Err(e) = then(&mut g.files) {
            g.error = Some(again(&e));
            return Err(e);
        }
        Ok(())
    }
}

impl Files {
    /// Appends one sample to every file.
    fn log(&mut self, s: &PowerSample) -> Result<(), PowerError> {
        let time_s = s.t.as_secs_f64();
        let [i_uwb, i_p2p] = s.i_radios;
        // Without radio columns the radios are "other" loads. Added only
        // when they draw something: an empty `i_other` sum is −0.0, and
        // −0.0 + 0.0 would print differently from the radio-less platform.
        let radios = i_uwb.0 + i_p2p.0;
        let i_other_all = if radios != 0.0 {
            s.i_other.0 + radios
        } else {
            s.i_other.0
        };
        // The columns of POWER_HEADER (and RADIO_HEADER), in order.
        let l = &mut self.power.line;
        l.u64(s.t.0)
            .f64(time_s)
            .f64(s.i_core.0)
            .f64(s.i_camera.0)
            .f64(s.i_stm32.0)
            // Without radio columns, the radios are "other" loads.
            .f64(if self.radio_columns {
                s.i_other.0
            } else {
                i_other_all
            })
            .f64(s.i_vcc.0)
            .f64(s.ldo_efficiency)
            .f64(s.i_vcc_battery.0)
            .f64(s.i_motor.0)
            .f64(s.i_battery.0)
            .f64(s.v_oc.0)
            .f64(s.v_battery.0)
            .f64(s.soc)
            .u64(u64::from(s.low_battery))
            .ident(s.selected.name());
        if self.radio_columns {
            l.f64(i_uwb.0).f64(i_p2p.0);
        }
        if self.cluster_columns {
            let c = s.cluster.unwrap_or_default();
            l.f64(c.cores_active_w)
                .f64(c.cores_gated_w)
                .f64(c.l1_w)
                .f64(c.dma_w)
                .f64(c.leakage_w)
                .f64(c.total_w());
        }
        self.power.end_row()?;
        for (kind, file) in PowerModelKind::ALL.iter().zip(self.models.iter_mut()) {
            let out = s.models[kind.index()];
            // The columns of MODEL_HEADER, in order.
            file.line
                .u64(s.t.0)
                .f64(time_s)
                .f64(s.motor.mean_omega())
                .f64(s.motor.horizontal_speed)
                .f64(s.motor.vertical_speed)
                .f64(s.motor.pitch)
                .f64(out.current.0)
                .f64(out.power.0)
                .f64(s.v_battery.0)
                .u64(u64::from(*kind == s.selected));
            file.end_row()?;
        }
        Ok(())
    }

    /// Flushes every file.
    fn flush(&mut self) -> Result<(), PowerError> {
        self.power.flush()?;
        for f in &mut self.models {
            f.flush()?;
        }
        Ok(())
    }

    /// Ends every file.
    fn finish(&mut self) -> Result<(), PowerError> {
        self.power.finish()?;
        for f in &mut self.models {
            f.finish()?;
        }
        Ok(())
    }
}

/// A copy of a write error, to report it again at every later log and
/// flush (`io::Error` is not `Clone`).
fn again(e: &PowerError) -> PowerError {
    match e {
        PowerError::Io { path, source } => PowerError::Io {
            path: path.clone(),
            source: std::io::Error::new(source.kind(), source.to_string()),
        },
        other => PowerError::Io {
            path: PathBuf::new(),
            source: std::io::Error::other(other.to_string()),
        },
    }
}

impl Drop for PowerLogger {
    fn drop(&mut self) {
        // Best effort on the error and panic paths; the normal path calls
        // `finish` and sees its errors.
        if let Err(e) = self.finish() {
            tracing::error!("power logs not flushed: {e}");
        }
    }
}
