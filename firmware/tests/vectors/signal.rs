//! Cases for `firmware::signal`: one function per module, named after it.
use super::{frontend::Figure, Outputs, Rng};
use firmware::sample::{AdcCode, TurnaroundKind};
use firmware::signal::{compensation, lockin, output};
use firmware::units::{PhaseDelta, TotalPhase};

/// The code of a conversion of `x` codes (truncated), which the generators keep in range.
fn adc_code(x: f32) -> AdcCode {
    AdcCode::new(x as u16).expect("a 12-bit code")
}

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
    use lockin::{
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
        rad_per_s_to_q16, rad_to_phase_delta, Coefficients, CompensationSettings, Compensator,
    };
    use lockin::LockinTerms;
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
        out.i64(rad_to_phase_delta(rng.f32_in(-4.0, 4.0)).to_q32());
        if rng.one_in(8) {
            comp.stage(settings(&mut rng));
        }
        let terms = LockinTerms {
            p1_s: rng.f32_in(-6e-5, 6e-5),
            p2_s: rng.f32_in(-6e-5, 6e-5),
        };
        let next = comp.staged_or_active();
        out.i32(next.coefficients.a_q16);
        out.i32(next.coefficients.b_q16);
        out.bool(next.enabled);
        out.f32(comp.active().coefficients.lockin_error_rad(terms));
        out.i64(comp.cycle_correction(terms).to_q32());
        out.i64(comp.total_correction().to_q32());
    }
}

fn reading(out: &mut Outputs, r: output::RateReading) {
    out.f64(r.rate_fringes_per_s);
    out.f64(r.rate_deg_per_h);
    out.f64(r.span_s);
    out.bool(r.whole_periods);
    out.u32(r.flags.0 as u32);
    out.u32(r.cycles);
}

/// The rate averager in both modes over cycles near the paper's 389 Hz dither, with a drift
/// that crosses whole-fringe boundaries, random flags, and the f64 readings it produces.
pub fn rate_output(out: &mut Outputs) {
    use lockin::{CycleFlags, CycleOutput};
    use output::{AveragerConfig, AveragingMode, RateAverager};
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
                increment: PhaseDelta::from_q32(drift_q32 + rng.i32_in(-1 << 28, 1 << 28) as i64),
                correction: PhaseDelta::from_q32(rng.i32() as i64),
                duration_ticks: (215_938 + rng.i32_in(-500, 500)) as u32,
                flags: CycleFlags(if rng.one_in(50) {
                    1 << (rng.u32() % 4)
                } else {
                    0
                }),
            };
            if let Some(r) = averager.push(&config, cycle) {
                reading(out, r);
            }
        }
        reading(out, averager.flush(&config)); // the partial window
    }
}

/// Cycle assembly from alternating turnarounds of a 389 Hz sine dither with drift, jitter, lost
/// signals and the odd missed turnaround, compensated by a compensator with fixed a, b.
pub fn cycle_assembly(out: &mut Outputs) {
    use compensation::{Coefficients, CompensationSettings, Compensator};
    use lockin::{CycleAssembler, CycleConfig, CycleFlags, LevelPair, TurnaroundReading};
    let mut rng = Rng::new(0x5eed_0013);
    let config = CycleConfig::for_dither(84e6, 389.0, 0.2);
    let coefficients = Coefficients::from_rad_per_s(387.0, 383.0).unwrap_or_default();
    let mut comp = Compensator::new(CompensationSettings {
        coefficients,
        enabled: true,
    });
    let mut assembler = CycleAssembler::new();
    let (mut phase_q32, mut ticks, mut plus) = (0i64, 0u32, true);
    for _ in 0..2000 {
        let excursion_q32 = 300i64 << 32; // 300 fringes peak to peak
        phase_q32 += if plus { excursion_q32 } else { -excursion_q32 } + rng.i32() as i64;
        ticks = ticks.wrapping_add((107_969 + rng.i32_in(-300, 300)) as u32);
        plus = !plus;
        if rng.one_in(300) {
            continue; // a missed turnaround
        }
        let levels = LevelPair {
            cos_psi_h: rng.f32_unit(),
            sin_psi_h: rng.f32_unit(),
        };
        let reading = TurnaroundReading {
            kind: if plus {
                TurnaroundKind::Plus
            } else {
                TurnaroundKind::Minus
            },
            phase: TotalPhase::from_q32(phase_q32),
            levels: (!rng.one_in(100)).then_some(levels),
            timestamp_ticks: ticks,
            flags: CycleFlags(if rng.one_in(100) { 2 } else { 0 }),
        };
        let Some(r) = assembler
            .on_turnaround(&config, reading)
            .map(|r| comp.compensate(r))
        else {
            continue;
        };
        out.i64(r.output.increment.to_q32());
        out.i64(r.output.correction.to_q32());
        out.u32(r.output.duration_ticks);
        out.u32(r.output.flags.0 as u32);
        out.i64(r.raw_increment.to_q32());
        out.f32(r.terms.p1_s);
        out.f32(r.terms.p2_s);
        out.i64(r.end_phase.to_q32());
        out.f32(r.dither_amplitude_rad);
        out.f32(r.dither_hz);
        out.f64(r.raw_increment_rad());
        out.f64(r.duration_s(&config));
    }
}

