//! Third-party GAP8 code on our runtime (docs/CLUSTER.md, "Code written for
//! the GAP SDK"): the GCC PULP builtins of `pmsis/pulp_builtins.h` checked
//! on the cluster against plain C (`pulp_builtins_test.elf`), and `make app`
//! building SDK-style code — several files, `pi_cl_team_barrier(0)`, the
//! builtins and the vector types, the user's own flags — without a warning.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn firmware(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("firmware/bin")
        .join(format!("{name}.elf"))
}

fn run_elf(elf: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sim-core"))
        .arg("run-elf")
        .arg(elf)
        .args(extra)
        .output()
        .expect("run sim-core")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Every builtin on every edge-case operand (pair) equals its plain C
/// definition, on cluster core 0; the barrier takes PULP-NN's argument.
#[test]
fn every_builtin_matches_plain_c_on_the_cluster() {
    for cores in ["8", "3"] {
        let o = run_elf(&firmware("pulp_builtins_test"), &["--cluster-cores", cores]);
        let out = text(&o.stdout);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{cores} cores: {out}{}",
            text(&o.stderr)
        );
        let line = out.lines().last().unwrap_or_default();
        let checks: u32 = line
            .strip_prefix("pulp_builtins_test: ")
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no summary line: {out}"));
        // 21 operands: the 441 pairs of 34 two-operand checks alone make
        // 14 994 checks, the unary and bit-field ones come on top.
        assert!(checks > 14_994, "{out}");
        assert!(line.ends_with(" 0 failures: PASS"), "{out}");
        assert_eq!(out.lines().count(), 1, "no FAIL line: {out}");
    }
}

/// `make app` with two files and `APP_CFLAGS`: SDK-style code (an include
/// directory, `NUM_CORES` on the command line, `pi_cl_team_barrier(0)`,
/// `v4u`/`v4s`, `__builtin_pulp_sdotusp4`, `clipu_r`, `fl1`) builds with
/// `-Werror` and computes what plain C computes.
#[test]
fn make_app_builds_sdk_style_code_without_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let inc = dir.path().join("include");
    std::fs::create_dir(&inc).unwrap();
    std::fs::write(
        inc.join("kernel.h"),
        "#include \"pmsis.h\"\nvoid dot_rows(const uint8_t *a, const int8_t *b, uint8_t *out, int rows, int len);\n",
    )
    .unwrap();
    let kernel = dir.path().join("kernel.c");
    std::fs::write(
        &kernel,
        r#"#include "pmsis.h"
#include "kernel.h"

#define log2(x) __builtin_pulp_fl1(x)

/* Rows split over the team as PULP-NN splits them. */
void dot_rows(const uint8_t *a, const int8_t *b, uint8_t *out, int rows, int len)
{
    int core = pi_core_id();
    int chunk = (rows >> log2(NUM_CORES)) + ((rows & (NUM_CORES - 1)) != 0);
    int start = core * chunk, stop = start + chunk < rows ? start + chunk : rows;
    for (int r = start; r < stop; r++) {
        int sum = 0;
        for (int i = 0; i < len; i += 4)
            sum = __builtin_pulp_sdotusp4(*(v4u *)(a + r * len + i), *(v4s *)(b + i), sum);
        out[r] = __builtin_pulp_clipu_r(sum >> 4, 255);
    }
    pi_cl_team_barrier(0);
}
"#,
    )
    .unwrap();
    let main = dir.path().join("main.c");
    std::fs::write(
        &main,
        r#"#include <pmsis.h>
#include <stdio.h>
#include "kernel.h"

#define ROWS 37
#define LEN 64
static uint8_t a[ROWS * LEN], out[ROWS];
static int8_t b[LEN];

static void work(void *arg) { (void)arg; dot_rows(a, b, out, ROWS, LEN); }
static void entry(void *arg) { (void)arg; pi_cl_team_fork(NUM_CORES, work, NULL); }

int main(void)
{
    for (int i = 0; i < ROWS * LEN; i++) a[i] = (uint8_t)(i * 37 + 11);
    for (int i = 0; i < LEN; i++) b[i] = (int8_t)(i * 53 - 90);
    struct pi_device cl;
    struct pi_cluster_conf conf;
    struct pi_cluster_task task;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cl, &conf);
    if (pi_cluster_open(&cl))
        return 1;
    pi_cluster_send_task_to_cl(&cl, pi_cluster_task(&task, entry, NULL));
    pi_cluster_close(&cl);
    int differ = 0, nonzero = 0;
    for (int r = 0; r < ROWS; r++) {
        int sum = 0;
        for (int i = 0; i < LEN; i++) sum += a[r * LEN + i] * b[i];
        sum >>= 4;
        int want = sum < 0 ? 0 : (sum > 255 ? 255 : sum);
        differ += out[r] != want;
        nonzero += want != 0;
    }
    printf("%d rows, %d nonzero, %d differ\n", ROWS, nonzero, differ);
    return differ;
}
"#,
    )
    .unwrap();
    let elf = dir.path().join("sdk.elf");
    let fw_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("firmware");
    let make = Command::new("make")
        .arg("-C")
        .arg(&fw_dir)
        .arg("app")
        .arg(format!("SRC={} {}", main.display(), kernel.display()))
        .arg(format!("OUT={}", elf.display()))
        .arg(format!(
            "APP_CFLAGS=-I{} -DNUM_CORES=8 -Werror",
            inc.display()
        ))
        .output()
        .expect("run make (install make, clang-19 and gcc-riscv64-unknown-elf: .ci/run)");
    assert!(
        make.status.success(),
        "make app: {}{}",
        text(&make.stdout),
        text(&make.stderr)
    );
    assert!(
        !text(&make.stderr).contains("warning"),
        "{}",
        text(&make.stderr)
    );
    let o = run_elf(&elf, &[]);
    let out = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}{}", text(&o.stderr));
    assert!(out.starts_with("37 rows, "), "{out}");
    assert!(out.ends_with(" 0 differ\n"), "{out}");
    assert!(
        !out.contains(" 0 nonzero"),
        "the check saw real sums: {out}"
    );
}
