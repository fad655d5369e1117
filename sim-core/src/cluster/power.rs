//! The cluster's energy (placeholder filled below).
