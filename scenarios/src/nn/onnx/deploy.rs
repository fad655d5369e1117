//! The imported model laid out for the AI deck (docs/NN_ONNX.md "On the
//! deck"): the L2 image and the HyperRAM (L3) contents the generic runtime
//! firmware (`nn_run.elf`) reads, in the format of its
//! `sim-core/firmware/src/nn/runtime/model.h`. Everything about memory is
//! decided here, ahead of time, as DORY does at code generation: where
//! each activation lives in L2 (reused once its last reader has run),
//! whether the weights stay in L2 or stream from L3, and each layer's L1
//! tile. The firmware follows the plan.
//!
//! Activations are stored HWC and in the "stored" int8 domain (a uint8
//! tensor as q − 128), weights as [Cout][Kh][Kw][Cin/groups], biases with
//! the input's zero point folded in (model.h gives the arithmetic).

use super::layers::{Layer, LayerKind, Model, PoolScale, QType};
use super::requant::Requant;

/// The cluster's L1 bytes the tiles are planned for: 64 KiB less the
/// cores' stacks (pmsis.h: 2 KiB for core 0, 1 KiB each for the other
/// seven) and the runtime's own few hundred bytes.
pub const L1_BUDGET: usize = 52 * 1024;
/// The AI deck's HyperRAM: 8 MiB (64 Mbit, in the S71KS512SC0 package).
pub const L3_BYTES: usize = 8 << 20;
/// Each of the two L2 buffers L3 weights are read into, at most.
pub const STAGE_BYTES: usize = 64 * 1024;

const MAGIC: u32 = 0x4e4e_4643;
const VERSION: u32 = 1;
const MAX_IN: usize = 8;
pub const MAX_LAYERS: usize = 256;
const HEADER_BYTES: usize = 64;
const VALUE_WORDS: usize = 6;
const LAYER_WORDS: usize = 34;

const F_W_L3: u32 = 1;
const F_COUNT_PAD: u32 = 2;
const F_POOL_RECORDS: u32 = 4;

/// Where the weights go.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WeightsPlace {
    /// L2 when the whole image fits, else every weight in L3.
    #[default]
    Auto,
    /// Every weight in L3 (to measure what streaming costs).
    L3,
}

/// Why a model cannot be laid out on the deck.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DeployError {
    #[error("node {node:?} ({op}): {why}")]
    Layer {
        node: String,
        op: String,
        why: String,
    },
    #[error("{0}")]
    Size(String),
}

fn layer_err(l: &Layer, why: impl Into<String>) -> DeployError {
    DeployError::Layer {
        node: l.name.clone(),
        op: l.op.clone(),
        why: why.into(),
    }
}

fn a4(n: usize) -> usize {
    n.div_ceil(4) * 4
}
fn a8(n: usize) -> usize {
    n.div_ceil(8) * 8
}

/// The stored domain's offset of a type: a uint8 value q is stored as
/// q − 128.
fn offset(t: QType) -> i32 {
    match t {
        QType::U8 => 128,
        QType::I8 => 0,
    }
}

/// A value's place and order in L2.
#[derive(Clone, Debug, PartialEq)]
pub struct ValuePlan {
    /// The descriptor's c × h × w.
    pub chw: [usize; 3],
    /// Stored as HWC of this logical C × H × W block: the logical (NCHW
    /// flat) element i = (ch·H + y)·W + x is at (y·W + x)·C + ch. A value
    /// flattened from an activation keeps its input's block.
    pub block: [usize; 3],
    pub off: usize,
    pub bytes: usize,
    /// Added to a native integer to store it.
    pub shift: i32,
}

impl ValuePlan {
    /// Storage position of the logical element `i`.
    pub fn position(&self, i: usize) -> usize {
        let [c, h, w] = self.block;
        let (ch, rest) = (i / (h * w), i % (h * w));
        rest * c + ch
    }
}

/// One layer's plan, as the profile reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerPlan {
    pub tile_oh: usize,
    pub tile_oc: usize,
    pub l1_bytes: usize,
    /// The weights stream from L3 (in parts of `part_oc` channels).
    pub weights_l3: bool,
    pub part_oc: usize,
}

/// The deck's memory contents for one model.
#[derive(Clone, Debug)]
pub struct Deployment {
    /// Written at the runtime's `nn_l2`.
    pub l2: Vec<u8>,
    /// Written at the HyperRAM's address 0 (empty when nothing is in L3).
    pub l3: Vec<u8>,
    pub values: Vec<ValuePlan>,
    pub layers: Vec<LayerPlan>,
    pub input: usize,
    pub output: usize,
    /// Bytes of the L2 image that are activations (the arena).
    pub arena_bytes: usize,
}

