//! `--mcap FILE`: what the world sees of a run, as an MCAP file that
//! Foxglove opens (DESIGN.md §15, docs/FOXGLOVE.md).
//!
//! The world is the one place that knows every drone's pose, the scene,
//! the camera frames and the radio channel, so it writes those live, as
//! the run goes (a run that dies still leaves a valid file: the writer is
//! finished on every exit path, and on drop). `cosim` then merges this file
//! with each platform's power, battery and map channels into the run's
//! `run.mcap` (`scenarios::foxglove`). Log time = publish time = world
//! time in ns; nothing of the host's clock goes in (the writer's header,
//! statistics and summary hold no wall time).
//!
//! Topics (per drone `D`): `/tf` (`foxglove.FrameTransform`, parent
//! `world`, child `D`, one per drone per world step), `/scene`
//! (`foxglove.SceneUpdate`: every box of the world — gate bars, obstacles,
//! walls — and a body with a heading arrow per drone, at t = 0),
//! `/D/camera` (`foxglove.RawImage`, mono8, every Nth frame served),
//! `/D/motors` (target and actual signed speeds), `/radio/packets` (one
//! message per frame and receiver with its outcome) and `/radio/links`
//! (`foxglove.SceneUpdate`: a line sender → receiver per received frame).

pub mod schemas;

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::Arc;

use base64::Engine as _;
use serde_json::{json, Value};

use crate::physics::World;
use crate::radio::{Outcome, RadioEvent};
use crate::scene::SceneBox;
use crate::time::Millis;

/// Default of `--mcap-image-every`: one camera frame in 30 served — about
/// one a second in the thesis's race (one frame per 32 ms step), which
/// keeps the images under a tenth of the race's wall time
/// (docs/FOXGLOVE.md "Cost").
pub const DEFAULT_IMAGE_EVERY: u64 = 30;

/// How long a radio link stays drawn after its frame was received (s):
/// long enough to be seen at normal playback speed.
const LINK_LIFETIME_NS: u64 = 250_000_000;

/// The Crazyflie's body as drawn: the cylinder of DESIGN.md §5 (r 0.05 m,
/// h 0.03 m) as a 0.1 × 0.1 × 0.03 m box.
const BODY_SIZE: [f64; 3] = [0.1, 0.1, 0.03];

/// Writer options of `cosim`'s `run.mcap`: zstd chunks of the crate's
/// default 1 MiB (Foxglove reads such chunks one at a time as it seeks), at
/// level [`RUN_MCAP_ZSTD_LEVEL`]: a race's run output fits in its budget
/// (docs/FOXGLOVE.md "Cost"). No worker pool: its size would depend on the
/// host, and so would the bytes.
pub fn write_options() -> mcap::WriteOptions {
    mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(RUN_MCAP_ZSTD_LEVEL)
        .compression_threads(0)
}

/// zstd's level for `run.mcap`'s chunks: 1, as for the series (protocol::series).
pub const RUN_MCAP_ZSTD_LEVEL: u32 = 1;

/// Writer options of the world's file: uncompressed chunks. The world is on
/// the run's critical path (every platform waits for it) and its file is
/// only the raw material `cosim` merges into `run.mcap`; lz4 there put the
/// race at +12 % of wall time on a loaded machine (docs/FOXGLOVE.md "Cost").
pub fn world_write_options() -> mcap::WriteOptions {
    mcap::WriteOptions::new()
        .compression(None)
        .compression_threads(0)
}

/// World time (ms) as MCAP time (ns).
pub fn ns_of_ms(t: Millis) -> u64 {
    t.0.saturating_mul(1_000_000)
}

