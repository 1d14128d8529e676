//! Cases for the turnaround front end of `firmware::signal`: count extension, CORDIC atan2, the
//! Lissajous (Heydemann) normalisation and the fringe phase resolver.
use super::{Outputs, Rng};
use firmware::math;
use firmware::sample::AdcCode;
use firmware::signal::fringe::NormalisedLevels;
use firmware::signal::{count, fringe, turnaround};
use firmware::units::{PhaseDelta, TotalPhase};
use micromath::F32Ext as M; // through the trait: the same code on host and target

/// Count extension of 16- and 32-bit encoder registers: wraps, steps near the bound, glitches
/// and resynchronisation.
pub fn fringe_count(out: &mut Outputs) {
    use count::{CountUpdate, CounterWidth, FringeCountConfig, FringeCounter};
    let mut rng = Rng::new(0x5eed_0030);
    out.u32(FringeCountConfig::max_step_for(2_400_000, 1285, 1_000_000));
    out.u32(FringeCountConfig::max_step_for(u32::MAX, u32::MAX, 0));
    for width in [CounterWidth::Bits16, CounterWidth::Bits32] {
        let config = FringeCountConfig {
            width,
            max_step_counts: 6168,
            resync_after: 3,
        };
        out.u32(config.effective_max_step());
        let mut counter = FringeCounter::new();
        let mut raw = rng.u32();
        for _ in 0..1000 {
            raw = match rng.one_in(50) {
                true => rng.u32(), // a glitch
                false => raw.wrapping_add(rng.i32_in(-7000, 7000) as u32),
            };
            out.i32(width.signed_step(raw, rng.u32()));
            let (tag, step) = match counter.update(&config, raw) {
                CountUpdate::Initialised => (0, 0),
                CountUpdate::Step(s) => (1, s),
                CountUpdate::Glitch(s) => (2, s),
                CountUpdate::Resynced(s) => (3, s),
            };
            out.u32(tag);
            out.i32(step);
            out.i64(counter.count());
            out.u32(counter.glitches());
        }
    }
}

/// CORDIC atan2 in Q32 turns over random and extreme inputs, and the Q30 radius.
pub fn fractional_fringe(out: &mut Outputs) {
    use math::{atan2_q32, radius_sq_q30};
    let mut rng = Rng::new(0x5eed_0032);
    let edges = [0, 1, -1, i32::MAX, i32::MIN, 1 << 30, -(1 << 30)];
    for y in edges {
        for x in edges {
            out.u32(atan2_q32(y, x).to_bits());
            out.u32(radius_sq_q30(x, y));
        }
    }
    for _ in 0..2000 {
        let (y, x) = (rng.i32() >> (rng.u32() % 24), rng.i32() >> (rng.u32() % 24));
        out.u32(atan2_q32(y, x).to_bits());
        out.u32(radius_sq_q30(x, y));
    }
}

/// A Lissajous figure of the two photodiode channels, in ADC codes.
pub struct Figure {
    pub offsets: (f32, f32),
    pub radii: (f32, f32),
    /// Quadrature error: the channels are 90 deg - alpha apart, rad.
    pub alpha: f32,
}

impl Figure {
    /// The codes at beat phase `psi` (rad), with a little noise.
    pub fn codes_at(&self, rng: &mut Rng, psi: f32) -> (AdcCode, AdcCode) {
        let noise = 2.0 * rng.f32_unit();
        let a = self.offsets.0 + self.radii.0 * M::cos(psi) + noise;
        let b = self.offsets.1 + self.radii.1 * M::sin(psi + self.alpha) + noise;
        let code = |x: f32| AdcCode::new(x.clamp(0.0, 4095.0) as u16).expect("clamped");
        (code(a), code(b))
    }
}

fn levels(out: &mut Outputs, l: NormalisedLevels) {
    out.i32(l.cos_q30);
    out.i32(l.sin_q30);
    out.f32(l.cos_f32());
    out.f32(l.sin_f32());
}

