//! `cosim nn import` end to end (DESIGN.md §18, docs/NN_ONNX.md): an ONNX
//! file written from onnx.proto's messages, its layer table, the host's
//! integer reference through .npy files against the closed form, and bad
//! input as one line with exit code 2. (Agreement with onnxruntime on real
//! quantized networks: python/tests/test_onnx_import.py.)

use std::path::Path;

use e2e_tests::{output_text as text, CosimBins as Bins};
use prost::Message;
use scenarios::nn::onnx::proto::{
    data_type, AttributeProto, Dimension, GraphProto, ModelProto, NodeProto, TensorProto,
    TensorShapeProto, TypeProto, TypeProtoTensor, ValueInfoProto,
};

const S_X: f64 = 0.5;
const S_Y: f64 = 0.25;
const S_W: [f64; 3] = [0.25, 0.5, 0.125];
/// Weights [out][in] (transB = 1).
const W: [[i8; 4]; 3] = [[1, -2, 3, -4], [5, 6, -7, 8], [-9, 10, 11, -12]];
/// In the accumulator's scale s_x · s_w[c].
const B: [i32; 3] = [3, -5, 7];

fn node(op: &str, name: &str, inputs: &[&str], output: &str) -> NodeProto {
    NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![output.to_string()],
        name: name.to_string(),
        op_type: op.to_string(),
        ..Default::default()
    }
}

fn raw(name: &str, dims: &[i64], ty: i32, raw_data: Vec<u8>) -> TensorProto {
    TensorProto {
        dims: dims.to_vec(),
        data_type: ty,
        name: name.to_string(),
        raw_data,
        ..Default::default()
    }
}

fn f32s(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|&x| (x as f32).to_le_bytes()).collect()
}

fn value(name: &str, dims: &[Option<i64>]) -> ValueInfoProto {
    ValueInfoProto {
        name: name.to_string(),
        r#type: Some(TypeProto {
            tensor_type: Some(TypeProtoTensor {
                elem_type: data_type::FLOAT,
                shape: Some(TensorShapeProto {
                    dim: dims
                        .iter()
                        .map(|&d| Dimension {
                            dim_value: d,
                            dim_param: d.is_none().then(|| "N".to_string()),
                        })
                        .collect(),
                }),
            }),
        }),
    }
}

/// x [N, 4] → Q/DQ (int8, s 0.5) → Gemm 4→3 (per-channel int8 weights,
/// int32 bias) → Q/DQ (int8, s 0.25) → Sigmoid; `extra` is put first.
fn gemm_model(extra: Option<NodeProto>) -> Vec<u8> {
    let mut gemm = node("Gemm", "fc", &["xf", "wf", "bf"], "g");
    gemm.attribute.push(AttributeProto {
        name: "transB".into(),
        i: 1,
        r#type: 2,
        ..Default::default()
    });
    let w: Vec<u8> = W.iter().flatten().map(|&v| v as u8).collect();
    let b: Vec<u8> = B.iter().flat_map(|v| v.to_le_bytes()).collect();
    let bias_scale: Vec<f64> = S_W.iter().map(|s| s * S_X).collect();
    let mut nodes = vec![
        node("QuantizeLinear", "q_x", &["x", "sx", "zp"], "xq"),
        node("DequantizeLinear", "dq_x", &["xq", "sx", "zp"], "xf"),
        node("DequantizeLinear", "dq_w", &["w", "sw", "zw"], "wf"),
        node("DequantizeLinear", "dq_b", &["b", "sb"], "bf"),
        gemm,
        node("QuantizeLinear", "q_y", &["g", "sy", "zp"], "yq"),
        node("DequantizeLinear", "dq_y", &["yq", "sy", "zp"], "yf"),
        node("Sigmoid", "out", &["yf"], "y"),
    ];
    if let Some(n) = extra {
        nodes.insert(0, n);
    }
    let graph = GraphProto {
        node: nodes,
        name: "gemm".into(),
        initializer: vec![
            raw("sx", &[], data_type::FLOAT, f32s(&[S_X])),
            raw("sy", &[], data_type::FLOAT, f32s(&[S_Y])),
            raw("zp", &[], data_type::INT8, vec![0]),
            raw("w", &[3, 4], data_type::INT8, w),
            raw("sw", &[3], data_type::FLOAT, f32s(&S_W)),
            raw("zw", &[3], data_type::INT8, vec![0; 3]),
            raw("b", &[3], data_type::INT32, b),
            raw("sb", &[3], data_type::FLOAT, f32s(&bias_scale)),
        ],
        input: vec![value("x", &[None, Some(4)])],
        output: vec![value("y", &[None, Some(3)])],
        ..Default::default()
    };
    ModelProto {
        ir_version: 8,
        producer_name: "e2e".into(),
        graph: Some(graph),
        ..Default::default()
    }
    .encode_to_vec()
}

