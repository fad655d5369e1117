//! The static geometry of a world as oriented boxes: gate bars, gate legs
//! and free boxes. Physics (colliders) and camera (faces) both build from
//! this list, so what the drone sees is exactly what it can hit.

use rapier3d::glamx::DVec3;

use crate::world_file::WorldDesc;

/// One static box: centre, half extents along its own axes, yaw about world z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBox {
    pub centre: DVec3,
    pub half: DVec3,
    pub yaw: f64,
    pub grey: u8,
    /// Which object of the world file it belongs to (collisions count per object).
    pub object: ObjectId,
}

/// A world object the drone can touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ObjectId {
    Ground,
    /// Gate `i` of the world file (0-based).
    Gate(usize),
    /// Box `i` of the world file (0-based).
    Box(usize),
    /// Drone `i` of the world file (0-based): another drone's hull.
    Drone(usize),
}

/// Drones are tagged above every gate and box value (bit 64 set), so the
/// gate/box packing stays what it was.
const DRONE_TAG: u128 = 1 << 64;

impl ObjectId {
    /// Packs the id into a collider's `user_data`.
    pub fn to_user_data(self) -> u128 {
        match self {
            ObjectId::Ground => 0,
            ObjectId::Gate(i) => 1 + 2 * i as u128,
            ObjectId::Box(i) => 2 + 2 * i as u128,
            ObjectId::Drone(i) => DRONE_TAG | i as u128,
        }
    }

    pub fn from_user_data(d: u128) -> ObjectId {
        match d {
            0 => ObjectId::Ground,
            d if d & DRONE_TAG != 0 => ObjectId::Drone((d & !DRONE_TAG) as usize),
            d if d % 2 == 1 => ObjectId::Gate(((d - 1) / 2) as usize),
            d => ObjectId::Box(((d - 2) / 2) as usize),
        }
    }
}

/// Every static box of the world, gates first (in file order), then boxes.
pub fn scene_boxes(desc: &WorldDesc) -> Vec<SceneBox> {
    let mut out = Vec::new();
    for (i, g) in desc.gates.iter().enumerate() {
        let c = DVec3::from_array(g.centre.0);
        let (s, b) = (g.inner.0, g.bar.0);
        let yaw = g.yaw.0;
        // Gate frame: local x = direction of travel, local y = across the opening.
        let (sin, cos) = yaw.sin_cos();
        let across = DVec3::new(-sin, cos, 0.0);
        let mut push = |offset_across: f64, offset_up: f64, half: DVec3| {
            out.push(SceneBox {
                centre: c + across * offset_across + DVec3::Z * offset_up,
                half,
                yaw,
                grey: g.grey,
                object: ObjectId::Gate(i),
            });
        };
        let side = s / 2.0 + b / 2.0;
        // Top and bottom bars span the full outer width; the side bars fill between them.
        push(0.0, side, DVec3::new(b / 2.0, s / 2.0 + b, b / 2.0));
        push(0.0, -side, DVec3::new(b / 2.0, s / 2.0 + b, b / 2.0));
        push(-side, 0.0, DVec3::new(b / 2.0, b / 2.0, s / 2.0));
        push(side, 0.0, DVec3::new(b / 2.0, b / 2.0, s / 2.0));
        let frame_bottom = c.z - s / 2.0 - b;
        if g.legs && frame_bottom > 0.0 {
            let h = frame_bottom;
            for sign in [-1.0, 1.0] {
                push(
                    sign * side,
                    -(s / 2.0 + b) - h / 2.0,
                    DVec3::new(b / 2.0, b / 2.0, h / 2.0),
                );
            }
        }
    }
    for (i, bx) in desc.boxes.iter().enumerate() {
        out.push(SceneBox {
            centre: DVec3::from_array(bx.centre.0),
            half: DVec3::new(bx.size[0].0, bx.size[1].0, bx.size[2].0) / 2.0,
            yaw: bx.yaw.0,
            grey: bx.grey,
            object: ObjectId::Box(i),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn user_data_round_trips() {
        for id in [
            ObjectId::Ground,
            ObjectId::Gate(0),
            ObjectId::Gate(7),
            ObjectId::Box(0),
            ObjectId::Box(3),
            ObjectId::Drone(0),
            ObjectId::Drone(5),
        ] {
            assert_eq!(ObjectId::from_user_data(id.to_user_data()), id);
        }
    }

    #[test]
    fn a_gate_frame_leaves_its_inner_opening_free() {
        let w = WorldDesc::parse(
            "[start]\nposition=[0.0,0.0,0.015]\n[[gate]]\ncentre=[1.0,2.0,1.0]\nyaw=0.0\ninner=0.8\nbar=0.1\ngrey=170\n",
            Path::new("t.toml"),
        )
        .unwrap();
        let boxes = scene_boxes(&w);
        assert_eq!(boxes.len(), 6, "4 bars + 2 legs");
        // Yaw 0: the opening spans world y in [1.6, 2.4] and z in [0.6, 1.4].
        let top = boxes[0];
        assert!((top.centre - DVec3::new(1.0, 2.0, 1.45)).length() < 1e-12);
        assert!((top.centre.z - top.half.z - 1.4).abs() < 1e-12);
        let left = boxes[2];
        assert!((left.centre.y + left.half.y - 1.6).abs() < 1e-12);
        let right = boxes[3];
        assert!((right.centre.y - right.half.y - 2.4).abs() < 1e-12);
        // Legs reach the ground and the frame's bottom.
        let leg = boxes[4];
        assert!((leg.centre.z - leg.half.z).abs() < 1e-12);
        assert!((leg.centre.z + leg.half.z - 0.5).abs() < 1e-12);
    }
}
