//! `cosim nn eval DIR`: the int8 network on the ISS over a labelled
//! dataset (DESIGN.md §13, docs/NN.md "cosim nn eval"), scored exactly as
//! `training/evaluate.py` scores the numpy reference.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use serde::Serialize;

use super::machine::{Inference, NnMachine, Outputs};

/// One row of `labels.csv` (`cosim dataset`, DESIGN.md §13).
#[derive(Debug, Clone, PartialEq)]
pub struct Label {
    pub file: String,
    /// The labelled centre (camera pixels) when a gate is visible.
    pub centre: Option<(f64, f64)>,
}

/// Reads `DIR/labels.csv`.
pub fn read_labels(dir: &Path) -> anyhow::Result<Vec<Label>> {
    let path = dir.join("labels.csv");
    let mut r = csv::Reader::from_path(&path).with_context(|| {
        format!(
            "{}: cannot read (a `cosim dataset` directory?)",
            path.display()
        )
    })?;
    let mut out = Vec::new();
    for (i, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: row {}", path.display(), i + 2))?;
        let bad = |what: &str| anyhow::anyhow!("{}: row {}: {what}", path.display(), i + 2);
        let file = rec.get(0).ok_or_else(|| bad("no file"))?.to_string();
        let visible = match rec.get(1) {
            Some("1") => true,
            Some("0") => false,
            other => return Err(bad(&format!("gate_visible {other:?} is not 0 or 1"))),
        };
        let num = |j: usize| -> anyhow::Result<f64> {
            rec.get(j)
                .and_then(|s| s.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(&format!("column {} is not a number", j + 1)))
        };
        let centre = if visible {
            Some((num(2)?, num(3)?))
        } else {
            None
        };
        out.push(Label { file, centre });
    }
    Ok(out)
}

/// A binary PGM (`P5`, maxval 255) of `side`×`side` pixels.
pub fn read_pgm(path: &Path, side: usize) -> anyhow::Result<Vec<u8>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    // The header: magic, width, height, maxval, separated by whitespace,
    // one whitespace byte before the pixels (netpbm's P5).
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if start == i {
            bail!("{}: not a binary PGM (truncated header)", path.display());
        }
        fields.push(String::from_utf8_lossy(&bytes[start..i]).into_owned());
    }
    let want = [
        "P5".to_string(),
        side.to_string(),
        side.to_string(),
        "255".to_string(),
    ];
    if fields != want {
        bail!(
            "{}: expected a {side}x{side} 8-bit binary PGM, header {:?}",
            path.display(),
            fields
        );
    }
    let pixels = &bytes[(i + 1).min(bytes.len())..];
    if pixels.len() != side * side {
        bail!(
            "{}: {} pixel bytes, expected {}",
            path.display(),
            pixels.len(),
            side * side
        );
    }
    Ok(pixels.to_vec())
}

/// The accuracy keys of evaluate.py's `metrics`, rounded as it rounds them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Accuracy {
    pub images: usize,
    pub with_gate: usize,
    pub detection_rate: f64,
    pub false_positive_rate: f64,
    pub mean_px_error: Option<f64>,
    pub p95_px_error: Option<f64>,
}

fn round(x: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (x * s).round() / s
}

/// numpy's default percentile: linear interpolation between the sorted
/// values at rank `q/100 · (n − 1)`.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    let r = q / 100.0 * (sorted.len() - 1) as f64;
    let lo = r.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (sorted[hi] - sorted[lo]) * (r - lo as f64)
}

/// evaluate.py's `metrics`: detection over the images with a gate, false
/// positives over those without, centre errors (camera pixels, the
/// reported 1/16-px centre against the label) over the detected gates.
pub fn accuracy(preds: &[Outputs], labels: &[Label]) -> Accuracy {
    let with_gate = labels.iter().filter(|l| l.centre.is_some()).count();
    let mut err = Vec::new();
    let mut fp = 0;
    for (p, l) in preds.iter().zip(labels) {
        match (p.visible, l.centre) {
            (true, Some((u, v))) => {
                err.push((p.u_q4 as f64 / 16.0 - u).hypot(p.v_q4 as f64 / 16.0 - v))
            }
            (true, None) => fp += 1,
            _ => {}
        }
    }
    let n = labels.len();
    let mut sorted = err.clone();
    sorted.sort_by(f64::total_cmp);
    Accuracy {
        images: n,
        with_gate,
        detection_rate: round(err.len() as f64 / with_gate.max(1) as f64, 4),
        false_positive_rate: round(fp as f64 / (n - with_gate).max(1) as f64, 4),
        mean_px_error: (!err.is_empty())
            .then(|| round(err.iter().sum::<f64>() / err.len() as f64, 2)),
        p95_px_error: (!sorted.is_empty()).then(|| round(percentile(&sorted, 95.0), 2)),
    }
}

