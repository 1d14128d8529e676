//! The fringe counter: the x4 up/down count of the squared photodiode signals as the board's
//! hardware encoder timer reports it.
//!
//! # Model
//!
//! The comparators of [`crate::photodiode`] square channel A (~cos psi_H) and channel B
//! (~sin psi_H). For increasing psi_H the pair `(A, B)` runs through the Gray sequence
//! `10 -> 11 -> 01 -> 00 -> 10`, and the x4 decoder counts **up** on every edge of it (set
//! [`CounterConfig::reverse`] to swap the channels' roles, which flips the sign). With ideal
//! comparators the count therefore equals `floor(psi_H / (pi/2))` relative to its start. The
//! state-to-quadrant table itself is the firmware's (`firmware::signal::quadrature`,
//! [`QuadratureState::bits`] gives its index); the tests hold the counter against it.
//!
//! [`QuadratureCounter`] is the hardware encoder timer (TIM5 in encoder mode 3), computed without
//! sampling: each noise-free comparator is an ideal comparator behind a backlash on the phase
//! ([`crate::photodiode::EdgeGeometry`]), so the number of edges it has produced is a floor
//! function of its backlashed phase, and the count is the sum over both channels. Exact for any
//! path of psi_H as long as psi_H moves monotonically between two calls of
//! [`QuadratureCounter::advance_to`] (with hysteresis, a reversal between calls that does not
//! show in the samples would be missed; without hysteresis the count depends on the end point
//! only). In practice: call it at each integrator step and at the exact turnarounds, where
//! psi_H reverses. The register wraps at the firmware's [`CounterWidth`] (the board profile's,
//! `firmware::profile::BoardProfile::counter_width`, by default).
//!
//! Design choice: the board counts with an encoder timer, so this is the only counter model.
//! A sampled comparator stream (a software decoder reading the pins, with comparator chatter and
//! the timer's input filter) is not modelled: nothing on the product path reads one, and the
//! firmware's software decoder is tested on its own vectors.
//!
//! [`latch_turnaround`] builds the firmware's `TurnaroundSample` from the counter, the ADC and the
//! capture timer at one instant.
//!
//! Glitches for tests: [`QuadratureCounter::inject_counts`] adds spurious counts to the register,
//! [`QuadratureCounter::miss_next_edges`] drops edges (the net effect of a missed edge: the
//! register stays one count behind).
//!
//! ```
//! use hal_sim::counter::{CounterConfig, QuadratureCounter};
//! use hal_sim::photodiode::PhotodiodeConfig;
//!
//! let ideal = PhotodiodeConfig::ideal();
//! let mut counter = QuadratureCounter::new(&ideal, CounterConfig::default(), 0.1).unwrap();
//! counter.advance_to(0.1 + 3.0 * std::f64::consts::TAU); // three fringes up
//! assert_eq!(counter.count(), 12);
//! counter.advance_to(0.1 - std::f64::consts::PI); // back to half a fringe below the start
//! assert_eq!(counter.count() as i32, -2);
//! ```
//!
//! # Limits
//!
//! - The counter assumes the comparators' edges alternate A, B, A, B around a fringe;
//!   [`QuadratureCounter::new`] refuses configurations where hysteresis bands, threshold errors
//!   and quadrature error make them overlap (the decoder would then see out-of-order edges).
//! - No comparator noise: the comparators see the noise-free levels, so they never chatter
//!   (the board's comparators have hysteresis and the timer a digital input filter for that).
//! - A real missed edge leaves the decoder's stored state stale, so the next edge of the other
//!   channel may count with the wrong sign; the model applies only the net one-count loss.
//! - The latch reads counter, both ADC channels and the timer at the same instant; real firmware
//!   sees interrupt latency and an ADC conversion time between them.

use core::f64::consts::{PI, TAU};

