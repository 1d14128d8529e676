//! The fringe counter against the analytic quadrant count, the firmware's quadrature table and
//! a sampled Schmitt trigger.
//!
//! Tolerances: the models are deterministic and discrete, so counts, codes, bytes and ticks are
//! compared exactly, marked "(exact)"; statistical and floating checks state bound and reason.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

mod schmitt;

use firmware::signal::count::CounterWidth;
use hal_sim::clock::CaptureTimer;
use hal_sim::counter::{
    ideal_quadrant_index, latch_turnaround, CounterConfig, CounterError, QuadratureCounter,
};
use hal_sim::photodiode::{PhotodiodeConfig, Photodiodes};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use schmitt::SchmittTrigger;

fn ideal_counter(psi0: f64, config: CounterConfig) -> QuadratureCounter {
    QuadratureCounter::new(&PhotodiodeConfig::ideal(), config, psi0).unwrap()
}

/// Signed register difference for a 32-bit register.
fn delta32(from: u32, to: u32) -> i64 {
    i64::from(to.wrapping_sub(from) as i32)
}

/// Ideal comparators: count - start == floor(psi/(pi/2)) - floor(psi0/(pi/2)) along ramps up and
/// down (exact: integer comparison; the ramp steps avoid exact edge positions).
#[test]
fn count_follows_floor_on_ramps_both_ways() {
    let psi0 = 0.123;
    let mut counter = ideal_counter(psi0, CounterConfig::default());
    let start = counter.count();
    let mut psi = psi0;
    for _ in 0..20_000 {
        psi += 0.0123;
        counter.advance_to(psi);
        let expected = ideal_quadrant_index(psi) - ideal_quadrant_index(psi0);
        assert_eq!(delta32(start, counter.count()), expected, "up at {psi}");
    }
    for _ in 0..50_000 {
        psi -= 0.0131;
        counter.advance_to(psi);
        let expected = ideal_quadrant_index(psi) - ideal_quadrant_index(psi0);
        assert_eq!(delta32(start, counter.count()), expected, "down at {psi}");
        assert_eq!(counter.edges_since_start(), expected);
    }
}

/// Without hysteresis the count depends on the end point only, so even steps of many fringes
/// give the floor (what the hardware counts if the signal is continuous between updates). (exact)
#[test]
fn ideal_count_is_path_independent() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut counter = ideal_counter(0.0, CounterConfig::default());
    for _ in 0..10_000 {
        let psi: f64 = rng.random_range(-1.0e4..1.0e4);
        counter.advance_to(psi);
        assert_eq!(delta32(0, counter.count()), ideal_quadrant_index(psi));
    }
}

/// The quadrant psi_H is in, for each comparator state `(A << 1) | B`: the Gray sequence
/// 10 -> 11 -> 01 -> 00 of an x4 encoder counting up (the board's TIM5 decodes it in hardware;
/// the firmware has no table of its own).
const QUADRANT_OF_STATE: [u8; 4] = [2, 3, 1, 0];

/// A reference x4 decoder over sampled states: +1 / -1 for a step to the next / previous
/// quadrant, nothing for no change, an illegal transition for a two-bit jump.
struct ReferenceDecoder {
    quadrant: u8,
    count: i64,
    illegal: u32,
}

impl ReferenceDecoder {
    fn new(state: u8) -> Self {
        Self {
            quadrant: QUADRANT_OF_STATE[state as usize],
            count: 0,
            illegal: 0,
        }
    }

    fn step(&mut self, state: u8) {
        let q = QUADRANT_OF_STATE[state as usize];
        match (q + 4 - self.quadrant) % 4 {
            0 => {}
            1 => self.count += 1,
            3 => self.count -= 1,
            _ => self.illegal += 1,
        }
        self.quadrant = q;
    }
}

