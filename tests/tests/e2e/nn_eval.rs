//! `cosim nn eval` end to end (DESIGN.md §13, docs/NN_KERNELS.md "On the cluster"):
//! the real nn_eval.elf on the ISS (FC + 8-core cluster) over the golden
//! images reproduces the numpy int8 reference (training/golden/golden.json,
//! `python3 training/make_golden.py`) bit for bit: every image's raw int16
//! head and its decoded outputs. The same on 3 cores (another split of the
//! work, more cycles); two runs give the same bytes; bad input is one line
//! and exit code 2. And the kernels' arithmetic on the ISS (nn_selftest.elf):
//! the three requantizations (the clip-first one with its records) against
//! the plain 64-bit formula, the decoding's
//! first maximum, the FC's block means.

use std::path::Path;

use e2e_tests::{binary, firmware, output_text as text, repo_root, CosimBins as Bins};
use serde_json::Value;

fn eval(bins: &Bins, data: &Path, cores: &str, out: &Path, heads: &Path) -> Value {
    eval_elf(bins, "nn_eval", data, cores, out, heads)
}

fn eval_elf(bins: &Bins, elf: &str, data: &Path, cores: &str, out: &Path, heads: &Path) -> Value {
    let elf = firmware(elf);
    let o = bins.cosim(&[
        "nn",
        "eval",
        data.to_str().unwrap(),
        "--cores",
        cores,
        "--elf",
        elf.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--heads",
        heads.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    serde_json::from_slice(&std::fs::read(out).unwrap()).unwrap()
}

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

/// A `#define NAME value` of the committed weights.h (the network's shape
/// is the export's, not this test's).
fn weights_define(name: &str) -> u64 {
    define_in("sim-core/firmware/src/nn/weights.h", name)
}

/// A `#define NAME value` of a generated weights.h (path from the repo root).
fn define_in(weights_h: &str, name: &str) -> u64 {
    let h = std::fs::read_to_string(repo_root().join(weights_h)).unwrap();
    let prefix = format!("#define {name} ");
    h.lines()
        .find_map(|l| l.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("weights.h has no {name}"))
        .trim()
        .parse()
        .unwrap()
}

/// Every image's head and outputs equal the reference's.
fn assert_golden(heads: &Value, golden: &Value, what: &str) {
    let head_len = weights_define("NN_GRID").pow(2) * weights_define("NN_HEAD_CHANNELS");
    let want = golden["images"].as_array().unwrap();
    let got = heads.as_array().unwrap();
    assert_eq!(got.len(), want.len(), "{what}: one record per golden image");
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g["file"], w["file"], "{what}: image order");
        assert_eq!(w["head"].as_array().unwrap().len() as u64, head_len);
        assert_eq!(g["head"], w["head"], "{what}: {} head", w["file"]);
        assert_eq!(g["outputs"], w["outputs"], "{what}: {} outputs", w["file"]);
    }
}

#[test]
fn the_cluster_reproduces_the_int8_reference_bit_for_bit() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let data = repo_root().join("training/golden");
    let golden = read_json(&data.join("golden.json"));
    let p = |f: &str| tmp.path().join(f);

    let r8 = eval(&bins, &data, "8", &p("e8.json"), &p("h8.json"));
    assert_golden(&read_json(&p("h8.json")), &golden, "8 cores");
    let r3 = eval(&bins, &data, "3", &p("e3.json"), &p("h3.json"));
    assert_golden(&read_json(&p("h3.json")), &golden, "3 cores");

    for key in [
        "images",
        "detection_rate",
        "false_positive_rate",
        "mean_px_error",
        "p95_px_error",
        "cycles_per_inference",
        "mac_per_inference",
        "mac_per_cycle",
        "energy_per_inference_mj",
    ] {
        assert!(r8.get(key).is_some(), "eval.json lacks {key}: {r8}");
    }
    assert_eq!(r8["images"], 8);
    let macs = weights_define("NN_MACS");
    assert_eq!(r8["mac_per_inference"], macs);
    // The accuracy is a function of the outputs alone: the same on 3 cores.
    for key in ["detection_rate", "false_positive_rate", "mean_px_error"] {
        assert_eq!(r8[key], r3[key], "{key}");
    }
    let c8 = r8["cycles_per_inference"].as_f64().unwrap();
    let c3 = r3["cycles_per_inference"].as_f64().unwrap();
    assert!(c3 > 2.0 * c8, "3 cores {c3} cycles vs 8 cores {c8}");
    let mpc = r8["mac_per_cycle"].as_f64().unwrap();
    assert!(
        (mpc - macs as f64 / c8).abs() < 1e-3,
        "{mpc} vs {c8} cycles"
    );
    let layers: f64 = r8["layer_cycles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .sum();
    assert!(layers <= c8 && layers > 0.9 * c8, "layers {layers} of {c8}");
    let e = r8["energy_per_inference_mj"].as_f64().unwrap();
    assert!(e > 0.0 && e < 10.0, "{e} mJ");

    // Deterministic: the same bytes again.
    eval(&bins, &data, "8", &p("again.json"), &p("h_again.json"));
    assert_eq!(
        std::fs::read(p("e8.json")).unwrap(),
        std::fs::read(p("again.json")).unwrap()
    );
}