use crate::clock::CaptureTimer;
use crate::photodiode::{EdgeGeometry, PhotodiodeConfig, Photodiodes};
use firmware::profile::BoardProfile;
use firmware::sample::{TurnaroundKind, TurnaroundSample};
use firmware::signal::count::CounterWidth;

/// A wrapping up/down counter register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EncoderRegister {
    width: CounterWidth,
    raw: u32,
}

impl EncoderRegister {
    /// A register of `width` holding `initial` (masked to the width).
    pub fn new(width: CounterWidth, initial: u32) -> Self {
        Self {
            width,
            raw: initial & width.mask(),
        }
    }

    /// Add `delta` counts, wrapping.
    pub fn add(&mut self, delta: i64) {
        self.raw = (i64::from(self.raw).wrapping_add(delta) as u32) & self.width.mask();
    }

    /// The raw register value as the firmware reads it.
    pub fn raw(&self) -> u32 {
        self.raw
    }

    /// The register's width.
    pub fn width(&self) -> CounterWidth {
        self.width
    }
}

/// The levels of the two squared signals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct QuadratureState {
    /// Comparator A (channel ~cos psi_H) is high.
    pub a: bool,
    /// Comparator B (channel ~sin psi_H) is high.
    pub b: bool,
}

impl QuadratureState {
    /// As the firmware reads the pins: `B << 1 | A` (the state index of
    /// `firmware::signal::quadrature`, whose table maps it to the quadrant of psi_H).
    pub fn bits(self) -> u8 {
        u8::from(self.a) | (u8::from(self.b) << 1)
    }
}

/// Settings of the encoder timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CounterConfig {
    /// Register width.
    pub width: CounterWidth,
    /// Register value at the start. A real timer starts wherever the firmware sets it; with ideal
    /// comparators, `ideal_quadrant_index(psi_h0_rad) as u32` makes the register read
    /// `floor(psi_H / (pi/2))` (modulo its width) from then on.
    pub initial_count: u32,
    /// Count down for increasing psi_H (channels swapped).
    pub reverse: bool,
}

impl Default for CounterConfig {
    fn default() -> Self {
        Self {
            width: BoardProfile::F405.counter_width,
            initial_count: 0,
            reverse: false,
        }
    }
}

/// Why a counter cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CounterError {
    /// The photodiode configuration is invalid.
    InvalidPhotodiodes(crate::photodiode::PhotodiodeConfigError),
    /// Comparator edges of A and B overlap or do not alternate.
    EdgesDoNotAlternate,
}

/// Check that the four hysteresis bands (two per comparator) are disjoint and alternate A, B.
fn check_alternation(geometry: &[EdgeGeometry; 2]) -> Result<(), CounterError> {
    let mut bands: Vec<(f64, f64, usize)> = Vec::with_capacity(4);
    for (channel, g) in geometry.iter().enumerate() {
        for sign in [-1.0, 1.0] {
            let centre = (g.phase_rad + sign * g.half_high_rad).rem_euclid(TAU);
            bands.push((centre, g.backlash_rad, channel));
        }
    }
    bands.sort_by(|p, q| p.0.total_cmp(&q.0));
    for i in 0..4 {
        let (c0, w0, ch0) = bands[i];
        let (c1, w1, ch1) = bands[(i + 1) % 4];
        let gap = (c1 - c0).rem_euclid(TAU) - w0 - w1;
        if ch0 == ch1 || gap <= 0.0 {
            return Err(CounterError::EdgesDoNotAlternate);
        }
    }
    Ok(())
}

/// The hardware x4 encoder timer, driven continuously by psi_H.
#[derive(Clone, Debug)]
pub struct QuadratureCounter {
    geometry: [EdgeGeometry; 2],
    backlashed_rad: [f64; 2],
    edge_index: [i64; 2],
    register: EncoderRegister,
    reverse: bool,
    edges_since_start: i64,
    pending_misses: u64,
}