/// The F405's readout with compensation on (a = 387, b = 383 rad/s) and the Lissajous fit
/// trained on 4096 conversions of an elliptic, offset figure; the figure, for the latches.
fn trained_readout(
    rng: &mut Rng,
) -> (
    firmware::readout::ReadoutConfig,
    firmware::readout::Readout,
    Figure,
) {
    use compensation::{Coefficients, CompensationSettings};
    let config = firmware::profile::BoardProfile::F405.readout_config(389.0);
    let settings = CompensationSettings {
        coefficients: Coefficients::from_rad_per_s(387.0, 383.0).unwrap_or_default(),
        enabled: true,
    };
    let mut readout = firmware::readout::Readout::new(&config, settings);
    let figure = Figure {
        offsets: (2010.0, 2090.0),
        radii: (1600.0, 1450.0),
        alpha: 0.08,
    };
    for _ in 0..4096 {
        let psi = rng.f32_in(0.0, core::f32::consts::TAU);
        let (a, b) = figure.codes_at(rng, psi);
        readout.on_lissajous_sample(&config, a, b);
    }
    (config, readout, figure)
}

/// The whole chain (`firmware::readout`): Lissajous samples teach the normalisation, then the
/// turnaround latches of a 389 Hz dither (encoder register, both ADC codes, capture time) with a
/// slow input rate become compensated cycles.
pub fn readout_chain(out: &mut Outputs) {
    use firmware::sample::TurnaroundSample;
    let mut rng = Rng::new(0x5eed_0014);
    let (config, mut readout, figure) = trained_readout(&mut rng);
    let register_offset = rng.u32();
    let (mut centre_q32, mut ticks) = (0i64, 0u32); // psi_H in Q32 turns
    for i in 0..1200u32 {
        centre_q32 += 40_000_000 + rng.i32_in(-1 << 20, 1 << 20) as i64; // the input rate
        let plus = i % 2 == 0; // "+" at a phase minimum, "-" at a maximum
        let excursion_q32 = (150i64 << 32) + rng.i32_in(-1 << 24, 1 << 24) as i64;
        let psi_q32 = centre_q32 + if plus { -excursion_q32 } else { excursion_q32 };
        ticks = ticks.wrapping_add((107_969 + rng.i32_in(-200, 200)) as u32);
        let angle = (psi_q32 as u32) as f32 * (core::f32::consts::TAU / 4_294_967_296.0);
        let (adc_a_code, adc_b_code) = figure.codes_at(&mut rng, angle);
        let sample = TurnaroundSample {
            kind: if plus {
                TurnaroundKind::Plus
            } else {
                TurnaroundKind::Minus
            },
            encoder_count: ((psi_q32 >> 30) as u32).wrapping_add(register_offset),
            adc_a_code,
            adc_b_code,
            timestamp_ticks: ticks,
            drive_locked: true,
        };
        if let Some(r) = readout.on_turnaround(&config, sample) {
            out.i64(r.output.increment.to_q32());
            out.i64(r.output.correction.to_q32());
            out.u32(r.output.duration_ticks);
            out.u32(r.output.flags.0 as u32);
            out.f32(r.terms.p1_s);
            out.f32(r.terms.p2_s);
        }
    }
    let c = readout.counters();
    for v in [
        c.turnarounds,
        c.cycles,
        c.counter_glitches,
        c.phase_glitches,
        c.signal_lost,
    ] {
        out.u32(v);
    }
    out.u32(c.lissajous_fits);
    out.u32(c.lissajous_rejections);
    let (amplitude_rad, dither_hz) = readout.dither();
    out.f32(amplitude_rad);
    out.f32(dither_hz);
}