/// A Foxglove `time` from ns.
pub fn stamp(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

/// Schemas and channels to write: one schema per name, shared by its
/// channels. Their ids are distinct from those of a file being merged (the
/// merge keeps both in one list), though the writer gives each channel its
/// own id when it is registered ([`KnownChannels`]).
pub struct Channels {
    schemas: BTreeMap<String, Arc<mcap::Schema<'static>>>,
    next_schema: u16,
    next_channel: u16,
}

impl Channels {
    /// Ids start after `schema_id` and `channel_id` (0, 0 for a new file).
    pub fn after(schema_id: u16, channel_id: u16) -> Channels {
        Channels {
            schemas: BTreeMap::new(),
            next_schema: schema_id + 1,
            next_channel: channel_id + 1,
        }
    }

    /// A channel on `topic` with the schema `schema` (its title is its name).
    pub fn add(&mut self, topic: &str, schema: &Value) -> Arc<mcap::Channel<'static>> {
        let name = schema["title"].as_str().unwrap_or("").to_string();
        let next_schema = &mut self.next_schema;
        let schema = self
            .schemas
            .entry(name.clone())
            .or_insert_with(|| {
                let id = *next_schema;
                *next_schema += 1;
                Arc::new(mcap::Schema {
                    id,
                    name,
                    encoding: schemas::SCHEMA_ENCODING.into(),
                    data: Cow::Owned(schema.to_string().into_bytes()),
                })
            })
            .clone();
        let id = self.next_channel;
        self.next_channel += 1;
        Arc::new(mcap::Channel {
            id,
            topic: topic.into(),
            schema: Some(schema),
            message_encoding: schemas::MESSAGE_ENCODING.into(),
            metadata: BTreeMap::new(),
        })
    }

    /// A channel of a Foxglove type (`schemas::FRAME_TRANSFORM`, …).
    pub fn foxglove(&mut self, topic: &str, name: &str) -> Arc<mcap::Channel<'static>> {
        let schema = schemas::foxglove(name).expect("a Foxglove schema we define");
        self.add(topic, &schema)
    }
}

/// Channels registered with a writer once, so that each message is
/// written by id (`write_to_known_channel`): `Writer::write` hashes the
/// channel's and schema's content on every message, which on the 290 000
/// messages of the race's power log cost more than the rest of the merge.
#[derive(Default)]
pub struct KnownChannels {
    ids: std::collections::HashMap<usize, u16>,
}

impl KnownChannels {
    /// The writer's id of `ch` (registered on first use). Keyed by the
    /// `Arc`'s address: the caller keeps its channels alive while writing.
    pub fn id<W: std::io::Write + std::io::Seek>(
        &mut self,
        w: &mut mcap::Writer<W>,
        ch: &Arc<mcap::Channel<'_>>,
    ) -> Result<u16, mcap::McapError> {
        let key = Arc::as_ptr(ch) as *const () as usize;
        if let Some(&id) = self.ids.get(&key) {
            return Ok(id);
        }
        let schema = match &ch.schema {
            Some(s) => w.add_schema(&s.name, &s.encoding, &s.data)?,
            None => 0,
        };
        let id = w.add_channel(schema, &ch.topic, &ch.message_encoding, &ch.metadata)?;
        self.ids.insert(key, id);
        Ok(id)
    }
}

/// Writes one message on `ch`; log time = publish time.
pub fn write_message<W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    known: &mut KnownChannels,
    ch: &Arc<mcap::Channel<'_>>,
    sequence: u32,
    log_time: u64,
    data: &[u8],
) -> Result<(), mcap::McapError> {
    let channel_id = known.id(w, ch)?;
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        },
        data,
    )
}

/// The topic of one drone's channel.
pub fn drone_topic(drone: &str, what: &str) -> String {
    format!("/{drone}/{what}")
}

/// Per drone: its channels.
struct DroneChannels {
    camera: Arc<mcap::Channel<'static>>,
    motors: Arc<mcap::Channel<'static>>,
}

/// The world's MCAP writer. Write errors are kept (the first one) and
/// returned by [`McapLog::finish`]: the run itself goes on.
pub struct McapLog {
    w: Option<mcap::Writer<BufWriter<File>>>,
    names: Vec<String>,
    tf: Arc<mcap::Channel<'static>>,
    scene: Arc<mcap::Channel<'static>>,
    links: Arc<mcap::Channel<'static>>,
    packets: Arc<mcap::Channel<'static>>,
    drones: Vec<DroneChannels>,
    image_every: u64,
    known: KnownChannels,
    error: Option<mcap::McapError>,
}

