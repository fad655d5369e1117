//! `cosim world perturb` (DESIGN.md §10): a world file whose gates are
//! displaced from where the race firmware's nominal waypoints expect them,
//! so that only a drone that looks can pass them.
//!
//! Each gate moves sideways in its own plane (along the horizontal axis
//! across its opening) by a distance drawn uniformly in
//! [max_offset/2, max_offset] with a random sign, and vertically by one drawn
//! uniformly in [−max_offset/2, max_offset/2], never so low that the frame's
//! bottom bar is under 0.1 m. Draws come from ChaCha8 seeded with `seed`,
//! gate by gate in file order (sideways, sign, vertical), so a seed always
//! gives the same file. Everything else of the file is kept (comments are
//! not: the file is rewritten from its TOML values, under a header naming
//! its origin).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The bottom bar's underside stays at least this high (m).
const MIN_FRAME_BOTTOM_M: f64 = 0.1;

/// Why a world file cannot be perturbed.
#[derive(Debug, thiserror::Error)]
pub enum PerturbError {
    #[error("--max-offset must be a positive number of metres, got {0}")]
    BadOffset(f64),
    #[error("{0}")]
    Toml(String),
    #[error("gate {index}: {what}")]
    Gate { index: usize, what: String },
    #[error("the world file has no [[gate]] to move")]
    NoGates,
}

/// One gate's displacement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Offset {
    pub sideways_m: f64,
    pub vertical_m: f64,
}