/// The output stage (`Readout::on_output_latch`: the pick-off stream's model, stripping with
/// K's in-phase and quadrature fit, the record, its wire frame): the pick-off stream at 40 kHz
/// and output latches at 1 kHz on a 389 Hz dither whose pick-off reads 4 % high and lags 3 us,
/// with a slow input rate, interleaved with the turnarounds that close cycles (so the
/// compensation's corrections enter too, and the model is seeded). Every record's fields, its
/// frame's bytes, the fitted taps and the measured lag: the model's integer sums, the f32 fits
/// and the i128 angle must agree bit for bit on both sides.
pub fn output_stage(out: &mut Outputs) {
    use firmware::protocol::output_frame::{encode_output_frame, MAX_OUTPUT_FRAME};
    use firmware::sample::{OutputSample, TurnaroundSample};
    use firmware::signal::output::dither_model::PickoffSample;
    let mut rng = Rng::new(0x5eed_0020);
    let (config, mut readout, figure) = trained_readout(&mut rng);
    // psi_H (Q32 turns) = rate t + 240 fringes sin(w t); the pick-off 1.04 x the nominal
    // 1125 codes per 450 arcsec, 3 us late. Latches every 84 000 ticks (1 kHz), turnarounds at
    // the dither's extremes.
    let w = core::f32::consts::TAU * 389.0;
    let psi_at = |t: f32| -> i64 {
        let fringes = 0.3 * t + 240.0 * libm::sinf(w * t);
        (fringes as f64 * 4_294_967_296.0) as i64
    };
    let pickoff_at = |t: f32| 2048.0 + 1.04 * 1125.0 * libm::sinf(w * (t - 3e-6));
    let mut frame = [0u8; MAX_OUTPUT_FRAME];
    let half_period = 1.0 / (2.0 * 389.0);
    let (mut next_sync, mut next_turn, mut plus) = (0.001f32, 0.25 * 4.0 * half_period, false);
    let mut tick = 0u32;
    let tick_s = |k: u32| k as f32 / 40_000.0;
    for _ in 0..1500 {
        let (t, is_sync) = if next_sync < next_turn {
            (next_sync, true)
        } else {
            (next_turn, false)
        };
        // The pick-off stream up to the latch.
        while tick_s(tick) <= t {
            let code = adc_code(pickoff_at(tick_s(tick)) + rng.f32_in(-1.0, 1.0));
            let timestamp_ticks = tick * 2100;
            readout.on_pickoff_sample(
                &config,
                PickoffSample {
                    timestamp_ticks,
                    code,
                },
            );
            tick += 1;
        }
        let psi_q32 = psi_at(t);
        let angle = (psi_q32 as u32) as f32 * (core::f32::consts::TAU / 4_294_967_296.0);
        let (adc_a_code, adc_b_code) = figure.codes_at(&mut rng, angle);
        let encoder_count = (psi_q32 >> 30) as u32;
        let timestamp_ticks = (t as f64 * 84e6) as u32;
        if is_sync {
            let sample = OutputSample {
                encoder_count,
                adc_a_code,
                adc_b_code,
                pickoff_code: adc_code(pickoff_at(t) + rng.f32_in(-1.0, 1.0)),
                timestamp_ticks,
                drive_locked: true,
            };
            let r = readout.on_output_latch(&config, sample);
            out.u64(r.sequence);
            out.u64(r.time_ticks);
            out.u32(r.period_ticks);
            out.i32(r.delta_angle_q16);
            out.i64(r.angle_q16);
            out.f32(r.rate_deg_per_h);
            out.u32(r.status.0 as u32);
            let n = encode_output_frame(&r, &mut frame);
            for &byte in &frame[..n] {
                out.u32(byte as u32);
            }
            next_sync += 0.001;
        } else {
            let sample = TurnaroundSample {
                kind: if plus {
                    TurnaroundKind::Plus
                } else {
                    TurnaroundKind::Minus
                },
                encoder_count,
                adc_a_code,
                adc_b_code,
                timestamp_ticks,
                drive_locked: true,
            };
            if let Some(c) = readout.on_turnaround(&config, sample) {
                out.i64(c.output.correction.to_q32());
            }
            plus = !plus;
            next_turn += half_period;
        }
    }
    let s = readout.strip_status(&config);
    out.f32(s.k);
    out.f32(s.k_quadrature);
    out.f32(s.k_std_rel);
    out.u32(s.updates);
    out.u32(s.converged as u32);
    out.i32(readout.pickoff_lag_ticks(&config).unwrap_or(i32::MIN));
    let m = readout.dither_model_status(&config);
    out.f32(m.frequency_hz);
    out.f32(m.amplitude_codes);
    out.u32(m.restarts);
}

