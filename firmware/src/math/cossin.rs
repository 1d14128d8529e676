//! `cos` and `sin` of a Q32 phase in Q31: QUARTIQ's `idsp::cossin` (MiSoC's cossin core, a
//! 7-bit table of (cos, sin) at the midpoints of 1/128 of an octant, interpolated to first
//! order), bit for bit, with its table in RAM.
//!
//! # Why a copy of `idsp::cossin`
//! The dither drive's DAC code must be computed while the flash stalls (a store programs or
//! erases it: `crate::board`'s RAM-resident drive tick keeps the drive going through it), and
//! `idsp`'s table is a `const` that the compiler places in flash. So this module is the one
//! cossin of the firmware: every caller (the DDS, the drive's and the dither model's
//! regressors) uses it, the table is a `static` that the start-up copies to RAM with the other
//! initialised data, and on the board the function itself lives in RAM
//! (`.data.ramfunc`, copied likewise); flash code reaches it through a long branch. The test
//! below checks it against `idsp::cossin` over every table entry and octant, so the two cannot
//! differ. Cost: 512 bytes of RAM for the table, the function's ~120 bytes of code.
//!
//! Accuracy (idsp's): 9e-6 max and 4e-6 rms error of full scale in each quadrature, spurs near
//! -120 dBc; the output's full scale is `2^31 - 0.85 * 2^15` (a gain of `1 - 1.3e-5`).

/// Table entries: 2^7 per octant.
const DEPTH: usize = 7;

/// `cos(z) * 2 - 1` in the low 16 bits (less one LSB), `sin(z)` in the high 16 bits, both
/// scaled by 65535, at `z = pi/4 (i + 1/2) / 128`: idsp's `build.rs` formula. On the board it
/// is initialised data (`.data`: in RAM, copied at start-up), never a constant read from flash.
#[cfg_attr(target_os = "none", link_section = ".data.cossin_table")]
static COSSIN: [u32; 1 << DEPTH] = [
    0x00C9FFFD, 0x025BFFF8, 0x03EDFFEF, 0x057FFFE0, 0x0711FFCC, 0x08A3FFB3, 0x0A35FF96, 0x0BC7FF73,
    0x0D58FF4C, 0x0EEAFF1F, 0x107BFEEE, 0x120DFEB8, 0x139EFE7D, 0x152EFE3D, 0x16BFFDF8, 0x184FFDAE,
    0x19E0FD5F, 0x1B70FD0B, 0x1CFFFCB2, 0x1E8FFC55, 0x201EFBF2, 0x21ACFB8B, 0x233BFB1F, 0x24C9FAAE,
    0x2657FA38, 0x27E4F9BD, 0x2971F93D, 0x2AFEF8B8, 0x2C8AF82F, 0x2E16F7A1, 0x2FA1F70D, 0x312CF675,
    0x32B6F5D8, 0x3440F537, 0x35CAF490, 0x3753F3E5, 0x38DBF335, 0x3A63F280, 0x3BEAF1C6, 0x3D71F107,
    0x3EF7F044, 0x407CEF7B, 0x4201EEAF, 0x4385EDDD, 0x4509ED06, 0x468CEC2B, 0x480EEB4B, 0x498FEA66,
    0x4B10E97D, 0x4C90E88F, 0x4E10E79C, 0x4F8EE6A4, 0x510CE5A8, 0x5289E4A7, 0x5405E3A1, 0x5581E297,
    0x56FBE188, 0x5875E075, 0x59EEDF5C, 0x5B66DE40, 0x5CDDDD1E, 0x5E53DBF8, 0x5FC9DACD, 0x613DD99E,
    0x62B1D86A, 0x6423D732, 0x6595D5F5, 0x6706D4B4, 0x6875D36E, 0x69E4D224, 0x6B51D0D5, 0x6CBECF81,
    0x6E29CE29, 0x6F94CCCD, 0x70FDCB6C, 0x7266CA07, 0x73CDC89E, 0x7533C730, 0x7698C5BD, 0x77FCC446,
    0x795EC2CB, 0x7AC0C14C, 0x7C20BFC8, 0x7D7FBE40, 0x7EDDBCB4, 0x803ABB23, 0x8195B98E, 0x82EFB7F5,
    0x8448B657, 0x85A0B4B6, 0x86F6B310, 0x884BB166, 0x899FAFB7, 0x8AF1AE05, 0x8C42AC4E, 0x8D92AA94,
    0x8EE0A8D5, 0x902DA712, 0x9179A54B, 0x92C3A380, 0x940CA1B1, 0x95539FDE, 0x96999E07, 0x97DD9C2B,
    0x99209A4C, 0x9A629869, 0x9BA29682, 0x9CE19497, 0x9E1E92A9, 0x9F5990B6, 0xA0938EBF, 0xA1CB8CC5,
    0xA3028AC7, 0xA43788C5, 0xA56B86BF, 0xA69D84B6, 0xA7CE82A8, 0xA8FD8097, 0xAA2A7E82, 0xAB557C6A,
    0xAC7F7A4E, 0xADA8782E, 0xAECE760B, 0xAFF373E4, 0xB11671B9, 0xB2386F8B, 0xB3586D5A, 0xB4766B24,
];

