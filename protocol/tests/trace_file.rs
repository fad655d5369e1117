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
