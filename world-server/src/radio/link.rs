//! One frame at one receiver (DESIGN.md §8, §16): flight time and DW1000
//! stamps with the chips' antenna delays and the non-line-of-sight excess,
//! received power with the reception edge (UWB), the P2P RSSI with path
//! loss, shadowing and fading.

use std::sync::Arc;

use protocol::radio::{dw1000_stamp, Picos, Radio};

use super::draw::{self, ReceptionDraws};
use super::fading::rayleigh_db;
use super::geometry::blocked;
use super::profile::{phi, Uwb, NOMINAL_PATH_DELAY_PS};
use super::{dist, log_distance, Channel, Frame, Reception, SPEED_OF_LIGHT_M_S};

/// Drone `drone`'s (TX, RX) antenna delays in ps: 0 without antenna delays
/// ("ideal"), else each path's nominal half of seed 003's 515.7 ns plus a
/// Gaussian of σ `antenna_delay_sd_ps`, drawn from the world's seed.
pub(super) fn antenna_delays(seed: u64, drone: usize, uwb: &Uwb) -> (i64, i64) {
    if !uwb.antenna_delays {
        return (0, 0);
    }
    let (tx, rx) = draw::antenna_delays(seed, drone);
    let path = |z: f64| (NOMINAL_PATH_DELAY_PS + z * uwb.antenna_delay_sd_ps).round() as i64;
    (path(tx), path(rx))
}

/// `t + d` ps, floored at 0.
pub(super) fn shift(t: Picos, d: i64) -> Picos {
    Picos((t.0 as i128 + d as i128).max(0) as u64)
}

impl Channel {
    /// The receptions of one frame at every other drone that carries its
    /// radio and has not stopped.
    pub(super) fn resolve_frame(
        &mut self,
        frame: &Arc<Frame>,
        position: &dyn Fn(usize, Picos) -> [f64; 3],
    ) {
        let uwb = self.cfg.uwb();
        let p_from = position(frame.from, frame.start);
        let airtime = Picos(frame.end.0 - frame.start.0);
        // Every drone's centre, for the bodies in the way (only when NLOS
        // matters: the "ideal" channel asks for nothing more than before).
        let nlos_on = frame.radio == Radio::Uwb && (uwb.nlos_bias_m > 0.0 || uwb.nlos_sd_m > 0.0);
        let centres: Vec<[f64; 3]> = if nlos_on {
            (0..self.drones.len())
                .map(|i| position(i, frame.start))
                .collect()
        } else {
            Vec::new()
        };
        for to in 0..self.drones.len() {
            let q = &self.drones[to];
            if to == frame.from || q.retired || !q.desc.radios.contains(&frame.radio) {
                continue;
            }
            let p_to = position(to, frame.start);
            let distance_m = dist(p_from, p_to);
            let draws = ReceptionDraws::new(self.cfg.seed, frame.from, frame.number, to);
            let tof_s = distance_m / SPEED_OF_LIGHT_M_S;
            let arrival = frame.start + Picos((tof_s * 1e12).round() as u64);
            let mut faded = false;
            let (rssi_dbm, audible, loss_p, rx_stamp) = match frame.radio {
                Radio::Uwb => {
                    let rssi = log_distance(
                        self.cfg.uwb_rssi_1m_dbm,
                        self.cfg.uwb_path_loss_exp,
                        distance_m,
                    );
                    // NLOS: the direct path crosses a box or a third drone,
                    // the chip stamps a later path (DESIGN.md §16).
                    let excess_m = if nlos_on
                        && blocked(
                            &self.obstacles,
                            self.body,
                            &centres,
                            frame.from,
                            to,
                            p_from,
                            p_to,
                        ) {
                        uwb.nlos_bias_m + draws.nlos * uwb.nlos_sd_m
                    } else {
                        0.0
                    };
                    // The ranging noise is the error of the receiver's
                    // leading-edge stamp; the frame's timing on the air (its
                    // end, its overlaps) is the noise-free start + D/c.
                    let noisy_tof_ps = ((tof_s
                        + (draws.range_noise * self.cfg.uwb_noise_m + excess_m)
                            / SPEED_OF_LIGHT_M_S)
                        * 1e12)
                        .round() as i128;
                    let at = (frame.start.0 as i128 + noisy_tof_ps).max(0) as u64;
                    let at = shift(Picos(at), q.rx_delay);
                    let rx_stamp = dw1000_stamp(at, q.clock_ppt, q.phase).0;
                    let audible = if uwb.edge_db > 0.0 {
                        // Received with probability Φ(margin / σ) about the
                        // power at the range limit; heard (interfering) down
                        // to 3 σ below it.
                        let limit = log_distance(
                            self.cfg.uwb_rssi_1m_dbm,
                            self.cfg.uwb_path_loss_exp,
                            self.cfg.uwb_max_range_m,
                        );
                        let margin = (rssi - limit) / uwb.edge_db;
                        faded = draws.edge >= phi(margin);
                        margin >= -3.0
                    } else {
                        distance_m <= self.cfg.uwb_max_range_m
                    };
                    (rssi, audible, self.cfg.uwb_loss, Some(rx_stamp))
                }
                Radio::P2p => {
                    let mut rssi = log_distance(
                        self.cfg.p2p_rssi_1m_dbm,
                        self.cfg.p2p_path_loss_exp,
                        distance_m,
                    ) + draws.rssi_noise * self.cfg.p2p_rssi_noise_db;
                    if let Some(s) = self.cfg.shadowing() {
                        let key = (frame.from.min(to), frame.from.max(to));
                        let (a, b) = if frame.from < to {
                            (p_from, p_to)
                        } else {
                            (p_to, p_from)
                        };
                        let t_s = frame.start.0 as f64 * 1e-12;
                        let next =
                            s.next(self.shadows.get(&key).copied(), t_s, a, b, draws.shadowing);
                        self.shadows.insert(key, next);
                        rssi += next.db;
                    }
                    if self.cfg.p2p_fading == super::fading::FastFading::Rayleigh {
                        rssi += rayleigh_db(draws.fading);
                    }
                    (
                        rssi,
                        rssi >= self.cfg.p2p_sensitivity_dbm,
                        self.cfg.p2p_loss,
                        None,
                    )
                }
            };
            self.live.push(Reception {
                frame: frame.clone(),
                to,
                arrival,
                end: arrival + airtime,
                distance_m,
                rssi_dbm,
                rx_stamp,
                audible,
                faded,
                lost: draws.loss < loss_p,
                done: false,
            });
        }
    }
}