/// The comparator states follow the Gray sequence 10, 11, 01, 00 over the four quadrants: each
/// state reads as the quadrant psi_H is in. (exact)
#[test]
fn states_follow_the_encoder_quadrant_table() {
    let mut counter = ideal_counter(-FRAC_PI_2 + 0.1, CounterConfig::default());
    for q in 0..12 {
        let psi = -FRAC_PI_2 + 0.1 + FRAC_PI_2 * f64::from(q);
        counter.advance_to(psi);
        let quadrant = ideal_quadrant_index(psi).rem_euclid(4) as u8;
        let state = counter.state().bits();
        assert_eq!(QUADRANT_OF_STATE[state as usize], quadrant, "quadrant {q}");
    }
}

/// 16-bit register wraps at 65536 both ways; 32-bit at 2^32 (exact).
#[test]
fn register_wraps_at_16_and_32_bits() {
    let config16 = CounterConfig {
        width: CounterWidth::Bits16,
        initial_count: 65_530,
        reverse: false,
    };
    let mut counter = ideal_counter(0.1, config16);
    counter.advance_to(0.1 + 10.0 * FRAC_PI_2);
    assert_eq!(counter.count(), 4);
    counter.advance_to(0.1 - 7.0 * FRAC_PI_2);
    assert_eq!(counter.count(), 65_523);
    let mut counter = ideal_counter(0.1, config16);
    counter.advance_to(0.1 + 65_536.0 * FRAC_PI_2 + 3.0 * FRAC_PI_2);
    assert_eq!(counter.count(), 65_533);

    let config32 = CounterConfig {
        width: CounterWidth::Bits32,
        initial_count: u32::MAX - 2,
        reverse: false,
    };
    let mut counter = ideal_counter(0.1, config32);
    counter.advance_to(0.1 + 5.0 * FRAC_PI_2);
    assert_eq!(counter.count(), 2);
    counter.advance_to(0.1 - 1.0 * FRAC_PI_2);
    assert_eq!(counter.count(), u32::MAX - 3);
}

/// `reverse` counts down for increasing psi_H. (exact)
#[test]
fn reverse_flips_the_sign() {
    let config = CounterConfig {
        reverse: true,
        ..CounterConfig::default()
    };
    let mut counter = ideal_counter(0.1, config);
    counter.advance_to(0.1 + 9.0 * FRAC_PI_2);
    assert_eq!(delta32(0, counter.count()), -9);
}

/// Hysteresis delays each edge by the backlash w in the direction of travel: on a ramp up the
/// count is floor((psi - w)/(pi/2)), on the way back floor((psi + w)/(pi/2)); a wiggle of less
/// than 2w around an edge produces no counts (exact integer checks away from edges).
#[test]
fn hysteresis_shifts_edges_and_stops_chatter() {
    let mut config = PhotodiodeConfig::ideal();
    config.a.comparator.hysteresis_v = 0.2;
    config.b.comparator.hysteresis_v = 0.2;
    let w = (0.1f64 / config.a.amplitude_v).asin();
    let mut counter = QuadratureCounter::new(&config, CounterConfig::default(), 0.3).unwrap();
    let start_index = ideal_quadrant_index(0.3);
    let mut psi = 0.3;
    for _ in 0..5000 {
        psi += 0.00517;
        counter.advance_to(psi);
        let expected = ideal_quadrant_index(psi - w) - start_index;
        assert_eq!(delta32(0, counter.count()), expected, "up {psi}");
    }
    let top = psi;
    for _ in 0..5000 {
        psi -= 0.00491;
        counter.advance_to(psi);
        let expected = if psi > top - 2.0 * w {
            ideal_quadrant_index(top - w) - start_index
        } else {
            ideal_quadrant_index(psi + w) - start_index
        };
        assert_eq!(delta32(0, counter.count()), expected, "down {psi}");
    }
    // Wiggle around the ideal edge at 4 pi/2 by +-0.9 w: no counts at all.
    let edge = 4.0 * FRAC_PI_2;
    counter.advance_to(edge - 3.0 * w);
    let before = counter.count();
    for i in 0..1000 {
        let psi = edge + 0.9 * w * (0.1 * f64::from(i)).sin();
        counter.advance_to(psi);
        assert_eq!(counter.count(), before);
    }
    // A wiggle of +-1.1 w crosses the hysteresis band: +1 then -1.
    counter.advance_to(edge + 1.1 * w);
    assert_eq!(delta32(before, counter.count()), 1);
    counter.advance_to(edge - 1.1 * w);
    assert_eq!(counter.count(), before);
}

