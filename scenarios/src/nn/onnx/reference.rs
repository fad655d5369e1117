//! The integer reference executor: the arithmetic the deck's cluster
//! kernels compute, on the host (not a run on the ISS). Integers in, the
//! layer list's int32 accumulations and requantization records, integers
//! out; float only at the edges (the model's own QuantizeLinear of the
//! input, the last DequantizeLinear, an output Sigmoid).

use super::layers::{LayerKind, Model, PoolScale, QParams, Window};
use super::requant::{round_clamp, Requant};

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("the input has {got} values; the model's input {name:?} has shape {shape:?} ({want})")]
    InputSize {
        name: String,
        shape: Vec<usize>,
        want: usize,
        got: usize,
    },
}

/// ONNX QuantizeLinear: round_half_even(x / scale) + zero point, saturated.
pub fn quantize(x: &[f32], q: QParams) -> Vec<i32> {
    let (lo, hi) = q.ty.range();
    x.iter()
        .map(|&v| round_clamp((v / q.scale) as f64 + q.zero_point as f64, lo, hi))
        .collect()
}

/// ONNX DequantizeLinear: (q − zero point) · scale.
pub fn dequantize(q: &[i32], p: QParams) -> Vec<f32> {
    q.iter()
        .map(|&v| (v - p.zero_point) as f32 * p.scale)
        .collect()
}

/// One inference on float input: quantize, the integer layers, dequantize
/// (and the output Sigmoid, if the graph ends with one).
pub fn run(model: &Model, input: &[f32]) -> Result<Vec<f32>, RunError> {
    let q = quantize_input(model, input)?;
    Ok(output_floats(model, &run_int(model, q)))
}

/// The model's own QuantizeLinear of a float input.
pub fn quantize_input(model: &Model, input: &[f32]) -> Result<Vec<i32>, RunError> {
    let iv = &model.values[model.input];
    let want: usize = iv.shape.iter().product();
    if input.len() != want {
        return Err(RunError::InputSize {
            name: model.input_name.clone(),
            shape: iv.shape.clone(),
            want,
            got: input.len(),
        });
    }
    Ok(quantize(input, iv.q))
}

/// The output's integers as the graph returns them: the last
/// DequantizeLinear, then the Sigmoid if the graph ends with one.
pub fn output_floats(model: &Model, q: &[i32]) -> Vec<f32> {
    let ov = &model.values[model.output];
    let mut y = dequantize(q, ov.q);
    if model.output_sigmoid {
        for v in &mut y {
            *v = 1.0 / (1.0 + (-*v).exp());
        }
    }
    y
}

/// The layers on the quantized input; returns the output value's integers.
pub fn run_int(model: &Model, input: Vec<i32>) -> Vec<i32> {
    let mut vals: Vec<Option<Vec<i32>>> = vec![None; model.values.len()];
    vals[model.input] = Some(input);
    for l in &model.layers {
        let out_v = &model.values[l.output];
        let ins: Vec<(&[i32], &super::layers::Value)> = l
            .inputs
            .iter()
            .map(|&i| {
                (
                    vals[i].as_deref().expect("layers are in topological order"),
                    &model.values[i],
                )
            })
            .collect();
        let (x, xv) = ins[0];
        let zx = xv.q.zero_point;
        let zy = out_v.q.zero_point as i64;
        let (lo, hi) = l.clamp;
        let fin = |acc: i64| (zy + acc).clamp(lo as i64, hi as i64) as i32;
        let y: Vec<i32> = match &l.kind {
            LayerKind::Conv {
                window,
                groups,
                weights,
                bias,
                requant,
            } => conv(
                x,
                zx,
                &xv.shape,
                &out_v.shape,
                window,
                *groups,
                weights,
                bias,
                requant,
                fin,
            ),
            LayerKind::Dense {
                weights,
                bias,
                requant,
            } => {
                let k = x.len();
                bias.iter()
                    .enumerate()
                    .map(|(o, &b)| {
                        let row = &weights[o * k..(o + 1) * k];
                        let acc: i64 = b as i64
                            + row
                                .iter()
                                .zip(x)
                                .map(|(&w, &v)| w as i64 * (v - zx) as i64)
                                .sum::<i64>();
                        fin(requant[o].apply(acc))
                    })
                    .collect()
            }
            LayerKind::MaxPool { window, requant } => {
                pool(x, &xv.shape, &out_v.shape, window, |vals, _| {
                    let m = vals
                        .iter()
                        .copied()
                        .max()
                        .expect("a window holds one input at least");
                    fin(requant.apply((m - zx) as i64))
                })
            }
            LayerKind::AvgPool {
                window,
                count_include_pad,
                scale,
            } => pool(x, &xv.shape, &out_v.shape, window, |vals, full| {
                let sum: i64 = vals.iter().map(|&v| (v - zx) as i64).sum();
                let count = if *count_include_pad { full } else { vals.len() };
                fin(pool_mean(sum, count, scale))
            }),
            LayerKind::GlobalAvgPool { scale } => {
                let hw = xv.shape[2] * xv.shape[3];
                x.chunks(hw)
                    .map(|plane| {
                        fin(pool_mean(
                            plane.iter().map(|&v| (v - zx) as i64).sum(),
                            hw,
                            scale,
                        ))
                    })
                    .collect()
            }
            LayerKind::Add { ra, rb } => {
                let (b, bv) = ins[1];
                let zb = bv.q.zero_point;
                let shift = ra.shift;
                x.iter()
                    .zip(b)
                    .map(|(&a, &b)| {
                        let acc = (a - zx) as i64 * ra.multiplier as i64
                            + (b - zb) as i64 * rb.multiplier as i64;
                        fin(round_shift(acc, shift))
                    })
                    .collect()
            }
            LayerKind::Concat { requant } => {
                // Channel-major: each input's planes in turn.
                let mut y = Vec::with_capacity(out_v.shape.iter().product());
                for ((v, vv), r) in ins.iter().zip(requant) {
                    let z = vv.q.zero_point;
                    y.extend(v.iter().map(|&q| fin(r.apply((q - z) as i64))));
                }
                y
            }
            LayerKind::Requant { requant } => x
                .iter()
                .map(|&q| fin(requant.apply((q - zx) as i64)))
                .collect(),
            LayerKind::Lut { table } => {
                let base = xv.q.ty.range().0;
                x.iter()
                    .map(|&q| table[(q - base) as usize].clamp(lo, hi))
                    .collect()
            }
        };
        vals[l.output] = Some(y);
    }
    vals[model.output].take().expect("the output is computed")
}

