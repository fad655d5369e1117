//! The Crazyflie's motor drivers as a speed limit (DESIGN.md §16): its
//! brushed coreless motors are switched by one MOSFET each straight from the
//! battery (the motor bus, η = 1, [`super`]); at 100 % PWM a brushed DC
//! motor with its propeller turns at a speed proportional to the voltage it
//! gets (back-EMF = Kv·ω), so a sagging battery lowers the highest speed the
//! PID can get.
//!
//! The proportionality is the thesis's own measurement: Table 3.2's full
//! throttle is 23 882 RPM, 70.24 rad/s in the simulator's units (RPM / 340,
//! [`super::models::EmpiricalModel`]), drawing Eq. 3.1's 4.290 A, at which
//! Eq. 3.2 puts the battery at 4.03495 − 0.16302 · 4.290 = 3.336 V: 21.06
//! rad/s per volt. The simulator's hover speed is 55.37 rad/s (PROTO mass
//! 0.05 kg, thrust constant 4e-5), so the drone holds its height while the
//! motors get 55.37 / 21.06 = 2.63 V, and its full-battery thrust-to-weight
//! ratio is (87.4 / 55.37)² ≈ 2.5 at 4.15 V — Bitcraze's Crazyflie 2.1 lifts
//! 27 g with 60 g of full thrust (2.2).

use crate::units::Volts;

use super::models::EmpiricalModel;

/// Highest motor speed per volt on the motor bus, rad/s per V (see the
/// module documentation).
pub fn rad_s_per_volt() -> f64 {
    let m = EmpiricalModel::default();
    let full = m.max_mean_omega;
    full / m.voltage_at(m.current_at(full)).0
}

/// The highest speed (rad/s) the motors reach on a bus at `v`; never
/// negative.
pub fn speed_cap(v: Volts) -> f64 {
    (rad_s_per_volt() * v.0).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_3_2_full_throttle_at_eq_3_2_voltage() {
        // I = 0.00100706·70.2412² − 0.0143·70.2412 + 0.32618 = 4.29035 A
        // V = 4.03495 − 0.16302·4.29035 = 3.33553 V; 70.2412 / 3.33553
        let k = rad_s_per_volt();
        assert!((k - 21.0585).abs() < 1e-3, "{k}");
        assert!((speed_cap(Volts(3.33553)) - 23_882.0 / 340.0).abs() < 1e-3);
        assert_eq!(speed_cap(Volts(-1.0)), 0.0);
    }

    #[test]
    fn hover_needs_about_2_6_volts() {
        // The simulator's hover speed: sqrt(0.05·9.81 / (4·4e-5)).
        let hover = (0.05f64 * 9.81 / (4.0 * 4e-5)).sqrt();
        let v = hover / rad_s_per_volt();
        assert!((v - 2.629).abs() < 0.01, "{v}");
        assert!(speed_cap(Volts(4.15)) > hover * 1.5);
    }
}