/// A float32 .npy (version 1.0), C order.
fn write_npy(path: &Path, shape: &[usize], v: &[f32]) {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let mut header = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({},), }}",
        dims.join(", ")
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    bytes.extend(v.iter().flat_map(|x| x.to_le_bytes()));
    std::fs::write(path, bytes).unwrap();
}

/// A float32 .npy's header and values.
fn read_npy(path: &Path) -> (String, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = String::from_utf8(bytes[10..10 + len].to_vec()).unwrap();
    let v = bytes[10 + len..]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    (header, v)
}

/// The closed form: ONNX's QuantizeLinear of x, the int32 dot product, the
/// ratio s_x·s_w/s_y rounded half up (the records' rounding), int8, then
/// DequantizeLinear and the Sigmoid.
fn expected(x: &[f32]) -> Vec<f32> {
    let q: Vec<i64> = x
        .iter()
        .map(|&v| ((v as f64) / S_X).round_ties_even().clamp(-128.0, 127.0) as i64)
        .collect();
    (0..3)
        .map(|c| {
            let acc = B[c] as i64 + (0..4).map(|i| W[c][i] as i64 * q[i]).sum::<i64>();
            let y = (acc as f64 * S_X * S_W[c] / S_Y + 0.5)
                .floor()
                .clamp(-128.0, 127.0);
            let r = (y as f32) * S_Y as f32;
            1.0 / (1.0 + (-r).exp())
        })
        .collect()
}

#[test]
fn gemm_model_table_and_integer_reference() {
    let bins = Bins::new();
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("gemm.onnx");
    std::fs::write(&model, gemm_model(None)).unwrap();
    let m = model.to_str().unwrap();

    let o = bins.cosim(&["nn", "import", m]);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let row = |first: &str| -> Vec<String> {
        let line = out
            .lines()
            .find(|l| l.starts_with(first))
            .unwrap_or_else(|| panic!("no {first} row: {out}"));
        line.split_whitespace().map(str::to_string).collect()
    };
    // in · out MACs; 12 int8 weights and 3 int32 biases.
    let fc = row("fc ");
    assert_eq!(fc[1], "Gemm");
    assert_eq!(fc[fc.len() - 2..], ["12", "24"]);
    let total = row("total");
    assert_eq!(total[total.len() - 2..], ["12", "24"]);
    assert!(out.contains("Sigmoid on the dequantized output"), "{out}");

    // Sums that land on halves and beyond the int8 range, both signs.
    let inputs: [[f32; 4]; 3] = [
        [0.3, -1.2, 2.5, 0.75],
        [10.0, -20.0, 100.0, -40.0],
        [-0.2, 0.6, -3.3, 1.24],
    ];
    for (k, x) in inputs.iter().enumerate() {
        let xp = dir.path().join(format!("x{k}.npy"));
        let yp = dir.path().join(format!("y{k}.npy"));
        write_npy(&xp, &[1, 4], x);
        let o = bins.cosim(&[
            "nn",
            "import",
            m,
            "--input",
            xp.to_str().unwrap(),
            "--output",
            yp.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("not the ISS"),
            "{}",
            text(&o)
        );
        let (header, y) = read_npy(&yp);
        assert!(
            header.contains("'<f4'") && header.contains("'shape': (1, 3,"),
            "{header}"
        );
        assert_eq!(y, expected(x), "input {x:?}");
    }
}

#[test]
fn bad_input_is_one_line_and_exit_code_2() {
    let bins = Bins::new();
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("gemm.onnx");
    std::fs::write(&good, gemm_model(None)).unwrap();
    let lstm = dir.path().join("lstm.onnx");
    std::fs::write(&lstm, gemm_model(Some(node("LSTM", "lstm0", &["x"], "h")))).unwrap();
    let garbage = dir.path().join("garbage.onnx");
    std::fs::write(&garbage, [0xff; 16]).unwrap();
    let short = dir.path().join("short.npy");
    write_npy(&short, &[1, 3], &[0.0; 3]);
    let (g, l, gb, s) = (
        good.to_str().unwrap(),
        lstm.to_str().unwrap(),
        garbage.to_str().unwrap(),
        short.to_str().unwrap(),
    );
    let cases: [(&[&str], &str); 4] = [
        (
            &["nn", "import", l],
            "node \"lstm0\" (LSTM): unsupported op",
        ),
        (&["nn", "import", gb], "not an ONNX model"),
        (&["nn", "import", "/nonexistent/model.onnx"], "model.onnx"),
        (&["nn", "import", g, "--input", s], "shape [1, 3]"),
    ];
    for (args, want) in cases {
        let o = bins.cosim(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}
