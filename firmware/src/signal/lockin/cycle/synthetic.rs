//! Synthetic turnaround readings of an ideal sine dither, for the tests of this stage and of
//! the stages after it.

use super::*;

/// The capture-timer clock, Hz.
pub const TIMER_HZ: f32 = 84e6;
/// The docs/physics.md dither frequency, Hz.
pub const DITHER_HZ: f64 = 389.0;
const Q32: f64 = Q32_PER_FRINGE;

/// Readings of an ideal sine dither (amplitude `amp` rad) on a constant rate. Traversal `i`
/// adds `err(i, psi0)`, where psi0 is the actual phase latched at its turnaround (all earlier
/// errors plus half of its own: an implicit equation, solved by iteration).
pub fn readings(
    amp: f64,
    rate: f64,
    n: usize,
    err: impl Fn(usize, f64) -> f64,
) -> Vec<TurnaroundReading> {
    readings_with_amplitude(|_| amp, rate, n, err)
}

/// As [`readings`], with the dither's amplitude `amp_at(t)` rad at turnaround time t s (a
/// wandering dither: the angle at a turnaround is -A(t) or +A(t)).
pub fn readings_with_amplitude(
    amp_at: impl Fn(f64) -> f64,
    rate: f64,
    n: usize,
    err: impl Fn(usize, f64) -> f64,
) -> Vec<TurnaroundReading> {
    let half = 0.5 / DITHER_HZ;
    let mut accumulated = 0.0;
    (0..n)
        .map(|i| {
            let t = i as f64 * half;
            let kind = if i.is_multiple_of(2) {
                TurnaroundKind::Plus
            } else {
                TurnaroundKind::Minus
            };
            let amp = amp_at(t);
            let dither = if i.is_multiple_of(2) { -amp } else { amp };
            let base = dither + rate * t + accumulated;
            let mut e = 0.0;
            for _ in 0..20 {
                e = err(i, base + 0.5 * e);
            }
            let psi = base + 0.5 * e;
            accumulated += e;
            TurnaroundReading {
                kind,
                phase: TotalPhase::from_q32((psi / core::f64::consts::TAU * Q32).round() as i64),
                levels: Some(LevelPair {
                    cos_psi_h: psi.cos() as f32,
                    sin_psi_h: psi.sin() as f32,
                }),
                timestamp_ticks: (t * TIMER_HZ as f64).round() as u32,
                flags: CycleFlags::empty(),
            }
        })
        .collect()
}

/// The cycles the assembler closes from `readings` (uncompensated).
pub fn assemble(readings: &[TurnaroundReading]) -> Vec<CycleRecord> {
    let config = CycleConfig::for_dither(TIMER_HZ, DITHER_HZ as f32, 0.2);
    let mut asm = CycleAssembler::new();
    readings
        .iter()
        .filter_map(|r| asm.on_turnaround(&config, *r))
        .collect()
}
