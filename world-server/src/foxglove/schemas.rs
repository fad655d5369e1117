//! The JSON schemas of the Foxglove message types a run's MCAP uses
//! (DESIGN.md §15: schema encoding `jsonschema`, message encoding `json`).
//!
//! Foxglove recognises a message type by its schema *name*
//! (`foxglove.FrameTransform`, …); the schema text describes the fields we
//! write, in the shape of Foxglove's published message definitions
//! (docs.foxglove.dev, "Message schemas"): times as `{sec, nsec}`, vectors
//! `{x, y, z}`, quaternions `{x, y, z, w}`, colours `{r, g, b, a}` in 0–1,
//! byte arrays as base64 strings. Our own channels (power, battery, motors,
//! radio packets) are plain JSON objects whose schema lists their keys.

use serde_json::{json, Value};

/// The schema encoding of every channel.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// The message encoding of every channel.
pub const MESSAGE_ENCODING: &str = "json";

pub const FRAME_TRANSFORM: &str = "foxglove.FrameTransform";
pub const SCENE_UPDATE: &str = "foxglove.SceneUpdate";
pub const RAW_IMAGE: &str = "foxglove.RawImage";
pub const GRID: &str = "foxglove.Grid";

fn time() -> Value {
    json!({"type": "object", "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}})
}

fn xyz() -> Value {
    json!({"type": "object", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}})
}

fn quaternion() -> Value {
    json!({"type": "object", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"},
        "z": {"type": "number"}, "w": {"type": "number"}}})
}

fn pose() -> Value {
    json!({"type": "object", "properties": {"position": xyz(), "orientation": quaternion()}})
}

fn color() -> Value {
    json!({"type": "object", "properties": {
        "r": {"type": "number"}, "g": {"type": "number"},
        "b": {"type": "number"}, "a": {"type": "number"}}})
}

fn bytes() -> Value {
    json!({"type": "string", "contentEncoding": "base64"})
}

/// The schema text of a Foxglove type by name (None for a name not ours).
pub fn foxglove(name: &str) -> Option<Value> {
    let body = match name {
        FRAME_TRANSFORM => json!({"properties": {
            "timestamp": time(),
            "parent_frame_id": {"type": "string"},
            "child_frame_id": {"type": "string"},
            "translation": xyz(),
            "rotation": quaternion()}}),
        SCENE_UPDATE => {
            let cube = json!({"type": "object", "properties": {
                "pose": pose(), "size": xyz(), "color": color()}});
            let arrow = json!({"type": "object", "properties": {
                "pose": pose(), "shaft_length": {"type": "number"},
                "shaft_diameter": {"type": "number"}, "head_length": {"type": "number"},
                "head_diameter": {"type": "number"}, "color": color()}});
            let line = json!({"type": "object", "properties": {
                "type": {"type": "integer", "description": "0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST"},
                "pose": pose(), "thickness": {"type": "number"},
                "scale_invariant": {"type": "boolean"},
                "points": {"type": "array", "items": xyz()},
                "color": color(),
                "colors": {"type": "array", "items": color()},
                "indices": {"type": "array", "items": {"type": "integer"}}}});
            // The primitives we never write still need typed items: Foxglove's and
            // Lichtblick's JSON-schema reader rejects the whole channel on an
            // array whose items have no type ("Unsupported type undefined for
            // array item entities.cylinders"), and the 3D panel then shows no scene.
            let sphere = json!({"type": "object", "properties": {
                "pose": pose(), "size": xyz(), "color": color()}});
            let cylinder = json!({"type": "object", "properties": {
                "pose": pose(), "size": xyz(), "bottom_scale": {"type": "number"},
                "top_scale": {"type": "number"}, "color": color()}});
            let triangles = json!({"type": "object", "properties": {
                "pose": pose(), "points": {"type": "array", "items": xyz()},
                "color": color(), "colors": {"type": "array", "items": color()},
                "indices": {"type": "array", "items": {"type": "integer"}}}});
            let text = json!({"type": "object", "properties": {
                "pose": pose(), "billboard": {"type": "boolean"},
                "font_size": {"type": "number"}, "scale_invariant": {"type": "boolean"},
                "color": color(), "text": {"type": "string"}}});
            let model = json!({"type": "object", "properties": {
                "pose": pose(), "scale": xyz(), "color": color(),
                "override_color": {"type": "boolean"}, "url": {"type": "string"},
                "media_type": {"type": "string"}, "data": bytes()}});
            let entity = json!({"type": "object", "properties": {
                "timestamp": time(), "frame_id": {"type": "string"}, "id": {"type": "string"},
                "lifetime": time(), "frame_locked": {"type": "boolean"},
                "metadata": {"type": "array", "items": {"type": "object", "properties": {
                    "key": {"type": "string"}, "value": {"type": "string"}}}},
                "arrows": {"type": "array", "items": arrow},
                "cubes": {"type": "array", "items": cube},
                "spheres": {"type": "array", "items": sphere},
                "cylinders": {"type": "array", "items": cylinder},
                "lines": {"type": "array", "items": line},
                "triangles": {"type": "array", "items": triangles},
                "texts": {"type": "array", "items": text},
                "models": {"type": "array", "items": model}}});
            json!({"properties": {
                "deletions": {"type": "array", "items": {"type": "object", "properties": {
                    "timestamp": time(), "type": {"type": "integer"}, "id": {"type": "string"}}}},
                "entities": {"type": "array", "items": entity}}})
        }
        RAW_IMAGE => json!({"properties": {
            "timestamp": time(), "frame_id": {"type": "string"},
            "width": {"type": "integer"}, "height": {"type": "integer"},
            "encoding": {"type": "string"}, "step": {"type": "integer"},
            "data": bytes()}}),
        GRID => json!({"properties": {
            "timestamp": time(), "frame_id": {"type": "string"}, "pose": pose(),
            "column_count": {"type": "integer"},
            "cell_size": {"type": "object", "properties": {
                "x": {"type": "number"}, "y": {"type": "number"}}},
            "row_stride": {"type": "integer"}, "cell_stride": {"type": "integer"},
            "fields": {"type": "array", "items": {"type": "object", "properties": {
                "name": {"type": "string"}, "offset": {"type": "integer"},
                "type": {"type": "integer", "description": "foxglove.NumericType: 1 UINT8, 2 INT8, 7 FLOAT32, 8 FLOAT64"}}}},
            "data": bytes()}}),
        _ => return None,
    };
    Some(with_title(name, body))
}