/// The Heydemann fit window by window (good ellipses, and ones it must refuse: a line, a tiny
/// signal, a partial arc), its coefficients, and the normalisation of random codes.
pub fn lissajous(out: &mut Outputs) {
    use fringe::{LissajousCoefficients, LissajousConfig, LissajousTracker};
    let mut rng = Rng::new(0x5eed_0033);
    let config = LissajousConfig {
        window_samples: 600,
        ..LissajousConfig::DEFAULT
    };
    let mut tracker = LissajousTracker::new(LissajousCoefficients::NOMINAL);
    let tau = core::f32::consts::TAU;
    let figure = |offsets, radii, alpha| Figure {
        offsets,
        radii,
        alpha,
    };
    let windows = [
        (figure((2100.0, 1980.0), (1500.0, 1300.0), 0.1), tau),
        (figure((2048.0, 2048.0), (1900.0, 1900.0), 0.0), tau),
        (figure((1900.0, 2200.0), (1200.0, 1600.0), -0.25), tau),
        (figure((2048.0, 2048.0), (1500.0, 1500.0), 1.5707964), tau), // in phase: a line
        (figure((2048.0, 2048.0), (100.0, 100.0), 0.0), tau),         // signal lost
        (figure((2048.0, 2048.0), (1500.0, 1500.0), 0.0), 2.0),       // partial arc
    ];
    for (figure, arc) in windows {
        let outcome = loop {
            let psi = rng.f32_in(0.0, arc);
            let (a, b) = figure.codes_at(&mut rng, psi);
            if let Some(outcome) = tracker.add(&config, a, b) {
                break outcome;
            }
        };
        match outcome {
            Ok(e) => {
                for v in [
                    e.offset_a_code,
                    e.offset_b_code,
                    e.radius_a_code,
                    e.radius_b_code,
                ] {
                    out.f32(v);
                }
                out.f32(e.quadrature_error_rad);
                out.i32(e.quadrature_error_q32);
                out.u32(e.samples);
            }
            Err(reason) => out.u32(0xdead_0000 | reason as u32),
        }
        let c = tracker.coefficients();
        let (m_aa, m_ba, m_bb) = c.matrix_q34();
        for v in [c.offset_a_q16(), c.offset_b_q16(), m_aa, m_ba, m_bb] {
            out.i32(v);
        }
        out.u32(tracker.rejections());
        for _ in 0..100 {
            levels(out, tracker.normalise(rng.adc_code(), rng.adc_code()));
        }
    }
}

/// The fringe phase resolver along a dithering phase path: count and levels agree, with
/// comparator skew, the odd lost count (glitch) and lost signal, under two board conventions.
pub fn fringe_phase(out: &mut Outputs) {
    use fringe::{FringeConvention, FringePhase, FringePhaseConfig, FringeResolver};
    let mut rng = Rng::new(0x5eed_0034);
    let q30 = (1u32 << 30) as f32;
    let conventions = [
        FringeConvention::STANDARD,
        FringeConvention {
            swap_channels: true,
            invert_b: true,
            ..FringeConvention::STANDARD
        },
    ];
    for convention in conventions {
        let config = FringePhaseConfig {
            convention,
            ..FringePhaseConfig::DEFAULT
        };
        let mut resolver = FringeResolver::new();
        let register_offset = rng.i32() as i64;
        let mut psi_q32: i64 = rng.i32() as i64; // psi_H in Q32 turns
        let mut previous = FringePhase::default();
        for i in 0..600 {
            psi_q32 +=
                (M::sin(i as f32 * 0.05) * 2e11) as i64 + rng.i32_in(-1 << 28, 1 << 28) as i64;
            let skew = rng.i32_in(-(1 << 26), 1 << 26) as i64; // comparator offset < 1/64 turn
            let mut count = ((psi_q32 + skew) >> 30) + register_offset;
            if rng.one_in(100) {
                count += rng.i32_in(-9, 9) as i64; // lost or spurious edges
            }
            let turn = (psi_q32 as u32) as f32 / 4_294_967_296.0 * core::f32::consts::TAU;
            let radius = if rng.one_in(50) {
                0.1
            } else {
                1.0 + 0.05 * rng.f32_unit()
            };
            let (c, s) = (
                (radius * M::cos(turn) * q30) as i32,
                (radius * M::sin(turn) * q30) as i32,
            );
            let board = convention.orient(NormalisedLevels {
                cos_q30: c,
                sin_q30: s,
            });
            let r = resolver.resolve(&config, convention.orient_count(count), board);
            out.i64(r.phase.turns);
            out.u32(r.phase.fraction.to_bits());
            levels(out, r.levels);
            out.i32(r.disagreement_q32);
            out.bool(r.glitch);
            out.bool(r.signal_lost);
            out.i64(r.phase.delta(&previous).to_q32());
            out.f64(r.phase.delta_fringes_f64(&previous));
            out.i32(resolver.mean_disagreement_q32());
            previous = r.phase;
        }
        out.u32(resolver.glitches());
        out.u32(resolver.signal_lost());
        out.i64(resolver.quadrant_offset(&config).unwrap_or(-1));
    }
}

