//! QDQ pattern matching: an ONNX graph as onnxruntime's `quantize_static`
//! writes it (QuantizeLinear/DequantizeLinear pairs around float ops,
//! weights as DequantizeLinear of int8 initializers) becomes the integer
//! layer list of [`super::layers`].
//!
//! The walk follows the graph's node order (ONNX graphs are topologically
//! sorted). Every activation tensor between layers is the output of a
//! QuantizeLinear, so its integers and (scale, zero point) are exact; a
//! DequantizeLinear of it is an alias. A compute node (Conv, Gemm, ...)
//! reads such aliases and the constants' DequantizeLinear, and its float
//! output runs, possibly through a Relu or Clip (fused as a clamp), into
//! the QuantizeLinear that fixes the layer's output scale.

use super::layers::{LayerKind, Model, PoolScale, QParams, QType, Value, Window};
use super::proto::{data_type, AttributeProto, GraphProto, NodeProto, TensorProto};
use super::requant::{round_clamp, Requant};
use std::collections::HashMap;

/// Why a model cannot be imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// Named for the node, on one line.
    #[error("node {node:?} ({op}): {why}")]
    Node {
        node: String,
        op: String,
        why: String,
    },
    #[error("{0}")]
    Model(String),
}

fn node_err(n: &NodeProto, why: impl Into<String>) -> ImportError {
    ImportError::Node {
        node: n.name.clone(),
        op: n.op_type.clone(),
        why: why.into(),
    }
}

/// A DequantizeLinear of an initializer: weights or a bias.
struct DqConst {
    dims: Vec<usize>,
    q: Vec<f64>,
    scale: Vec<f64>,
    zero_point: Vec<f64>,
}

impl DqConst {
    /// The scale of channel `c` (per-tensor or per-channel).
    fn scale(&self, c: usize) -> f64 {
        self.scale[if self.scale.len() == 1 { 0 } else { c }]
    }
}

struct Importer<'a> {
    nodes: &'a [NodeProto],
    inits: HashMap<&'a str, &'a TensorProto>,
    consumers: HashMap<&'a str, Vec<usize>>,
    done: Vec<bool>,
    model: Model,
    /// Tensor name (a QuantizeLinear's output, a DequantizeLinear's float
    /// alias of it, a layer's float output) -> value.
    by_name: HashMap<String, usize>,
    consts: HashMap<String, DqConst>,
    input_shape: Vec<usize>,
    output_sigmoid_of: Option<String>,
}

/// Imports a decoded graph.
pub fn import_graph(g: &GraphProto) -> Result<Model, ImportError> {
    let inits: HashMap<&str, &TensorProto> =
        g.initializer.iter().map(|t| (t.name.as_str(), t)).collect();
    let inputs: Vec<_> = g
        .input
        .iter()
        .filter(|i| !inits.contains_key(i.name.as_str()))
        .collect();
    let [input] = inputs[..] else {
        return Err(ImportError::Model(format!(
            "the graph has {} inputs; one is supported",
            inputs.len()
        )));
    };
    let [output] = &g.output[..] else {
        return Err(ImportError::Model(format!(
            "the graph has {} outputs; one is supported",
            g.output.len()
        )));
    };
    let dims = input
        .dims()
        .ok_or_else(|| ImportError::Model(format!("input {:?} has no shape", input.name)))?;
    let mut input_shape = Vec::new();
    for (i, d) in dims.iter().enumerate() {
        match (i, d) {
            (0, None | Some(1)) => input_shape.push(1),
            (_, Some(d)) if *d > 0 => input_shape.push(*d as usize),
            _ => {
                return Err(ImportError::Model(format!(
                    "input {:?}: dimension {i} is {d:?}; batch 1 and fixed sizes are supported",
                    input.name
                )))
            }
        }
    }
    let mut consumers: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, n) in g.node.iter().enumerate() {
        for inp in n.input.iter().filter(|s| !s.is_empty()) {
            consumers.entry(inp.as_str()).or_default().push(i);
        }
    }
    let mut im = Importer {
        nodes: &g.node,
        inits,
        consumers,
        done: vec![false; g.node.len()],
        model: Model {
            values: Vec::new(),
            layers: Vec::new(),
            input_name: input.name.clone(),
            input: usize::MAX,
            output: usize::MAX,
            output_name: output.name.clone(),
            output_sigmoid: false,
        },
        by_name: HashMap::new(),
        consts: HashMap::new(),
        input_shape,
        output_sigmoid_of: None,
    };
    for i in 0..g.node.len() {
        if im.done[i] {
            continue;
        }
        im.done[i] = true;
        im.node(i)?;
    }
    if im.model.input == usize::MAX {
        return Err(ImportError::Model(format!(
            "no QuantizeLinear reads the input {:?}",
            im.model.input_name
        )));
    }
    let out_name = im.output_sigmoid_of.clone().unwrap_or(output.name.clone());
    im.model.output_sigmoid = im.output_sigmoid_of.is_some();
    im.model.output = *im.by_name.get(&out_name).ok_or_else(|| {
        ImportError::Model(format!(
            "the output {:?} is not a DequantizeLinear of a quantized tensor",
            output.name
        ))
    })?;
    Ok(im.model)
}