impl QuadratureCounter {
    /// A counter whose comparators follow `photodiodes`, starting at `psi_h0_rad` with the
    /// register at `config.initial_count`.
    pub fn new(
        photodiodes: &PhotodiodeConfig,
        config: CounterConfig,
        psi_h0_rad: f64,
    ) -> Result<Self, CounterError> {
        photodiodes
            .validate()
            .map_err(CounterError::InvalidPhotodiodes)?;
        let geometry = photodiodes.edge_geometry();
        check_alternation(&geometry)?;
        let backlashed_rad = geometry.map(|g| psi_h0_rad - g.phase_rad);
        Ok(Self {
            geometry,
            backlashed_rad,
            edge_index: [0, 1].map(|k| geometry[k].edge_index(backlashed_rad[k])),
            register: EncoderRegister::new(config.width, config.initial_count),
            reverse: config.reverse,
            edges_since_start: 0,
            pending_misses: 0,
        })
    }

    /// Move the beat phase to `psi_h_rad` (monotonically from the previous value) and count the
    /// edges on the way.
    pub fn advance_to(&mut self, psi_h_rad: f64) {
        let mut edges = 0;
        for k in 0..2 {
            let g = &self.geometry[k];
            let x = psi_h_rad - g.phase_rad;
            let y = self.backlashed_rad[k].clamp(x - g.backlash_rad, x + g.backlash_rad);
            self.backlashed_rad[k] = y;
            let index = g.edge_index(y);
            edges += index - self.edge_index[k];
            self.edge_index[k] = index;
        }
        self.edges_since_start += edges;
        let missed = self.pending_misses.min(edges.unsigned_abs());
        self.pending_misses -= missed;
        let counted = edges - edges.signum() * missed as i64;
        self.register
            .add(if self.reverse { -counted } else { counted });
    }

    /// The raw register, as `TurnaroundSample::encoder_count`.
    pub fn count(&self) -> u32 {
        self.register.raw()
    }

    /// True signed edges since the start (unwrapped, up for increasing psi_H, no glitches).
    pub fn edges_since_start(&self) -> i64 {
        self.edges_since_start
    }

    /// The comparator outputs now.
    pub fn state(&self) -> QuadratureState {
        QuadratureState {
            a: self.edge_index[0] & 1 != 0,
            b: self.edge_index[1] & 1 != 0,
        }
    }

    /// Add `counts` spurious counts to the register (an EMI burst the decoder took for edges).
    pub fn inject_counts(&mut self, counts: i64) {
        self.register.add(counts);
    }

    /// Do not count the next `edges` edges (in either direction).
    pub fn miss_next_edges(&mut self, edges: u64) {
        self.pending_misses += edges;
    }
}

/// What the turnaround interrupt latches, built from the simulated peripherals at `t_s`: the
/// counter advanced to `psi_h_rad`, one simultaneous conversion of both ADC channels, and the
/// capture timer. All three are taken at the same instant (no interrupt latency).
pub fn latch_turnaround(
    kind: TurnaroundKind,
    t_s: f64,
    psi_h_rad: f64,
    counter: &mut QuadratureCounter,
    photodiodes: &mut Photodiodes,
    timer: &CaptureTimer,
) -> TurnaroundSample {
    counter.advance_to(psi_h_rad);
    let codes = photodiodes.sample_codes(psi_h_rad);
    TurnaroundSample {
        kind,
        encoder_count: counter.count(),
        adc_a_code: codes.a_code,
        adc_b_code: codes.b_code,
        timestamp_ticks: timer.ticks_at(t_s),
        // The board's drive state is the caller's (the harness sets it from its drive loop).
        drive_locked: true,
    }
}

/// `floor(psi_h_rad / (pi/2))`: the ideal-comparator count relative to `psi_H = 0`.
pub fn ideal_quadrant_index(psi_h_rad: f64) -> i64 {
    (psi_h_rad / (PI / 2.0)).floor() as i64
}
