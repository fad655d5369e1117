//! The cluster control unit (docs/CLUSTER.md "CTRL"): power, the cores'
//! boot address and fetch enable, the FC mailbox (a task written there
//! raises core 0's mailbox event) and the cluster-to-FC event counter
//! (gap_sdk's cluster control unit and FC event line, with our layout).

use super::event_unit::EVENT_MAILBOX;
use super::{CoreState, Shared};
use crate::units::Picos;

pub const POWER: u32 = 0x00;
pub const NB_CORES: u32 = 0x04;
pub const FREQ_HZ: u32 = 0x08;
pub const BOOT_ADDR: u32 = 0x0C;
pub const FETCH_EN: u32 = 0x10;
pub const RUNNING: u32 = 0x14;
pub const FC_EVENT: u32 = 0x18;
pub const HALT: u32 = 0x1C;
pub const MAILBOX: u32 = 0x20;
pub const FC_IRQ: u32 = 0x24;

/// The unit's own registers.
#[derive(Debug, Clone, Default)]
pub struct Ctrl {
    pub boot_addr: u32,
    pub fc_events: u32,
    /// `FC_IRQ`: a pending FC event drives the FC's external interrupt.
    pub fc_irq: bool,
    pub mailbox: u32,
    pub freq_hz: u32,
    /// Powered time before the current power-on, and when it began
    /// (`Some` exactly while the cluster is on).
    pub powered_before: Picos,
    pub powered_since: Option<Picos>,
}

impl Ctrl {
    /// Whether the cluster is powered (CTRL.POWER reads 1).
    pub fn is_on(&self) -> bool {
        self.powered_since.is_some()
    }
}

/// Who accesses the unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Who {
    Fc,
    Core(usize),
}

impl Shared {
    /// The cluster's level on the FC's external interrupt line: FC events
    /// pending and `FC_IRQ` set (ORed with the platform's radios by
    /// [`Cluster::run_until`](super::Cluster::run_until)).
    pub fn fc_irq_level(&self) -> bool {
        self.ctrl.fc_irq && self.ctrl.fc_events != 0
    }

    /// Bit i: core i started and not halted (asleep counts as running).
    pub fn running_mask(&self) -> u32 {
        (0..self.n)
            .filter(|&i| matches!(self.state[i], CoreState::Running | CoreState::Gated))
            .fold(0, |m, i| m | 1 << i)
    }

    /// A CTRL read; `None`: access fault.
    pub fn ctrl_read(&mut self, who: Who, off: u32) -> Option<u32> {
        let c = &mut self.ctrl;
        Some(match (off, who) {
            (POWER, _) => c.is_on() as u32,
            (NB_CORES, _) => self.n as u32,
            (FREQ_HZ, _) => c.freq_hz,
            (BOOT_ADDR, _) => c.boot_addr,
            (RUNNING, _) => self.running_mask(),
            (FC_EVENT, Who::Fc) => {
                let level = self.fc_irq_level();
                let v = std::mem::take(&mut self.ctrl.fc_events);
                // The line drops: the FC's run stops so that it follows.
                self.fc_irq_changed |= level;
                v
            }
            (MAILBOX, _) => c.mailbox,
            (FC_IRQ, _) => c.fc_irq as u32,
            _ => return None,
        })
    }

    /// A CTRL write at time `t`; `false`: access fault.
    pub fn ctrl_write(&mut self, who: Who, off: u32, v: u32, t: Picos) -> bool {
        match (off, who) {
            (POWER, Who::Fc) => {
                let on = v & 1 != 0;
                if self.ctrl.is_on() && !on {
                    for i in 0..self.n {
                        self.halt(i);
                    }
                }
                match (self.ctrl.powered_since, on) {
                    (None, true) => self.ctrl.powered_since = Some(t),
                    (Some(since), false) => {
                        self.ctrl.powered_before += t - since;
                        self.ctrl.powered_since = None;
                    }
                    _ => {}
                }
            }
            (BOOT_ADDR, _) => self.ctrl.boot_addr = v & !1,
            (FETCH_EN, _) if self.ctrl.is_on() => {
                for i in 0..self.n {
                    if v & (1 << i) != 0 {
                        self.eu.reset_core(i);
                        self.state[i] = CoreState::Running;
                        self.time[i] = t;
                        self.start[i] = Some(self.ctrl.boot_addr);
                    }
                }
            }
            (FC_EVENT, Who::Core(_)) => self.ctrl.fc_events += 1,
            (FC_IRQ, Who::Fc) => {
                let level = self.fc_irq_level();
                self.ctrl.fc_irq = v & 1 != 0;
                self.fc_irq_changed |= level != self.fc_irq_level();
            }
            (HALT, Who::Core(i)) => {
                self.halt(i);
                self.stop = true;
            }
            (MAILBOX, who) => {
                self.ctrl.mailbox = v;
                // A task for core 0: wake it if it sleeps on the event.
                if who == Who::Fc && v != 0 && self.ctrl.is_on() {
                    self.eu.trigger(EVENT_MAILBOX, 1, t);
                }
            }
            _ => return false,
        }
        true
    }

    fn halt(&mut self, i: usize) {
        if self.state[i] != CoreState::Off {
            self.state[i] = CoreState::Halted;
        }
        self.eu.reset_core(i);
        self.start[i] = None;
    }
}