fn attr<'a>(n: &'a NodeProto, name: &str) -> Option<&'a AttributeProto> {
    n.attribute.iter().find(|a| a.name == name)
}

fn attr_i(n: &NodeProto, name: &str, default: i64) -> i64 {
    attr(n, name).map_or(default, |a| a.i)
}

fn attr_ints(n: &NodeProto, name: &str) -> Option<Vec<i64>> {
    attr(n, name).map(|a| a.ints.clone())
}

fn attr_s(n: &NodeProto, name: &str) -> String {
    attr(n, name).map_or(String::new(), |a| {
        String::from_utf8_lossy(&a.s).into_owned()
    })
}

impl<'a> Importer<'a> {
    fn node(&mut self, i: usize) -> Result<(), ImportError> {
        let n = &self.nodes[i];
        let std_domain = matches!(n.domain.as_str(), "" | "ai.onnx");
        let qdq_domain = std_domain || n.domain == "com.microsoft";
        match n.op_type.as_str() {
            "QuantizeLinear" if qdq_domain => self.quantize(n),
            "DequantizeLinear" if qdq_domain => self.dequantize(n),
            "Conv" | "Gemm" | "MatMul" | "MaxPool" | "AveragePool" | "GlobalAveragePool"
            | "Add" | "Concat" | "Flatten" | "Reshape" | "Relu" | "Clip"
                if std_domain =>
            {
                self.compute(n)
            }
            "Sigmoid" if std_domain => self.sigmoid(n),
            _ => Err(node_err(n, "unsupported op")),
        }
    }