/// Perturbs the world file `text` (named `origin` in the header); returns
/// the new file and each gate's offset.
pub fn perturb(
    text: &str,
    origin: &str,
    seed: u64,
    max_offset: f64,
) -> Result<(String, Vec<Offset>), PerturbError> {
    if !(max_offset.is_finite() && max_offset > 0.0) {
        return Err(PerturbError::BadOffset(max_offset));
    }
    let mut table: toml::Table =
        toml::from_str(text).map_err(|e| PerturbError::Toml(e.to_string().trim_end().into()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut offsets = Vec::new();
    let gates = match table.get_mut("gate") {
        Some(toml::Value::Array(gates)) if !gates.is_empty() => gates,
        _ => return Err(PerturbError::NoGates),
    };
    for (index, gate) in gates.iter_mut().enumerate() {
        let bad = |what: &str| PerturbError::Gate {
            index,
            what: what.to_string(),
        };
        let g = gate.as_table_mut().ok_or_else(|| bad("not a table"))?;
        let num = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
        let yaw = g
            .get("yaw")
            .map_or(Some(0.0), num)
            .ok_or_else(|| bad("yaw"))?;
        let inner = g.get("inner").and_then(num).ok_or_else(|| bad("inner"))?;
        let bar = g.get("bar").and_then(num).ok_or_else(|| bad("bar"))?;
        let centre: Vec<f64> = g
            .get("centre")
            .and_then(|c| c.as_array())
            .map(|a| a.iter().filter_map(num).collect())
            .filter(|c: &Vec<f64>| c.len() == 3)
            .ok_or_else(|| bad("centre must be [x, y, z]"))?;
        let magnitude = rng.random_range(max_offset / 2.0..=max_offset);
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let drawn = rng.random_range(-max_offset / 2.0..=max_offset / 2.0);
        let lowest = MIN_FRAME_BOTTOM_M + inner / 2.0 + bar;
        let vertical = drawn.max(lowest - centre[2]);
        let sideways = sign * magnitude;
        let (s, c) = yaw.sin_cos();
        // Across the opening: the horizontal unit vector (−sin, cos) of the
        // gate's frame (world-server/src/scene.rs).
        let moved = [
            centre[0] - s * sideways,
            centre[1] + c * sideways,
            centre[2] + vertical,
        ];
        g.insert(
            "centre".into(),
            toml::Value::Array(
                moved
                    .iter()
                    .map(|v| toml::Value::Float(round_um(*v)))
                    .collect(),
            ),
        );
        offsets.push(Offset {
            sideways_m: sideways,
            vertical_m: vertical,
        });
    }
    if let Some(toml::Value::String(name)) = table.get_mut("name") {
        *name = format!("{name}-perturbed-s{seed}");
    }
    let body = toml::to_string(&table).map_err(|e| PerturbError::Toml(e.to_string()))?;
    let mut lines = format!(
        "# Perturbed course (cosim world perturb --seed {seed} --max-offset {max_offset}) from\n# {origin}: every gate moved sideways in its plane by {:.2}-{max_offset} m and\n# vertically by up to {:.2} m (scenarios/src/perturb.rs). Offsets (m):\n",
        max_offset / 2.0,
        max_offset / 2.0
    );
    for (i, o) in offsets.iter().enumerate() {
        lines.push_str(&format!(
            "#   gate {}: sideways {:+.3}, vertical {:+.3}\n",
            i + 1,
            o.sideways_m,
            o.vertical_m
        ));
    }
    Ok((format!("{lines}\n{body}"), offsets))
}

/// Rounded to the micrometre (a readable file; far below any tolerance).
fn round_um(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

#[cfg(test)]
mod tests {
    use super::*;

    const WORLD: &str = "name = \"w\"\n[start]\nposition = [0.0, 0.0, 0.015]\n\
        [[gate]]\ncentre = [1.0, 2.0, 1.0]\nyaw = 0.0\ninner = 0.8\nbar = 0.06\ngrey = 170\n\
        [[gate]]\ncentre = [3.0, 2.0, 0.6]\nyaw = 1.5707963267948966\ninner = 0.8\nbar = 0.06\ngrey = 170\n";

    fn centres(text: &str) -> Vec<Vec<f64>> {
        let t: toml::Table = toml::from_str(text).unwrap();
        t["gate"]
            .as_array()
            .unwrap()
            .iter()
            .map(|g| {
                g["centre"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_float().unwrap())
                    .collect()
            })
            .collect()
    }

    #[test]
    fn gates_move_in_their_plane_within_the_bounds_and_the_seed_fixes_the_draw() {
        let (a, offs) = perturb(WORLD, "w.toml", 7, 0.4).unwrap();
        let (b, _) = perturb(WORLD, "w.toml", 7, 0.4).unwrap();
        assert_eq!(a, b);
        let (c, _) = perturb(WORLD, "w.toml", 8, 0.4).unwrap();
        assert_ne!(a, c);
        let moved = centres(&a);
        // Gate 1 faces +x: it moves along y only; gate 2 faces +y: along x.
        assert!((moved[0][0] - 1.0).abs() < 1e-6);
        assert!((moved[0][1] - 2.0 - offs[0].sideways_m).abs() < 1e-6);
        assert!((moved[1][0] - 3.0 + offs[1].sideways_m).abs() < 1e-6);
        assert!((moved[1][1] - 2.0).abs() < 1e-6);
        for o in &offs {
            assert!((0.2..=0.4).contains(&o.sideways_m.abs()), "{o:?}");
            assert!(o.vertical_m.abs() <= 0.2, "{o:?}");
        }
        // Gate 2 is low (bottom bar at 0.14 m): it never goes under 0.1 m.
        assert!(moved[1][2] - 0.4 - 0.06 >= 0.1 - 1e-9, "{moved:?}");
        // The file is a world file again.
        let w =
            world_server::world_file::WorldDesc::parse(&a, std::path::Path::new("p.toml")).unwrap();
        assert_eq!(w.gates.len(), 2);
        assert!(a.starts_with("# Perturbed course"));
    }

    #[test]
    fn bad_input_is_refused() {
        assert!(matches!(
            perturb(WORLD, "w", 1, 0.0),
            Err(PerturbError::BadOffset(_))
        ));
        assert!(matches!(
            perturb("name = \"x\"\n", "w", 1, 0.3),
            Err(PerturbError::NoGates)
        ));
        assert!(perturb("gate = [", "w", 1, 0.3).is_err());
    }
}
