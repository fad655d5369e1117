//! Frame body → top-level fields, with the camera image taken by the fast
//! path of [`crate::image`].
//!
//! A top-level object is walked here key by key; every value except
//! `"camera"` is parsed by serde_json into a `Value` (the messages are small),
//! and `"camera"` is parsed by hand so that 102,400 pixels never become
//! 102,400 `Value`s. If the hand-written camera parser refuses something,
//! serde_json parses it again: invalid JSON is then reported as such, and
//! valid JSON that is not an image only matters if the command is
//! `GET_IMAGE` (elsewhere `camera` is just an unknown, ignored key).

use serde_json::{Map, Value};

use crate::error::{ProtocolError, Result};
use crate::image::{decode_base64, parse_pixel_array, skip_ws, Image, ImageEncoding};
use crate::message::command::GET_IMAGE;
use crate::shm::ShmFrame;

/// What `"camera"` holds: the pixels, or where to find them.
pub(crate) enum Camera {
    Pixels(Image),
    Shm(ShmFrame),
}

pub(crate) struct Parsed {
    /// Every top-level key except `"camera"`.
    pub fields: Map<String, Value>,
    /// The image under `"camera"`, if the key was present.
    pub camera: Option<Result<Camera>>,
}

pub(crate) fn parse_message(body: &[u8]) -> Result<Parsed> {
    let mut ascii = None;
    let parsed = parse_object(body, &mut ascii);
    // Invalid UTF-8 is reported as such, before anything else the walk
    // found (the walk itself never assumes valid UTF-8).
    check_utf8(body, ascii)?;
    parsed
}

/// Bytes `[start, end)` of a body that are known to be ASCII.
type AsciiSpan = Option<(usize, usize)>;

/// The body is UTF-8, or the `InvalidUtf8` error with the offset of the
/// first bad byte. A span the walk proved ASCII (a pixel array: digits,
/// commas, whitespace, brackets — 99 % of an image reply) is not checked
/// again: ASCII bytes can neither end nor continue a multi-byte sequence,
/// so the body is UTF-8 exactly when the parts before and after are.
fn check_utf8(body: &[u8], ascii: AsciiSpan) -> Result<()> {
    let valid = match ascii {
        Some((start, end)) => {
            std::str::from_utf8(&body[..start]).is_ok() && std::str::from_utf8(&body[end..]).is_ok()
        }
        None => std::str::from_utf8(body).is_ok(),
    };
    if valid {
        return Ok(());
    }
    let e = std::str::from_utf8(body)
        .expect_err("UTF-8 on both sides of an ASCII span makes a UTF-8 body");
    Err(ProtocolError::InvalidUtf8 {
        offset: e.valid_up_to(),
    })
}

/// The walk of [`parse_message`]; records in `ascii` the span of a pixel
/// array it decoded (all ASCII).
fn parse_object(body: &[u8], ascii: &mut AsciiSpan) -> Result<Parsed> {
    let mut pos = skip_ws(body, 0);
    if body.get(pos) != Some(&b'{') {
        // Distinguish "valid JSON, but not an object" from garbage.
        return Err(
            match serde_json::from_slice::<serde::de::IgnoredAny>(body) {
                Ok(_) => ProtocolError::NotAnObject,
                Err(e) => ProtocolError::json(&e, 0, body),
            },
        );
    }
    pos += 1;
    let mut fields = Map::new();
    let mut camera = None;
    pos = skip_ws(body, pos);
    if body.get(pos) == Some(&b'}') {
        pos += 1;
    } else {
        loop {
            let (key, after_key) = parse_key(body, pos)?;
            pos = skip_ws(body, after_key);
            if body.get(pos) != Some(&b':') {
                return Err(syntax("expected ':' after an object key", pos));
            }
            pos = skip_ws(body, pos + 1);
            if key == "camera" {
                match parse_camera(body, pos, ascii) {
                    Ok((img, end)) => {
                        camera = Some(Ok(img));
                        pos = end;
                    }
                    Err(why) => {
                        // Validate (and skip) it the general way.
                        let (_, end) = parse_value(body, pos)?;
                        camera = Some(Err(ProtocolError::bad(GET_IMAGE, why)));
                        pos = end;
                    }
                }
            } else {
                let (v, end) = parse_value(body, pos)?;
                fields.insert(key, v);
                pos = end;
            }
            pos = skip_ws(body, pos);
            match body.get(pos) {
                Some(b',') => pos = skip_ws(body, pos + 1),
                Some(b'}') => {
                    pos += 1;
                    break;
                }
                _ => return Err(syntax("expected ',' or '}' in the object", pos)),
            }
        }
    }
    pos = skip_ws(body, pos);
    if pos != body.len() {
        return Err(syntax("trailing characters after the object", pos));
    }
    Ok(Parsed { fields, camera })
}