    fn init(&self, n: &NodeProto, name: &str) -> Result<&'a TensorProto, ImportError> {
        let t = self
            .inits
            .get(name)
            .copied()
            .ok_or_else(|| node_err(n, format!("{name:?} is not a constant initializer")))?;
        if t.data_location == 1 {
            return Err(node_err(
                n,
                format!("{name:?} is stored in an external file"),
            ));
        }
        Ok(t)
    }

    fn init_values(&self, n: &NodeProto, name: &str) -> Result<Vec<f64>, ImportError> {
        let t = self.init(n, name)?;
        t.values()
            .ok_or_else(|| node_err(n, format!("{name:?} has data type {}", t.data_type)))
    }

    /// (scale, zero point, type) of a QuantizeLinear or DequantizeLinear of
    /// an activation (per-tensor).
    fn qparams(&self, n: &NodeProto) -> Result<QParams, ImportError> {
        let scale = self.init_values(n, n.input.get(1).map_or("", |s| s))?;
        let (zp, ty) = match n.input.get(2).filter(|s| !s.is_empty()) {
            Some(z) => {
                let t = self.init(n, z)?;
                let ty = match t.data_type {
                    data_type::UINT8 => QType::U8,
                    data_type::INT8 => QType::I8,
                    d => return Err(node_err(n, format!("zero point of data type {d}"))),
                };
                (self.init_values(n, z)?, ty)
            }
            None => (vec![0.0], QType::U8),
        };
        if scale.len() != 1 || zp.len() != 1 {
            return Err(node_err(n, "per-axis activation quantization"));
        }
        Ok(QParams {
            scale: scale[0] as f32,
            zero_point: zp[0] as i32,
            ty,
        })
    }

    fn add_value(&mut self, name: &str, shape: Vec<usize>, q: QParams) -> usize {
        self.model.values.push(Value {
            name: name.to_string(),
            shape,
            q,
        });
        let id = self.model.values.len() - 1;
        self.by_name.insert(name.to_string(), id);
        id
    }

    fn act(&self, n: &NodeProto, name: &str) -> Result<usize, ImportError> {
        if self.consts.contains_key(name) || self.inits.contains_key(name) {
            return Err(node_err(
                n,
                format!("a constant activation input {name:?} is not supported"),
            ));
        }
        self.by_name.get(name).copied().ok_or_else(|| {
            node_err(
                n,
                format!("input {name:?} is not a DequantizeLinear of a quantized tensor"),
            )
        })
    }

    fn quantize(&mut self, n: &NodeProto) -> Result<(), ImportError> {
        let q = self.qparams(n)?;
        let x = n.input[0].as_str();
        let y = n.output[0].as_str();
        if x == self.model.input_name {
            let id = self.add_value(y, self.input_shape.clone(), q);
            self.model.input = id;
            return Ok(());
        }
        let id = self.act(n, x)?;
        if self.model.values[id].q == q {
            self.by_name.insert(y.to_string(), id);
            return Ok(());
        }
        // A second quantization of a quantized tensor: a change of scale.
        let shape = self.model.values[id].shape.clone();
        let out = self.add_value(y, shape, q);
        let requant = self.ratio(n, self.model.values[id].q.scale as f64 / q.scale as f64)?;
        self.push(
            n,
            "QuantizeLinear",
            vec![id],
            out,
            q.ty.range(),
            0,
            LayerKind::Requant { requant },
        );
        Ok(())
    }

    fn dequantize(&mut self, n: &NodeProto) -> Result<(), ImportError> {
        let x = n.input[0].as_str();
        let y = n.output[0].clone();
        if let Some(t) = self.inits.get(x) {
            let q = self.init_values(n, x)?;
            let scale = self.init_values(n, &n.input[1])?;
            let zero_point = match n.input.get(2).filter(|s| !s.is_empty()) {
                Some(z) => self.init_values(n, z)?,
                None => vec![0.0],
            };
            let dims = t.dims.iter().map(|&d| d as usize).collect();
            self.consts.insert(
                y,
                DqConst {
                    dims,
                    q,
                    scale,
                    zero_point,
                },
            );
            return Ok(());
        }
        let q = self.qparams(n)?;
        let id = self.act(n, x)?;
        if self.model.values[id].q != q {
            return Err(node_err(n, "its scale differs from its QuantizeLinear's"));
        }
        self.by_name.insert(y, id);
        Ok(())
    }

    fn ratio(&self, n: &NodeProto, r: f64) -> Result<Requant, ImportError> {
        Requant::from_ratio(r).map_err(|e| node_err(n, e.to_string()))
    }

    #[allow(clippy::too_many_arguments)]
    fn push(
        &mut self,
        n: &NodeProto,
        op: &str,
        inputs: Vec<usize>,
        output: usize,
        clamp: (i32, i32),
        macs: u64,
        kind: LayerKind,
    ) {
        self.model.layers.push(super::layers::Layer {
            name: n.name.clone(),
            op: op.to_string(),
            inputs,
            output,
            clamp,
            kind,
            macs,
        });
    }

    /// The real bounds a Relu or Clip node imposes.
    fn activation_bounds(&self, n: &NodeProto) -> Result<(f64, f64), ImportError> {
        Ok(match n.op_type.as_str() {
            "Relu" => (0.0, f64::INFINITY),
            _ => {
                let bound = |k: usize, attr_name: &str, default: f64| -> Result<f64, ImportError> {
                    match n.input.get(k).filter(|s| !s.is_empty()) {
                        Some(name) => {
                            let v = match self.consts.get(name.as_str()) {
                                Some(c) => vec![(c.q[0] - c.zero_point[0]) * c.scale[0]],
                                None => self.init_values(n, name)?,
                            };
                            Ok(v[0])
                        }
                        None => Ok(attr(n, attr_name).map_or(default, |a| a.f as f64)),
                    }
                };
                (
                    bound(1, "min", f64::NEG_INFINITY)?,
                    bound(2, "max", f64::INFINITY)?,
                )
            }
        })
    }

    /// Follows `n`'s float output through fused Relu/Clip nodes to the
    /// QuantizeLinear that fixes the layer's output: its parameters, the
    /// clamp, the fused op's name, and the float tensor the
    /// QuantizeLinear reads (mapped to the layer's output value).
    fn resolve_output(
        &mut self,
        n: &NodeProto,
    ) -> Result<(QParams, (i32, i32), String, String), ImportError> {
        let mut op = n.op_type.clone();
        let (mut lo, mut hi) = if matches!(n.op_type.as_str(), "Relu" | "Clip") {
            self.activation_bounds(n)?
        } else {
            (f64::NEG_INFINITY, f64::INFINITY)
        };
        let mut cur = n.output[0].clone();
        loop {
            let cons = self
                .consumers
                .get(cur.as_str())
                .cloned()
                .unwrap_or_default();
            let [c] = cons[..] else {
                let why = if cons.is_empty() {
                    format!("its output {cur:?} is not quantized (no QuantizeLinear)")
                } else {
                    format!(
                        "its output {cur:?} has {} consumers; one QuantizeLinear is supported",
                        cons.len()
                    )
                };
                return Err(node_err(n, why));
            };
            let c_node = &self.nodes[c];
            match c_node.op_type.as_str() {
                "Relu" | "Clip" => {
                    let (l, h) = self.activation_bounds(c_node)?;
                    lo = lo.max(l);
                    hi = hi.min(h);
                    op = format!("{op}+{}", c_node.op_type);
                    self.done[c] = true;
                    cur = c_node.output[0].clone();
                }
                "QuantizeLinear" => {
                    let q = self.qparams(c_node)?;
                    let (qmin, qmax) = q.ty.range();
                    let to_q = |r: f64| -> f64 {
                        q.zero_point as f64 + (r / q.scale as f64).round_ties_even()
                    };
                    let clamp = (
                        if lo.is_finite() {
                            (to_q(lo).max(qmin as f64)) as i32
                        } else {
                            qmin
                        },
                        if hi.is_finite() {
                            (to_q(hi).min(qmax as f64)) as i32
                        } else {
                            qmax
                        },
                    );
                    return Ok((q, clamp, op, cur));
                }
                _ => {
                    return Err(node_err(
                        n,
                        format!(
                            "its output {cur:?} goes to {} ({}), not to a QuantizeLinear",
                            c_node.name, c_node.op_type
                        ),
                    ))
                }
            }
        }
    }

    /// The 2-D window of a Conv or pool node on an [1, C, H, W] input.
    fn window(
        &self,
        n: &NodeProto,
        in_hw: [usize; 2],
        kernel: [usize; 2],
    ) -> Result<(Window, [usize; 2]), ImportError> {
        if let Some(d) = attr_ints(n, "dilations") {
            if d.iter().any(|&d| d != 1) {
                return Err(node_err(n, format!("dilations {d:?}; 1 is supported")));
            }
        }
        if attr_i(n, "ceil_mode", 0) != 0 {
            return Err(node_err(n, "ceil_mode 1 is not supported"));
        }
        let strides = attr_ints(n, "strides").unwrap_or(vec![1, 1]);
        if strides.len() != 2 || strides.iter().any(|&s| s < 1) {
            return Err(node_err(n, format!("strides {strides:?}")));
        }
        let stride = [strides[0] as usize, strides[1] as usize];
        let auto_pad = attr_s(n, "auto_pad");
        let mut pads = [0usize; 4];
        match auto_pad.as_str() {
            "" | "NOTSET" => {
                if let Some(p) = attr_ints(n, "pads") {
                    if p.len() != 4 || p.iter().any(|&v| v < 0) {
                        return Err(node_err(n, format!("pads {p:?}")));
                    }
                    pads = [p[0] as usize, p[1] as usize, p[2] as usize, p[3] as usize];
                }
            }
            "VALID" => {}
            "SAME_UPPER" | "SAME_LOWER" => {
                for a in 0..2 {
                    let out = in_hw[a].div_ceil(stride[a]);
                    let total = ((out - 1) * stride[a] + kernel[a]).saturating_sub(in_hw[a]);
                    let small = total / 2;
                    let (begin, end) = if auto_pad == "SAME_UPPER" {
                        (small, total - small)
                    } else {
                        (total - small, small)
                    };
                    pads[a] = begin;
                    pads[a + 2] = end;
                }
            }
            other => return Err(node_err(n, format!("auto_pad {other:?}"))),
        }
        let mut out = [0; 2];
        for a in 0..2 {
            let padded = in_hw[a] + pads[a] + pads[a + 2];
            if padded < kernel[a] {
                return Err(node_err(n, "the window is larger than the padded input"));
            }
            out[a] = (padded - kernel[a]) / stride[a] + 1;
        }
        Ok((
            Window {
                kernel,
                stride,
                pads,
            },
            out,
        ))
    }

    fn compute(&mut self, n: &'a NodeProto) -> Result<(), ImportError> {
        let (q, clamp, op, float_out) = self.resolve_output(n)?;
        let x = self.act(n, &n.input[0])?;
        let xv = self.model.values[x].clone();
        let s_x = xv.q.scale as f64;
        let s_y = q.scale as f64;
        let rank_err = |what: &str| node_err(n, format!("input shape {:?}: {what}", xv.shape));
        let (kind, shape, macs, inputs) = match n.op_type.as_str() {
            "Conv" => {
                let w = self.const_input(n, 1, "weights")?;
                if w.dims.len() != 4 || xv.shape.len() != 4 {
                    return Err(rank_err("2-D convolutions (4-D tensors) are supported"));
                }
                let groups = attr_i(n, "group", 1).max(1) as usize;
                let (cout, cin_g, kh, kw) = (w.dims[0], w.dims[1], w.dims[2], w.dims[3]);
                let cin = xv.shape[1];
                if cin_g * groups != cin || cout % groups != 0 {
                    return Err(node_err(
                        n,
                        format!(
                            "weights {:?} with group {groups} on {} channels",
                            w.dims, cin
                        ),
                    ));
                }
                let (window, [ho, wo]) = self.window(n, [xv.shape[2], xv.shape[3]], [kh, kw])?;
                let weights = int8_weights(n, w)?;
                let (bias, requant) = self.bias_requant(n, w, cout, s_x, s_y)?;
                let macs = (cout * ho * wo * cin_g * kh * kw) as u64;
                (
                    LayerKind::Conv {
                        window,
                        groups,
                        weights,
                        bias,
                        requant,
                    },
                    vec![1, cout, ho, wo],
                    macs,
                    vec![x],
                )
            }
            "Gemm" | "MatMul" => {
                let w = self.const_input(n, 1, "weights")?;
                let gemm = n.op_type == "Gemm";
                if gemm {
                    if attr_i(n, "transA", 0) != 0 {
                        return Err(node_err(n, "transA 1 is not supported"));
                    }
                    for a in ["alpha", "beta"] {
                        if let Some(v) = attr(n, a).map(|a| a.f).filter(|&v| v != 1.0) {
                            return Err(node_err(n, format!("{a} {v}; 1 is supported")));
                        }
                    }
                }
                let trans_b = gemm && attr_i(n, "transB", 0) != 0;
                if xv.shape.len() != 2 || w.dims.len() != 2 {
                    return Err(rank_err("a [1, K] input and 2-D weights are supported"));
                }
                let (k, nout) = if trans_b {
                    (w.dims[1], w.dims[0])
                } else {
                    (w.dims[0], w.dims[1])
                };
                if k != xv.shape[1] {
                    return Err(rank_err(&format!("weights {:?}", w.dims)));
                }
                let flat = int8_weights(n, w)?;
                // Stored [out][in] whatever the file's order.
                let weights = if trans_b {
                    flat
                } else {
                    let mut t = vec![0i8; k * nout];
                    for i in 0..k {
                        for o in 0..nout {
                            t[o * k + i] = flat[i * nout + o];
                        }
                    }
                    t
                };
                let (bias, requant) = self.bias_requant(n, w, nout, s_x, s_y)?;
                (
                    LayerKind::Dense {
                        weights,
                        bias,
                        requant,
                    },
                    vec![1, nout],
                    (k * nout) as u64,
                    vec![x],
                )
            }
            "MaxPool" | "AveragePool" => {
                if n.output.iter().skip(1).any(|o| !o.is_empty()) {
                    return Err(node_err(n, "the Indices output is not supported"));
                }
                if xv.shape.len() != 4 {
                    return Err(rank_err("2-D pooling (4-D tensors) is supported"));
                }
                let k = attr_ints(n, "kernel_shape").unwrap_or_default();
                if k.len() != 2 || k.iter().any(|&v| v < 1) {
                    return Err(node_err(n, format!("kernel_shape {k:?}")));
                }
                let kernel = [k[0] as usize, k[1] as usize];
                let (window, [ho, wo]) = self.window(n, [xv.shape[2], xv.shape[3]], kernel)?;
                let kind = if n.op_type == "MaxPool" {
                    LayerKind::MaxPool {
                        window,
                        requant: self.ratio(n, s_x / s_y)?,
                    }
                } else {
                    LayerKind::AvgPool {
                        window,
                        count_include_pad: attr_i(n, "count_include_pad", 0) != 0,
                        scale: self.pool_scale(n, s_x, s_y, kernel[0] * kernel[1])?,
                    }
                };
                (kind, vec![1, xv.shape[1], ho, wo], 0, vec![x])
            }
            "GlobalAveragePool" => {
                if xv.shape.len() != 4 {
                    return Err(rank_err("4-D tensors are supported"));
                }
                let hw = xv.shape[2] * xv.shape[3];
                (
                    LayerKind::GlobalAvgPool {
                        scale: self.pool_scale(n, s_x, s_y, hw)?,
                    },
                    vec![1, xv.shape[1], 1, 1],
                    0,
                    vec![x],
                )
            }
            "Add" => {
                let b = self.act(n, n.input.get(1).map_or("", |s| s))?;
                let bv = &self.model.values[b];
                if bv.shape != xv.shape {
                    return Err(node_err(
                        n,
                        format!(
                            "shapes {:?} and {:?}; broadcasting is not supported",
                            xv.shape, bv.shape
                        ),
                    ));
                }
                let (ra, rb) = (s_x / s_y, bv.q.scale as f64 / s_y);
                // One shift for both: the larger ratio's.
                let big = self.ratio(n, ra.max(rb))?;
                let scaled = |r: f64| Requant {
                    multiplier: (r * (big.shift as f64).exp2()).round() as i32,
                    shift: big.shift,
                };
                (
                    LayerKind::Add {
                        ra: scaled(ra),
                        rb: scaled(rb),
                    },
                    xv.shape.clone(),
                    0,
                    vec![x, b],
                )
            }
            "Concat" => {
                let mut axis = attr_i(n, "axis", 1);
                if axis < 0 {
                    axis += xv.shape.len() as i64;
                }
                if axis != 1 {
                    return Err(node_err(
                        n,
                        format!("axis {axis}; channels (1) are supported"),
                    ));
                }
                let mut ids = Vec::new();
                let mut requant = Vec::new();
                let mut shape = xv.shape.clone();
                shape[1] = 0;
                for name in &n.input {
                    let id = self.act(n, name)?;
                    let v = &self.model.values[id];
                    if v.shape.len() != xv.shape.len() || v.shape[2..] != xv.shape[2..] {
                        return Err(node_err(
                            n,
                            format!(
                                "shapes {:?} and {:?} differ beyond channels",
                                xv.shape, v.shape
                            ),
                        ));
                    }
                    shape[1] += v.shape[1];
                    requant.push(self.ratio(n, v.q.scale as f64 / s_y)?);
                    ids.push(id);
                }
                (LayerKind::Concat { requant }, shape, 0, ids)
            }
            "Flatten" | "Reshape" => {
                let total: usize = xv.shape.iter().product();
                let shape = if n.op_type == "Flatten" {
                    let mut axis = attr_i(n, "axis", 1);
                    if axis < 0 {
                        axis += xv.shape.len() as i64;
                    }
                    let a = (axis.max(0) as usize).min(xv.shape.len());
                    vec![
                        xv.shape[..a].iter().product(),
                        xv.shape[a..].iter().product(),
                    ]
                } else {
                    let target = self.init_values(n, n.input.get(1).map_or("", |s| s))?;
                    reshape(&xv.shape, &target).ok_or_else(|| {
                        node_err(
                            n,
                            format!("shape {target:?} for an input of {:?}", xv.shape),
                        )
                    })?
                };
                if shape.first() != Some(&1) || shape.iter().product::<usize>() != total {
                    return Err(node_err(
                        n,
                        format!("output shape {shape:?}; batch 1 is kept"),
                    ));
                }
                (
                    LayerKind::Requant {
                        requant: self.ratio(n, s_x / s_y)?,
                    },
                    shape,
                    0,
                    vec![x],
                )
            }
            // Relu and Clip between their own DequantizeLinear and
            // QuantizeLinear.
            _ => (
                LayerKind::Requant {
                    requant: self.ratio(n, s_x / s_y)?,
                },
                xv.shape.clone(),
                0,
                vec![x],
            ),
        };
        let out = self.add_value(&n.output[0], shape, q);
        self.by_name.insert(float_out, out);
        self.push(n, &op, inputs, out, clamp, macs, kind);
        Ok(())
    }

    /// An average pool's division: exact where the scale is kept, else
    /// one record per window count (1..=max).
    fn pool_scale(
        &self,
        n: &NodeProto,
        s_x: f64,
        s_y: f64,
        max: usize,
    ) -> Result<PoolScale, ImportError> {
        if s_x == s_y {
            return Ok(PoolScale::Divide);
        }
        let records = (0..=max)
            .map(|c| self.ratio(n, s_x / (s_y * c.max(1) as f64)))
            .collect::<Result<_, _>>()?;
        Ok(PoolScale::Records(records))
    }

    fn const_input(&self, n: &NodeProto, k: usize, what: &str) -> Result<&DqConst, ImportError> {
        let name = n.input.get(k).map_or("", |s| s);
        self.consts.get(name).ok_or_else(|| {
            node_err(
                n,
                format!("{what} {name:?} are not a DequantizeLinear of a constant"),
            )
        })
    }

    /// The bias in the accumulator's scale (s_x · s_w[c]) and the output
    /// records s_x · s_w[c] / s_y.
    fn bias_requant(
        &self,
        n: &NodeProto,
        w: &DqConst,
        cout: usize,
        s_x: f64,
        s_y: f64,
    ) -> Result<(Vec<i32>, Vec<Requant>), ImportError> {
        if w.scale.len() != 1 && w.scale.len() != cout {
            return Err(node_err(
                n,
                format!("{} weight scales for {cout} output channels", w.scale.len()),
            ));
        }
        let mut bias = vec![0i32; cout];
        if let Some(name) = n.input.get(2).filter(|s| !s.is_empty()) {
            let b = self.consts.get(name.as_str()).ok_or_else(|| {
                node_err(
                    n,
                    format!("bias {name:?} is not a DequantizeLinear of a constant"),
                )
            })?;
            if b.q.len() != cout {
                return Err(node_err(
                    n,
                    format!("{} biases for {cout} channels", b.q.len()),
                ));
            }
            for (c, v) in bias.iter_mut().enumerate() {
                let zp = b.zero_point[if b.zero_point.len() == 1 { 0 } else { c }];
                let real = (b.q[c] - zp) * b.scale(c);
                let acc = (real / (s_x * w.scale(c))).round();
                if acc.abs() >= 2f64.powi(31) {
                    return Err(node_err(n, format!("bias {c} overflows int32")));
                }
                *v = acc as i32;
            }
        }
        let requant = (0..cout)
            .map(|c| self.ratio(n, s_x * w.scale(c) / s_y))
            .collect::<Result<_, _>>()?;
        Ok((bias, requant))
    }

    fn sigmoid(&mut self, n: &NodeProto) -> Result<(), ImportError> {
        let x = self.act(n, &n.input[0])?;
        let has_consumers = self.consumers.contains_key(n.output[0].as_str());
        if !has_consumers {
            if n.output[0] != self.model.output_name {
                return Err(node_err(n, "its output is unused"));
            }
            // On the dequantized output, in float.
            self.output_sigmoid_of = Some(n.input[0].clone());
            return Ok(());
        }
        let (q, clamp, op, float_out) = self.resolve_output(n)?;
        let xq = self.model.values[x].q;
        let (lo, hi) = xq.ty.range();
        let (qmin, qmax) = q.ty.range();
        // As onnxruntime's table for QLinearSigmoid: dequantize, sigmoid
        // and quantize in f32.
        let table = (lo..=hi)
            .map(|v| {
                let r = (v - xq.zero_point) as f32 * xq.scale;
                let s = 1.0 / (1.0 + (-r).exp());
                round_clamp((s / q.scale) as f64 + q.zero_point as f64, qmin, qmax)
            })
            .collect();
        let shape = self.model.values[x].shape.clone();
        let out = self.add_value(&n.output[0], shape, q);
        self.by_name.insert(float_out, out);
        self.push(n, &op, vec![x], out, clamp, 0, LayerKind::Lut { table });
        Ok(())
    }
}

