//! Power buses (§4.5.2): a bus sits at a voltage and collects the currents of
//! the loads attached to it, each through its converter, as MESSY's
//! `power_bus` sums `current_out` of every load converter.

use crate::units::{Amps, Volts};

use super::converter::Converter;

/// A load attached to a bus: its supply voltage and its converter.
#[derive(Debug, Clone, PartialEq)]
pub struct BusLoad {
    /// Name (for logs and CSV headers).
    pub name: String,
    /// The load's own supply voltage.
    pub vref: Volts,
    /// Converter from the bus to the load.
    pub converter: Converter,
}

/// A power bus: loads in a fixed order, so results are deterministic.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PowerBus {
    loads: Vec<BusLoad>,
}

impl PowerBus {
    /// An empty bus.
    pub fn new() -> PowerBus {
        PowerBus::default()
    }

    /// Attaches a load and returns its index (the position of its current
    /// in [`PowerBus::draw`]'s arguments).
    pub fn attach(&mut self, name: &str, vref: Volts, converter: Converter) -> usize {
        self.loads.push(BusLoad {
            name: name.to_string(),
            vref,
            converter,
        });
        self.loads.len() - 1
    }

    /// The attached loads.
    pub fn loads(&self) -> &[BusLoad] {
        &self.loads
    }

    /// Bus-side currents of the loads drawing `load_currents` (same order as
    /// attached) from a bus at `v_bus`, written into `out`; returns their sum.
    pub fn draw(&self, v_bus: Volts, load_currents: &[Amps], out: &mut [Amps]) -> Amps {
        debug_assert_eq!(load_currents.len(), self.loads.len());
        debug_assert_eq!(out.len(), self.loads.len());
        let mut total = 0.0;
        for ((load, i), o) in self.loads.iter().zip(load_currents).zip(out.iter_mut()) {
            *o = load.converter.input_current(*i, load.vref, v_bus);
            total += o.0;
        }
        Amps(total)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_converted_currents() {
        let mut bus = PowerBus::new();
        bus.attach("core", Volts(1.2), Converter::fixed(0.8));
        bus.attach("camera", Volts(3.0), Converter::ideal());
        let mut out = [Amps(0.0); 2];
        // core: 1.2·0.010/(0.8·3.0) = 0.005 A; camera 0.00175 A as is.
        let total = bus.draw(Volts(3.0), &[Amps(0.010), Amps(0.00175)], &mut out);
        assert!((out[0].0 - 0.005).abs() < 1e-15);
        assert_eq!(out[1], Amps(0.00175));
        assert!((total.0 - 0.00675).abs() < 1e-15);
    }
}
