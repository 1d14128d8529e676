//! Instruction counts of the signal chain on the Cortex-M4F: run with
//! `cargo fw-icount --example cost` (QEMU with `-icount shift=0`, where TIM2 at PSC = 0 counts
//! exactly one per executed instruction; see TOOLCHAIN.md section 7). Without `-icount` the
//! numbers follow host time and mean nothing.
//!
//! Measures, on a synthetic steady dither (389 Hz, 450 arcsec at SF 1.8655 arcsec/pulse):
//! - one Lissajous sample (`Readout::on_lissajous_sample`, moment accumulation) and one
//!   Lissajous window solve (the 5x5 fit, once per 4096 samples);
//! - one turnaround (`Readout::on_turnaround`: count extension, normalisation, CORDIC, fringe
//!   phase, P1/P2 share), averaged over "-" turnarounds, and one cycle-closing "+" turnaround
//!   (adds cycle assembly and compensation);
//! - one sample of the pick-off stream (`Readout::on_pickoff_sample`: the dither model's
//!   oscillator, regressors and sums; averaged over the samples, and the most, a window's
//!   close with its fit and frequency loop), 40 000 a second;
//! - one output latch (`Readout::on_output_latch`: count extension, normalisation, CORDIC,
//!   the dither model at the latch, dither stripping and K's fit, the record) and its wire
//!   frame (`encode_output_frame`: COBS and CRC-32): the work between a sync edge and the
//!   record's first byte on the UART.
//!
//! These are instructions, not cycles: on the M4 at 168 MHz with flash wait states a cycle
//! count is some 1.2 to 1.6 times higher; the board's DWT.CYCCNT gives the real figure.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::icount::{InstructionCounter, Timer};
    use firmware::protocol::output_frame::{encode_output_frame, MAX_OUTPUT_FRAME};
    use firmware::readout::Readout;
    use firmware::sample::{AdcCode, OutputSample, TurnaroundKind, TurnaroundSample};
    use firmware::signal::compensation::{Coefficients, CompensationSettings};
    use firmware::signal::output::dither_model::PickoffSample;
    use micromath::F32Ext;

    const TIMER_HZ: f64 = 84e6;
    const DITHER_HZ: f64 = 389.0;
    /// Half-cycle excursion of the docs/physics.md dither, x4 counts (2 x 1515.6 rad / (pi/2)).
    const EXCURSION_COUNTS: u32 = 1930;

    /// ADC codes of a point on the Lissajous circle (centre 2048, radius 1300 codes).
    fn codes(phase: f32) -> (AdcCode, AdcCode) {
        let (s, c) = phase.sin_cos();
        let code = |x: f32| AdcCode::saturating(x as u16);
        (code(2048.0 + 1300.0 * c), code(2048.0 + 1300.0 * s))
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let counter = InstructionCounter::start(Timer::Tim2);

        // The readout: Lissajous samples until the first window is solved.
        let config = firmware::profile::BoardProfile::F405.readout_config(DITHER_HZ);
        let settings = CompensationSettings {
            coefficients: Coefficients::from_rad_per_s(344.0, 579.0).unwrap(),
            enabled: true,
        };
        let mut readout = Readout::new(&config, settings);
        let window = config.lissajous.window_samples;
        let mut phase = 0.0f32;
        let mut lissajous_total = 0u32;
        for _ in 0..window - 1 {
            phase += 2.399_963; // golden angle: covers the circle
            let (a, b) = codes(phase);
            lissajous_total += counter.count(|| readout.on_lissajous_sample(&config, a, b));
        }
        let (a, b) = codes(phase + 2.4);
        let solve = counter.count(|| readout.on_lissajous_sample(&config, a, b));
        let lissajous_per_sample = lissajous_total / (window - 1);

        // Turnarounds of a steady dither at a small rate.
        let half_ticks = (TIMER_HZ / (2.0 * DITHER_HZ)) as u32;
        let (mut minus_total, mut minus_n, mut plus_total, mut plus_n) = (0u32, 0u32, 0u32, 0u32);
        let mut base = 100_000u32;
        for i in 0..400u32 {
            let kind = if i % 2 == 0 {
                TurnaroundKind::Plus
            } else {
                TurnaroundKind::Minus
            };
            let count_now = if i % 2 == 0 {
                base
            } else {
                base + EXCURSION_COUNTS
            };
            if i % 2 == 1 {
                base += 3; // slow drift of the count: a small input rate
            }
            let (a, b) = codes(count_now as f32 * core::f32::consts::FRAC_PI_2 + 0.3);
            let sample = TurnaroundSample {
                kind,
                encoder_count: count_now,
                adc_a_code: a,
                adc_b_code: b,
                timestamp_ticks: i * half_ticks,
                drive_locked: true,
            };
            let mut closed = false;
            let n = counter.count(|| closed = readout.on_turnaround(&config, sample).is_some());
            if i >= 4 {
                if kind == TurnaroundKind::Minus {
                    minus_total += n;
                    minus_n += 1;
                } else if closed {
                    plus_total += n;
                    plus_n += 1;
                }
            }
        }
        // Output latches at 1 kHz on the same steady dither (the count and pick-off follow it),
        // the pick-off stream at 40 kHz before each.
        let (mut latch_total, mut frame_total, mut latch_n) = (0u32, 0u32, 0u32);
        let (mut stream_total, mut stream_n, mut stream_max) = (0u32, 0u32, 0u32);
        let mut frame = [0u8; MAX_OUTPUT_FRAME];
        let pickoff = |k: u32| {
            let t = k as f32 / 40_000.0;
            let x = 2048.0 + 1125.0 * (core::f32::consts::TAU * DITHER_HZ as f32 * t).sin();
            AdcCode::saturating(x as u16)
        };
        for i in 0..300u32 {
            for k in 40 * i..40 * i + 40 {
                let sample = PickoffSample {
                    timestamp_ticks: k * 2100,
                    code: pickoff(k),
                };
                let n = counter.count(|| readout.on_pickoff_sample(&config, sample));
                if i >= 100 {
                    stream_total += n;
                    stream_n += 1;
                    stream_max = stream_max.max(n);
                }
            }
            // The latch half a stream period after a sample (its own conversion agrees with
            // the model there).
            let t = (i * 84_000 + 1_050) as f32 / TIMER_HZ as f32;
            let dither = (core::f32::consts::TAU * DITHER_HZ as f32 * t).sin();
            let count = 100_000 + (dither * EXCURSION_COUNTS as f32 / 2.0) as i32 as u32;
            let (a, b) = codes(count as f32 * core::f32::consts::FRAC_PI_2 + 0.3);
            let sample = OutputSample {
                encoder_count: count,
                adc_a_code: a,
                adc_b_code: b,
                pickoff_code: AdcCode::saturating((2048.0 + 1125.0 * dither) as u16),
                timestamp_ticks: i * 84_000 + 1_050,
                drive_locked: true,
            };
            let mut record = None;
            let n = counter.count(|| record = Some(readout.on_output_latch(&config, sample)));
            let m = match record {
                Some(r) => counter.count(|| {
                    encode_output_frame(&r, &mut frame);
                }),
                None => 0,
            };
            if i >= 100 {
                latch_total += n;
                frame_total += m;
                latch_n += 1;
            }
        }
        let per_latch = latch_total / latch_n.max(1);
        let per_stream_sample = stream_total / stream_n.max(1);
        let per_frame = frame_total / latch_n.max(1);

        let per_minus = minus_total / minus_n.max(1);
        let per_plus = plus_total / plus_n.max(1);

        defmt::info!(
            "Lissajous sample: {=u32} instructions; window solve (every {=u32} samples): {=u32}",
            lissajous_per_sample,
            window,
            solve
        );
        defmt::info!("turnaround (-): {=u32} instructions; cycle-closing turnaround (+): {=u32} instructions ({=u32} cycles closed)", per_minus, per_plus, plus_n);
        let per_cycle = per_minus + per_plus;
        defmt::info!("per dither cycle: {=u32} instructions = {=u32} per mille of 168 M instructions/s at 389 Hz, {=u32} per mille at 1 kHz", per_cycle, per_cycle * 389 / 168_000, per_cycle * 1000 / 168_000);
        defmt::info!("pick-off stream sample: {=u32} instructions on average, {=u32} at most (a window's close); at 40 kHz {=u32} per mille of 168 M instructions/s", per_stream_sample, stream_max, per_stream_sample * 40_000 / 168_000);
        let modelled = record_status_model(&readout, &config);
        defmt::info!("output latch: {=u32} instructions; its frame (COBS + CRC-32): {=u32}; sync edge to frame ready: {=u32} instructions = {=u32} ns at 168 MHz and 1 instruction per cycle (dither model valid: {=bool})", per_latch, per_frame, per_latch + per_frame, (per_latch + per_frame) * 1000 / 168, modelled);
        semihosting::process::exit(if plus_n > 100 && latch_n == 200 && modelled {
            0
        } else {
            1
        })
    }

    /// The dither model was valid for the latches measured.
    fn record_status_model(readout: &Readout, config: &firmware::readout::ReadoutConfig) -> bool {
        readout.dither_model_status(config).valid
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("cost: an MCU example (`cargo fw-icount --example cost`)");
}