/// An average pool's sum over `count` inputs in the output's scale.
fn pool_mean(sum: i64, count: usize, scale: &PoolScale) -> i64 {
    match scale {
        PoolScale::Divide => div_round_half_even(sum, count as i64),
        PoolScale::Records(r) => r[count].apply(sum),
    }
}

/// `a / b` rounded half to even, in integers (b > 0).
pub fn div_round_half_even(a: i64, b: i64) -> i64 {
    let (q, r) = (a.div_euclid(b), a.rem_euclid(b));
    match (2 * r).cmp(&b) {
        std::cmp::Ordering::Greater => q + 1,
        std::cmp::Ordering::Equal if q % 2 != 0 => q + 1,
        _ => q,
    }
}

/// `(acc + 2^(shift−1)) >> shift`, the records' rounding.
fn round_shift(acc: i64, shift: u32) -> i64 {
    Requant {
        multiplier: 1,
        shift,
    }
    .apply(acc)
}

#[allow(clippy::too_many_arguments)]
fn conv(
    x: &[i32],
    zx: i32,
    in_shape: &[usize],
    out_shape: &[usize],
    w: &Window,
    groups: usize,
    weights: &[i8],
    bias: &[i32],
    requant: &[Requant],
    fin: impl Fn(i64) -> i32,
) -> Vec<i32> {
    let (cin, h, wd) = (in_shape[1], in_shape[2], in_shape[3]);
    let (cout, ho, wo) = (out_shape[1], out_shape[2], out_shape[3]);
    let (kh, kw) = (w.kernel[0], w.kernel[1]);
    let cin_g = cin / groups;
    let cout_g = cout / groups;
    let mut y = vec![0; cout * ho * wo];
    for co in 0..cout {
        let g = co / cout_g;
        let wc = &weights[co * cin_g * kh * kw..(co + 1) * cin_g * kh * kw];
        for oy in 0..ho {
            for ox in 0..wo {
                let mut acc = bias[co] as i64;
                for ci in 0..cin_g {
                    let plane = &x[(g * cin_g + ci) * h * wd..][..h * wd];
                    for ky in 0..kh {
                        // Padding is the zero point: it adds nothing.
                        let Some(iy) = (oy * w.stride[0] + ky)
                            .checked_sub(w.pads[0])
                            .filter(|&v| v < h)
                        else {
                            continue;
                        };
                        for kx in 0..kw {
                            let Some(ix) = (ox * w.stride[1] + kx)
                                .checked_sub(w.pads[1])
                                .filter(|&v| v < wd)
                            else {
                                continue;
                            };
                            acc += (plane[iy * wd + ix] - zx) as i64
                                * wc[(ci * kh + ky) * kw + kx] as i64;
                        }
                    }
                }
                y[(co * ho + oy) * wo + ox] = fin(requant[co].apply(acc));
            }
        }
    }
    y
}

/// A pooling window over every channel: `f(inputs inside, window size)`.
fn pool(
    x: &[i32],
    in_shape: &[usize],
    out_shape: &[usize],
    w: &Window,
    f: impl Fn(&[i32], usize) -> i32,
) -> Vec<i32> {
    let (c, h, wd) = (in_shape[1], in_shape[2], in_shape[3]);
    let (ho, wo) = (out_shape[2], out_shape[3]);
    let mut y = Vec::with_capacity(c * ho * wo);
    let mut inside = Vec::with_capacity(w.kernel[0] * w.kernel[1]);
    for ch in 0..c {
        let plane = &x[ch * h * wd..][..h * wd];
        for oy in 0..ho {
            for ox in 0..wo {
                inside.clear();
                for ky in 0..w.kernel[0] {
                    let Some(iy) = (oy * w.stride[0] + ky)
                        .checked_sub(w.pads[0])
                        .filter(|&v| v < h)
                    else {
                        continue;
                    };
                    for kx in 0..w.kernel[1] {
                        if let Some(ix) = (ox * w.stride[1] + kx)
                            .checked_sub(w.pads[1])
                            .filter(|&v| v < wd)
                        {
                            inside.push(plane[iy * wd + ix]);
                        }
                    }
                }
                y.push(f(&inside, w.kernel[0] * w.kernel[1]));
            }
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::div_round_half_even as d;

    #[test]
    fn pool_division_rounds_half_to_even() {
        assert_eq!(d(3, 6), 0); // 0.5
        assert_eq!(d(9, 6), 2); // 1.5
        assert_eq!(d(15, 6), 2); // 2.5
        assert_eq!(d(-3, 6), 0); // -0.5
        assert_eq!(d(-9, 6), -2); // -1.5
        assert_eq!(d(-15, 6), -2); // -2.5
        assert_eq!(d(4, 6), 1);
        assert_eq!(d(-4, 6), -1);
        assert_eq!(d(2, 6), 0);
        assert_eq!(d(-2, 6), 0);
        assert_eq!(d(17, 9), 2);
    }
}
