//! The cluster's energy (DESIGN.md §12): active and gated core cycles, L1
//! accesses, DMA bytes and leakage while the cluster is powered, turned
//! into mean power per sampling interval for `power.csv`.
//!
//! # Figures and sources
//!
//! The one published total: GreenWaves gives the GAP8 22.65 GOPS at
//! 4.24 mW/GOP (greenwaves-technologies.com/gap8_gap9, "GAP8 | GAP9"
//! table), i.e. **96 mW** for the cluster at full load, 8 cores at its
//! 175 MHz maximum, which the GAP8 datasheet gives at 1.2 V. We calibrate
//! the model on it: 8 cores active every cycle, one L1 access every second
//! cycle per core (a dense int8 kernel: PULP-NN's inner loop loads one
//! word per MAC pair), no DMA. How the 96 mW splits is our assumption (no
//! public per-block breakdown of the GAP8 was found): 70 % cores, 25 % L1
//! and interconnect, 5 % leakage, the proportions of PULP cluster
//! breakdowns in the literature:
//!
//! | item | value | derivation |
//! |---|---|---|
//! | active core | 48.0 pJ/cycle | 0.70 × 96 mW / (8 × 175 MHz) |
//! | gated core | 0 dynamic; its leakage share, 0.36 mW | DESIGN.md §12: a gated core costs no dynamic energy; 60 % of the leakage is the 8 cores' (assumption) |
//! | L1 access | 34.3 pJ | 0.25 × 96 mW / (8 × 87.5 M accesses/s) |
//! | DMA | 17.1 pJ/byte | one L1 word access (34.3 pJ / 4 B) plus the L2 side's, taken equal (assumption) |
//! | leakage | 4.8 mW | 0.05 × 96 mW while the cluster is powered |
//!
//! Dynamic energies scale with `(vref / 1.2 V)²`, leakage with
//! `vref / 1.2 V` (first-order CMOS scaling).

use crate::units::Picos;

use super::Cluster;
use crate::iss::Memory;

/// The reference point of the figures: GAP8 at 1.2 V, 175 MHz.
pub const REF_VOLTS: f64 = 1.2;
/// Full-load cluster power (GreenWaves: 22.65 GOPS × 4.24 mW/GOP).
pub const FULL_LOAD_W: f64 = 22.65e9 * 4.24e-3 / 1e9;
const REF_HZ: f64 = 175e6;
const CORES_SHARE: f64 = 0.70;
const L1_SHARE: f64 = 0.25;
const LEAK_SHARE: f64 = 0.05;
/// The cores' share of the cluster's leakage (the rest: L1 and the
/// interconnect; assumption).
const CORES_LEAK_SHARE: f64 = 0.60;
/// L1 accesses per core cycle at the calibration load.
const L1_PER_CYCLE: f64 = 0.5;

/// Energy figures at a supply voltage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyModel {
    pub core_active_j: f64,
    /// Leakage of one core (what a gated core costs), W.
    pub core_leak_w: f64,
    pub l1_access_j: f64,
    pub dma_byte_j: f64,
    pub leakage_w: f64,
}

impl EnergyModel {
    /// The figures of the table above, scaled to `vref`.
    pub fn at(vref: f64) -> EnergyModel {
        let dyn_scale = (vref / REF_VOLTS).powi(2);
        let core_active_j = CORES_SHARE * FULL_LOAD_W / (8.0 * REF_HZ);
        let l1_access_j = L1_SHARE * FULL_LOAD_W / (8.0 * REF_HZ * L1_PER_CYCLE);
        let leakage_w = LEAK_SHARE * FULL_LOAD_W * (vref / REF_VOLTS);
        EnergyModel {
            core_active_j: core_active_j * dyn_scale,
            core_leak_w: CORES_LEAK_SHARE * leakage_w / 8.0,
            l1_access_j: l1_access_j * dyn_scale,
            dma_byte_j: 2.0 * l1_access_j / 4.0 * dyn_scale,
            leakage_w,
        }
    }
}

/// The cluster's counters at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Totals {
    pub active_cycles: u64,
    pub gated_cycles: u64,
    pub l1_accesses: u64,
    pub dma_bytes: u64,
    pub powered: Picos,
}

impl Totals {
    pub fn of(cluster: &Cluster, mem: &Memory, t: Picos) -> Totals {
        let mut tot = Totals {
            dma_bytes: cluster.dma_totals().0,
            powered: cluster.powered_time(t),
            ..Totals::default()
        };
        for r in cluster.report_at(mem, t) {
            tot.active_cycles += r.active_cycles;
            tot.gated_cycles += r.gated_cycles;
            tot.l1_accesses += r.l1_accesses;
        }
        tot
    }
}

