//! Throughput and latency of the protocol (numbers for docs/PROTOCOL.md and
//! the project's goals):
//! - `pingpong/raw_4_bytes`: the floor — a 4-byte write and a 4-byte read
//!   each way over a UNIX socket pair, no framing, no JSON;
//! - `pingpong/get_sensors`: a GET_SENSORS request and its 15-field reply
//!   through the blocking transport over the same kind of socket pair;
//! - `image_*/*`: encoding and decoding one 320×320 image in each encoding,
//!   throughput in bytes of JSON body.
//!
//! The image benchmarks measure the benchmark thread's CPU time
//! (`CLOCK_THREAD_CPUTIME_ID`), not wall time: on a shared machine the wall
//! clock mostly measures the other tenants. The ping-pongs must use wall time
//! (a round trip is mostly waiting for the peer); compare them with each
//! other, as both suffer the same load.
//!
//! Run: `cargo bench -p protocol`.

use std::hint::black_box;
use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::thread;
use std::time::Duration;

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use protocol::blocking::{Connection, Options, Role, Stream};
use protocol::{decode_reply, encode_reply, Image, ImageEncoding, Reply, Request, Sensors};

fn sensors() -> Reply {
    Reply::Sensors(Sensors {
        time_s: 12.345,
        x: -2.6123456789,
        y: 0.12345678901234,
        z: 0.9876543210123,
        altitude: 0.9876543210123,
        roll: -0.0123456789,
        pitch: 0.0234567891,
        yaw: std::f64::consts::FRAC_PI_2,
        roll_rate: 0.00123,
        pitch_rate: -0.00456,
        yaw_rate: 0.0789,
        range_front: 2000.0,
        range_left: 1234.5678,
        range_back: 2000.0,
        range_right: 876.54321,
        ..Sensors::default()
    })
}

/// A deterministic 320×320 grey image with values over the whole range
/// (xorshift), so the array spelling has realistic 1–3 digit numbers.
fn test_image() -> Image {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let data = (0..320 * 320)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 56) as u8
        })
        .collect();
    Image {
        width: 320,
        height: 320,
        data,
    }
}

fn pingpong(c: &mut Criterion) {
    let mut g = c.benchmark_group("pingpong");
    g.measurement_time(Duration::from_secs(4));

    // Floor: raw 4-byte echo.
    let (mut a, mut b) = UnixStream::pair().unwrap();
    let echo = thread::spawn(move || {
        let mut buf = [0u8; 4];
        while b.read_exact(&mut buf).is_ok() {
            if b.write_all(&buf).is_err() {
                break;
            }
        }
    });
    g.bench_function("raw_4_bytes", |bn| {
        let mut buf = [0u8; 4];
        bn.iter(|| {
            a.write_all(b"ping").unwrap();
            a.read_exact(&mut buf).unwrap();
            black_box(&buf);
        })
    });
    drop(a);
    echo.join().unwrap();

    // Framed, typed GET_SENSORS round trip through the blocking transport.
    let (pa, wb) = UnixStream::pair().unwrap();
    let mut platform = Connection::new(Stream::Unix(pa), Role::Platform, Options::default());
    let mut world = Connection::new(Stream::Unix(wb), Role::World, Options::default());
    let reply = sensors();
    let server = thread::spawn(move || {
        while let Ok(Some(_req)) = world.recv_request() {
            world.send_reply(&reply).unwrap();
        }
    });
    // Two frames per iteration: request and reply.
    g.throughput(Throughput::Elements(2));
    g.bench_function("get_sensors", |bn| {
        bn.iter(|| black_box(platform.request(&Request::GetSensors).unwrap()))
    });
    drop(platform);
    server.join().unwrap();
    g.finish();
}

/// CPU time of the calling thread, in ns.
struct ThreadCpu;

fn thread_cpu_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec we pass and nothing else.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(r, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

impl Measurement for ThreadCpu {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, start: u64) -> u64 {
        thread_cpu_ns() - start
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &CpuFormatter
    }
}

/// µs of CPU, and GB/s (decimal, as the goals are stated) of CPU time.
struct CpuFormatter;

impl ValueFormatter for CpuFormatter {
    fn scale_values(&self, _typical: f64, values: &mut [f64]) -> &'static str {
        values.iter_mut().for_each(|v| *v /= 1e3);
        "µs cpu"
    }
    fn scale_throughputs(&self, _typical: f64, t: &Throughput, values: &mut [f64]) -> &'static str {
        match *t {
            Throughput::Bytes(n) | Throughput::BytesDecimal(n) => {
                values.iter_mut().for_each(|v| *v = n as f64 / *v);
                "GB/s cpu"
            }
            Throughput::Elements(n) => {
                values.iter_mut().for_each(|v| *v = n as f64 * 1e3 / *v);
                "Melem/s cpu"
            }
            _ => "?",
        }
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}

fn image(c: &mut Criterion<ThreadCpu>) {
    let img = test_image();
    let reply = Reply::Image(img);
    for enc in [ImageEncoding::Array, ImageEncoding::Base64] {
        let mut body = Vec::new();
        encode_reply(&reply, enc, &mut body);
        let mut g = c.benchmark_group(format!("image_{enc}"));
        g.throughput(Throughput::Bytes(body.len() as u64));
        g.measurement_time(Duration::from_secs(3));
        let mut out = Vec::with_capacity(body.len());
        g.bench_function("encode", |bn| {
            bn.iter(|| {
                out.clear();
                encode_reply(black_box(&reply), enc, &mut out);
                black_box(out.len())
            })
        });
        g.bench_function("decode", |bn| {
            bn.iter(|| black_box(decode_reply(black_box(&body)).unwrap()))
        });
        g.finish();
    }
}

criterion_group!(wall, pingpong);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ThreadCpu);
    targets = image
}
criterion_main!(wall, cpu);
