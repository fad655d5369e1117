//! The flown drone's airframe as both processes must agree on it: the
//! world integrates it, the platform's motor model turns the firmware's
//! PWM into the propeller speeds the world is sent (DESIGN.md §5, §20).
//! The values are the Bitcraze Webots `Crazyflie.proto`'s.

/// Mass of the whole drone (kg; PROTO `physics Physics { mass 0.05 }`).
pub const MASS_KG: f64 = 0.05;
/// Thrust of one propeller: `THRUST_CONSTANT`·ω|ω| N (`thrustConstants 4e-05 0`).
pub const THRUST_CONSTANT: f64 = 4e-5;
