//! The cases: one entry per core function. Add one in a few lines, then regenerate the golden
//! values on the host (`UPDATE_GOLDEN=1 cargo test -p firmware --test golden`) and run the
//! suite on the target (`cargo fw-test`).
//!
//! Inputs come from [`Rng`] with a fixed seed per case; every output goes to `out`.
use super::{calibration, dither, frontend, signal, Case, Outputs, Rng};

pub const CASES: &[Case] = &[
    // The platform: input generator, integer and float arithmetic, the f32 maths library.
    Case::exact("rng_stream", rng_stream),
    Case::exact("int_phase_arith", int_phase_arith),
    Case::exact("f32_ieee_basic", f32_ieee_basic),
    Case::abs_tol("micromath_trig", 1e-6, micromath_trig),
    // The signal chain (firmware::signal): the turnaround front end ... The names are the
    // keys of golden.rs: fringe_count is signal::count,
    // fractional_fringe math::atan2_q32, lissajous and fringe_phase signal::fringe,
    // turnaround_schedule signal::turnaround, lockin_terms and cycle signal::lockin.
    Case::exact("signal::fringe_count", frontend::fringe_count),
    Case::exact("signal::fractional_fringe", frontend::fractional_fringe),
    Case::exact("signal::lissajous", frontend::lissajous),
    Case::exact("signal::fringe_phase", frontend::fringe_phase),
    Case::exact("signal::turnaround_schedule", frontend::turnaround_schedule),
    // ... and the per-cycle stages.
    Case::exact("signal::lockin_terms", signal::lockin_terms),
    Case::exact("signal::compensation", signal::compensation),
    Case::exact("signal::output", signal::rate_output),
    Case::exact("signal::cycle", signal::cycle_assembly),
    Case::exact("readout (whole chain)", signal::readout_chain),
    Case::exact("readout output stage", signal::output_stage),
    Case::exact("signal::dither_model", signal::dither_model),
    Case::exact(
        "output thermal correction and frames",
        signal::thermal_output,
    ),
    // Calibration (firmware::calibration).
    Case::exact("calibration::fit", calibration::calibration_fit),
    Case::exact("calibration::tracking", calibration::calibration_tracking),
    // The dither drive (firmware::dither): DDS codes, the half-cycle fit, the controller.
    Case::exact("dither::dds", dither::dds),
    Case::exact("dither::half_cycle_fit", dither::half_cycle_fit),
    Case::exact("dither::controller", dither::controller),
];

/// The input generator itself (64-bit shifts on a 32-bit core).
fn rng_stream(out: &mut Outputs) {
    let mut rng = Rng::new(1);
    for _ in 0..256 {
        out.u64(rng.u64());
    }
}

/// Wrapping i32 phase (a full turn = 2^32), i64 accumulators, 64-bit division and saturation:
/// the integer operations the fixed-point signal chain is built from. On the Cortex-M4 the
/// 64-bit division is a compiler-builtins routine, on x86 one instruction.
fn int_phase_arith(out: &mut Outputs) {
    let mut rng = Rng::new(0x5eed_0001);
    let mut acc: i64 = 0;
    for _ in 0..1000 {
        let (a, b) = (rng.i32(), rng.i32());
        out.i32(a.wrapping_add(b));
        out.i32(a.wrapping_sub(b));
        out.i32(a.saturating_add(b));
        out.i64(a as i64 * b as i64);
        out.i32(((a as i64 * b as i64) >> 31) as i32); // Q31 multiply
        acc = acc.wrapping_add(a as i64 * b as i64);
        let d = rng.i32_in(1, i32::MAX) as i64;
        out.i64(acc / d);
        out.i64(acc % d);
        out.u32(a.unsigned_abs().leading_zeros());
    }
}

/// Basic IEEE operations (+, -, *, /, conversions): correctly rounded, so bit-identical.
fn f32_ieee_basic(out: &mut Outputs) {
    let mut rng = Rng::new(0x5eed_0002);
    for _ in 0..1000 {
        let (x, y) = (rng.f32_in(-1e3, 1e3), rng.f32_in(-1e3, 1e3));
        out.f32(x + y);
        out.f32(x - y);
        out.f32(x * y);
        out.f32(x / y);
        out.i32(x as i32);
        out.f32(rng.i32() as f32);
    }
}

/// `micromath` (the firmware's f32 maths): atan2, sin, cos, sqrt. Called through the trait on
/// purpose: with `std` (host) the inherent `f32` methods would win and call the C library.
fn micromath_trig(out: &mut Outputs) {
    use micromath::F32Ext as M;
    let mut rng = Rng::new(0x5eed_0003);
    for _ in 0..64 {
        let (y, x) = (rng.f32_unit(), rng.f32_unit());
        let angle = rng.f32_in(-3.2, 3.2);
        out.f32(M::atan2(y, x));
        out.f32(M::sin(angle));
        out.f32(M::cos(angle));
        out.f32(M::sqrt(x * x + y * y));
    }
}
