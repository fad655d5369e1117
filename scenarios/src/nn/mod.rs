//! The int8 gate network on the GAP8 (DESIGN.md §13, docs/NN.md): the
//! machine that runs `nn_eval.elf` frame after frame ([`machine`]) and
//! `cosim nn eval` over a labelled dataset ([`eval`]).

pub mod eval;
pub mod machine;
