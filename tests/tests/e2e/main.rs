//! The end-to-end tests, one module per subject, in ONE test binary: each
//! separate `tests/tests/*.rs` file is a binary that links the whole
//! workspace (sim-core, world-server, scenarios, rapier3d), and thirty links
//! cost more than the tests' own compilation. The tests start the real
//! binaries (`cosim`, `sim-core`, `world-server`) over real sockets
//! (`e2e_tests::binary`).
//!
//! Adding a test: a new file `tests/tests/e2e/<subject>.rs` and its line
//! `mod <subject>;` below (kept in alphabetical order). Run one subject with
//! `cargo test -p e2e-tests --test e2e <subject>::`. tests/README.md says
//! more.

// Shared helpers of several modules.
mod multi;
mod vision_util;

mod aideck_power;
mod busy_poll;
mod cosim_keys;
mod cosim_multi;
mod cosim_run;
mod cosim_shm;
mod cosim_signals;
mod cosim_tcp;
mod cosim_world_cmd;
mod crtp_link;
mod crtp_pacing;
mod example_world_python;
mod explore_e2e;
mod foxglove_mcap;
mod mcap_time_base;
mod nn_dataset;
mod nn_eval;
mod nn_import;
mod nn_race;
mod peer_killed;
mod platform_bad_input;
mod platform_cli;
mod platform_race;
mod protocol_foreign_world;
mod radar_e2e;
mod radio_ping;
mod series_forms;
mod stm32_motion;
mod swarm_flight;
mod swarm_table;
mod sweep_shards;
mod timestep_rules;
mod vision_detector;
mod vision_race;
mod world_any_client;
mod world_multi;
mod world_radio;
mod world_server;
