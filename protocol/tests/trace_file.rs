//! Trace files: a partial last line (a writer that died mid-line) is
//! reported and skipped; a broken line in the middle is an error; images
//! are kept verbatim when asked.

use protocol::trace::{
    Direction, FrameEvent, TraceClock, TraceError, TraceReader, TraceWriter, TruncatedLine,
};
use protocol::{encode_reply, sha256_hex, Image, ImageEncoding, Reply};

fn ev<'a>(dir: Direction, bytes: &'a [u8], image: Option<&'a Image>) -> FrameEvent<'a> {
    FrameEvent {
        dir,
        bytes,
        image,
        valid: true,
    }
}

#[test]
fn lines_are_complete_json_and_partial_tail_is_reported() {
    let mut w = TraceWriter::new(Vec::new(), TraceClock::WorldMs, false);
    w.record(
        &ev(Direction::ToWorld, br#"{"command":"GET_IMAGE"}"#, None),
        2000,
    )
    .unwrap();
    let img = Image {
        width: 2,
        height: 1,
        data: vec![7, 8],
    };
    let mut body = Vec::new();
    encode_reply(&Reply::Image(img.clone()), ImageEncoding::Array, &mut body);
    w.record(&ev(Direction::ToPlatform, &body, Some(&img)), 2000)
        .unwrap();
    // A frame that failed to decode is still one valid JSON line.
    w.record(
        &FrameEvent {
            dir: Direction::ToWorld,
            bytes: b"{\"com\xffmand\"\n",
            image: None,
            valid: false,
        },
        2032,
    )
    .unwrap();
    let mut text = String::from_utf8(w.into_inner()).unwrap();
    let lines: Vec<String> = text.lines().map(str::to_owned).collect();
    assert_eq!(
        lines[0],
        r#"{"seq":0,"dir":"to_world","len":23,"msg":{"command":"GET_IMAGE"},"world_ms":2000}"#
    );
    assert_eq!(
        lines[1],
        format!(
            r#"{{"seq":1,"dir":"to_platform","len":{},"msg":{{"camera":{{"height":1,"sha256":"{}","width":2}},"command":"GET_IMAGE"}},"world_ms":2000}}"#,
            body.len(),
            sha256_hex(&[7, 8])
        )
    );
    assert!(
        lines[2].contains(r#""msg":{"invalid_frame":"{\"com"#),
        "{}",
        lines[2]
    );

    // Simulate a crash in the middle of a fourth line.
    text.push_str(r#"{"seq":3,"dir":"to_wor"#);
    let mut r = TraceReader::new(text.as_bytes());
    let recs: Vec<_> = r.by_ref().collect::<Result<_, _>>().unwrap();
    assert_eq!(recs.len(), 3);
    assert_eq!(recs[1].msg["camera"]["sha256"], sha256_hex(&[7, 8]));
    assert_eq!(recs[2].world_ms, Some(2032));
    assert_eq!(r.truncated(), Some(TruncatedLine { line: 4, bytes: 22 }));

    // A broken line followed by more lines is corruption, not truncation.
    let bad = format!("{}\nnot json\n{}\n", lines[0], lines[0]);
    let res: Vec<_> = TraceReader::new(bad.as_bytes()).collect();
    assert!(matches!(res[1], Err(TraceError::BadLine { line: 2, .. })));
}

#[test]
fn images_kept_when_asked() {
    let img = Image {
        width: 1,
        height: 1,
        data: vec![42],
    };
    let mut body = Vec::new();
    encode_reply(&Reply::Image(img.clone()), ImageEncoding::Array, &mut body);
    let mut w = TraceWriter::new(Vec::new(), TraceClock::PlatformPs, true);
    w.record(&ev(Direction::ToPlatform, &body, Some(&img)), 5)
        .unwrap();
    let text = String::from_utf8(w.into_inner()).unwrap();
    assert_eq!(
        text,
        format!(
            "{{\"seq\":0,\"dir\":\"to_platform\",\"len\":{},\"msg\":{},\"platform_ps\":5}}\n",
            body.len(),
            String::from_utf8(body).unwrap()
        )
    );
}

/// A writer into a buffer the test keeps.
#[derive(Clone, Default)]
struct Shared(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl std::io::Write for Shared {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

proptest::proptest! {
    /// A queue writes the lines a writer writes, whenever its work runs:
    /// frames and images (large enough to take several slices to hash)
    /// pushed in one order, work done after any of them or never before
    /// the flush.
    #[test]
    fn a_queue_writes_what_a_writer_writes(
        kinds in proptest::collection::vec(0u8..4, 1..24),
        work_after in proptest::collection::vec(0usize..40, 24),
        keep_images: bool,
    ) {
        use protocol::trace::TraceQueue;
        let images: Vec<Image> = (0..4u8)
            .map(|k| Image {
                width: 320,
                height: 160 + u32::from(k),
                data: (0..320 * (160 + u32::from(k)))
                    .map(|i| (i as u8).wrapping_mul(k + 1))
                    .collect(),
            })
            .collect();
        let bodies: Vec<Vec<u8>> = images
            .iter()
            .map(|img| {
                let mut b = Vec::new();
                encode_reply(&Reply::Image(img.clone()), ImageEncoding::Array, &mut b);
                b
            })
            .collect();
        let mut direct = TraceWriter::new(Vec::new(), TraceClock::PlatformPs, keep_images);
        let out = Shared::default();
        let mut queue = TraceQueue::new(TraceWriter::new(out.clone(), TraceClock::PlatformPs, keep_images));
        for (i, &k) in kinds.iter().enumerate() {
            let now = 1000 * i as u64;
            let e = match k {
                0 => ev(Direction::ToWorld, br#"{"command":"GET_IMAGE"}"#, None),
                1 => ev(Direction::ToPlatform, br#"{"command":"GET_SENSORS","x":1}"#, None),
                _ => {
                    let n = usize::from(k) % images.len();
                    ev(Direction::ToPlatform, &bodies[n], Some(&images[n]))
                }
            };
            direct.record(&e, now).unwrap();
            queue.push(&e, now).unwrap();
            for _ in 0..work_after[i] {
                if !queue.work() {
                    break;
                }
            }
            proptest::prop_assert_eq!(queue.records(), direct.records());
        }
        queue.flush().unwrap();
        let written = out.0.lock().unwrap().clone();
        proptest::prop_assert_eq!(String::from_utf8(written).unwrap(), String::from_utf8(direct.into_inner()).unwrap());
        // Nothing is left to do after a flush.
        proptest::prop_assert!(!queue.work());
    }
}

#[test]
fn a_queue_hashes_an_image_a_slice_at_a_time() {
    use protocol::trace::TraceQueue;
    let img = Image {
        width: 320,
        height: 320,
        data: (0..320 * 320).map(|i| (i % 251) as u8).collect(),
    };
    let mut body = Vec::new();
    encode_reply(&Reply::Image(img.clone()), ImageEncoding::Array, &mut body);
    let out = Shared::default();
    let mut q = TraceQueue::new(TraceWriter::new(out.clone(), TraceClock::PlatformPs, false));
    q.push(&ev(Direction::ToPlatform, &body, Some(&img)), 7)
        .unwrap();
    // 102,400 bytes in 16 KB slices: 7 slices of hashing, then the line.
    let mut slices = 1;
    while q.work() {
        slices += 1;
    }
    assert_eq!(slices, 8);
    q.flush().unwrap();
    let text = String::from_utf8(out.0.lock().unwrap().clone()).unwrap();
    assert!(text.contains(&sha256_hex(&img.data)), "{text}");
    assert!(text.contains(&format!("\"len\":{}", body.len())), "{text}");
}

#[test]
fn a_compressed_trace_reads_as_the_plain_one_and_keeps_its_prefix_when_cut() {
    let dir = tempfile::tempdir().unwrap();
    let (plain, zst) = (dir.path().join("a.trace"), dir.path().join("b.trace.zst"));
    // Enough records for several of the writer's 64 KiB blocks.
    let write = |path: &std::path::Path| {
        let mut w = TraceWriter::create(path, TraceClock::WorldMs, false).unwrap();
        for k in 0..4000u64 {
            let body = format!(r#"{{"command":"GET_SENSORS","k":{k}}}"#);
            w.record(
                &ev(Direction::ToWorld, body.as_bytes(), None),
                2000 + 32 * k,
            )
            .unwrap();
        }
        w.finish().unwrap();
    };
    write(&plain);
    write(&zst);
    let text = std::fs::read(&plain).unwrap();
    let packed = std::fs::read(&zst).unwrap();
    assert!(
        packed.len() * 4 < text.len(),
        "{} vs {}",
        packed.len(),
        text.len()
    );
    assert_eq!(zstd::decode_all(&packed[..]).unwrap(), text);

    // Read by its plain name, the compressed file gives the same records.
    let all = |r: TraceReader<_>| r.collect::<Result<Vec<_>, _>>().unwrap();
    let a = all(TraceReader::open(&plain).unwrap());
    let b = all(TraceReader::open(&dir.path().join("b.trace")).unwrap());
    assert_eq!(a.len(), 4000);
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );

    // A writer killed mid-run: the frame has no end. The blocks that reached
    // the disk are read, and the reader says the rest is lost.
    std::fs::write(&zst, &packed[..packed.len() * 2 / 3]).unwrap();
    let mut r = TraceReader::open(&zst).unwrap();
    let kept = r.by_ref().collect::<Result<Vec<_>, _>>().unwrap();
    assert!(kept.len() > 1000 && kept.len() < 4000, "{}", kept.len());
    assert_eq!(kept[kept.len() - 1].msg["k"], (kept.len() - 1) as u64);
    assert_eq!(r.truncated().map(|t| t.line), Some(kept.len() + 1));
}