fn syntax(detail: &str, offset: usize) -> ProtocolError {
    ProtocolError::InvalidJson {
        detail: detail.to_owned(),
        offset,
    }
}

/// One JSON value at `pos`, by serde_json; returns it and the end position.
fn parse_value(body: &[u8], pos: usize) -> Result<(Value, usize)> {
    let mut it = serde_json::Deserializer::from_slice(&body[pos..]).into_iter::<Value>();
    match it.next() {
        Some(Ok(v)) => Ok((v, pos + it.byte_offset())),
        Some(Err(e)) => Err(ProtocolError::json(&e, pos, &body[pos..])),
        None => Err(syntax("unexpected end of the frame, expected a value", pos)),
    }
}

/// A JSON string at `pos` (must start with '"'); returns it unescaped and the
/// position after the closing quote.
fn parse_key(body: &[u8], pos: usize) -> Result<(String, usize)> {
    if body.get(pos) != Some(&b'"') {
        return Err(syntax("expected a string key", pos));
    }
    // Fast path: no escapes (all of our keys).
    if let Some(len) = memchr::memchr2(b'"', b'\\', &body[pos + 1..]) {
        let end = pos + 1 + len;
        if body[end] == b'"' {
            let raw = &body[pos + 1..end];
            if !raw.iter().any(|&c| c < 0x20) {
                // Not UTF-8: serde_json below says why (and check_utf8
                // reports it first anyway).
                if let Ok(s) = std::str::from_utf8(raw) {
                    return Ok((s.to_owned(), end + 1));
                }
            }
        }
    }
    match parse_value(body, pos)? {
        (Value::String(s), end) => Ok((s, end)),
        _ => unreachable!("a value starting with '\"' is a string"),
    }
}