/// The int8 weights of a DequantizeLinear constant with zero point 0.
fn int8_weights(n: &NodeProto, w: &DqConst) -> Result<Vec<i8>, ImportError> {
    if w.zero_point.iter().any(|&z| z != 0.0) {
        return Err(node_err(
            n,
            "weights with a non-zero zero point (asymmetric) are not supported",
        ));
    }
    w.q.iter()
        .map(|&v| {
            if (-128.0..=127.0).contains(&v) {
                Ok(v as i8)
            } else {
                Err(node_err(n, format!("weight {v} is not int8")))
            }
        })
        .collect()
}

/// ONNX Reshape's target (0 copies the input's dimension, −1 is inferred).
fn reshape(input: &[usize], target: &[f64]) -> Option<Vec<usize>> {
    let total: usize = input.iter().product();
    let mut out = Vec::with_capacity(target.len());
    let mut infer = None;
    for (i, &t) in target.iter().enumerate() {
        match t as i64 {
            0 => out.push(*input.get(i)?),
            -1 if infer.is_none() => {
                infer = Some(i);
                out.push(1);
            }
            d if d > 0 => out.push(d as usize),
            _ => return None,
        }
    }
    if let Some(i) = infer {
        let rest: usize = out.iter().product();
        if rest == 0 || !total.is_multiple_of(rest) {
            return None;
        }
        out[i] = total / rest;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::onnx::proto::{
        Dimension, TensorShapeProto, TypeProto, TypeProtoTensor, ValueInfoProto,
    };
    use crate::nn::onnx::reference;

    fn node(op: &str, name: &str, inputs: &[&str], output: &str) -> NodeProto {
        NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![output.to_string()],
            name: name.to_string(),
            op_type: op.to_string(),
            ..Default::default()
        }
    }

    fn tensor(name: &str, dims: &[i64], ty: i32, raw: Vec<u8>) -> TensorProto {
        TensorProto {
            dims: dims.to_vec(),
            data_type: ty,
            name: name.to_string(),
            raw_data: raw,
            ..Default::default()
        }
    }

    fn f32s(v: &[f32]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    /// Input [1, 1, 3, 3] → Q → DQ → Conv 1x1 (2 channels, weights 2 and
    /// −1 with per-channel scales 0.5 and 1) → Relu → Q → DQ, every
    /// activation scale 1, int8, zero point 0: channel 0 is max(x, 0) and
    /// channel 1 max(−x, 0).
    fn conv_relu_graph() -> GraphProto {
        let i8 = data_type::INT8;
        let vi = |name: &str, dims: &[i64]| ValueInfoProto {
            name: name.to_string(),
            r#type: Some(TypeProto {
                tensor_type: Some(TypeProtoTensor {
                    elem_type: data_type::FLOAT,
                    shape: Some(TensorShapeProto {
                        dim: dims
                            .iter()
                            .map(|&d| Dimension {
                                dim_value: Some(d),
                                dim_param: None,
                            })
                            .collect(),
                    }),
                }),
            }),
        };
        GraphProto {
            node: vec![
                node("QuantizeLinear", "q_in", &["x", "one", "zp"], "xq"),
                node("DequantizeLinear", "dq_in", &["xq", "one", "zp"], "xf"),
                node("DequantizeLinear", "dq_w", &["w", "ws", "wzp"], "wf"),
                node("Conv", "conv", &["xf", "wf"], "c"),
                node("Relu", "relu", &["c"], "r"),
                node("QuantizeLinear", "q_out", &["r", "one", "zp"], "yq"),
                node("DequantizeLinear", "dq_out", &["yq", "one", "zp"], "y"),
            ],
            initializer: vec![
                tensor("one", &[], data_type::FLOAT, f32s(&[1.0])),
                tensor("zp", &[], i8, vec![0]),
                tensor("w", &[2, 1, 1, 1], i8, vec![2, (-1i8) as u8]),
                tensor("ws", &[2], data_type::FLOAT, f32s(&[0.5, 1.0])),
                tensor("wzp", &[2], i8, vec![0, 0]),
            ],
            input: vec![vi("x", &[1, 1, 3, 3])],
            output: vec![vi("y", &[1, 2, 3, 3])],
            ..Default::default()
        }
    }

    #[test]
    fn conv_relu_fuses_into_one_clamped_layer() {
        let m = import_graph(&conv_relu_graph()).unwrap();
        assert_eq!(m.layers.len(), 1);
        let l = &m.layers[0];
        assert_eq!((l.name.as_str(), l.op.as_str()), ("conv", "Conv+Relu"));
        assert_eq!(l.clamp, (0, 127));
        assert_eq!(l.macs, 2 * 3 * 3);
        assert_eq!(l.weight_bytes(), 2 + 4 * 2);
        assert_eq!(m.values[m.output].shape, [1, 2, 3, 3]);
        let x: Vec<f32> = (-4..5).map(|v| v as f32 * 1.2).collect();
        let y = reference::run(&m, &x).unwrap();
        let q: Vec<f32> = x.iter().map(|v| v.round_ties_even()).collect();
        let want: Vec<f32> = q
            .iter()
            .map(|v| v.max(0.0))
            .chain(q.iter().map(|v| (-v).max(0.0)))
            .collect();
        assert_eq!(y, want);
    }

    #[test]
    fn an_unsupported_node_is_named_with_its_op() {
        let mut g = conv_relu_graph();
        g.node[4] = node("Softmax", "sm", &["c"], "r");
        let e = import_graph(&g).unwrap_err().to_string();
        assert!(
            e.starts_with("node \"conv\" (Conv): its output \"c\" goes to sm (Softmax)"),
            "{e}"
        );
        let mut g = conv_relu_graph();
        g.node.insert(0, node("LSTM", "lstm0", &["x"], "h"));
        let e = import_graph(&g).unwrap_err().to_string();
        assert_eq!(e, "node \"lstm0\" (LSTM): unsupported op");
        assert!(!e.contains('\n'));
    }
}
