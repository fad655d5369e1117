//! Wire protocol shared by `sim-core` and `world-server` (DESIGN.md §2).