/// `(cos, sin)` of `phase` (a full turn = 2^32, `i32::MIN` = -pi) in Q31 (see the module docs).
#[cfg_attr(target_os = "none", link_section = ".data.ramfunc.cossin")]
#[cfg_attr(target_os = "none", inline(never))]
#[allow(clippy::indexing_slicing)] // the index is 7 bits of the phase: always inside the table
pub fn cossin(mut phase: i32) -> (i32, i32) {
    let mut octant = phase as u32;
    if octant & (1 << 29) != 0 {
        // phase = pi/4 - phase
        phase = !phase;
    }
    // 16 + 1 bits for cos/sin and 15 for dphi to saturate the i32 range.
    const ALIGN_MSB: usize = 32 - 16 - 1;
    // The angle in [0, pi/4).
    phase = (((phase as u32) << 3) >> (32 - DEPTH - ALIGN_MSB)) as i32;
    let lookup = COSSIN[(phase >> ALIGN_MSB) as usize];
    phase &= (1 << ALIGN_MSB) - 1;
    // Interpolate from the entry's midpoint.
    phase -= 1 << (ALIGN_MSB - 1);
    // pi/4 in Q16.
    const PI4: i32 = (core::f64::consts::FRAC_PI_4 * (1 << 16) as f64) as i32;
    let dphi = (phase * PI4) >> 16;
    // 1/2 < cos(0 <= x <= pi/4) <= 1: the cos values shifted, the sin values scaled.
    let mut cos = lookup as u16 as i32 + (1 << 16);
    let mut sin = (lookup >> 16) as i32;
    let dcos = (sin * dphi) >> DEPTH;
    let dsin = (cos * dphi) >> (DEPTH + 1);
    cos = (cos << (ALIGN_MSB - 1)) - dcos;
    sin = (sin << ALIGN_MSB) + dsin;
    // Back to the octant.
    octant ^= octant >> 1;
    if octant & (1 << 29) != 0 {
        (cos, sin) = (sin, cos);
    }
    if octant & (1 << 30) != 0 {
        cos = -cos;
    }
    if octant & (1 << 31) != 0 {
        sin = -sin;
    }
    (cos, sin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    /// Bit for bit `idsp::cossin`: every table entry of every octant at its ends and at random
    /// points between (2^24 phases), and the quarter-turn boundaries exactly.
    #[test]
    fn equals_idsp_cossin_bit_for_bit() {
        let mut rng = XorShift(29);
        let mut checked = 0u64;
        for top in 0..(1u32 << 10) {
            // The top 10 bits: the octant (3) and the table entry (7).
            let base = top << 22;
            let mut check = |phase: u32| {
                let p = phase as i32;
                assert_eq!(cossin(p), idsp::cossin(p), "phase {phase:#010x}");
                checked += 1;
            };
            check(base);
            check(base | ((1 << 22) - 1));
            for _ in 0..(1 << 14) {
                check(base | ((rng.next() >> 42) as u32));
            }
        }
        for q in [0u32, 1 << 30, 2 << 30, 3 << 30] {
            for d in [0u32, 1, u32::MAX] {
                let p = q.wrapping_add(d) as i32;
                assert_eq!(cossin(p), idsp::cossin(p));
            }
        }
        assert!(checked > 1 << 24, "{checked}");
    }
}