impl McapLog {
    /// Creates `path` and writes the scene at t = 0.
    pub fn create(
        path: &Path,
        names: &[String],
        boxes: &[SceneBox],
        image_every: u64,
    ) -> Result<McapLog, mcap::McapError> {
        let file = File::create(path)?;
        let w = world_write_options().create(BufWriter::with_capacity(1 << 20, file))?;
        let mut ch = Channels::after(0, 0);
        let motors_schema = schemas::plain(
            "cosim.Motors",
            &[
                ("time_s", "number", "world time"),
                (
                    "target_rad_s",
                    "number[]",
                    "m1..m4 signed target speeds (SET_VELOCITY)",
                ),
                (
                    "speed_rad_s",
                    "number[]",
                    "m1..m4 signed speeds after the 30 rad/s² ramp (DESIGN.md §5)",
                ),
            ],
        );
        let packets_schema = schemas::plain(
            "cosim.RadioPacket",
            &[
                (
                    "start_s",
                    "number",
                    "world time the frame started to leave the sender",
                ),
                (
                    "end_s",
                    "number",
                    "world time the reception ended (RX-done)",
                ),
                ("radio", "string", "uwb | p2p"),
                ("from", "string", "sender"),
                ("to", "string", "receiver"),
                ("distance_m", "number", "centre distance at the start"),
                ("rssi_dbm", "number", "received signal strength"),
                (
                    "outcome",
                    "string",
                    "received | collision | half_duplex | out_of_range | lost | retired",
                ),
            ],
        );
        let mut log = McapLog {
            tf: ch.foxglove("/tf", schemas::FRAME_TRANSFORM),
            scene: ch.foxglove("/scene", schemas::SCENE_UPDATE),
            links: ch.foxglove("/radio/links", schemas::SCENE_UPDATE),
            packets: ch.add("/radio/packets", &packets_schema),
            drones: names
                .iter()
                .map(|n| DroneChannels {
                    camera: ch.foxglove(&drone_topic(n, "camera"), schemas::RAW_IMAGE),
                    motors: ch.add(&drone_topic(n, "motors"), &motors_schema),
                })
                .collect(),
            w: Some(w),
            names: names.to_vec(),
            image_every,
            known: KnownChannels::default(),
            error: None,
        };
        let scene = scene_update(boxes, names);
        let channel = log.scene.clone();
        log.put(&channel, 0, &scene);
        Ok(log)
    }

    fn put(&mut self, channel: &Arc<mcap::Channel<'static>>, log_time: u64, v: &Value) {
        let data = serde_json::to_vec(v).expect("a JSON value serialises");
        self.put_bytes(channel, log_time, data);
    }

    fn put_bytes(&mut self, channel: &Arc<mcap::Channel<'static>>, log_time: u64, data: Vec<u8>) {
        let (Some(w), None) = (self.w.as_mut(), self.error.as_ref()) else {
            return;
        };
        if let Err(e) = write_message(w, &mut self.known, channel, 0, log_time, &data) {
            self.error = Some(e);
        }
    }

    /// After a world step (and each warm-up step): every drone's transform
    /// and motors.
    pub fn step(&mut self, world: &World) {
        let t = ns_of_ms(world.time());
        for d in 0..self.names.len() {
            let p = world.position(d);
            let q = world.rotation(d);
            let tf = json!({
                "timestamp": stamp(t),
                "parent_frame_id": "world",
                "child_frame_id": self.names[d],
                "translation": {"x": p.x, "y": p.y, "z": p.z},
                "rotation": {"x": q.x, "y": q.y, "z": q.z, "w": q.w},
            });
            let channel = self.tf.clone();
            self.put(&channel, t, &tf);
            let m = world.motors(d);
            let motors = json!({
                "time_s": world.time().as_secs_f64(),
                "target_rad_s": m.targets(),
                "speed_rad_s": m.speeds(),
            });
            let channel = self.drones[d].motors.clone();
            self.put(&channel, t, &motors);
        }
    }

    /// Drone `d`'s `n`-th camera frame (0-based), served at `time`: kept
    /// when `n` is a multiple of the image interval.
    pub fn image(
        &mut self,
        d: usize,
        n: u64,
        time: Millis,
        width: usize,
        height: usize,
        mono8: &[u8],
    ) {
        if self.image_every == 0 || !n.is_multiple_of(self.image_every) {
            return;
        }
        let t = ns_of_ms(time);
        let data = base64::engine::general_purpose::STANDARD.encode(mono8);
        let msg = json!({
            "timestamp": stamp(t),
            "frame_id": self.names[d],
            "width": width,
            "height": height,
            "encoding": "mono8",
            "step": width,
            "data": data,
        });
        let channel = self.drones[d].camera.clone();
        self.put(&channel, t, &msg);
    }

