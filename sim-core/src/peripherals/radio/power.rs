//! The power side of a radio (MESSY's `sensor_*_power`, thesis §4.5.1): the
//! radio's state over time and the mean current it drew over each power
//! sample interval.
//!
//! Unlike the camera and the STM32 (whose states last milliseconds and are
//! read at the sample's instant, as MESSY does), a radio's TX state lasts one
//! frame's airtime (~0.2 ms for a DW1000 ranging frame): an instant reading
//! every 1 ms would miss most transmissions. [`RadioPower::take_mean`]
//! integrates the state currents exactly over the interval since the previous
//! sample instead, so the energy of every frame is counted.

use std::collections::VecDeque;

use crate::units::{Amps, Picos};

/// A radio's states for the power model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RadioPowerState {
    /// Never switched on: the radio draws nothing (a platform that never
    /// uses its radios is electrically the thesis's).
    Off,
    Sleep,
    Idle,
    Rx,
    Tx,
}

/// The current of each state (A).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadioCurrents {
    pub tx: Amps,
    pub rx: Amps,
    pub idle: Amps,
    pub sleep: Amps,
}

impl RadioCurrents {
    pub const ZERO: RadioCurrents = RadioCurrents {
        tx: Amps(0.0),
        rx: Amps(0.0),
        idle: Amps(0.0),
        sleep: Amps(0.0),
    };

    pub fn of(&self, s: RadioPowerState) -> Amps {
        match s {
            RadioPowerState::Off => Amps(0.0),
            RadioPowerState::Sleep => self.sleep,
            RadioPowerState::Idle => self.idle,
            RadioPowerState::Rx => self.rx,
            RadioPowerState::Tx => self.tx,
        }
    }
}

/// The state history of one radio since the last sample.
#[derive(Debug, Clone)]
pub struct RadioPower {
    currents: RadioCurrents,
    /// Commanded states from a time on (the last one before `since` first).
    log: VecDeque<(Picos, RadioPowerState)>,
    /// Transmissions `[from, until)`; TX overrides the commanded state.
    tx: VecDeque<(Picos, Picos)>,
    /// End of the last sample interval.
    since: Picos,
}

impl RadioPower {
    pub fn new(currents: RadioCurrents) -> Self {
        RadioPower {
            currents,
            log: VecDeque::from([(Picos::ZERO, RadioPowerState::Off)]),
            tx: VecDeque::new(),
            since: Picos::ZERO,
        }
    }

    pub fn currents(&self) -> RadioCurrents {
        self.currents
    }

    /// The commanded state is `s` from `t` on.
    pub fn set(&mut self, t: Picos, s: RadioPowerState) {
        // Changes come at non-decreasing times; a change at the same time
        // replaces the previous one.
        while self.log.back().is_some_and(|(at, _)| *at >= t) && self.log.len() > 1 {
            self.log.pop_back();
        }
        if self.log.len() == 1 && self.log[0].0 >= t {
            self.log[0] = (t, s);
        } else {
            self.log.push_back((t, s));
        }
    }

    /// A transmission is on the air during `[from, until)`.
    pub fn transmit(&mut self, from: Picos, until: Picos) {
        self.tx.push_back((from, until));
    }

    /// The state at time `t`.
    pub fn state_at(&self, t: Picos) -> RadioPowerState {
        if self.tx.iter().any(|(a, b)| *a <= t && t < *b) {
            return RadioPowerState::Tx;
        }
        self.log
            .iter()
            .rev()
            .find(|(at, _)| *at <= t)
            .map_or(RadioPowerState::Off, |(_, s)| *s)
    }

    /// The mean current over `[since, until)` (the state's current at
    /// `until` if the interval is empty); the next interval starts at `until`.
    pub fn take_mean(&mut self, until: Picos) -> Amps {
        let from = self.since;
        if until <= from {
            return self.currents.of(self.state_at(until));
        }
        let mut cuts: Vec<Picos> = vec![from, until];
        cuts.extend(self.log.iter().map(|(t, _)| *t));
        cuts.extend(self.tx.iter().flat_map(|(a, b)| [*a, *b]));
        cuts.retain(|t| *t >= from && *t <= until);
        cuts.sort_unstable();
        cuts.dedup();
        let mut charge = 0.0; // A·ps
        for w in cuts.windows(2) {
            let i = self.currents.of(self.state_at(w[0]));
            charge += i.0 * (w[1].0 - w[0].0) as f64;
        }
        self.since = until;
        // Forget what lies wholly before the next interval.
        while self.log.len() > 1 && self.log[1].0 <= until {
            self.log.pop_front();
        }
        self.tx.retain(|(_, b)| *b > until);
        Amps(charge / (until.0 - from.0) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const C: RadioCurrents = RadioCurrents {
        tx: Amps(0.031),
        rx: Amps(0.064),
        idle: Amps(0.012),
        sleep: Amps(0.000_001),
    };

    #[test]
    fn off_until_switched_on() {
        let mut p = RadioPower::new(C);
        assert_eq!(p.take_mean(Picos::from_ms(1)), Amps(0.0));
        assert_eq!(p.state_at(Picos::from_ms(5)), RadioPowerState::Off);
    }

    #[test]
    fn a_short_transmission_is_integrated_not_sampled() {
        let mut p = RadioPower::new(C);
        p.set(Picos::ZERO, RadioPowerState::Idle);
        // 200 µs of TX inside the second millisecond, between two samples.
        p.transmit(Picos::from_us(1_300), Picos::from_us(1_500));
        assert!((p.take_mean(Picos::from_ms(1)).0 - 0.012).abs() < 1e-15);
        let mean = p.take_mean(Picos::from_ms(2)).0;
        let expected = 0.012 * 0.8 + 0.031 * 0.2;
        assert!((mean - expected).abs() < 1e-12, "{mean} vs {expected}");
        assert!((p.take_mean(Picos::from_ms(3)).0 - 0.012).abs() < 1e-15);
    }

    #[test]
    fn transmission_over_rx_returns_to_rx() {
        let mut p = RadioPower::new(C);
        p.set(Picos::ZERO, RadioPowerState::Rx);
        p.transmit(Picos::from_us(500), Picos::from_us(1_500));
        assert_eq!(p.state_at(Picos::from_us(600)), RadioPowerState::Tx);
        assert_eq!(p.state_at(Picos::from_us(1_500)), RadioPowerState::Rx);
        let a = p.take_mean(Picos::from_ms(1)).0;
        let b = p.take_mean(Picos::from_ms(2)).0;
        assert!((a - (0.064 + 0.031) / 2.0).abs() < 1e-12);
        assert!((b - (0.031 + 0.064) / 2.0).abs() < 1e-12);
    }

    #[test]
    fn state_changes_inside_an_interval_are_weighted() {
        let mut p = RadioPower::new(C);
        p.set(Picos::from_us(250), RadioPowerState::Idle);
        p.set(Picos::from_us(500), RadioPowerState::Rx);
        p.set(Picos::from_us(750), RadioPowerState::Sleep);
        let mean = p.take_mean(Picos::from_ms(1)).0;
        let expected = (0.0 + 0.012 + 0.064 + 0.000_001) / 4.0;
        assert!((mean - expected).abs() < 1e-15);
        assert_eq!(p.state_at(Picos::from_ms(9)), RadioPowerState::Sleep);
    }
}
