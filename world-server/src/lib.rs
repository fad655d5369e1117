//! The physics world: the Webots Crazyflie in rapier3d (DESIGN.md §5).