/// `eval.json` (DESIGN.md §13's keys first, then ours).
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    pub images: usize,
    pub detection_rate: f64,
    pub false_positive_rate: f64,
    pub mean_px_error: Option<f64>,
    pub p95_px_error: Option<f64>,
    /// Cluster cycles of the network, mean over the images.
    pub cycles_per_inference: f64,
    pub mac_per_inference: u64,
    pub mac_per_cycle: f64,
    /// FC + cluster, frame in to outputs decoded, mean, mJ.
    pub energy_per_inference_mj: f64,
    pub with_gate: usize,
    pub cores: usize,
    pub cluster_mhz: u64,
    /// FC cycles of the 4x4 averaging, mean.
    pub fc_cycles_per_inference: f64,
    /// Frame in to outputs decoded (FC + cluster), mean, ms.
    pub latency_ms: f64,
    pub cycles_per_inference_max: u64,
    /// Instructions of all cluster cores, and their L1 bank-conflict
    /// stall cycles, per inference (mean).
    pub cluster_instructions_per_inference: f64,
    pub l1_stall_cycles_per_inference: f64,
    /// Cluster cycles of each layer, mean, and its MAC/cycle.
    pub layer_cycles: Vec<f64>,
    pub layer_mac_per_cycle: Vec<f64>,
    pub elf: String,
    pub data: String,
}

/// What `cosim nn eval` is asked.
#[derive(Debug, Clone)]
pub struct EvalArgs {
    pub data: PathBuf,
    pub cores: usize,
    pub mhz: u64,
    pub limit: Option<usize>,
    pub elf: PathBuf,
    pub platform: PathBuf,
    /// Where eval.json goes (the caller writes it).
    pub out_json: PathBuf,
    /// The ISS back end of the FC and the cluster (results are identical;
    /// only the host time differs, docs/ISS.md).
    pub iss: sim_core::iss::Backend,
}

/// One image's raw results, as training/golden/golden.json holds them.
#[derive(Debug, Clone, Serialize)]
pub struct HeadRecord {
    pub file: String,
    pub head: Vec<i16>,
    pub outputs: Outputs,
}

