//! The model as data: the layer list an imported ONNX file becomes
//! (layer descriptors, int8 weights, int32 biases, per-channel
//! requantization records), the form a generic firmware would read.
//! Tensors are batch-1 NCHW (or [1, N] after Flatten/Gemm), stored as
//! their quantized integers.

use super::requant::Requant;

/// The integer type of an activation tensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QType {
    U8,
    I8,
}

impl QType {
    /// The representable range.
    pub fn range(self) -> (i32, i32) {
        match self {
            QType::U8 => (0, 255),
            QType::I8 => (-128, 127),
        }
    }
}

/// An activation's quantization: real = (q − zero_point) · scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QParams {
    pub scale: f32,
    pub zero_point: i32,
    pub ty: QType,
}

/// One tensor between layers.
#[derive(Clone, Debug)]
pub struct Value {
    /// The ONNX tensor name (the quantized one where there is one).
    pub name: String,
    /// Batch first (always 1).
    pub shape: Vec<usize>,
    pub q: QParams,
}

/// A 2-D window: kernel, strides, pads (top, left, bottom, right).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub kernel: [usize; 2],
    pub stride: [usize; 2],
    pub pads: [usize; 4],
}

/// What a layer computes.
#[derive(Clone, Debug)]
pub enum LayerKind {
    /// acc[co] = bias[co] + Σ (x − zp_x) · w[co][ci/g][ky][kx];
    /// weights [Cout][Cin/groups][Kh][Kw].
    Conv {
        window: Window,
        groups: usize,
        weights: Vec<i8>,
        bias: Vec<i32>,
        requant: Vec<Requant>,
    },
    /// Gemm and MatMul: weights [out][in].
    Dense {
        weights: Vec<i8>,
        bias: Vec<i32>,
        requant: Vec<Requant>,
    },
    /// The maximum of the integers (the map to the output is monotone),
    /// then requantized where the output's scale differs.
    MaxPool { window: Window, requant: Requant },
    /// The mean of (x − zp) over the window (edge windows without the pad
    /// count fewer): see [`PoolScale`].
    AvgPool {
        window: Window,
        count_include_pad: bool,
        scale: PoolScale,
    },
    /// AvgPool over the whole plane.
    GlobalAvgPool { scale: PoolScale },
    /// a·ra + b·rb with one common shift (`ra.shift == rb.shift`).
    Add { ra: Requant, rb: Requant },
    /// Channel concatenation, each input requantized to the output's scale.
    Concat { requant: Vec<Requant> },
    /// Element-wise requantization: a Relu or Clip between its own
    /// DequantizeLinear and QuantizeLinear, a change of scale, and Flatten
    /// or Reshape (the same integers in the same order; the record is 1
    /// where the scale is kept).
    Requant { requant: Requant },
    /// A table from input integer to output integer (Sigmoid between
    /// DequantizeLinear and QuantizeLinear); indexed by q − qmin.
    Lut { table: Vec<i32> },
}

/// How an average pool's sum becomes its output.
#[derive(Clone, Debug)]
pub enum PoolScale {
    /// The output keeps the input's scale (onnxruntime's quantizer gives
    /// pools their input's): an integer division by the window's count,
    /// rounding half to even as ONNX's QuantizeLinear does. Half-way sums
    /// are frequent here (a sum of 3 over 6 inputs), and a kernel rounding
    /// them up would be one step off onnxruntime on every one.
    Divide,
    /// Another scale: `records[count]` is scale_in / (scale_out · count)
    /// (ties are then no likelier than anywhere else).
    Records(Vec<Requant>),
}

/// One layer: fused from the ONNX nodes named in `op`.
#[derive(Clone, Debug)]
pub struct Layer {
    /// The ONNX node's name (the compute node of a fused group).
    pub name: String,
    /// Its op, with the fused activation: "Conv", "Conv+Relu", ...
    pub op: String,
    /// Indices into [`Model::values`].
    pub inputs: Vec<usize>,
    pub output: usize,
    /// The output's clamp (the type's range, narrowed by a fused Relu or
    /// Clip).
    pub clamp: (i32, i32),
    pub kind: LayerKind,
    /// Multiply-accumulates from the ONNX shapes (Conv:
    /// Cout·Hout·Wout·Cin/groups·Kh·Kw; Gemm: in·out; others 0).
    pub macs: u64,
}

impl Layer {
    /// Bytes of parameters: int8 weights and int32 biases.
    pub fn weight_bytes(&self) -> usize {
        match &self.kind {
            LayerKind::Conv { weights, bias, .. } | LayerKind::Dense { weights, bias, .. } => {
                weights.len() + 4 * bias.len()
            }
            _ => 0,
        }
    }
}

/// An imported model.
#[derive(Clone, Debug)]
pub struct Model {
    pub values: Vec<Value>,
    pub layers: Vec<Layer>,
    /// The float input's name and shape, and the value its QuantizeLinear
    /// writes.
    pub input_name: String,
    pub input: usize,
    /// The value the last DequantizeLinear reads, and the graph output's
    /// name.
    pub output: usize,
    pub output_name: String,
    /// The graph ends with a Sigmoid on the dequantized output (computed
    /// in float).
    pub output_sigmoid: bool,
}

impl Model {
    /// Total MACs.
    pub fn macs(&self) -> u64 {
        self.layers.iter().map(|l| l.macs).sum()
    }

    /// Total parameter bytes.
    pub fn weight_bytes(&self) -> usize {
        self.layers.iter().map(Layer::weight_bytes).sum()
    }
}