/// The dither model alone (`signal::output::dither_model`): a noisy pick-off stream at 40 kHz
/// of a dither at 300-600 Hz with random amplitude, phase and offset, a seed off by up to
/// 0.5 Hz, a gap, a far re-seed; the estimates at random instants between samples and the
/// model's state after every window. Integer sums, `cossin`, the f32 solve and `atan2`.
pub fn dither_model(out: &mut Outputs) {
    use firmware::signal::output::dither_model::{DitherModel, DitherModelConfig, PickoffSample};
    let mut rng = Rng::new(0x5eed_0022);
    let config = DitherModelConfig::for_pickoff(40_000.0, 84_000_000, AdcCode::MID);
    for _ in 0..3 {
        let hz = rng.f32_in(300.0, 600.0);
        let amp = rng.f32_in(400.0, 1500.0);
        let (phase, offset) = (rng.f32_in(-3.0, 3.0), rng.f32_in(-40.0, 40.0));
        let mut model = DitherModel::new();
        model.seed(&config, hz + rng.f32_in(-0.5, 0.5));
        let mut timestamp_ticks = rng.u32();
        for k in 0..8_000u32 {
            if k == 5_000 {
                timestamp_ticks = timestamp_ticks.wrapping_add(100 * 2100); // a gap
            }
            if k == 6_000 {
                model.seed(&config, hz + 3.0); // far: restarts
            }
            let t = k as f32 / 40_000.0;
            let x = amp * libm::cosf(core::f32::consts::TAU * hz * t + phase);
            let code = adc_code(2048.0 + offset + x + rng.f32_in(-1.5, 1.5));
            model.push(
                &config,
                PickoffSample {
                    timestamp_ticks,
                    code,
                },
            );
            if k % 97 == 0 {
                let at = timestamp_ticks.wrapping_add(rng.i32_in(0, 2099) as u32);
                match model.estimate(&config, at) {
                    Some(e) => {
                        out.f32(e.in_phase_codes);
                        out.f32(e.quadrature_codes);
                        out.f32(e.offset_codes);
                    }
                    None => out.u32(u32::MAX),
                }
                let s = model.status(&config);
                out.bool(s.valid);
                out.f32(s.frequency_hz);
                out.f32(s.frequency_error_hz);
                out.f32(s.amplitude_codes);
                out.u32(s.restarts);
            }
            timestamp_ticks = timestamp_ticks.wrapping_add(2100);
        }
    }
}