/// `elf` (built with the weights in `weights_dir`) on the golden images,
/// on 8 cores and on 3: its heads equal `golden` (the int8 reference's).
fn reproduces_its_reference(elf: &str, weights_dir: &str, golden: &str) {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let data = repo_root().join("training/golden");
    let golden = read_json(&repo_root().join(golden));
    let p = |f: &str| tmp.path().join(f);
    let weights = format!("{weights_dir}/weights.h");
    let macs = define_in(&weights, "NN_MACS");
    let layers = define_in(&weights, "NN_N_LAYERS") as usize;
    for cores in ["8", "3"] {
        let r = eval_elf(&bins, elf, &data, cores, &p("e.json"), &p("h.json"));
        assert_golden(
            &read_json(&p("h.json")),
            &golden,
            &format!("{elf}, {cores} cores"),
        );
        assert_eq!(r["mac_per_inference"], macs);
        assert_eq!(r["layer_cycles"].as_array().unwrap().len(), layers);
    }
}

/// The depthwise-separable network (docs/NN.md "Depthwise-separable"):
/// its depthwise layers run on the cluster's depthwise kernel, their
/// inputs in CHW planes written by the layers before, and nn_eval_sep.elf
/// reproduces its int8 reference (training/sep/golden.json) bit for bit,
/// on 8 cores and on 3.
#[test]
fn the_depthwise_separable_network_reproduces_its_reference_bit_for_bit() {
    reproduces_its_reference(
        "nn_eval_sep",
        "sim-core/firmware/src/nn/sep",
        "training/sep/golden.json",
    );
}

/// The kernels' 64-bit requantization forms, which no committed network's
/// layer takes (every one takes the clip-first form): the fallback network
/// (training/make_fallback.py, the sep network with activation ranges
/// scaled) puts conv1, dw3, pw4 and pw7 in the fast form and pw3, dw4 and
/// the head in the general one, so the depthwise kernel (one plane, both
/// strides) and the 2x4 kernel (CHW, HWC and int16 outputs) run them;
/// nn_eval_fallback.elf reproduces training/fallback/golden.json bit for
/// bit on 8 cores and on 3.
#[test]
fn the_fallback_requantizations_reproduce_their_reference_bit_for_bit() {
    reproduces_its_reference(
        "nn_eval_fallback",
        "sim-core/firmware/src/nn/fallback",
        "training/fallback/golden.json",
    );
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    let bins = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let golden = repo_root().join("training/golden");
    let bad_pgm = tmp.path().join("bad");
    std::fs::create_dir(&bad_pgm).unwrap();
    std::fs::write(
        bad_pgm.join("labels.csv"),
        "file,gate_visible,u,v,distance_m,corners\nimg.pgm,0,,,,\n",
    )
    .unwrap();
    std::fs::write(bad_pgm.join("img.pgm"), b"P5\n32 32\n255\n").unwrap();
    let cases: [(&[&str], &str); 3] = [
        (&["nn", "eval", "/nonexistent/dir"], "labels.csv"),
        (
            &["nn", "eval", golden.to_str().unwrap(), "--cores", "9"],
            "--cores: cluster.cores must be 1 to 8, got 9",
        ),
        (&["nn", "eval", bad_pgm.to_str().unwrap()], "320x320"),
    ];
    for (args, want) in cases {
        let o = bins.cosim(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn kernel_arithmetic_passes_its_self_test_on_the_iss() {
    let o = std::process::Command::new(binary("sim-core", "sim-core"))
        .arg("run-elf")
        .arg(firmware("nn_selftest"))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", text(&o));
    // The nearest-cell decoding (weights.h's NN_DECODE_THRESHOLD) has one
    // check more than the best-cell one.
    let h =
        std::fs::read_to_string(repo_root().join("sim-core/firmware/src/nn/weights.h")).unwrap();
    let checks = if h.contains("#define NN_DECODE_THRESHOLD ") {
        10265
    } else {
        10264
    };
    assert!(
        out.contains(" 0 failures: PASS") && out.contains(&format!("nn_selftest: {checks} checks")),
        "{out}"
    );
}
