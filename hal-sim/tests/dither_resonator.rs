//! The driven dither's physics against brute force and against the textbook resonator.
//!
//! - The closed-form segment response against classic RK4 of the same three-state ODE
//!   (amplifier low-pass + resonator) with the same continuous sinusoidal drive, and its
//!   derivative jet against finite differences.
//! - The zero-order-hold model (fundamental only) against RK4 of the true DAC staircase
//!   through the amplifier's gain and clip, the low-pass and the resonator: the difference is
//!   the images' effect, which must stay within the stated bound.
//! - Free ring-down with `tau = Q / (pi f0)`, the steady state at resonance
//!   (`Q G` times the drive, -90 deg plus the amplifier's lags) and the Lorentzian off it.
//!
//! Everything is deterministic (no noise); each tolerance is stated where it is checked.

use core::f64::consts::{PI, TAU};
use hal_sim::dither::drive::DriveSegment;
use hal_sim::dither::driven::DrivenDither;
use hal_sim::dither::linear::{Forcing, LinearSystem, ResonatorState, SegmentResponse};
use hal_sim::dither::open_loop::OpenLoopDrive;
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::dither::MAX_JET;

/// `[v, theta, theta']' ` of the low-pass + resonator driven by `y`.
fn rhs(sys: &LinearSystem, y: f64, x: [f64; 3]) -> [f64; 3] {
    let w0 = sys.w0_rad_per_s;
    [
        sys.lowpass_rad_per_s * (y - x[0]),
        x[2],
        -w0 / sys.q * x[2] - w0 * w0 * x[1] + w0 * w0 * sys.gain_arcsec_per_v * x[0],
    ]
}