/// Quadrature error, unequal gains and threshold trims move the edges but the count still changes
/// by exactly 4 per fringe, the counter's states equal those of Schmitt triggers fed the
/// noise-free voltages at the same points, and the firmware's software decoder fed those states
/// counts what the counter's register counts (exact).
#[test]
fn imperfect_channels_agree_with_voltage_comparators() {
    let mut config = PhotodiodeConfig::ideal();
    config.quadrature_error_rad = 0.2;
    config.a.amplitude_v = 1.1;
    config.b.mid_level_v = 1.7;
    config.a.comparator.threshold_offset_v = 0.15;
    config.b.comparator.threshold_offset_v = -0.1;
    config.a.comparator.hysteresis_v = 0.05;
    config.b.comparator.hysteresis_v = 0.03;
    let psi0 = 0.4;
    let mut counter = QuadratureCounter::new(&config, CounterConfig::default(), psi0).unwrap();
    let initial = counter.state();
    let mut triggers = [
        SchmittTrigger::new(&config.a, initial.a),
        SchmittTrigger::new(&config.b, initial.b),
    ];
    let mut decoder = ReferenceDecoder::new(initial.bits());
    let register0 = counter.count();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut psi = psi0;
    for _ in 0..200_000 {
        psi += rng.random_range(-0.3..0.32);
        counter.advance_to(psi);
        let [va, vb] = config.levels_v(psi);
        let (a, b) = (triggers[0].update(va), triggers[1].update(vb));
        let s = counter.state();
        assert_eq!((s.a, s.b), (a, b), "at {psi}");
        decoder.step(s.bits());
        assert_eq!(decoder.count, delta32(register0, counter.count()));
    }
    assert_eq!(decoder.illegal, 0);
    let start = counter.count();
    let psi_start = psi;
    counter.advance_to(psi_start + 25.0 * TAU);
    assert_eq!(delta32(start, counter.count()), 100);
}

/// Configurations whose A and B edges do not alternate are refused. (exact)
#[test]
fn overlapping_edges_are_refused() {
    let mut config = PhotodiodeConfig::ideal();
    config.quadrature_error_rad = FRAC_PI_2;
    assert_eq!(
        QuadratureCounter::new(&config, CounterConfig::default(), 0.0).unwrap_err(),
        CounterError::EdgesDoNotAlternate
    );
    let mut config = PhotodiodeConfig::ideal();
    config.quadrature_error_rad = 1.2;
    config.a.comparator.hysteresis_v = 1.0;
    assert!(QuadratureCounter::new(&config, CounterConfig::default(), 0.0).is_err());
}

/// Glitches: injected counts add to the register; a missed edge leaves it one count short. (exact)
#[test]
fn glitch_injection() {
    let mut counter = ideal_counter(0.1, CounterConfig::default());
    counter.inject_counts(3);
    counter.advance_to(0.1 + 10.0 * FRAC_PI_2);
    assert_eq!(delta32(0, counter.count()), 13);
    counter.miss_next_edges(2);
    counter.advance_to(0.1 + 11.0 * FRAC_PI_2);
    assert_eq!(delta32(0, counter.count()), 13);
    counter.advance_to(0.1 + 20.0 * FRAC_PI_2);
    assert_eq!(delta32(0, counter.count()), 21);
    assert_eq!(counter.edges_since_start(), 20);
}

/// The turnaround latch builds the firmware's sample from the three peripherals. (exact)
#[test]
fn latch_builds_turnaround_sample() {
    use firmware::sample::TurnaroundKind;
    let pd_config = PhotodiodeConfig::ideal();
    let mut photodiodes = Photodiodes::new(pd_config, 0);
    let mut counter = QuadratureCounter::new(&pd_config, CounterConfig::default(), 0.1).unwrap();
    let timer = CaptureTimer::default();
    let psi = 0.1 + 5.0 * PI + 0.3;
    let sample = latch_turnaround(
        TurnaroundKind::Minus,
        0.5,
        psi,
        &mut counter,
        &mut photodiodes,
        &timer,
    );
    assert_eq!(sample.kind, TurnaroundKind::Minus);
    assert_eq!(sample.encoder_count, 10);
    assert_eq!(sample.timestamp_ticks, 42_000_000);
    let [va, vb] = pd_config.levels_v(psi);
    assert_eq!(sample.adc_a_code, pd_config.adc.code(va));
    assert_eq!(sample.adc_b_code, pd_config.adc.code(vb));
}

