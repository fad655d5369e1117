//! Scenario files and the `cosim` launcher.
