//! The committed firmware runs to completion on the ISS: the semihosting
//! hello, the self-checking ISA programs, and the benchmark whose checksums
//! are recomputed here in Rust.

mod iss_util;

use iss_util::run_firmware;
use sim_core::map_image::crc32;

#[test]
fn hello_prints_and_exits_zero() {
    let (code, out, cpu) = run_firmware("hello");
    assert_eq!(code, 0);
    assert_eq!(out, "Hello from the RV32IMC ISS!\n");
    // Time advances with cycles at 250 MHz (4 ns per cycle).
    assert_eq!(cpu.now().0, cpu.cycles().0 * 4_000);
    assert!(cpu.cycles().0 >= cpu.instret());
}

#[test]
fn isa_base_self_check_passes() {
    let (code, out, _) = run_firmware("isa_base");
    assert!(
        out.contains("isa_base:") && out.contains("0 failures: PASS"),
        "{out}"
    );
    assert_eq!(code, 0, "{out}");
}

#[test]
fn isa_priv_self_check_passes() {
    let (code, out, cpu) = run_firmware("isa_priv");
    assert!(out.contains("0 failures: PASS"), "{out}");
    assert_eq!(code, 0, "{out}");
    // The wfi in the timer test slept.
    assert!(cpu.stats().sleep_cycles > 0);
}

// The benchmark's kernels, written again from its C source.
struct Lcg(u32);
impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(1664525).wrapping_add(1013904223);
        self.0
    }
}

fn sort_kernel(r: &mut Lcg) -> u32 {
    let mut a: Vec<u32> = (0..1024).map(|_| r.next()).collect();
    a.sort_unstable();
    a.iter()
        .fold(0u32, |s, &x| s.wrapping_mul(31).wrapping_add(x))
}

#[allow(clippy::needless_range_loop)] // mirrors the C source
fn matmul_kernel(r: &mut Lcg) -> u32 {
    const N: usize = 24;
    let mut ma = [[0i32; N]; N];
    let mut mb = [[0i32; N]; N];
    for i in 0..N {
        for j in 0..N {
            ma[i][j] = (r.next() >> 24) as i32 - 128;
            mb[i][j] = (r.next() >> 24) as i32 - 128;
        }
    }
    let mut sum = 0u32;
    for row in &ma {
        for j in 0..N {
            let s: i32 = (0..N).map(|k| row[k] * mb[k][j]).sum();
            sum = sum.wrapping_mul(33) ^ s as u32;
        }
    }
    sum
}

fn fsm_kernel(r: &mut Lcg) -> u32 {
    let buf: Vec<u8> = (0..8192).map(|_| (r.next() >> 24) as u8).collect();
    #[derive(PartialEq)]
    enum S {
        Idle,
        Number,
        Word,
    }
    let (mut state, mut numbers, mut words, mut others, mut value, mut acc) =
        (S::Idle, 0u32, 0u32, 0u32, 0u32, 0u32);
    for &c in &buf {
        let digit = c < 40;
        let letter = (40..160).contains(&c);
        match state {
            S::Idle => {
                if digit {
                    state = S::Number;
                    value = c as u32;
                } else if letter {
                    state = S::Word;
                } else {
                    others += 1;
                }
            }
            S::Number => {
                if digit {
                    value = value.wrapping_mul(10).wrapping_add(c as u32);
                } else {
                    numbers += 1;
                    acc = acc.wrapping_add(value / (c as u32 + 1) + value % 7);
                    state = if letter { S::Word } else { S::Idle };
                }
            }
            S::Word => {
                if !letter {
                    words += 1;
                    state = if digit { S::Number } else { S::Idle };
                    value = c as u32;
                }
            }
        }
    }
    numbers.wrapping_mul(1000003) ^ words.wrapping_mul(10007) ^ others.wrapping_mul(101) ^ acc
}

#[test]
fn benchmark_checksums_match_rust() {
    let mut r = Lcg(12345);
    let (mut crc, mut sorted, mut mat, mut fsm) = (0u32, 0u32, 0u32, 0u32);
    for _ in 0..4 {
        let buf: Vec<u8> = (0..4096).map(|_| (r.next() >> 16) as u8).collect();
        crc ^= crc32(&buf);
        sorted ^= sort_kernel(&mut r);
        mat ^= matmul_kernel(&mut r);
        fsm ^= fsm_kernel(&mut r);
    }
    let want = format!(
        "crc32 {crc:08x}\nsort {sorted:08x}\nmatmul {mat:08x}\nfsm {fsm:08x}\nchecksum {:08x}\n",
        crc ^ sorted ^ mat ^ fsm
    );
    let (code, out, _) = run_firmware("bench");
    assert_eq!(code, 0);
    assert_eq!(out, want);
}
