//! Port 6, localization (the firmware's `crtp_localization_service.c`,
//! cflib's `localization.py`): the external positions a motion-capture
//! system sends, fused into the estimate (see
//! [`crate::peripherals::stm32::estimator`]'s note on external positions).
//!
//! | channel | packet | what |
//! |---|---|---|
//! | 0 | `[x, y, z]` (f32, m) | cflib's `send_extpos` |
//! | 1 | `[8, x, y, z, qx, qy, qz, qw]` (f32) | `send_extpose` (EXT_POSE): the position; the attitude is the IMU's here |
//! | 1 | `[9, {id, x, y, z (i16 mm), quat (u32)}…]` | EXT_POSE_PACKED: the items with this drone's id |
//! | 2 | `[{id, x, y, z (i16 mm)}…]` | EXT_POSITION_PACKED (a broadcast to a swarm): the items with this drone's id |
//!
//! Other generic types (LPS, Lighthouse, emergency stop, …) are not served.

use super::packet::f32_at;

pub const CHAN_POSITION: u8 = 0;
pub const CHAN_GENERIC: u8 = 1;
pub const CHAN_POSITION_PACKED: u8 = 2;
/// Generic types (the firmware's `locsrv_t`, cflib's constants).
const EXT_POSE: u8 = 8;
const EXT_POSE_PACKED: u8 = 9;
/// Packed items' sizes: id (1) + three int16 (6), + a compressed
/// quaternion (4) for poses.
const POSITION_ITEM: usize = 7;
const POSE_ITEM: usize = 11;

/// The id a packed item must carry to be this drone's: the firmware takes
/// the low byte of its radio address (`configblockGetRadioAddress()`),
/// 0xE7 for the Crazyflie's default address 0xE7E7E7E7E7.
pub const OWN_ID: u8 = 0xE7;

/// The firmware's default `locSrv.extPosStdDev` (m): the standard deviation
/// an external position is fused with.
pub const DEFAULT_EXT_POS_STD: f64 = 0.01;

/// The positions (x, y, z; m) a localization packet gives this drone, or
/// `None` if it is not a (well-formed, finite) external position.
pub fn positions(channel: u8, d: &[u8]) -> Option<Vec<[f64; 3]>> {
    let xyz = |d: &[u8]| -> Option<[f64; 3]> {
        let p = [f32_at(d, 0)?, f32_at(d, 4)?, f32_at(d, 8)?];
        p.iter().all(|v| v.is_finite()).then_some(p)
    };
    let packed = |d: &[u8], size: usize| -> Vec<[f64; 3]> {
        d.chunks_exact(size)
            .filter(|item| item[0] == OWN_ID)
            .map(|item| {
                let mm = |i: usize| f64::from(i16::from_le_bytes([item[i], item[i + 1]])) / 1000.0;
                [mm(1), mm(3), mm(5)]
            })
            .collect()
    };
    match (channel, d.first()) {
        (CHAN_POSITION, _) => xyz(d).map(|p| vec![p]),
        (CHAN_GENERIC, Some(&EXT_POSE)) => xyz(&d[1..]).map(|p| vec![p]),
        (CHAN_GENERIC, Some(&EXT_POSE_PACKED)) => Some(packed(&d[1..], POSE_ITEM)),
        (CHAN_POSITION_PACKED, _) => Some(packed(d, POSITION_ITEM)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f32s(v: &[f32]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    #[test]
    fn the_four_layouts_give_positions() {
        assert_eq!(
            positions(0, &f32s(&[1.5, -2.0, 0.25])),
            Some(vec![[1.5, -2.0, 0.25]])
        );
        let mut pose = vec![EXT_POSE];
        pose.extend(f32s(&[1.0, 2.0, 0.5, 0.0, 0.0, 0.0, 1.0]));
        assert_eq!(positions(1, &pose), Some(vec![[1.0, 2.0, 0.5]]));
        // Two packed items, one of them ours.
        let item = |id: u8, mm: [i16; 3]| {
            let mut v = vec![id];
            mm.iter().for_each(|c| v.extend(c.to_le_bytes()));
            v
        };
        let d = [item(0x01, [1, 2, 3]), item(OWN_ID, [1500, -250, 300])].concat();
        assert_eq!(positions(2, &d), Some(vec![[1.5, -0.25, 0.3]]));
        let mut d = vec![EXT_POSE_PACKED];
        d.extend(item(OWN_ID, [100, 200, 300]));
        d.extend([0; 4]);
        assert_eq!(positions(1, &d), Some(vec![[0.1, 0.2, 0.3]]));
        // Short, non-finite, or another generic type: not a position.
        assert_eq!(positions(0, &[0; 11]), None);
        assert_eq!(positions(0, &f32s(&[f32::NAN, 0.0, 0.0])), None);
        assert_eq!(positions(1, &[3]), None);
        assert_eq!(positions(1, &[]), None);
    }
}
