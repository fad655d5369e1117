//! The int8 gate network on the GAP8 (DESIGN.md §13, docs/NN.md): the
//! machine that runs `nn_eval.elf` frame after frame ([`machine`]) and
//! `cosim nn eval` over a labelled dataset ([`eval`]); a user's int8
//! ONNX network imported ([`onnx`], DESIGN.md §18) and run on the GAP8 by
//! the generic runtime firmware ([`deck`]). Both programs run on
//! [`gap8`]: FC + cluster + HyperRAM in this process.

pub mod deck;
pub mod eval;
pub mod gap8;
pub mod machine;
pub mod onnx;
pub mod profile;