/// Mean power of each part over an interval, W (the `power.csv` columns):
/// the active cores' dynamic power, the gated cores' leakage, L1, DMA,
/// and the rest of the leakage (shared parts, cores not gated).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClusterPower {
    pub cores_active_w: f64,
    pub cores_gated_w: f64,
    pub l1_w: f64,
    pub dma_w: f64,
    pub leakage_w: f64,
}

impl ClusterPower {
    pub fn total_w(&self) -> f64 {
        self.cores_active_w + self.cores_gated_w + self.l1_w + self.dma_w + self.leakage_w
    }
}

/// Turns counter differences into power, sample after sample.
#[derive(Debug, Clone)]
pub struct Meter {
    model: EnergyModel,
    /// The cluster clock's period, s.
    period_s: f64,
    last: Totals,
    last_t: Picos,
    /// Energy so far, J.
    pub energy_j: f64,
}

impl Meter {
    pub fn new(vref: f64, clock: crate::units::Hertz) -> Meter {
        Meter {
            model: EnergyModel::at(vref),
            period_s: 1.0 / clock.0.max(1) as f64,
            last: Totals::default(),
            last_t: Picos::ZERO,
            energy_j: 0.0,
        }
    }

    /// The mean power since the previous sample, given the totals at `t`.
    pub fn sample(&mut self, now: Totals, t: Picos) -> ClusterPower {
        let dt = (t.0.saturating_sub(self.last_t.0)) as f64 * 1e-12;
        let d = |a: u64, b: u64| a.saturating_sub(b) as f64;
        let m = &self.model;
        let leak = d(now.powered.0, self.last.powered.0) * 1e-12 * m.leakage_w;
        let gated = d(now.gated_cycles, self.last.gated_cycles) * self.period_s * m.core_leak_w;
        let gated = gated.min(leak);
        let e = ClusterPower {
            cores_active_w: d(now.active_cycles, self.last.active_cycles) * m.core_active_j,
            cores_gated_w: gated,
            l1_w: d(now.l1_accesses, self.last.l1_accesses) * m.l1_access_j,
            dma_w: d(now.dma_bytes, self.last.dma_bytes) * m.dma_byte_j,
            leakage_w: leak - gated,
        };
        self.energy_j += e.total_w();
        self.last = now;
        self.last_t = t;
        if dt == 0.0 {
            return ClusterPower::default();
        }
        ClusterPower {
            cores_active_w: e.cores_active_w / dt,
            cores_gated_w: e.cores_gated_w / dt,
            l1_w: e.l1_w / dt,
            dma_w: e.dma_w / dt,
            leakage_w: e.leakage_w / dt,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_load_reproduces_the_published_power() {
        let m = EnergyModel::at(REF_VOLTS);
        let p = 8.0 * REF_HZ * (m.core_active_j + L1_PER_CYCLE * m.l1_access_j) + m.leakage_w;
        assert!((p - FULL_LOAD_W).abs() < 1e-9, "{p}");
        assert!((FULL_LOAD_W - 0.096).abs() < 0.001);
        // Half the voltage: a quarter of the dynamic energy.
        let h = EnergyModel::at(0.6);
        assert!((h.core_active_j * 4.0 - m.core_active_j).abs() < 1e-18);
    }

    #[test]
    fn meter_turns_counts_into_mean_power() {
        let mut meter = Meter::new(REF_VOLTS, crate::units::Hertz(175_000_000));
        let one_ms = Picos::from_ms(1);
        // 1 ms: one core active all along, one gated all along.
        let t = Totals {
            active_cycles: 175_000,
            gated_cycles: 175_000,
            powered: one_ms,
            ..Totals::default()
        };
        let p = meter.sample(t, one_ms);
        let m = EnergyModel::at(REF_VOLTS);
        assert!((p.cores_active_w - 175_000.0 * m.core_active_j / 1e-3).abs() < 1e-12);
        assert!((p.cores_gated_w - m.core_leak_w).abs() < 1e-12);
        // The leakage is counted once: gated share + the rest.
        assert!((p.cores_gated_w + p.leakage_w - m.leakage_w).abs() < 1e-12);
        assert!((meter.energy_j - (p.total_w() * 1e-3)).abs() < 1e-15);
    }
}
