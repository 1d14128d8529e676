//! Cases for `firmware::signal`: one function per module, named after it.
use super::{Outputs, Rng};
use firmware::sample::TurnaroundKind;
use firmware::signal::{compensation, lockin_terms, output};

/// Edge inputs every float case should see besides the random ones.
const SPECIAL_F32: [f32; 6] = [0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e-40];

fn kind(rng: &mut Rng) -> TurnaroundKind {
    if rng.one_in(2) {
        TurnaroundKind::Plus
    } else {
        TurnaroundKind::Minus
    }
}

/// P1/P2 terms: k = sqrt(2 pi / |psi_ddot|) (`libm::sqrtf`), the sine-dither acceleration, and
/// the per-traversal shares with their sums and weights.
pub fn lockin_terms(out: &mut Outputs) {
    use lockin_terms::{
        sine_dither_accel_rad_per_s2, traversal_terms, traversal_time_s, LevelPair, LockinTerms,
    };
    let mut rng = Rng::new(0x5eed_0010);
    for x in SPECIAL_F32 {
        out.opt_f32(traversal_time_s(x));
        out.opt_f32(sine_dither_accel_rad_per_s2(x, 1.3e-3));
        out.opt_f32(sine_dither_accel_rad_per_s2(400.0, x));
    }
    let mut cycle = LockinTerms::default();
    for _ in 0..500 {
        let accel = sine_dither_accel_rad_per_s2(rng.f32_in(-2e3, 2e3), rng.f32_in(0.0, 2e-3));
        out.opt_f32(accel);
        let k_s = traversal_time_s(accel.unwrap_or(0.0) * rng.f32_in(-1.5, 1.5));
        out.opt_f32(k_s);
        let levels = LevelPair {
            cos_psi_h: rng.f32_unit(),
            sin_psi_h: rng.f32_unit(),
        };
        let share = traversal_terms(kind(&mut rng), levels, k_s.unwrap_or(26e-6));
        cycle = cycle + share.scaled(if rng.one_in(4) { 0.5 } else { 1.0 });
        for v in [share.p1_s, share.p2_s, cycle.p1_s, cycle.p2_s] {
            out.f32(v);
        }
    }
}

/// Q15.16 coefficients (rounding, refusals), a P1 + b P2, rad -> Q32 fringes, and a
/// compensator with staged coefficient sets accumulating its integer total.
pub fn compensation(out: &mut Outputs) {
    use compensation::{
        rad_per_s_to_q16, rad_to_q32_fringes, Coefficients, CompensationSettings, Compensator,
    };
    use lockin_terms::LockinTerms;
    let q16 = |out: &mut Outputs, v: f32| match rad_per_s_to_q16(v) {
        Ok(code) => out.i32(code),
        Err(e) => out.u32(0xdead_0000 | e as u32),
    };
    let mut rng = Rng::new(0x5eed_0011);
    for v in SPECIAL_F32
        .into_iter()
        .chain([32767.0, -32767.0, 32767.002, 0.5 / 65536.0])
    {
        q16(out, v);
    }
    let settings = |rng: &mut Rng| CompensationSettings {
        coefficients: Coefficients::from_rad_per_s(rng.f32_in(-1e3, 1e3), rng.f32_in(-1e3, 1e3))
            .unwrap_or_default(),
        enabled: !rng.one_in(5),
    };
    let mut comp = Compensator::new(settings(&mut rng));
    for _ in 0..500 {
        q16(out, rng.f32_in(-4e4, 4e4));
        out.i64(rad_to_q32_fringes(rng.f32_in(-4.0, 4.0)));
        if rng.one_in(8) {
            comp.stage(settings(&mut rng));
        }
        let terms = LockinTerms {
            p1_s: rng.f32_in(-6e-5, 6e-5),
            p2_s: rng.f32_in(-6e-5, 6e-5),
        };
        out.f32(comp.active().coefficients.lockin_error_rad(terms));
        out.i64(comp.cycle_correction(terms));
        out.i64(comp.total_correction_q32());
    }
}

/// The rate averager in both modes over cycles near the paper's 389 Hz dither, with a drift
/// that crosses whole-fringe boundaries, random flags, and the f64 readings it produces.
pub fn rate_output(out: &mut Outputs) {
    use output::{AveragerConfig, AveragingMode, CycleFlags, CycleOutput, RateAverager};
    let mut rng = Rng::new(0x5eed_0012);
    for (mode, window_cycles) in [
        (AveragingMode::FixedWindow, 7),
        (AveragingMode::WholePeriods, 97),
    ] {
        let config = AveragerConfig {
            window_cycles,
            mode,
            timer_hz: 84e6,
            scale_factor_arcsec: 1.8655,
        };
        let mut averager = RateAverager::new();
        let drift_q32 = rng.i32() as i64 * 3; // up to ~1.5 fringe per cycle
        for _ in 0..1500 {
            let cycle = CycleOutput {
                increment_q32: drift_q32 + rng.i32_in(-1 << 28, 1 << 28) as i64,
                correction_q32: rng.i32() as i64,
                duration_ticks: (215_938 + rng.i32_in(-500, 500)) as u32,
                flags: CycleFlags(if rng.one_in(50) {
                    1 << (rng.u32() % 4)
                } else {
                    0
                }),
            };
            if let Some(r) = averager.push(&config, cycle) {
                out.f64(r.rate_fringes_per_s);
                out.f64(r.rate_deg_per_h);
                out.f64(r.span_s);
                out.bool(r.whole_periods);
                out.u32(r.flags.0 as u32);
                out.u32(r.cycles);
            }
        }
    }
}
