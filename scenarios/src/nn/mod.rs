//! The int8 gate network on the GAP8 (DESIGN.md §13, docs/NN.md): the
//! machine that runs `nn_eval.elf` frame after frame ([`machine`]) and
//! `cosim nn eval` over a labelled dataset ([`eval`]); a user's int8
//! ONNX network imported and run by the host's integer reference
//! ([`onnx`], DESIGN.md §18).

pub mod eval;
pub mod machine;
pub mod onnx;
