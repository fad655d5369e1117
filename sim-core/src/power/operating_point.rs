//! The battery's operating point under a load that depends on its voltage
//! (`battery_load = "sag"`, DESIGN.md §16).
//!
//! The terminal voltage is `V = v_oc − R·I` and the load's current is a
//! function of the voltage it gets, `I(V)`: constant for a linear
//! regulator or the empirical motor model (current from the rotor speed),
//! `P / V` for a switching converter or the D'Andrea and Stolaroff motor
//! models (power from the flight state). Evaluating `I` at the previous
//! sample's voltage, as the thesis's network does with its milliohm
//! resistances, diverges once `R·I` is a sizeable part of `v_oc`: with the
//! Crazyflie's 0.16–0.51 Ω a constant-power load near empty drove the
//! explicit iteration to −3,658 V. Here `V` is the root of
//! `f(V) = V − v_oc + R·I(V)` on the upper branch, the stable one a real
//! battery settles on.
//!
//! A constant-power load `P` has a root only while `P ≤ v_oc² / (4R)`,
//! the battery's maximum power (delivered at `V = v_oc / 2`). Beyond it the
//! battery cannot deliver what the load asks: it gives its maximum power at
//! `v_oc / 2`, the load is *starved* (the motors then get less than they
//! ask and their speed, capped by the bus voltage, falls: the drone sinks,
//! as a Crazyflie browns out at the end of its battery).

use super::Ohms;
use crate::units::{Amps, Volts};

/// Bisection steps: the bracket is at most `v_oc` wide (≈ 4.2 V), so 48
/// halvings leave it under 2e-14 V, at f64's resolution of the voltage.
const BISECTIONS: u32 = 48;

/// Where the battery settles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// The terminal voltage.
    pub v: Volts,
    /// The battery's current: `I(v)`, or its maximum `v_oc / 2R` when
    /// starved.
    pub i: Amps,
    /// The load asked for more power than the battery can deliver.
    pub starved: bool,
}

/// Solves `V = v_oc − r·i(V)` for the upper root; `i` must be non-negative
/// and must not increase with `V` (true of constant-current and
/// constant-power loads and their sums).
pub fn solve(v_oc: Volts, r: Ohms, i: impl Fn(Volts) -> Amps) -> OperatingPoint {
    let f = |v: f64| v - v_oc.0 + r.0 * i(Volts(v)).0;
    let hi = v_oc.0;
    if v_oc.0 <= 0.0 || r.0 <= 0.0 || f(hi) <= 0.0 {
        // No resistance or no load: the open-circuit voltage.
        return OperatingPoint {
            v: Volts(hi - r.0 * i(v_oc).0),
            i: i(v_oc),
            starved: false,
        };
    }
    let mid = hi / 2.0;
    // f(hi) > 0. The upper root lies in [mid, hi] when f(mid) ≤ 0 (always
    // so for a load of constant power the battery can deliver); a
    // constant-current load heavier than v_oc / 2R has its root below mid.
    let lo = hi * 1e-3;
    let bracket = if f(mid) <= 0.0 {
        Some((mid, hi))
    } else if f(lo) <= 0.0 {
        Some((lo, mid))
    } else {
        None
    };
    match bracket {
        Some((mut a, mut b)) => {
            // Invariant: f(a) ≤ 0 < f(b).
            for _ in 0..BISECTIONS {
                let m = 0.5 * (a + b);
                if f(m) <= 0.0 {
                    a = m;
                } else {
                    b = m;
                }
            }
            OperatingPoint {
                v: Volts(a),
                i: i(Volts(a)),
                starved: false,
            }
        }
        None => OperatingPoint {
            v: Volts(mid),
            i: Amps(mid / r.0),
            starved: true,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn a_constant_current_sags_by_i_r() {
        let p = solve(Volts(4.0), Ohms(0.2), |_| Amps(3.0));
        assert!(close(p.v.0, 4.0 - 0.6), "{p:?}");
        assert!(!p.starved);
    }

    #[test]
    fn a_constant_power_settles_on_the_quadratics_upper_root() {
        // V = (v_oc + sqrt(v_oc² − 4RP)) / 2 with P = 8 W, R = 0.3 Ω.
        let (v_oc, r, w) = (3.7, 0.3, 8.0);
        let p = solve(Volts(v_oc), Ohms(r), |v| Amps(w / v.0));
        let expected = (v_oc + (v_oc * v_oc - 4.0 * r * w).sqrt()) / 2.0;
        assert!(close(p.v.0, expected), "{p:?} vs {expected}");
        assert!(close(p.v.0 * p.i.0, w));
    }

    #[test]
    fn beyond_the_maximum_power_the_load_is_starved_at_half_the_voltage() {
        // v_oc² / 4R = 2.0 W at 2 V, 0.5 Ω: an 8 W hover cannot be served.
        let p = solve(Volts(2.0), Ohms(0.5), |v| Amps(8.0 / v.0));
        assert!(p.starved);
        assert!(close(p.v.0, 1.0) && close(p.i.0, 2.0), "{p:?}");
    }

    #[test]
    fn a_heavy_constant_current_has_its_root_below_half_the_voltage() {
        let p = solve(Volts(3.0), Ohms(0.5), |_| Amps(4.0));
        assert!(close(p.v.0, 1.0), "{p:?}");
        assert!(!p.starved);
    }

    #[test]
    fn no_load_or_no_resistance_is_the_open_circuit_voltage() {
        assert_eq!(solve(Volts(4.1), Ohms(0.3), |_| Amps(0.0)).v, Volts(4.1));
        assert!(close(solve(Volts(4.1), Ohms(0.0), |_| Amps(2.0)).v.0, 4.1));
    }
}