/// Turnaround prediction from pick-off comparator edges of a 389 Hz dither with a threshold
/// offset (unequal high and low times), jitter, the odd missing edge, and input-rate shifts.
pub fn turnaround_schedule(out: &mut Outputs) {
    use firmware::sample::TurnaroundKind;
    use firmware::signal::lockin::{CycleFlags, CycleOutput, CycleRecord, LockinTerms};
    use firmware::signal::output::rate_shift_ticks;
    use turnaround::{shift_ticks_for_rate, Edge, Scheduler, SchedulerConfig};
    let mut rng = Rng::new(0x5eed_0035);
    let timer_hz = 84_000_000;
    let config =
        SchedulerConfig::for_dither_range(timer_hz, 300, 500, 21, 63, TurnaroundKind::Minus);
    let mut scheduler = Scheduler::new();
    let (mut t, mut rising) = (rng.u32(), true);
    for _ in 0..1500 {
        let half = if rising { 109_000 } else { 106_900 }; // threshold offset
        t = t.wrapping_add((half + rng.i32_in(-150, 150)) as u32);
        if rng.one_in(200) {
            t = t.wrapping_add(half as u32); // a missed edge: the next interval is implausible
        }
        let edge = if rising { Edge::Falling } else { Edge::Rising };
        rising = !rising;
        let shift = shift_ticks_for_rate(rng.f32_in(-20.0, 20.0), 940.0, 389.0, timer_hz);
        out.i32(shift);
        let lag = rng.i32_in(-500, 500);
        let outcome = scheduler.on_edge(&config, edge, t, shift, lag);
        out.bool(outcome.implausible);
        match outcome.schedule {
            Some(s) => {
                out.u32(s.compare_ticks);
                out.bool(s.kind == TurnaroundKind::Plus);
            }
            None => out.u32(0xdead_0000),
        }
    }
    for _ in 0..200 {
        let record = CycleRecord {
            output: CycleOutput {
                increment: PhaseDelta::from_q32(rng.i32() as i64 * 8),
                correction: PhaseDelta::ZERO,
                duration_ticks: (215_938 + rng.i32_in(-300, 300)) as u32,
                flags: CycleFlags::empty(),
            },
            raw_increment: PhaseDelta::ZERO,
            terms: LockinTerms::default(),
            end_phase: TotalPhase::from_q32(0),
            dither_amplitude_rad: rng.f32_in(0.0, 2000.0),
            dither_hz: rng.f32_in(300.0, 500.0),
        };
        out.i32(rate_shift_ticks(&record, timer_hz));
    }
    for x in [0.0, f32::NAN, f32::INFINITY, -1.0] {
        out.i32(shift_ticks_for_rate(5.0, x, 389.0, timer_hz));
        out.i32(shift_ticks_for_rate(x, 940.0, 389.0, timer_hz));
        out.i32(shift_ticks_for_rate(5.0, 940.0, x, timer_hz));
    }
}