/// The thermal part of the output (`thermal::model`, `signal::output::record`,
/// `protocol::thermal_frame`): a model with random coefficients gives the correction at random
/// temperatures and rates (the f32 polynomials); records are made under it, some with the
/// sensor failed or the model off (the corrected increments, the status bits, the temperature
/// words), and the thermal frames the stream puts before them (which records get one, and
/// their bytes) must agree bit for bit on both sides.
pub fn thermal_output(out: &mut Outputs) {
    use firmware::profile::BoardProfile;
    use firmware::protocol::thermal_frame::{encode_thermal_frame, ThermalFramer, THERMAL_FRAME};
    use firmware::signal::output::record::{OutputRecorder, OutputStatus};
    use firmware::thermal::model::{ThermalCorrection, ThermalModel};
    use firmware::thermal::state::{ThermalInput, NO_VALUE};
    use firmware::units::TotalPhase;
    let mut rng = Rng::new(0x5eed_0027);
    let config = BoardProfile::F405.readout_config(389.0).output;
    let model = ThermalModel {
        reference_c: 25.0,
        min_c: -20.0,
        max_c: 60.0,
        bias_deg_h: [
            rng.f32_in(-0.1, 0.1),
            rng.f32_in(-0.01, 0.01),
            rng.f32_in(-1e-4, 1e-4),
            rng.f32_in(-1e-6, 1e-6),
        ],
        bias_deg_h_per_c_per_min: rng.f32_in(-0.01, 0.01),
        scale_ppm: [
            rng.f32_in(-10.0, 10.0),
            rng.f32_in(-1.0, 1.0),
            rng.f32_in(-0.01, 0.01),
        ],
    };
    let mut recorder = OutputRecorder::new();
    let mut framer = ThermalFramer::default();
    let mut frame = [0u8; THERMAL_FRAME];
    let (mut timestamp_ticks, mut phase_q32) = (0u32, 0i64);
    let (mut temperature_q7, mut rate_centi_c_per_min) = (25 * 128, 0i16);
    let (mut corrected, mut frames) = (0u32, 0u32);
    for k in 0..2000 {
        // The sensor's results change the temperature and its rate now and then (8 results a
        // second against 1000 records), so most records need no thermal frame.
        if rng.one_in(64) {
            temperature_q7 += rng.i32_in(-2, 3) as i16;
            rate_centi_c_per_min = rng.i32_in(-200, 200) as i16;
        }
        let sensor_fault = rng.one_in(50);
        let temp_c = f32::from(temperature_q7) / 128.0;
        let rate_c_per_min = f32::from(rate_centi_c_per_min) / 100.0;
        let correction = (!sensor_fault && k % 500 < 400)
            .then(|| ThermalCorrection::of(&model, temp_c, rate_c_per_min, 1.8655));
        if let Some(c) = correction {
            out.f32(c.bias_fringes_per_s);
            out.f32(c.scale_error);
        }
        recorder.set_thermal(ThermalInput {
            temperature_q7: if sensor_fault {
                NO_VALUE
            } else {
                temperature_q7
            },
            rate_centi_c_per_min: if sensor_fault {
                NO_VALUE
            } else {
                rate_centi_c_per_min
            },
            sensor_fault,
            correction,
        });
        // 1 kHz latches with a little jitter; the stripped phase at about 1 fringe/s.
        timestamp_ticks = timestamp_ticks.wrapping_add((84_000 + rng.i32_in(-1100, 1100)) as u32);
        phase_q32 += 4_294_967 + i64::from(rng.i32_in(-50_000, 50_000));
        let r = recorder.record(
            &config,
            timestamp_ticks,
            TotalPhase::from_q32(phase_q32),
            OutputStatus::DITHER_LOCKED,
        );
        out.u64(r.sequence);
        out.i32(r.delta_angle_q16);
        out.i64(r.angle_q16);
        out.f32(r.rate_deg_per_h);
        out.u32(u32::from(r.status.0));
        out.i32(i32::from(r.temperature_q7));
        out.i32(i32::from(r.temperature_rate_centi_c_per_min));
        corrected += u32::from(r.status.0 & OutputStatus::THERMAL_CORRECTED.0 != 0);
        if let Some(f) = framer.before(&r) {
            frames += 1;
            let n = encode_thermal_frame(&f, &mut frame);
            out.u64(f.from_sequence);
            for &byte in frame.get(..n).unwrap_or(&[]) {
                out.u32(u32::from(byte));
            }
        }
    }
    // The case covers what it says: corrected and uncorrected records (expected 2000 x 0.8
    // x 49/50 = 1568; 1558 with this seed) and thermal frames for some records only (about 31
    // changes of the values, two per sensor fault, a refresh: 126 with this seed).
    assert!(
        (1450..1650).contains(&corrected),
        "{corrected} corrected records"
    );
    assert!((80..200).contains(&frames), "{frames} thermal frames");
    out.u32(corrected);
    out.u32(frames);
}
