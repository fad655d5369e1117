//! The radio log (`--radio-log`, docs/SWARM.md §3): one CSV row per (frame,
//! receiver) once its outcome is final, in the order of the receptions' end
//! times (then sender, frame, receiver).

use std::io::Write;

use protocol::radio::Radio;
use serde::Serialize;

/// What became of one frame at one receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Delivered to the receiver.
    Received,
    /// Another audible frame of the same radio overlapped it at the receiver.
    Collision,
    /// The receiver was transmitting on the same radio during the reception.
    HalfDuplex,
    /// Beyond `uwb_max_range_m` (uwb) or below the nRF51's sensitivity (p2p).
    OutOfRange,
    /// Lost by the loss probability (`uwb_loss` / `p2p_loss`).
    Lost,
    /// The receiver stopped (retired) before the reception ended.
    Retired,
}

impl Outcome {
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Received => "received",
            Outcome::Collision => "collision",
            Outcome::HalfDuplex => "half_duplex",
            Outcome::OutOfRange => "out_of_range",
            Outcome::Lost => "lost",
            Outcome::Retired => "retired",
        }
    }
}

/// The columns, in the order of [`LogRow`]'s fields.
pub const HEADER: [&str; 10] = [
    "start_ps",
    "end_ps",
    "radio",
    "from",
    "to",
    "distance_m",
    "rssi_dbm",
    "outcome",
    "tx_stamp",
    "rx_stamp",
];

/// One row of the log.
#[derive(Clone, Debug, Serialize)]
pub struct LogRow<'a> {
    /// When the frame started to leave the sender, world ps.
    pub start_ps: u64,
    /// When the reception ended at the receiver (RX-done), world ps.
    pub end_ps: u64,
    pub radio: Radio,
    pub from: &'a str,
    pub to: &'a str,
    /// Centre distance at the start time, m.
    pub distance_m: f64,
    pub rssi_dbm: f64,
    pub outcome: Outcome,
    /// uwb: the sender's stamp (empty for p2p).
    pub tx_stamp: Option<u64>,
    /// uwb: the receiver's stamp (empty for p2p).
    pub rx_stamp: Option<u64>,
}

/// One row of the log as the world's MCAP takes it (`crate::foxglove`):
/// drones by index, so their positions can be looked up.
#[derive(Clone, Debug, PartialEq)]
pub struct RadioEvent {
    pub start_ps: u64,
    pub end_ps: u64,
    pub radio: Radio,
    pub from: usize,
    pub to: usize,
    pub distance_m: f64,
    pub rssi_dbm: f64,
    pub outcome: Outcome,
}

/// Where the rows go: the CSV writer (and the first error it met: the
/// channel's methods do not fail on a log error; it is kept and returned
/// by [`RadioLog::flush`]) and/or a list of events taken by
/// [`RadioLog::take_events`].
#[derive(Default)]
pub struct RadioLog {
    w: Option<csv::Writer<Box<dyn Write + Send>>>,
    error: Option<std::io::Error>,
    events: Option<Vec<RadioEvent>>,
}

impl RadioLog {
    /// The header row is written at once, so a run without frames still
    /// leaves a well-formed CSV.
    pub fn set_csv(&mut self, w: Box<dyn Write + Send>) {
        let mut w = csv::WriterBuilder::new().has_headers(false).from_writer(w);
        self.error = w.write_record(HEADER).err().map(into_io);
        self.w = Some(w);
    }

    /// Keeps every row from now on until [`RadioLog::take_events`].
    pub fn keep_events(&mut self) {
        self.events.get_or_insert_with(Vec::new);
    }

    /// The rows kept since the last call (empty unless kept).
    pub fn take_events(&mut self) -> Vec<RadioEvent> {
        self.events.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// One row; `from` and `to` are the drones' indices.
    pub fn write(&mut self, from: usize, to: usize, row: &LogRow<'_>) {
        if let Some(events) = &mut self.events {
            events.push(RadioEvent {
                start_ps: row.start_ps,
                end_ps: row.end_ps,
                radio: row.radio,
                from,
                to,
                distance_m: row.distance_m,
                rssi_dbm: row.rssi_dbm,
                outcome: row.outcome,
            });
        }
        let Some(w) = &mut self.w else {
            return;
        };
        if self.error.is_some() {
            return;
        }
        if let Err(e) = w.serialize(row) {
            self.error = Some(into_io(e));
        }
    }

    /// Flushes; returns the first error met since the log was set, if any.
    pub fn flush(&mut self) -> std::io::Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        match &mut self.w {
            Some(w) => w.flush(),
            None => Ok(()),
        }
    }
}

fn into_io(e: csv::Error) -> std::io::Error {
    match e.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => std::io::Error::other(format!("radio log: {other:?}")),
    }
}