impl Deployment {
    /// The input's native integers (NCHW order) as the bytes to write at
    /// its place in L2.
    pub fn input_bytes(&self, q: &[i32]) -> Vec<u8> {
        let v = &self.values[self.input];
        let mut b = vec![0u8; v.bytes];
        for (i, &x) in q.iter().enumerate() {
            b[v.position(i)] = (x - v.shift) as i8 as u8;
        }
        b
    }

    /// The output's bytes read from L2 as native integers (NCHW order).
    pub fn output_values(&self, bytes: &[u8]) -> Vec<i32> {
        let v = &self.values[self.output];
        let n: usize = v.chw.iter().product();
        (0..n)
            .map(|i| bytes[v.position(i)] as i8 as i32 + v.shift)
            .collect()
    }
}

/// Little-endian words and bytes, appended 4-aligned.
#[derive(Default)]
struct Image {
    bytes: Vec<u8>,
}

impl Image {
    fn put(&mut self, data: &[u8]) -> usize {
        let off = a8(self.bytes.len());
        self.bytes.resize(off, 0);
        self.bytes.extend_from_slice(data);
        off
    }
}

fn words(v: &[i32]) -> Vec<u8> {
    v.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn records(r: &[Requant]) -> Vec<u8> {
    r.iter()
        .flat_map(|r| {
            let mut b = r.multiplier.to_le_bytes().to_vec();
            b.extend(r.shift.to_le_bytes());
            b
        })
        .collect()
}

/// A layer's descriptor words before the L2/L3 offsets are known.
struct Desc {
    words: [u32; LAYER_WORDS],
    /// Weights (reordered), and where they go.
    weights: Vec<u8>,
    per_channel: usize,
    c_out: usize,
    small: Vec<(usize, Vec<u8>)>,
}

// Word indices of nn_layer_t (model.h).
const W_KIND: usize = 0;
const W_NIN: usize = 1;
const W_IN: usize = 2;
const W_OUT: usize = 10;
const W_WIN: usize = 11; // kh, kw, sh, sw, pt, pl, pb, pr
const W_GROUPS: usize = 19;
const W_LO: usize = 20;
const W_HI: usize = 21;
const W_FLAGS: usize = 22;
const W_WOFF: usize = 23;
const W_WBYTES: usize = 24;
const W_BOFF: usize = 25;
const W_RQOFF: usize = 26;
const W_LUTOFF: usize = 27;
const W_TILE_OH: usize = 28;
const W_TILE_OC: usize = 29;
const W_L1: usize = 30;
const W_PART_OC: usize = 31;
const W_MACS: usize = 32;

/// Lays `model` out for a runtime whose L2 image holds `l2_capacity`
/// bytes.
pub fn deploy(
    model: &Model,
    l2_capacity: usize,
    place: WeightsPlace,
) -> Result<Deployment, DeployError> {
    if model.layers.len() > MAX_LAYERS {
        return Err(DeployError::Size(format!(
            "{} layers; the runtime takes at most {MAX_LAYERS}",
            model.layers.len()
        )));
    }
    let values = plan_values(model)?;
    let (offsets, arena_bytes) = plan_arena(model, &values);
    let mut values: Vec<ValuePlan> = values
        .into_iter()
        .zip(offsets)
        .map(|(mut v, off)| {
            v.off = off;
            v
        })
        .collect();

    let mut descs = Vec::with_capacity(model.layers.len());
    let mut plans = Vec::with_capacity(model.layers.len());
    for l in &model.layers {
        let (d, p) = describe(model, &values, l)?;
        descs.push(d);
        plans.push(p);
    }

    // The image: header, tables, the small parameters (biases, records,
    // tables), the weights if they stay, the stage buffers if not, then
    // the arena.
    let n_v = values.len();
    let n_l = descs.len();
    let mut img = Image::default();
    img.bytes.resize(HEADER_BYTES, 0);
    let values_off = img.put(&vec![0; n_v * VALUE_WORDS * 4]);
    let layers_off = img.put(&vec![0; n_l * LAYER_WORDS * 4]);
    for d in &mut descs {
        for (word, data) in std::mem::take(&mut d.small) {
            d.words[word] = img.put(&data) as u32;
        }
    }
    let weights_total: usize = descs.iter().map(|d| a8(d.weights.len())).sum();
    let fixed = a8(img.bytes.len());
    let all_l2 = fixed + weights_total + arena_bytes;
    if fixed + arena_bytes > l2_capacity {
        return Err(DeployError::Size(format!(
            "the activations ({arena_bytes} B) and the descriptors ({fixed} B) need {} B of L2; the \
             runtime's L2 image holds {l2_capacity} B",
            fixed + arena_bytes
        )));
    }
    let to_l3 = match place {
        WeightsPlace::L3 => weights_total > 0,
        WeightsPlace::Auto => all_l2 > l2_capacity,
    };
    let mut l3 = Image::default();
    let mut stage = (0usize, 0usize);
    if !to_l3 {
        for d in &mut descs {
            if !d.weights.is_empty() {
                d.words[W_WOFF] = img.put(&d.weights) as u32;
            }
        }
    } else {
        // The stage buffers take what L2 has left, up to STAGE_BYTES each.
        let left = l2_capacity.saturating_sub(fixed + arena_bytes + 16);
        let stage_bytes = (left / 2).min(STAGE_BYTES) / 8 * 8;
        let largest_channel = descs.iter().map(|d| d.per_channel).max().unwrap_or(0);
        if stage_bytes < largest_channel.max(1) {
            return Err(DeployError::Size(format!(
                "weights {weights_total} B do not fit L2 beside the activations ({arena_bytes} B) and the \
                 descriptors ({fixed} B) of a {l2_capacity} B L2 image, and the {} B left for L3 staging \
                 cannot hold one output channel's weights ({largest_channel} B)",
                left
            )));
        }
        for (d, p) in descs.iter_mut().zip(&mut plans) {
            if d.weights.is_empty() {
                continue;
            }
            d.words[W_WOFF] = l3.put(&d.weights) as u32;
            d.words[W_FLAGS] |= F_W_L3;
            let part = (stage_bytes / d.per_channel).min(d.c_out);
            d.words[W_PART_OC] = part as u32;
            p.weights_l3 = true;
            p.part_oc = part;
        }
        if l3.bytes.len() > L3_BYTES {
            return Err(DeployError::Size(format!(
                "weights {} B exceed the AI deck's {L3_BYTES} B HyperRAM",
                l3.bytes.len()
            )));
        }
        let off = img.put(&vec![0; 2 * stage_bytes]);
        stage = (off, stage_bytes);
    }
    let arena_off = a8(img.bytes.len());
    let l2_bytes = arena_off + arena_bytes;
    if l2_bytes > l2_capacity {
        return Err(DeployError::Size(format!(
            "the model needs {l2_bytes} B of L2 (activations {arena_bytes} B, weights {} B, descriptors \
             {fixed} B); the runtime's L2 image holds {l2_capacity} B",
            if to_l3 { 2 * stage.1 } else { weights_total }
        )));
    }
    img.bytes.resize(l2_bytes, 0);
    for v in &mut values {
        v.off += arena_off;
    }

    // Tables and header.
    for (i, v) in values.iter().enumerate() {
        let zp = model.values[i].q.zero_point - v.shift;
        let w = [
            v.chw[0] as i32,
            v.chw[1] as i32,
            v.chw[2] as i32,
            zp,
            v.off as i32,
            v.bytes as i32,
        ];
        let at = values_off + i * VALUE_WORDS * 4;
        img.bytes[at..at + VALUE_WORDS * 4].copy_from_slice(&words(&w));
    }
    for (i, d) in descs.iter().enumerate() {
        let at = layers_off + i * LAYER_WORDS * 4;
        let b: Vec<u8> = d.words.iter().flat_map(|w| w.to_le_bytes()).collect();
        img.bytes[at..at + b.len()].copy_from_slice(&b);
    }
    let header = [
        MAGIC,
        VERSION,
        n_v as u32,
        n_l as u32,
        values_off as u32,
        layers_off as u32,
        model.input as u32,
        model.output as u32,
        stage.0 as u32,
        stage.1 as u32,
        l3.bytes.len() as u32,
        l2_bytes as u32,
        L1_BUDGET as u32,
    ];
    let hb: Vec<u8> = header.iter().flat_map(|w| w.to_le_bytes()).collect();
    img.bytes[..hb.len()].copy_from_slice(&hb);

    Ok(Deployment {
        l2: img.bytes,
        l3: l3.bytes,
        values,
        layers: plans,
        input: model.input,
        output: model.output,
        arena_bytes,
    })
}

/// Every value's descriptor shape and storage block (offsets later).
fn plan_values(model: &Model) -> Result<Vec<ValuePlan>, DeployError> {
    let chw = |shape: &[usize]| -> [usize; 3] {
        let c = shape.get(1).copied().unwrap_or(1);
        let h = shape.get(2).copied().unwrap_or(1);
        let w = shape.get(3..).map_or(1, |s| s.iter().product());
        [c, h, w]
    };
    let mut v: Vec<ValuePlan> = model
        .values
        .iter()
        .map(|val| {
            let chw = chw(&val.shape);
            ValuePlan {
                chw,
                block: chw,
                off: 0,
                bytes: chw.iter().product(),
                shift: offset(val.q.ty),
            }
        })
        .collect();
    for l in &model.layers {
        let natural = |i: usize| v[i].block == v[i].chw;
        match &l.kind {
            // Element-wise: the output keeps the input's order.
            LayerKind::Requant { .. } | LayerKind::Lut { .. } | LayerKind::Add { .. } => {
                let b = v[l.inputs[0]].block;
                if l.inputs.iter().any(|&i| v[i].block != b) {
                    return Err(layer_err(l, "its inputs are stored in different orders"));
                }
                v[l.output].block = b;
            }
            LayerKind::Dense { .. } => {}
            LayerKind::Concat { .. } => {
                if l.inputs.len() > MAX_IN {
                    return Err(layer_err(
                        l,
                        format!("{} inputs; the runtime takes {MAX_IN}", l.inputs.len()),
                    ));
                }
                if !l.inputs.iter().all(|&i| natural(i)) {
                    return Err(layer_err(
                        l,
                        "an input was reshaped from an activation; the runtime stores activations HWC",
                    ));
                }
            }
            _ => {
                if !natural(l.inputs[0]) {
                    return Err(layer_err(
                        l,
                        "its input was reshaped from an activation of another shape; the runtime stores activations HWC",
                    ));
                }
            }
        }
    }
    Ok(v)
}

/// Offsets in the arena (from its start) by first fit over the values'
/// lifetimes: a value lives from the layer that writes it to the last
/// that reads it (the model's output to the end). Returns the offsets and
/// the arena's size.
fn plan_arena(model: &Model, values: &[ValuePlan]) -> (Vec<usize>, usize) {
    let n = model.layers.len();
    let mut last = vec![0usize; values.len()];
    for (i, l) in model.layers.iter().enumerate() {
        for &v in &l.inputs {
            last[v] = last[v].max(i);
        }
    }
    last[model.output] = n;
    let mut off = vec![0usize; values.len()];
    // (offset, bytes, value) of the values alive.
    let mut live: Vec<(usize, usize, usize)> = Vec::new();
    let mut size = 0usize;
    let mut place = |v: usize, live: &mut Vec<(usize, usize, usize)>| {
        let need = a8(values[v].bytes.max(1));
        live.sort();
        let mut at = 0usize;
        for &(o, b, _) in live.iter() {
            if o >= at + need {
                break;
            }
            at = at.max(o + a8(b.max(1)));
        }
        live.push((at, values[v].bytes, v));
        off[v] = at;
        size = size.max(at + need);
    };
    place(model.input, &mut live);
    for (i, l) in model.layers.iter().enumerate() {
        live.retain(|&(_, _, v)| last[v] >= i);
        place(l.output, &mut live);
    }
    (off, size)
}

/// The descriptor, reordered weights and small parameters of a layer,
/// and its L1 tile.
fn describe(
    model: &Model,
    values: &[ValuePlan],
    l: &Layer,
) -> Result<(Desc, LayerPlan), DeployError> {
    let mut w = [0u32; LAYER_WORDS];
    let out = &values[l.output];
    let o_shift = out.shift;
    let kind = match &l.kind {
        LayerKind::Conv { .. } => 1,
        LayerKind::Dense { .. } => 2,
        LayerKind::MaxPool { .. } => 3,
        LayerKind::AvgPool { .. } => 4,
        LayerKind::GlobalAvgPool { .. } => 5,
        LayerKind::Add { .. } => 6,
        LayerKind::Concat { .. } => 7,
        LayerKind::Requant { .. } => 8,
        LayerKind::Lut { .. } => 9,
    };
    w[W_KIND] = kind;
    w[W_NIN] = l.inputs.len() as u32;
    for (k, &i) in l.inputs.iter().enumerate() {
        w[W_IN + k] = i as u32;
    }
    w[W_OUT] = l.output as u32;
    w[W_LO] = (l.clamp.0 - o_shift) as u32;
    w[W_HI] = (l.clamp.1 - o_shift) as u32;
    w[W_GROUPS] = 1;
    w[W_MACS] = l.macs as u32;
    w[W_MACS + 1] = (l.macs >> 32) as u32;
    let x = &values[l.inputs[0]];
    let zx = model.values[l.inputs[0]].q.zero_point - x.shift;
    let [c_in, h_in, w_in] = x.chw;
    let [c_out, h_out, w_out] = out.chw;
    let mut small = Vec::new();
    let mut weights = Vec::new();
    let mut per_channel = 0;
    let mut flags = 0u32;
    let set_window = |w: &mut [u32; LAYER_WORDS], win: &super::layers::Window| {
        let v = [
            win.kernel[0],
            win.kernel[1],
            win.stride[0],
            win.stride[1],
            win.pads[0],
            win.pads[1],
            win.pads[2],
            win.pads[3],
        ];
        for (k, x) in v.iter().enumerate() {
            w[W_WIN + k] = *x as u32;
        }
    };
    let fold = |weights: &[i8], bias: &[i32], per: usize| -> Result<Vec<i32>, DeployError> {
        bias.iter()
            .enumerate()
            .map(|(c, &b)| {
                let s: i64 = weights[c * per..(c + 1) * per]
                    .iter()
                    .map(|&x| x as i64)
                    .sum();
                let v = b as i64 - zx as i64 * s;
                i32::try_from(v).map_err(|_| {
                    layer_err(l, format!("channel {c}: the folded bias {v} exceeds int32"))
                })
            })
            .collect()
    };
    let (tile_oh, tile_oc, l1);
    match &l.kind {
        LayerKind::Conv {
            window,
            groups,
            weights: wt,
            bias,
            requant,
        } => {
            set_window(&mut w, window);
            w[W_GROUPS] = *groups as u32;
            let (kh, kw) = (window.kernel[0], window.kernel[1]);
            let cin_g = c_in / groups;
            per_channel = kh * kw * cin_g;
            // [Cout][Cin/g][Kh][Kw] -> [Cout][Kh][Kw][Cin/g]
            weights = vec![0u8; wt.len()];
            for co in 0..c_out {
                for ci in 0..cin_g {
                    for ky in 0..kh {
                        for kx in 0..kw {
                            weights[co * per_channel + (ky * kw + kx) * cin_g + ci] =
                                wt[((co * cin_g + ci) * kh + ky) * kw + kx] as u8;
                        }
                    }
                }
            }
            small.push((W_BOFF, words(&fold(wt, bias, per_channel)?)));
            small.push((W_RQOFF, records(requant)));
            let wp = window.pads[1] + window.pads[3];
            let cost = |oh: usize, oc: usize| {
                2 * (a4(((oh - 1) * window.stride[0] + kh) * (w_in + wp) * c_in)
                    + a4(oc * per_channel)
                    + oc * 12
                    + a4(oh * w_out * oc))
            };
            (tile_oh, tile_oc) = fit2(h_out, c_out, cost).ok_or_else(|| {
                layer_err(
                    l,
                    format!(
                        "one output row of 4 channels needs {} B of L1; {L1_BUDGET} B are planned",
                        cost(1, c_out.min(4))
                    ),
                )
            })?;
            l1 = cost(tile_oh, tile_oc);
        }
        LayerKind::Dense {
            weights: wt,
            bias,
            requant,
        } => {
            let k = wt.len() / c_out;
            per_channel = k;
            // Columns in the input's storage order.
            weights = vec![0u8; wt.len()];
            for o in 0..c_out {
                for i in 0..k {
                    weights[o * k + x.position(i)] = wt[o * k + i] as u8;
                }
            }
            small.push((W_BOFF, words(&fold(wt, bias, k)?)));
            small.push((W_RQOFF, records(requant)));
            let cost = |_: usize, oc: usize| 2 * (a4(k) + a4(oc * k) + oc * 12 + a4(oc));
            (tile_oh, tile_oc) = fit2(1, c_out, cost)
                .ok_or_else(|| layer_err(l, format!("its input of {k} B does not fit L1 twice")))?;
            l1 = cost(1, tile_oc);
        }
        LayerKind::MaxPool { window, requant } => {
            set_window(&mut w, window);
            small.push((W_RQOFF, records(&[*requant])));
            (tile_oh, l1) = pool_tile(window, w_in, w_out, c_in, h_out)
                .ok_or_else(|| layer_err(l, "one row does not fit L1"))?;
            tile_oc = c_out;
        }
        LayerKind::AvgPool {
            window,
            count_include_pad,
            scale,
        } => {
            set_window(&mut w, window);
            if *count_include_pad {
                flags |= F_COUNT_PAD;
            }
            if let PoolScale::Records(r) = scale {
                flags |= F_POOL_RECORDS;
                small.push((W_RQOFF, records(r)));
            }
            (tile_oh, l1) = pool_tile(window, w_in, w_out, c_in, h_out)
                .ok_or_else(|| layer_err(l, "one row does not fit L1"))?;
            tile_oc = c_out;
        }
        LayerKind::GlobalAvgPool { scale } => {
            if let PoolScale::Records(r) = scale {
                flags |= F_POOL_RECORDS;
                small.push((W_RQOFF, records(&[r[h_in * w_in]])));
            }
            let cost = |rows: usize| 2 * (a4(rows * w_in * c_in) + 4 * c_in);
            (tile_oh, l1) = rows_tile(l, h_in, cost)?;
            tile_oc = c_out;
        }
        LayerKind::Add { ra, rb } => {
            small.push((W_RQOFF, records(&[*ra, *rb])));
            let row = w_in * c_in;
            let cost = |oh: usize| 2 * 3 * a4(oh * row);
            (tile_oh, l1) = rows_tile(l, h_out, cost)?;
            tile_oc = c_out;
        }
        LayerKind::Concat { requant } => {
            small.push((W_RQOFF, records(requant)));
            let ins: Vec<usize> = l.inputs.iter().map(|&i| values[i].chw[0]).collect();
            let cost = |oh: usize| {
                2 * (ins.iter().map(|&c| a4(oh * w_out * c)).sum::<usize>()
                    + a4(oh * w_out * c_out))
            };
            (tile_oh, l1) = rows_tile(l, h_out, cost)?;
            tile_oc = c_out;
        }
        LayerKind::Requant { requant } => {
            small.push((W_RQOFF, records(&[*requant])));
            // Rows of the input's storage (a flattened value is one row).
            let [_, h, wd] = x.chw;
            let row = wd * c_in;
            let cost = |oh: usize| 2 * 2 * a4(oh * row);
            (tile_oh, l1) = rows_tile(l, h, cost)?;
            tile_oc = c_out;
        }
        LayerKind::Lut { table } => {
            let base = model.values[l.inputs[0]].q.ty.range().0;
            let lut: Vec<u8> = (0..256)
                .map(|k| {
                    // Stored index k = q' + 128; the native q = k − 128 + shift.
                    let q = k - 128 + x.shift;
                    let t = table
                        .get((q - base) as usize)
                        .copied()
                        .unwrap_or(0)
                        .clamp(l.clamp.0, l.clamp.1);
                    (t - o_shift) as i8 as u8
                })
                .collect();
            small.push((W_LUTOFF, lut));
            let [_, h, wd] = x.chw;
            let row = wd * c_in;
            let cost = |oh: usize| 2 * 2 * a4(oh * row);
            (tile_oh, l1) = rows_tile(l, h, cost)?;
            tile_oc = c_out;
        }
    }
    let _ = h_out;
    w[W_FLAGS] = flags;
    w[W_WBYTES] = weights.len() as u32;
    w[W_TILE_OH] = tile_oh as u32;
    w[W_TILE_OC] = tile_oc as u32;
    w[W_L1] = l1 as u32;
    let plan = LayerPlan {
        tile_oh,
        tile_oc,
        l1_bytes: l1,
        weights_l3: false,
        part_oc: 0,
    };
    Ok((
        Desc {
            words: w,
            weights,
            per_channel,
            c_out,
            small,
        },
        plan,
    ))
}

/// The most rows (up to `rows`) whose tile of `cost(rows)` bytes fits,
/// and its L1 bytes.
fn rows_tile(
    l: &Layer,
    rows: usize,
    cost: impl Fn(usize) -> usize,
) -> Result<(usize, usize), DeployError> {
    let oh = fit1(rows, &cost).ok_or_else(|| layer_err(l, "one row does not fit L1"))?;
    Ok((oh, cost(oh)))
}

/// A pool's tile: the most output rows whose input band and output fit
/// (model.h), and its L1 bytes.
fn pool_tile(
    window: &super::layers::Window,
    w_in: usize,
    w_out: usize,
    c: usize,
    h_out: usize,
) -> Option<(usize, usize)> {
    let cost = |oh: usize| {
        2 * (a4(((oh - 1) * window.stride[0] + window.kernel[0]) * w_in * c) + a4(oh * w_out * c))
    };
    let oh = fit1(h_out, cost)?;
    Some((oh, cost(oh)))
}

/// The most rows (up to `rows`) whose tile fits the budget.
fn fit1(rows: usize, cost: impl Fn(usize) -> usize) -> Option<usize> {
    (1..=rows.max(1)).rev().find(|&r| cost(r) <= L1_BUDGET)
}

/// A tile of output rows × output channels that fits: every channel if
/// one row allows, else the most channels (a multiple of 4 where there
/// are 4 or more, the kernels' quads); then the most rows.
fn fit2(
    rows: usize,
    channels: usize,
    cost: impl Fn(usize, usize) -> usize,
) -> Option<(usize, usize)> {
    let oc = if cost(1, channels) <= L1_BUDGET {
        channels
    } else {
        let step = if channels >= 4 { 4 } else { 1 };
        (1..=channels / step)
            .rev()
            .map(|k| k * step)
            .find(|&c| cost(1, c) <= L1_BUDGET)?
    };
    let oh = (1..=rows.max(1))
        .rev()
        .find(|&r| cost(r, oc) <= L1_BUDGET)?;
    Some((oh, oc))
}

#[cfg(test)]
mod tests {
    use super::super::layers::{QParams, Value, Window};
    use super::*;

    fn value(name: &str, shape: &[usize], zp: i32, ty: QType) -> Value {
        Value {
            name: name.into(),
            shape: shape.to_vec(),
            q: QParams {
                scale: 0.1,
                zero_point: zp,
                ty,
            },
        }
    }

    fn record() -> Requant {
        Requant::from_ratio(0.01).unwrap()
    }

    /// input [1,2,4,4] u8 -> conv 3x3 pad 1 -> [1,3,4,4] -> flatten ->
    /// dense 48 -> 5.
    fn model(dense_out: usize) -> Model {
        let conv_w: Vec<i8> = (0..3 * 2 * 9).map(|i| (i % 7) as i8 - 3).collect();
        let dense_w: Vec<i8> = (0..48 * dense_out).map(|i| (i % 5) as i8 - 2).collect();
        Model {
            values: vec![
                value("x", &[1, 2, 4, 4], 130, QType::U8),
                value("c", &[1, 3, 4, 4], 120, QType::U8),
                value("f", &[1, 48], 120, QType::U8),
                value("y", &[1, dense_out], -3, QType::I8),
            ],
            layers: vec![
                Layer {
                    name: "conv".into(),
                    op: "Conv".into(),
                    inputs: vec![0],
                    output: 1,
                    clamp: (0, 255),
                    kind: LayerKind::Conv {
                        window: Window {
                            kernel: [3, 3],
                            stride: [1, 1],
                            pads: [1, 1, 1, 1],
                        },
                        groups: 1,
                        weights: conv_w,
                        bias: vec![10, -20, 30],
                        requant: vec![record(); 3],
                    },
                    macs: 3 * 16 * 18,
                },
                Layer {
                    name: "flat".into(),
                    op: "Flatten".into(),
                    inputs: vec![1],
                    output: 2,
                    clamp: (0, 255),
                    kind: LayerKind::Requant {
                        requant: Requant::from_ratio(1.0).unwrap(),
                    },
                    macs: 0,
                },
                Layer {
                    name: "fc".into(),
                    op: "Gemm".into(),
                    inputs: vec![2],
                    output: 3,
                    clamp: (-128, 127),
                    kind: LayerKind::Dense {
                        weights: dense_w,
                        bias: vec![5; dense_out],
                        requant: vec![record(); dense_out],
                    },
                    macs: 48 * dense_out as u64,
                },
            ],
            input_name: "x".into(),
            input: 0,
            output: 3,
            output_name: "y".into(),
            output_sigmoid: false,
        }
    }

    fn word(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    fn layer_word(d: &Deployment, layer: usize, w: usize) -> u32 {
        let off = word(&d.l2, 20) as usize;
        word(&d.l2, off + (layer * LAYER_WORDS + w) * 4)
    }

    #[test]
    fn header_tables_and_the_stored_domain() {
        let m = model(5);
        let d = deploy(&m, 400 * 1024, WeightsPlace::Auto).unwrap();
        assert_eq!(word(&d.l2, 0), MAGIC);
        assert_eq!(word(&d.l2, 8), 4);
        assert_eq!(word(&d.l2, 12), 3);
        assert_eq!(word(&d.l2, 44), d.l2.len() as u32);
        assert!(d.l3.is_empty());
        // The input's zero point in the stored domain: 130 - 128.
        let voff = word(&d.l2, 16) as usize;
        assert_eq!(word(&d.l2, voff + 12) as i32, 2);
        // The output is int8: no shift.
        assert_eq!(word(&d.l2, voff + 3 * 24 + 12) as i32, -3);
        // The conv's clamp in the stored domain.
        assert_eq!(layer_word(&d, 0, W_LO) as i32, -128);
        assert_eq!(layer_word(&d, 0, W_HI) as i32, 127);
        // Bias folded: bias - zp' * sum(weights of the channel).
        let LayerKind::Conv { weights, bias, .. } = &m.layers[0].kind else {
            unreachable!()
        };
        let boff = layer_word(&d, 0, W_BOFF) as usize;
        for c in 0..3 {
            let s: i32 = weights[c * 18..(c + 1) * 18]
                .iter()
                .map(|&w| w as i32)
                .sum();
            assert_eq!(word(&d.l2, boff + 4 * c) as i32, bias[c] - 2 * s);
        }
        // Weights [co][ky][kx][ci]: (co 1, ky 2, kx 0, ci 1) came from
        // [co][ci][ky][kx] = (1, 1, 2, 0).
        let woff = layer_word(&d, 0, W_WOFF) as usize;
        assert_eq!(
            d.l2[woff + 18 + (2 * 3) * 2 + 1] as i8,
            weights[18 + 9 + 2 * 3]
        );
    }

    #[test]
    fn hwc_order_round_trips_and_the_flattened_dense_reads_it() {
        let m = model(5);
        let d = deploy(&m, 400 * 1024, WeightsPlace::Auto).unwrap();
        let q: Vec<i32> = (0..32).map(|i| 100 + i).collect();
        let b = d.input_bytes(&q);
        // Logical (ch 1, y 0, x 2) = index 16 + 2 at HWC (0*4 + 2)*2 + 1.
        assert_eq!(b[5] as i8 as i32, 118 - 128);
        // The flattened value keeps the conv output's HWC block.
        assert_eq!(d.values[2].block, [3, 4, 4]);
        // Dense column 17 (logical ch 1, y 0, x 1) sits at storage
        // position (0*4 + 1)*3 + 1 = 4.
        let LayerKind::Dense { weights, .. } = &m.layers[2].kind else {
            unreachable!()
        };
        let woff = layer_word(&d, 2, W_WOFF) as usize;
        assert_eq!(d.l2[woff + 48 + 4] as i8, weights[48 + 17]);
    }

    #[test]
    fn values_alive_together_do_not_overlap() {
        let m = model(5);
        let d = deploy(&m, 400 * 1024, WeightsPlace::Auto).unwrap();
        for l in &m.layers {
            let o = &d.values[l.output];
            for &i in &l.inputs {
                let v = &d.values[i];
                assert!(
                    o.off >= v.off + v.bytes || v.off >= o.off + o.bytes,
                    "{}",
                    l.name
                );
            }
        }
        // The input is dead once the conv ran: the flatten's output may
        // reuse it.
        assert!(
            d.arena_bytes
                < d.values
                    .iter()
                    .map(|v| v.bytes.div_ceil(8) * 8)
                    .sum::<usize>()
        );
    }

    #[test]
    fn weights_beyond_l2_go_to_l3_in_parts() {
        // 48 x 6000 = 288 kB of dense weights against a 200 kB L2 image.
        let m = model(6000);
        let d = deploy(&m, 200 * 1024, WeightsPlace::Auto).unwrap();
        assert!(d.layers[2].weights_l3 && d.layers[0].weights_l3);
        assert_eq!(word(&d.l2, 40) as usize, d.l3.len());
        let stage = word(&d.l2, 36) as usize;
        assert!(stage > 0 && stage <= STAGE_BYTES);
        assert_eq!(d.layers[2].part_oc, stage / 48);
        assert_eq!(layer_word(&d, 2, W_FLAGS) & F_W_L3, F_W_L3);
        // Forced: the same model, small, in L3 too.
        let f = deploy(&model(5), 400 * 1024, WeightsPlace::L3).unwrap();
        assert!(f.layers[0].weights_l3 && !f.l3.is_empty());
    }

    #[test]
    fn too_large_is_refused_with_sizes() {
        // Activations alone beyond the image.
        let e = deploy(&model(5), 256, WeightsPlace::Auto).unwrap_err();
        assert!(e.to_string().contains("holds 256 B"), "{e}");
        // Weights beyond the HyperRAM: 48 x 200 000 = 9.6 MB (on an L2
        // large enough for the 200 000 channels' biases and records).
        let e = deploy(&model(200_000), 64 << 20, WeightsPlace::L3).unwrap_err();
        assert!(e.to_string().contains("HyperRAM"), "{e}");
    }
}