/// The schema of one of our plain JSON channels: an object with these
/// keys, each `(name, JSON type, description)`; a type `T[]` is an array
/// of `T` (a reader needs the items' type to decode the array at all).
pub fn plain(name: &str, keys: &[(&str, &str, &str)]) -> Value {
    let props: serde_json::Map<String, Value> = keys
        .iter()
        .map(|(k, t, d)| {
            let field = match t.strip_suffix("[]") {
                Some(item) => json!({"type": "array", "items": {"type": item}, "description": d}),
                None => json!({"type": t, "description": d}),
            };
            (k.to_string(), field)
        })
        .collect();
    with_title(name, json!({"properties": props}))
}

fn with_title(name: &str, mut body: Value) -> Value {
    if let Value::Object(m) = &mut body {
        m.insert("title".into(), json!(name));
        m.insert("type".into(), json!("object"));
    }
    body
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_foxglove_schema_is_titled_by_its_name() {
        for name in [FRAME_TRANSFORM, SCENE_UPDATE, RAW_IMAGE, GRID] {
            let s = foxglove(name).unwrap();
            assert_eq!(s["title"], name);
            assert_eq!(s["type"], "object");
            assert!(s["properties"].is_object());
        }
        assert!(foxglove("foxglove.Nothing").is_none());
    }

    /// Every array node names its items' type, everywhere below `v`.
    fn arrays_typed(v: &Value, at: &str, bad: &mut Vec<String>) {
        match v {
            Value::Object(m) => {
                if m.get("type") == Some(&json!("array"))
                    && m.get("items").and_then(|i| i.get("type")).is_none()
                {
                    bad.push(at.to_string());
                }
                for (k, c) in m {
                    arrays_typed(c, &format!("{at}.{k}"), bad);
                }
            }
            Value::Array(a) => a.iter().for_each(|c| arrays_typed(c, at, bad)),
            _ => {}
        }
    }

    #[test]
    fn every_array_has_typed_items() {
        let mut bad = Vec::new();
        for name in [FRAME_TRANSFORM, SCENE_UPDATE, RAW_IMAGE, GRID] {
            arrays_typed(&foxglove(name).unwrap(), name, &mut bad);
        }
        let motors = plain("m", &[("speed_rad_s", "number[]", "")]);
        assert_eq!(
            motors["properties"]["speed_rad_s"]["items"]["type"],
            "number"
        );
        arrays_typed(&motors, "m", &mut bad);
        assert!(bad.is_empty(), "arrays without typed items: {bad:?}");
    }
}