/// Runs the network over the dataset; the report and every image's head.
pub fn evaluate(
    args: &EvalArgs,
    mut progress: impl FnMut(usize, usize),
) -> anyhow::Result<(EvalReport, Vec<HeadRecord>)> {
    if let Err(e) = sim_core::cluster::CoreCount::new(args.cores) {
        bail!("--cores: {e}");
    }
    if args.mhz == 0 {
        bail!("--mhz must be positive");
    }
    let mut labels = read_labels(&args.data)?;
    if let Some(k) = args.limit {
        labels.truncate(k);
    }
    if labels.is_empty() {
        bail!("{}: no images to evaluate", args.data.display());
    }
    if !args.elf.is_file() {
        bail!(
            "no ELF at {} (make -C sim-core/firmware)",
            args.elf.display()
        );
    }
    let mut m = NnMachine::new(&args.elf, &args.platform, args.cores, args.mhz, args.iss)?;
    let side = m.shape.camera;
    let mut runs: Vec<Inference> = Vec::with_capacity(labels.len());
    for (i, l) in labels.iter().enumerate() {
        let image = read_pgm(&args.data.join(&l.file), side)?;
        runs.push(
            m.infer(&image)
                .with_context(|| format!("image {}", l.file))?,
        );
        progress(i + 1, labels.len());
    }
    let shape = m.shape.clone();
    let exit = m.finish()?;
    if exit != 0 {
        bail!("the program exited with {exit} after its last frame");
    }
    let preds: Vec<Outputs> = runs.iter().map(|r| r.outputs.clone()).collect();
    let acc = accuracy(&preds, &labels);
    let n = runs.len() as f64;
    let mean = |f: &dyn Fn(&Inference) -> f64| runs.iter().map(f).sum::<f64>() / n;
    let cycles = mean(&|r| r.cluster_cycles as f64);
    let n_layers = runs[0].layer_cycles.len();
    let layer_cycles: Vec<f64> = (0..n_layers)
        .map(|j| mean(&|r| r.layer_cycles[j] as f64))
        .collect();
    let report = EvalReport {
        images: acc.images,
        detection_rate: acc.detection_rate,
        false_positive_rate: acc.false_positive_rate,
        mean_px_error: acc.mean_px_error,
        p95_px_error: acc.p95_px_error,
        cycles_per_inference: round(cycles, 1),
        mac_per_inference: shape.macs,
        mac_per_cycle: round(shape.macs as f64 / cycles, 3),
        energy_per_inference_mj: round(mean(&|r| r.energy_j) * 1e3, 5),
        with_gate: acc.with_gate,
        cores: args.cores,
        cluster_mhz: args.mhz,
        fc_cycles_per_inference: round(mean(&|r| r.fc_cycles as f64), 1),
        latency_ms: round(mean(&|r| r.latency.as_secs_f64()) * 1e3, 4),
        cycles_per_inference_max: runs.iter().map(|r| r.cluster_cycles).max().unwrap_or(0),
        cluster_instructions_per_inference: round(mean(&|r| r.cluster_instructions as f64), 1),
        l1_stall_cycles_per_inference: round(mean(&|r| r.l1_stall_cycles as f64), 1),
        layer_mac_per_cycle: layer_cycles
            .iter()
            .zip(&shape.layer_macs)
            .map(|(c, m)| round(*m as f64 / c, 3))
            .collect(),
        layer_cycles: layer_cycles.iter().map(|c| round(*c, 1)).collect(),
        elf: args.elf.display().to_string(),
        data: args.data.display().to_string(),
    };
    let heads = labels
        .iter()
        .zip(runs)
        .map(|(l, r)| HeadRecord {
            file: l.file.clone(),
            head: r.head,
            outputs: r.outputs,
        })
        .collect();
    Ok((report, heads))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn out(visible: bool, u: f64, v: f64) -> Outputs {
        Outputs {
            visible,
            score: 0,
            cell: [0, 0],
            u_q4: (u * 16.0) as i32,
            v_q4: (v * 16.0) as i32,
            distance_mm: 0,
            corners_q4: [0; 8],
        }
    }

    fn label(centre: Option<(f64, f64)>) -> Label {
        Label {
            file: String::new(),
            centre,
        }
    }

    #[test]
    fn percentile_interpolates_as_numpy() {
        // numpy.percentile([1, 2, 3, 4], 95) = 3.85; of one value, itself.
        assert!((percentile(&[1.0, 2.0, 3.0, 4.0], 95.0) - 3.85).abs() < 1e-12);
        assert_eq!(percentile(&[7.0], 95.0), 7.0);
        assert_eq!(percentile(&[1.0, 3.0], 50.0), 2.0);
    }

    #[test]
    fn accuracy_counts_as_evaluate_py() {
        // Two gates, one found 5 px off (3-4-5), one missed; two empty
        // images, one with a false positive.
        let labels = [
            label(Some((100.0, 100.0))),
            label(Some((50.0, 50.0))),
            label(None),
            label(None),
        ];
        let preds = [
            out(true, 103.0, 104.0),
            out(false, 50.0, 50.0),
            out(true, 10.0, 10.0),
            out(false, 0.0, 0.0),
        ];
        let a = accuracy(&preds, &labels);
        assert_eq!(a.images, 4);
        assert_eq!(a.with_gate, 2);
        assert_eq!(a.detection_rate, 0.5);
        assert_eq!(a.false_positive_rate, 0.5);
        assert_eq!(a.mean_px_error, Some(5.0));
        assert_eq!(a.p95_px_error, Some(5.0));
        // Nothing detected: no errors to average.
        let none = accuracy(&[out(false, 0.0, 0.0)], &[label(Some((1.0, 1.0)))]);
        assert_eq!((none.detection_rate, none.mean_px_error), (0.0, None));
    }

    #[test]
    fn pgm_and_labels_are_checked() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.pgm");
        let mut good = b"P5\n4 4\n255\n".to_vec();
        good.extend(0..16u8);
        std::fs::write(&p, &good).unwrap();
        assert_eq!(read_pgm(&p, 4).unwrap(), (0..16u8).collect::<Vec<_>>());
        let e = read_pgm(&p, 320).unwrap_err().to_string();
        assert!(e.contains("320x320"), "{e}");
        std::fs::write(&p, &good[..20]).unwrap();
        assert!(read_pgm(&p, 4)
            .unwrap_err()
            .to_string()
            .contains("pixel bytes"));

        let csv = "file,gate_visible,u,v,distance_m,corners\n\
                   a.pgm,1,10.5,20.25,3.0,1 2 3 4 5 6 7 8\nb.pgm,0,,,,\n";
        std::fs::write(dir.path().join("labels.csv"), csv).unwrap();
        let l = read_labels(dir.path()).unwrap();
        assert_eq!(l[0].centre, Some((10.5, 20.25)));
        assert_eq!((l[1].file.as_str(), l[1].centre), ("b.pgm", None));
        std::fs::write(
            dir.path().join("labels.csv"),
            "file,gate_visible\na.pgm,2\n",
        )
        .unwrap();
        let e = read_labels(dir.path()).unwrap_err().to_string();
        assert!(e.contains("row 2"), "{e}");
    }
}
