//! `--trajectory FILE`: one CSV row per world step (DESIGN.md §6): time,
//! position, attitude, velocities, signed motor speeds, collisions. With
//! several drones (DESIGN.md §7): one row per drone per step, in world-file
//! order, with a `drone` column second; one drone keeps [`HEADER`] exactly.
//!
//! A series file ([`protocol::series`]): a `FILE` ending in `.zst` is
//! written zstd-compressed.

use std::path::Path;

use protocol::series::SeriesWriter;

use crate::sensors::DroneState;

/// Column names, in row order.
pub const HEADER: [&str; 17] = [
    "time_ms",
    "x",
    "y",
    "z",
    "roll",
    "pitch",
    "yaw",
    "vx",
    "vy",
    "vz",
    "w1",
    "w2",
    "w3",
    "w4",
    "collisions",
    "ground_contacts",
    "gates_passed",
];

/// The name of the column a world with several drones adds (second).
pub const DRONE_COLUMN: &str = "drone";

/// Writes the trajectory; call [`TrajectoryWriter::finish`] on every exit
/// path (dropping it also finishes, but cannot report an error).
pub struct TrajectoryWriter {
    /// `None` once finished.
    out: Option<csv::Writer<SeriesWriter>>,
    multi: bool,
    rec: csv::StringRecord,
}

impl TrajectoryWriter {
    /// `multi`: the world has several drones (rows carry the drone's name).
    pub fn create(path: &Path, multi: bool) -> Result<TrajectoryWriter, csv::Error> {
        // The series writer buffers; the csv crate's own buffer in front of
        // it stays at its default.
        let mut out = csv::Writer::from_writer(SeriesWriter::create(path)?);
        if multi {
            let mut h = HEADER.to_vec();
            h.insert(1, DRONE_COLUMN);
            out.write_record(h)?;
        } else {
            out.write_record(HEADER)?;
        }
        Ok(TrajectoryWriter {
            out: Some(out),
            multi,
            rec: csv::StringRecord::with_capacity(256, HEADER.len() + 1),
        })
    }

    /// One row; `drone` is written only by a multi-drone writer.
    pub fn row(&mut self, s: &DroneState, drone: &str) -> Result<(), csv::Error> {
        let [roll, pitch, yaw] = s.attitude();
        let [x, y, z] = s.position;
        let [vx, vy, vz] = s.velocity;
        let [w1, w2, w3, w4] = s.motor_speeds;
        let floats = [x, y, z, roll, pitch, yaw, vx, vy, vz, w1, w2, w3, w4];
        let rec = &mut self.rec;
        rec.clear();
        rec.push_field(&s.time.0.to_string());
        if self.multi {
            rec.push_field(drone);
        }
        for v in floats {
            rec.push_field(&v.to_string());
        }
        rec.push_field(&s.collisions.to_string());
        rec.push_field(&s.ground_contacts.to_string());
        rec.push_field(&s.gates_passed.to_string());
        match &mut self.out {
            Some(out) => out.write_record(&*rec),
            None => Err(std::io::Error::other("trajectory written after its end").into()),
        }
    }

    /// Writes every row and ends the file (a compressed file's frame);
    /// later rows fail.
    pub fn finish(&mut self) -> std::io::Result<()> {
        match self.out.take() {
            Some(out) => out.into_inner().map_err(|e| e.into_error())?.finish(),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::Millis;

    #[test]
    fn rows_round_trip_through_csv() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        let mut w = TrajectoryWriter::create(&path, false).unwrap();
        let s = DroneState {
            time: Millis(2032),
            position: [1.0, -2.5, 0.015],
            quaternion: [1.0, 0.0, 0.0, 0.0],
            velocity: [0.1, 0.2, 0.3],
            omega_body: [0.0; 3],
            motor_speeds: [-48.0, 48.0, -48.0, 48.0],
            collisions: 2,
            ground_contacts: 1,
            gates_passed: 3,
        };
        w.row(&s, "cf1").unwrap();
        w.finish().unwrap();
        let mut r = csv::Reader::from_path(&path).unwrap();
        assert_eq!(r.headers().unwrap().iter().collect::<Vec<_>>(), HEADER);
        let rec = r.records().next().unwrap().unwrap();
        assert_eq!(&rec[0], "2032");
        assert_eq!(rec[2].parse::<f64>().unwrap(), -2.5);
        assert_eq!(&rec[10], "-48");
        assert_eq!(&rec[14], "2");
        assert_eq!(&rec[15], "1");
        assert_eq!(&rec[16], "3");
    }

    #[test]
    fn several_drones_add_a_drone_column_second() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        let mut w = TrajectoryWriter::create(&path, true).unwrap();
        let s = DroneState {
            time: Millis(2000),
            position: [1.0, 2.0, 3.0],
            quaternion: [1.0, 0.0, 0.0, 0.0],
            velocity: [0.0; 3],
            omega_body: [0.0; 3],
            motor_speeds: [0.0; 4],
            collisions: 0,
            ground_contacts: 0,
            gates_passed: 0,
        };
        w.row(&s, "A").unwrap();
        w.row(&s, "B").unwrap();
        w.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        // The compressed form holds the same text.
        let zst = dir.path().join("t.csv.zst");
        let mut w = TrajectoryWriter::create(&zst, true).unwrap();
        w.row(&s, "A").unwrap();
        w.row(&s, "B").unwrap();
        w.finish().unwrap();
        assert_eq!(protocol::series::read(&zst).unwrap().bytes, text.as_bytes());
        assert!(
            lines[0].starts_with("time_ms,drone,x,y,z,roll"),
            "{}",
            lines[0]
        );
        assert!(lines[1].starts_with("2000,A,1,2,3,"), "{}", lines[1]);
        assert!(lines[2].starts_with("2000,B,1,2,3,"), "{}", lines[2]);
    }
}