    /// The radio channel's decided receptions: one packet message each, and
    /// a link line for each received frame, from the sender's to the
    /// receiver's position `at` the reception's end.
    pub fn radio(&mut self, events: &[RadioEvent], at: impl Fn(usize, u64) -> [f64; 3]) {
        for e in events {
            let t = e.end_ps / 1000;
            let packet = json!({
                "start_s": e.start_ps as f64 * 1e-12,
                "end_s": e.end_ps as f64 * 1e-12,
                "radio": e.radio.as_str(),
                "from": self.names[e.from],
                "to": self.names[e.to],
                "distance_m": e.distance_m,
                "rssi_dbm": e.rssi_dbm,
                "outcome": e.outcome.as_str(),
            });
            let channel = self.packets.clone();
            self.put(&channel, t, &packet);
            if e.outcome != Outcome::Received {
                continue;
            }
            let (a, b) = (at(e.from, e.end_ps), at(e.to, e.end_ps));
            // uwb blue, p2p orange.
            let color = match e.radio.as_str() {
                "uwb" => json!({"r": 0.1, "g": 0.4, "b": 1.0, "a": 1.0}),
                _ => json!({"r": 1.0, "g": 0.55, "b": 0.0, "a": 1.0}),
            };
            let link = json!({"deletions": [], "entities": [{
                "timestamp": stamp(t),
                "frame_id": "world",
                "id": format!("{}>{}:{}", self.names[e.from], self.names[e.to], e.radio.as_str()),
                "lifetime": stamp(LINK_LIFETIME_NS),
                "frame_locked": false,
                "metadata": [],
                "arrows": [], "cubes": [], "spheres": [], "cylinders": [],
                "triangles": [], "texts": [], "models": [],
                "lines": [{
                    "type": 0,
                    "pose": identity(),
                    "thickness": 2.0,
                    "scale_invariant": true,
                    "points": [{"x": a[0], "y": a[1], "z": a[2]}, {"x": b[0], "y": b[1], "z": b[2]}],
                    "color": color,
                    "colors": [], "indices": [],
                }],
            }]});
            let channel = self.links.clone();
            self.put(&channel, t, &link);
        }
    }

    /// Writes the summary and closes the file; the first error met, if any.
    pub fn finish(&mut self) -> Result<(), mcap::McapError> {
        if let Some(mut w) = self.w.take() {
            let done = w.finish();
            if self.error.is_none() {
                if let Err(e) = done {
                    self.error = Some(e);
                }
            }
        }
        match self.error.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

fn identity() -> Value {
    json!({"position": {"x": 0.0, "y": 0.0, "z": 0.0},
           "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}})
}

fn empty_entity(id: &str, frame: &str, locked: bool) -> serde_json::Map<String, Value> {
    let v = json!({
        "timestamp": stamp(0), "frame_id": frame, "id": id,
        "lifetime": stamp(0), "frame_locked": locked, "metadata": [],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [],
        "triangles": [], "texts": [], "models": [],
    });
    match v {
        Value::Object(m) => m,
        _ => unreachable!("an object literal"),
    }
}

/// The static scene: each box of the world (gate bars, obstacles, walls)
/// as a cube in its grey, and per drone a body and a heading arrow (+x)
/// locked to its frame.
pub fn scene_update(boxes: &[SceneBox], names: &[String]) -> Value {
    let cubes: Vec<Value> = boxes
        .iter()
        .map(|b| {
            let g = b.grey as f64 / 255.0;
            let (s, c) = (b.yaw / 2.0).sin_cos();
            json!({
                "pose": {"position": {"x": b.centre.x, "y": b.centre.y, "z": b.centre.z},
                         "orientation": {"x": 0.0, "y": 0.0, "z": s, "w": c}},
                "size": {"x": 2.0 * b.half.x, "y": 2.0 * b.half.y, "z": 2.0 * b.half.z},
                "color": {"r": g, "g": g, "b": g, "a": 1.0},
            })
        })
        .collect();
    let mut world = empty_entity("world", "world", false);
    world.insert("cubes".into(), Value::Array(cubes));
    let mut entities = vec![Value::Object(world)];
    for n in names {
        let mut e = empty_entity(&format!("body-{n}"), n, true);
        e.insert(
            "cubes".into(),
            json!([{"pose": identity(),
                    "size": {"x": BODY_SIZE[0], "y": BODY_SIZE[1], "z": BODY_SIZE[2]},
                    "color": {"r": 0.9, "g": 0.1, "b": 0.1, "a": 1.0}}]),
        );
        e.insert(
            "arrows".into(),
            json!([{"pose": identity(), "shaft_length": 0.12, "shaft_diameter": 0.01,
                    "head_length": 0.04, "head_diameter": 0.03,
                    "color": {"r": 1.0, "g": 0.9, "b": 0.0, "a": 1.0}}]),
        );
        entities.push(Value::Object(e));
    }
    json!({"deletions": [], "entities": entities})
}