/// Throughput of the counter (informational; run with
/// `cargo test -p hal-sim --test board_counter -- --ignored --nocapture`).
#[test]
#[ignore]
fn throughput() {
    let config = PhotodiodeConfig::default();
    let psi = |t: f64| TAU * 590e3 * t;
    let mut counter = QuadratureCounter::new(&config, CounterConfig::default(), 0.0).unwrap();
    let start = std::time::Instant::now();
    for i in 0..10_000_000u32 {
        counter.advance_to(psi(f64::from(i) * 1e-7));
    }
    let wall_s = start.elapsed().as_secs_f64();
    println!(
        "counter: 1e7 updates in {wall_s:.3} s (count {})",
        counter.count()
    );
}

/// End to end through the boundary: a dithered psi_H (389 Hz, 590 kHz peak beat, plus drift)
/// drives the counter in 1 us steps and the turnaround latch at the exact extrema of psi_H. The
/// latched count plus the fractional fringe from the ADC codes (atan2 about mid-scale)
/// reconstructs psi_H. Tolerance 6 mrad: ADC noise 1 mV and quantisation 0.23 mV RMS on a
/// 1.32 V amplitude give ~0.8 mrad RMS per channel, so 6 mrad is > 7 sigma.
#[test]
fn latched_samples_reconstruct_the_beat_phase() {
    use firmware::sample::TurnaroundKind;
    let config = PhotodiodeConfig::default();
    let w_d = TAU * 389.0;
    let amp_rad = TAU * 590e3 / w_d;
    let drift_rad_per_s = 40.0;
    let psi = |t: f64| 0.3 + amp_rad * (w_d * t).sin() + drift_rad_per_s * t;
    let counter_config = CounterConfig {
        initial_count: ideal_quadrant_index(psi(0.0)) as u32,
        ..CounterConfig::default()
    };
    let mut counter = QuadratureCounter::new(&config, counter_config, psi(0.0)).unwrap();
    let mut photodiodes = Photodiodes::new(config, 99);
    let timer = CaptureTimer::default();
    // Extrema: cos(w t) = -drift / (amp w), two per dither period.
    let c = (-drift_rad_per_s / (amp_rad * w_d)).acos();
    let mut turnarounds: Vec<(f64, TurnaroundKind)> = (0..40)
        .flat_map(|n| {
            let base = TAU * f64::from(n);
            [
                ((base + c) / w_d, TurnaroundKind::Minus),
                ((base + TAU - c) / w_d, TurnaroundKind::Plus),
            ]
        })
        .collect();
    turnarounds.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut t = 0.0;
    let mut worst = 0.0f64;
    for (t_turn, kind) in turnarounds {
        while t + 1e-6 < t_turn {
            t += 1e-6;
            counter.advance_to(psi(t));
        }
        let s = latch_turnaround(
            kind,
            t_turn,
            psi(t_turn),
            &mut counter,
            &mut photodiodes,
            &timer,
        );
        let mid = config.adc.code(config.a.mid_level_v).to_f64();
        let frac = (s.adc_b_code.to_f64() - mid).atan2(s.adc_a_code.to_f64() - mid);
        let quadrant_centre = f64::from(s.encoder_count as i32) * FRAC_PI_2 + PI / 4.0;
        let psi_est = frac + TAU * ((quadrant_centre - frac) / TAU).round();
        worst = worst.max((psi_est - psi(t_turn)).abs());
        assert_eq!(s.timestamp_ticks, timer.ticks_at(t_turn));
    }
    println!("worst reconstruction error {worst:.2e} rad");
    assert!(worst < 6e-3, "worst {worst}");
}