/// One classic RK4 step of length `h` from `t` with the drive `y(t)`.
fn rk4(sys: &LinearSystem, y: impl Fn(f64) -> f64, t: f64, h: f64, x: [f64; 3]) -> [f64; 3] {
    let add =
        |a: [f64; 3], b: [f64; 3], k: f64| [a[0] + k * b[0], a[1] + k * b[1], a[2] + k * b[2]];
    let k1 = rhs(sys, y(t), x);
    let k2 = rhs(sys, y(t + 0.5 * h), add(x, k1, 0.5 * h));
    let k3 = rhs(sys, y(t + 0.5 * h), add(x, k2, 0.5 * h));
    let k4 = rhs(sys, y(t + h), add(x, k3, h));
    let mut out = x;
    for i in 0..3 {
        out[i] += h / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
    out
}

fn to_array(s: &ResonatorState) -> [f64; 3] {
    [s.amp_output_v, s.angle_arcsec, s.rate_arcsec_per_s]
}

fn default_system() -> LinearSystem {
    ResonatorParams::default().system_at(0.0)
}

/// Closed form vs RK4 (h = T/20000: its error ~ (p h)^4 ~ 1e-11 of the low-pass transient,
/// far below the 1e-9 tolerance) over 5 cycles from a state far from the steady one (all
/// three transients present), on and off resonance. Tolerance 1e-9 of the peak angle (the
/// brief's; measured ~1e-12, regression bound 1e-10).
#[test]
fn closed_form_matches_rk4_of_the_same_ode() {
    let sys = default_system();
    let start = ResonatorState {
        amp_output_v: 4.0,
        angle_arcsec: 100.0,
        rate_arcsec_per_s: -2.0e5,
    };
    for freq_hz in [389.0, 385.0, 500.0] {
        let forcing = Forcing {
            dc_v: 0.5,
            amplitude_v: 7.5,
            freq_hz,
            phase_rad: 0.7,
        };
        let t0 = 0.25;
        let closed = SegmentResponse::new(&sys, &forcing, t0, &start);
        let y = |t: f64| {
            forcing.dc_v
                + forcing.amplitude_v * (TAU * freq_hz * (t - t0) + forcing.phase_rad).sin()
        };
        let period = 1.0 / freq_hz;
        let steps = 20_000;
        let h = period / steps as f64;
        let mut x = to_array(&start);
        let (mut worst, mut peak) = (0.0f64, 0.0f64);
        for n in 0..5 * steps {
            let t = t0 + n as f64 * h;
            x = rk4(&sys, y, t, h, x);
            if (n + 1) % 1000 == 0 {
                let c = to_array(&closed.state_at(t + h));
                worst = worst.max((c[1] - x[1]).abs());
                peak = peak.max(c[1].abs());
            }
        }
        let rel = worst / peak;
        eprintln!("{freq_hz} Hz: closed form vs RK4 {rel:.2e} of the peak angle {peak:.1} arcsec");
        assert!(rel < 1e-10, "{rel}");
    }
}

/// The jet (angle and 15 derivatives) against fourth-order central differences of the
/// previous order (h = 1 us: truncation (p h)^4 / 30 ~ 4e-9 of the fastest term, the
/// low-pass transient; rounding ~1e-11). Tolerance 1e-7 of each order's scale.
#[test]
fn jet_matches_finite_differences() {
    let sys = default_system();
    let start = ResonatorState {
        amp_output_v: -6.0,
        angle_arcsec: 300.0,
        rate_arcsec_per_s: 1.0e5,
    };
    let forcing = Forcing {
        dc_v: 0.0,
        amplitude_v: 7.5,
        freq_hz: 389.0,
        phase_rad: 0.0,
    };
    let r = SegmentResponse::new(&sys, &forcing, 0.0, &start);
    let jet = |t: f64| {
        let mut j = [0.0; MAX_JET];
        r.angle_jet(t, 1.0, &mut j);
        j
    };
    let fastest = sys.lowpass_rad_per_s.max(sys.w0_rad_per_s);
    let h = 1e-6;
    for t in [1e-4, 7e-4, 3e-3] {
        let j = jet(t);
        let (m2, m1, p1, p2) = (jet(t - 2.0 * h), jet(t - h), jet(t + h), jet(t + 2.0 * h));
        for k in 0..MAX_JET - 1 {
            let fd = (m2[k] - 8.0 * m1[k] + 8.0 * p1[k] - p2[k]) / (12.0 * h);
            let scale = j[k + 1].abs() + fastest * j[k].abs();
            assert!(
                (fd - j[k + 1]).abs() < 1e-7 * scale,
                "t {t} order {}: {fd} vs {}",
                k + 1,
                j[k + 1]
            );
        }
    }
}

/// The true DAC staircase (every sample through the amplifier's gain and clip, held for a
/// tick) integrated by RK4 with 64 steps per tick, from `start` at t = 0; returns the angle at
/// the end of every tick.
fn staircase_angles(
    params: &ResonatorParams,
    segments: &[DriveSegment],
    start: ResonatorState,
    ticks: u64,
) -> Vec<f64> {
    let sys = params.system_at(0.0);
    let dac = &params.dac;
    let amp = &params.amplifier;
    let k = amp.gain_v_per_v;
    let sub = 64;
    let h = dac.tick_s() / sub as f64;
    let mut x = to_array(&start);
    let mut out = Vec::with_capacity(ticks as usize);
    let mut seg = 0;
    for n in 0..ticks {
        let t = n as f64 * dac.tick_s();
        while seg + 1 < segments.len() && segments[seg + 1].start_s <= t + 1e-12 {
            seg += 1;
        }
        let s = &segments[seg];
        let m = ((t - s.start_s) * dac.tick_hz).round();
        let u = (s.offset_v + s.amplitude_v * (s.phase_rad + m * s.step_rad).sin())
            .clamp(0.0, dac.reference_v);
        let y = (k * (u - amp.input_ref_v)).clamp(-amp.output_limit_v, amp.output_limit_v);
        for i in 0..sub {
            x = rk4(&sys, |_| y, t + i as f64 * h, h, x);
        }
        out.push(x[1]);
    }
    out
}

/// The model's angle at the end of every tick.
fn model_angles(
    params: &ResonatorParams,
    segments: &[DriveSegment],
    start: ResonatorState,
    ticks: u64,
) -> Vec<f64> {
    let mut d = DrivenDither::new(
        &ResonatorParams {
            initial: start,
            ..*params
        },
        389.0,
        1.0,
    );
    for s in segments {
        d.push(*s).unwrap();
    }
    d.extend_until(ticks as f64 * params.dac.tick_s()).unwrap();
    (1..=ticks)
        .map(|n| d.angle_arcsec(n as f64 * params.dac.tick_s()))
        .collect()
}

/// Segments `k0..k1` of `drive`, with the amplitude scaled by `gain` and the phase shifted.
fn segments(
    drive: &OpenLoopDrive,
    k0: u64,
    k1: u64,
    gain: f64,
    shift_rad: f64,
) -> Vec<DriveSegment> {
    (k0..k1)
        .map(|k| {
            let s = drive.segment(k);
            DriveSegment {
                amplitude_v: s.amplitude_v * gain,
                phase_rad: s.phase_rad + shift_rad,
                ..s
            }
        })
        .collect()
}

/// The largest difference between the staircase and the model over ticks `[from, to)`.
fn worst(truth: &[f64], model: &[f64], from: usize, to: usize) -> f64 {
    (from..to).fold(0.0f64, |m, i| m.max((truth[i] - model[i]).abs()))
}

/// The steady images: a DDS at 389 Hz re-stated every half cycle, f_s = 20 kHz, at Q = 20 so
/// that the staircase's own start-up (it starts from the model's state, which lacks the
/// images' ripple) has rung down after 0.3 s (19 ring-down times). Over the next 4 cycles
/// the staircase and the model differ by the images' steady response only, which
/// `image_bound_arcsec` bounds (the sum of the images' amplitudes; they align at the ticks,
/// so the bound is reached). The RK4 reference is converged (64 steps per tick, h p = 0.015:
/// 32 and 64 steps agree to 1e-3 of the difference), so the bound gets 1 % of margin.
#[test]
fn steady_images_stay_within_the_bound() {
    let params = ResonatorParams {
        q: 20.0,
        ..Default::default()
    };
    let drive = OpenLoopDrive::new(&params.dac, 389.0, 0.4, params.amplifier.input_ref_v);
    let start = drive.steady_state(&params);
    let segs = segments(&drive, 0, 260, 1.0, 0.0);
    let settled = (0.3 * params.dac.tick_hz) as usize;
    let ticks = settled as u64 + 4 * 52;
    let truth = staircase_angles(&params, &segs, start, ticks);
    let model = model_angles(&params, &segs, start, ticks);
    let measured = worst(&truth, &model, settled, ticks as usize);
    let bound = params.image_bound_arcsec(drive.freq_hz(), drive.amplitude_v());
    let peak = model.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    eprintln!("steady images: {measured:.3e} arcsec (bound {bound:.3e}) of {peak:.2} arcsec");
    assert!(measured <= 1.01 * bound, "{measured} vs {bound}");
}

/// A change of the DDS changes its images, and the change of their steady ripple on the
/// piezo voltage kicks the resonator: a ringing the model (fundamental only) does not have,
/// bounded by `image_ring_bound_arcsec` (about `(pi^2/3) (|da|/a) (f/f_s) (f0/f_s) / Q` of the
/// resonant amplitude: 1.25e-6 of it at 389 Hz, f_s = 20 kHz, Q = 1000, `|da| = a`; the images
/// align at the ticks, so it is reached). Here at 450 arcsec and Q = 1000: a DDS re-stated
/// every half cycle for 4 cycles (no change: no ring), then +10 % amplitude, then a phase jump
/// of pi/2, 4 cycles each. The staircase starts from the model's state, which lacks the
/// images: a switch-on, `|da| = a`. The rings add at most; the steady images (5e-7 arcsec) on
/// top. The RK4 reference is converged (32 vs 64 steps per tick agree to 1e-3 of the
/// difference measured), so the bound gets 1 % of margin.
#[test]
fn dds_changes_ring_within_the_bound() {
    let params = ResonatorParams::default();
    let drive = OpenLoopDrive::tuned(&params, 389.0, 450.0);
    let start = drive.steady_state(&params);
    let (f, fs) = (drive.freq_hz(), params.dac.tick_hz);
    let a = drive.amplitude_v();
    let mut segs = segments(&drive, 0, 8, 1.0, 0.0);
    segs.extend(segments(&drive, 8, 16, 1.1, 0.0));
    segs.extend(segments(&drive, 16, 24, 1.1, PI / 2.0));
    let ticks = (segs[23].start_s * fs) as u64 + 205;
    let truth = staircase_angles(&params, &segs, start, ticks);
    let model = model_angles(&params, &segs, start, ticks);
    let ring = |da_v: f64| params.image_ring_bound_arcsec(f, da_v);
    let steady = params.image_bound_arcsec(f, 1.1 * a);
    let t8 = (segs[8].start_s * fs) as usize;
    let first = worst(&truth, &model, 0, t8);
    let all = worst(&truth, &model, 0, ticks as usize);
    let first_bound = steady + ring(a);
    let bound = first_bound + ring(0.1 * a) + ring(1.1 * a * 2f64.sqrt());
    let approx = PI * PI / 3.0 * (f / fs) * (params.f0_hz / fs) / params.q * 450.0;
    eprintln!(
        "staircase vs fundamental: {first:.4e} arcsec after the switch-on (bound {first_bound:.4e}, \
         approximation {approx:.4e}), {all:.4e} after the changes (bound {bound:.4e})"
    );
    assert!(first <= 1.01 * first_bound, "{first} vs {first_bound}");
    assert!(all <= 1.01 * bound, "{all} vs {bound}");
    // Regression: the switch-on ring reaches its bound (the images align at the ticks).
    assert!(first >= 0.8 * first_bound, "{first} vs {first_bound}");
}

/// Overdriven (the DAC at 1.5 V: exactly the amplifier's +-30 V; at 1.8 V: 20 % beyond the
/// clip): the describing function gets the fundamental, the clip's harmonics are left out.
/// Their effect is at most `sum_n 1/(n (n^2 - 1)) / Q` (n = 3, 5, ...: 1/(17.6 Q)) of the
/// response at resonance for a hard clip (the n-th harmonic of a square wave is 1/n of the
/// fundamental, the resonator at n f0 gives 1/((n^2 - 1) Q) of its resonant response); on
/// top, the staircase's switch-on ring (1.25e-6, see above).
#[test]
fn clip_harmonics_stay_within_the_bound() {
    let params = ResonatorParams::default();
    for dac_v in [1.5, 1.8] {
        let drive = OpenLoopDrive::new(&params.dac, 389.0, dac_v, params.amplifier.input_ref_v);
        let start = drive.steady_state(&params);
        let segs = segments(&drive, 0, 8, 1.0, 0.0);
        let ticks = (segs[7].start_s * params.dac.tick_hz) as u64 + 200;
        let truth = staircase_angles(&params, &segs, start, ticks);
        let model = model_angles(&params, &segs, start, ticks);
        let peak = model.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let worst = truth
            .iter()
            .zip(&model)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let rel = worst / peak;
        let harmonics: f64 = (3..200)
            .step_by(2)
            .map(|n| 1.0 / (n * (n * n - 1)) as f64)
            .sum();
        let bound = harmonics / params.q + 1.3e-6;
        eprintln!("DAC {dac_v} V: amplitude {peak:.1} arcsec, clip harmonics {rel:.2e} (bound {bound:.2e})");
        assert!(rel < bound, "{rel}");
    }
}

/// Extremes of the angle (zeros of the rate) over `[t0, t1]`: `(t, angle)`.
fn extremes(d: &DrivenDither, t0: f64, t1: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut t = t0;
    while let Some((te, _)) = d.pickoff_turnaround_after(t) {
        if te > t1 {
            break;
        }
        out.push((te, d.angle_arcsec(te)));
        t = te;
    }
    out
}

/// The resonator started in the steady state of `drive` (no start-up transient), its
/// nominal frequency 389 Hz and its phase scale 1 (the angle read in arcsec).
fn at_steady_state(params: &ResonatorParams, drive: &OpenLoopDrive) -> DrivenDither {
    DrivenDither::new(
        &ResonatorParams {
            initial: drive.steady_state(params),
            ..*params
        },
        389.0,
        1.0,
    )
}

/// Free ring-down: drive removed at t = 0 from the 450 arcsec steady state. The maxima decay
/// as `e^{-t/tau}`, `tau = Q/(pi f0)` = 0.8183 s: the log-linear fit of 1 s of maxima (after
/// the amplifier's low-pass has settled, 10 ms) gives tau to 1e-6 (rounding and the extremes'
/// bisection: measured ~1e-9).
#[test]
fn ring_down_time_is_q_over_pi_f0() {
    for q in [1000.0, 5000.0] {
        let params = ResonatorParams {
            q,
            ..Default::default()
        };
        let drive = OpenLoopDrive::tuned(&params, 389.0, 450.0);
        let mut d = at_steady_state(&params, &drive);
        d.push(DriveSegment {
            amplitude_v: 0.0,
            ..drive.segment(0)
        })
        .unwrap();
        d.extend_until(1.1).unwrap();
        let maxima: Vec<(f64, f64)> = extremes(&d, 0.01, 1.01)
            .into_iter()
            .filter(|&(_, a)| a > 0.0)
            .collect();
        let n = maxima.len() as f64;
        let (st, sl) = maxima
            .iter()
            .fold((0.0, 0.0), |(a, b), &(t, x)| (a + t, b + x.ln()));
        let (mt, ml) = (st / n, sl / n);
        let (num, den) = maxima.iter().fold((0.0, 0.0), |(a, b), &(t, x)| {
            (a + (t - mt) * (x.ln() - ml), b + (t - mt) * (t - mt))
        });
        let tau = -den / num;
        let expect = params.ring_down_s(0.0);
        eprintln!("Q {q}: tau {tau:.9} s vs Q/(pi f0) {expect:.9} s");
        assert!((tau / expect - 1.0).abs() < 1e-6);
    }
}

/// Amplitude and phase of the steady state (20 s = 24 tau after a start at rest: the free
/// mode is down to e^-24) against the textbook resonator times the amplifier chain:
/// `|theta| = G |H_lp| K sinc a / sqrt((1 - r^2)^2 + (r/Q)^2)`, at resonance `Q G |H_lp| K
/// sinc a` and -90 deg - atan(f/f_c) - pi f/f_s to the DAC's sine. Amplitudes to 1e-7
/// (bisected extremes; the residual free mode ~4e-11), phase to 1e-6 rad.
#[test]
fn steady_state_is_the_lorentzian() {
    let params = ResonatorParams::default();
    let (f0, q, g) = (params.f0_hz, params.q, params.piezo_gain_arcsec_per_v);
    let (k, fc, fs) = (
        params.amplifier.gain_v_per_v,
        params.amplifier.cutoff_hz,
        params.dac.tick_hz,
    );
    let a = 0.3;
    let half_width = f0 / (2.0 * q);
    for df in [0.0, half_width, -3.0 * half_width, 10.0 * half_width, 50.0] {
        let drive = OpenLoopDrive::new(&params.dac, f0 + df, a, params.amplifier.input_ref_v);
        let f = drive.freq_hz();
        let mut d = DrivenDither::new(&params, f0, 1.0);
        d.push(drive.segment(0)).unwrap();
        d.extend_until(20.01).unwrap();
        let ext = extremes(&d, 20.0, 20.01);
        let amp = ext.iter().fold(0.0f64, |m, &(_, x)| m.max(x.abs()));
        let r = f / f0;
        let chain = k * (PI * f / fs).sin() / (PI * f / fs) / (1.0 + (f / fc).powi(2)).sqrt();
        let lorentz = g * chain * a / ((1.0 - r * r).powi(2) + (r / q).powi(2)).sqrt();
        eprintln!("f0 {df:+.4} Hz: {amp:.6} arcsec vs {lorentz:.6}");
        assert!((amp / lorentz - 1.0).abs() < 1e-7, "{amp} vs {lorentz}");
        if df == 0.0 {
            assert!((amp / (q * g * chain * a) - 1.0).abs() < 1e-7);
            // The maximum of the angle follows the drive's phase pi/2 by the resonator's lag
            // (90 deg at f0; the DDS's frequency is f0 to 2e-6 Hz, 1e-5 rad of lag) + the
            // low-pass's + half a tick.
            let (t_max, _) = ext.iter().copied().find(|&(_, x)| x > 0.0).unwrap();
            let drive_phase = (TAU * f * t_max).rem_euclid(TAU);
            let lag = drive_phase - PI / 2.0;
            let resonator_lag = (r / q).atan2(1.0 - r * r);
            let expect = resonator_lag + (f / fc).atan() + PI * f / fs;
            eprintln!(
                "  lag {:.6} deg vs {:.6} deg",
                lag.to_degrees(),
                expect.to_degrees()
            );
            assert!((lag - expect).abs() < 1e-6, "{lag} vs {expect}");
        }
    }
}

/// A DDS re-stated every half cycle (phase continued by its Q32 accumulator) is the same
/// drive as one long segment: from rest, the angle agrees over 1 s (780 segments) to
/// rounding: 1e-11 of the 357 arcsec it reaches (measured 4e-11 arcsec).
#[test]
fn restated_segments_equal_one_long_segment() {
    let params = ResonatorParams::default();
    let drive = OpenLoopDrive::tuned(&params, 389.0, 450.0);
    let mut chained = DrivenDither::new(&params, 389.0, 1.0);
    let mut single = DrivenDither::new(&params, 389.0, 1.0);
    single.push(drive.segment(0)).unwrap();
    single.extend_until(1.0).unwrap();
    let mut k = 0;
    while chained.known_until_s() < 1.0 {
        chained.push(drive.segment(k)).unwrap();
        k += 1;
    }
    let mut worst = 0.0f64;
    for i in 0..10_000 {
        let t = i as f64 * 1e-4;
        worst = worst.max((chained.angle_arcsec(t) - single.angle_arcsec(t)).abs());
    }
    eprintln!("{k} segments vs one: {worst:.2e} arcsec");
    assert!(worst < 1e-11 * 357.0, "{worst}");
}

/// f0 and Q follow the scripted temperature: a 10 K ramp over the first second (-0.04 Hz/K,
/// -0.5 %/K: f0 389 -> 388.6 Hz, two half-widths; Q 1000 -> 950), held constant per 10 ms
/// (`hold_s`) while it drifts. An open-loop drive at 389 Hz keeps running; 15 s after the ramp
/// (18 ring-down times: the transient is down to 1e-8) the amplitude is the Lorentzian of the
/// new f0 and Q (to 1e-6: the residual ring and the bisected extremes).
#[test]
fn temperature_drift_moves_the_resonance() {
    use hal_sim::dither::resonator::{TemperatureDrift, TemperatureProfile};
    let params = ResonatorParams {
        temperature: TemperatureDrift {
            profile: TemperatureProfile::ramp(0.0, 25.0, 1.0, 35.0).unwrap(),
            f0_hz_per_c: -0.04,
            q_relative_per_c: -0.005,
            ..TemperatureDrift::NONE
        },
        ..Default::default()
    };
    params.validate().unwrap();
    let drive = OpenLoopDrive::tuned(&params, 389.0, 450.0);
    let mut d = at_steady_state(&params, &drive);
    d.push(drive.segment(0)).unwrap();
    d.extend_until(16.01).unwrap();
    // Split every 10 ms while the temperature changes (100 in the first second), not after.
    assert_eq!(d.index_at(0.999), 100);
    assert_eq!(d.index_at(16.0), 101);
    let amp = extremes(&d, 16.0, 16.01)
        .iter()
        .fold(0.0f64, |m, &(_, x)| m.max(x.abs()));
    let (f0, q) = params.f0_q_at(2.0);
    assert!((f0 - 388.6).abs() < 1e-12 && (q - 950.0).abs() < 1e-9);
    let expect = params.dac_to_angle(drive.freq_hz(), 2.0).abs() * drive.amplitude_v();
    let r = drive.freq_hz() / f0;
    let lorentz_ratio = (1.0 / ((1.0 - r * r).powi(2) + (r / q).powi(2)).sqrt()) / 1000.0;
    eprintln!(
        "after the drift: {amp:.6} arcsec (Lorentzian {expect:.6}, {:.4} of the start)",
        lorentz_ratio
    );
    assert!((amp / expect - 1.0).abs() < 1e-6, "{amp} vs {expect}");
    assert!((amp / 450.0 - lorentz_ratio).abs() < 1e-3, "{amp}");
}
