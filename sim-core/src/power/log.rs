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
//! Every file gets its header when it is created and is flushed by
//! [`PowerLogger::flush`] and again when the logger is dropped — on normal
//! exit, on an error return and while unwinding from a panic — so the files
//! are always valid CSV (a row is written whole by `csv` before any flush).

use std::fs::File;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::models::PowerModelKind;
use super::{PowerError, PowerSample};

/// File name of the network log.
pub const POWER_CSV: &str = "power.csv";

/// File name of one motor model's log (`motor_empirical.csv`, …).
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

#[derive(Serialize)]
struct PowerRow<'a> {
    t_ps: u64,
    time_s: f64,
    i_core_a: f64,
    i_camera_a: f64,
    i_stm32_a: f64,
    i_other_a: f64,
    i_vcc_a: f64,
    ldo_efficiency: f64,
    i_vcc_battery_a: f64,
    i_motor_a: f64,
    i_battery_a: f64,
    v_oc_v: f64,
    v_battery_v: f64,
    soc: f64,
    low_battery: u8,
    power_model: &'a str,
}

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

#[derive(Serialize)]
struct ModelRow {
    t_ps: u64,
    time_s: f64,
    mean_omega_rad_s: f64,
    horizontal_speed_m_s: f64,
    vertical_speed_m_s: f64,
    pitch_rad: f64,
    current_a: f64,
    power_w: f64,
    v_battery_v: f64,
    selected: u8,
}

struct CsvFile {
    path: PathBuf,
    writer: csv::Writer<File>,
}

impl CsvFile {
    fn create(path: PathBuf, header: &[&str]) -> Result<CsvFile, PowerError> {
        let file = File::create(&path).map_err(|source| PowerError::Io {
            path: path.clone(),
            source,
        })?;
        let mut writer = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(file);
        writer
            .write_record(header)
            .map_err(|source| PowerError::Csv {
                path: path.clone(),
                source,
            })?;
        let mut f = CsvFile { path, writer };
        f.flush()?;
        Ok(f)
    }

    fn row<T: Serialize>(&mut self, row: &T) -> Result<(), PowerError> {
        self.writer
            .serialize(row)
            .map_err(|source| PowerError::Csv {
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
}

/// `power.csv` row with the radio columns (same columns, two more at the end).
#[derive(Serialize)]
struct PowerRowRadios<'a> {
    t_ps: u64,
    time_s: f64,
    i_core_a: f64,
    i_camera_a: f64,
    i_stm32_a: f64,
    i_other_a: f64,
    i_vcc_a: f64,
    ldo_efficiency: f64,
    i_vcc_battery_a: f64,
    i_motor_a: f64,
    i_battery_a: f64,
    v_oc_v: f64,
    v_battery_v: f64,
    soc: f64,
    low_battery: u8,
    power_model: &'a str,
    i_uwb_a: f64,
    i_p2p_a: f64,
}

/// Writers for `power.csv` and the three model files.
pub struct PowerLogger {
    power: CsvFile,
    models: [CsvFile; 3],
    radio_columns: bool,
}

impl PowerLogger {
    /// Creates (truncates) the four files in `dir`, headers written;
    /// `radio_columns` adds the radios' columns to `power.csv`.
    pub fn create(dir: &Path, radio_columns: bool) -> Result<PowerLogger, PowerError> {
        let header: Vec<&str> = if radio_columns {
            POWER_HEADER
                .iter()
                .chain(RADIO_HEADER.iter())
                .copied()
                .collect()
        } else {
            POWER_HEADER.to_vec()
        };
        let power = CsvFile::create(dir.join(POWER_CSV), &header)?;
        let model = |k: PowerModelKind| CsvFile::create(dir.join(model_csv_name(k)), &MODEL_HEADER);
        Ok(PowerLogger {
            power,
            models: [
                model(PowerModelKind::Empirical)?,
                model(PowerModelKind::DAndrea)?,
                model(PowerModelKind::Stolaroff)?,
            ],
            radio_columns,
        })
    }

    /// Paths of the four files (power first, then the models in order).
    pub fn paths(&self) -> Vec<PathBuf> {
        std::iter::once(&self.power)
            .chain(self.models.iter())
            .map(|f| f.path.clone())
            .collect()
    }

    /// Appends one sample to every file.
    pub fn log(&mut self, s: &PowerSample) -> Result<(), PowerError> {
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
        if self.radio_columns {
            self.power.row(&PowerRowRadios {
                t_ps: s.t.0,
                time_s,
                i_core_a: s.i_core.0,
                i_camera_a: s.i_camera.0,
                i_stm32_a: s.i_stm32.0,
                i_other_a: s.i_other.0,
                i_vcc_a: s.i_vcc.0,
                ldo_efficiency: s.ldo_efficiency,
                i_vcc_battery_a: s.i_vcc_battery.0,
                i_motor_a: s.i_motor.0,
                i_battery_a: s.i_battery.0,
                v_oc_v: s.v_oc.0,
                v_battery_v: s.v_battery.0,
                soc: s.soc,
                low_battery: u8::from(s.low_battery),
                power_model: s.selected.name(),
                i_uwb_a: i_uwb.0,
                i_p2p_a: i_p2p.0,
            })?;
        } else {
            self.power.row(&PowerRow {
                t_ps: s.t.0,
                time_s,
                i_core_a: s.i_core.0,
                i_camera_a: s.i_camera.0,
                i_stm32_a: s.i_stm32.0,
                // Nothing separate for the radios: they are "other" loads.
                i_other_a: i_other_all,
                i_vcc_a: s.i_vcc.0,
                ldo_efficiency: s.ldo_efficiency,
                i_vcc_battery_a: s.i_vcc_battery.0,
                i_motor_a: s.i_motor.0,
                i_battery_a: s.i_battery.0,
                v_oc_v: s.v_oc.0,
                v_battery_v: s.v_battery.0,
                soc: s.soc,
                low_battery: u8::from(s.low_battery),
                power_model: s.selected.name(),
            })?;
        }
        for (kind, file) in PowerModelKind::ALL.iter().zip(self.models.iter_mut()) {
            let out = s.models[kind.index()];
            file.row(&ModelRow {
                t_ps: s.t.0,
                time_s,
                mean_omega_rad_s: s.motor.mean_omega(),
                horizontal_speed_m_s: s.motor.horizontal_speed,
                vertical_speed_m_s: s.motor.vertical_speed,
                pitch_rad: s.motor.pitch,
                current_a: out.current.0,
                power_w: out.power.0,
                v_battery_v: s.v_battery.0,
                selected: u8::from(*kind == s.selected),
            })?;
        }
        Ok(())
    }

    /// Flushes every file.
    pub fn flush(&mut self) -> Result<(), PowerError> {
        self.power.flush()?;
        for f in &mut self.models {
            f.flush()?;
        }
        Ok(())
    }
}

impl Drop for PowerLogger {
    fn drop(&mut self) {
        // Best effort on the error and panic paths; the normal path calls
        // `flush` and sees its errors.
        if let Err(e) = self.flush() {
            tracing::error!("power logs not flushed: {e}");
        }
    }
}
