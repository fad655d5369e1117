//! The handlers of `cosim`'s subcommands, one file per family; the
//! command line itself (clap) is in `main.rs`.

pub(crate) mod bench;
pub(crate) mod keys;
pub(crate) mod nn;
pub(crate) mod nn_deck;
pub(crate) mod run;
pub(crate) mod sweep;
pub(crate) mod trace;