/// The camera object by hand. `Err` carries why it is not an image; the
/// caller then re-parses it with serde_json to tell bad JSON from a bad image.
fn parse_camera(
    body: &[u8],
    mut pos: usize,
    ascii: &mut AsciiSpan,
) -> std::result::Result<(Camera, usize), String> {
    if body.get(pos) != Some(&b'{') {
        return Err("camera must be an object".into());
    }
    let (mut width, mut height, mut data, mut encoding) = (None, None, None, None);
    let (mut seq, mut path) = (None, None);
    pos = skip_ws(body, pos + 1);
    if body.get(pos) == Some(&b'}') {
        pos += 1;
    } else {
        loop {
            let (key, after) = parse_key(body, pos).map_err(|e| e.to_string())?;
            pos = skip_ws(body, after);
            if body.get(pos) != Some(&b':') {
                return Err("expected ':'".into());
            }
            pos = skip_ws(body, pos + 1);
            match (key.as_str(), body.get(pos)) {
                ("data", Some(b'[')) => {
                    let (px, end) = parse_pixel_array(body, pos)?;
                    // A decoded array has only ASCII bytes.
                    *ascii = Some((pos, end));
                    data = Some((px, ImageEncoding::Array));
                    pos = end;
                }
                ("data", Some(b'"')) => {
                    let (px, end) = parse_base64_string(body, pos)?;
                    data = Some((px, ImageEncoding::Base64));
                    pos = end;
                }
                ("data", _) => return Err("camera.data must be an array or a base64 string".into()),
                (k, _) => {
                    let (v, end) = parse_value(body, pos).map_err(|e| e.to_string())?;
                    pos = end;
                    match k {
                        "width" => width = Some(dimension("width", &v)?),
                        "height" => height = Some(dimension("height", &v)?),
                        "seq" => {
                            seq = Some(v.as_u64().ok_or_else(|| {
                                format!("camera.seq must be a non-negative integer, got {v}")
                            })?)
                        }
                        "path" => {
                            path = Some(
                                v.as_str()
                                    .filter(|s| !s.is_empty())
                                    .ok_or_else(|| {
                                        format!("camera.path must be a non-empty string, got {v}")
                                    })?
                                    .to_owned(),
                            )
                        }
                        "encoding" => {
                            encoding = Some(
                                v.as_str()
                                    .and_then(|s| s.parse::<ImageEncoding>().ok())
                                    .ok_or_else(|| {
                                        format!(
                                        "camera.encoding must be \"array\", \"base64\" or \"shm\", got {v}"
                                    )
                                    })?,
                            )
                        }
                        _ => {} // unknown keys are ignored
                    }
                }
            }
            pos = skip_ws(body, pos);
            match body.get(pos) {
                Some(b',') => pos = skip_ws(body, pos + 1),
                Some(b'}') => {
                    pos += 1;
                    break;
                }
                _ => return Err("expected ',' or '}' in camera".into()),
            }
        }
    }
    let width = width.ok_or("missing field `camera.width`")?;
    let height = height.ok_or("missing field `camera.height`")?;
    if encoding == Some(ImageEncoding::Shm) {
        // The pixels are in the file the reply names (crate::shm).
        if data.is_some() {
            return Err("camera.encoding says shm but the frame has data".into());
        }
        return Ok((
            Camera::Shm(ShmFrame {
                width,
                height,
                seq: seq.ok_or("missing field `camera.seq`")?,
                path: path.ok_or("missing field `camera.path`")?,
            }),
            pos,
        ));
    }
    let (data, spelled) = data.ok_or("missing field `camera.data`")?;
    if let Some(declared) = encoding {
        if declared != spelled {
            return Err(format!(
                "camera.encoding says {declared} but data is spelled as {spelled}"
            ));
        }
    }
    if data.len() as u64 != u64::from(width) * u64::from(height) {
        return Err(format!(
            "camera.data has {} pixels, width × height = {width} × {height}",
            data.len()
        ));
    }
    Ok((
        Camera::Pixels(Image {
            width,
            height,
            data,
        }),
        pos,
    ))
}

fn dimension(name: &str, v: &Value) -> std::result::Result<u32, String> {
    v.as_u64()
        .and_then(|n| u32::try_from(n).ok())
        .ok_or_else(|| format!("camera.{name} must be a non-negative integer, got {v}"))
}

fn parse_base64_string(body: &[u8], pos: usize) -> std::result::Result<(Vec<u8>, usize), String> {
    // The base64 alphabet has no '"' or '\\': the string normally ends at the
    // next quote. A foreign encoder may escape '/' as "\/": then unescape with
    // serde_json first.
    let rest = &body[pos + 1..];
    match memchr::memchr2(b'"', b'\\', rest) {
        Some(i) if rest[i] == b'"' => Ok((decode_base64(&rest[..i])?, pos + 1 + i + 1)),
        Some(_) => match parse_value(body, pos).map_err(|e| e.to_string())? {
            (Value::String(s), end) => Ok((decode_base64(s.as_bytes())?, end)),
            _ => unreachable!("a value starting with '\"' is a string"),
        },
        None => Err("unterminated string".into()),
    }
}
