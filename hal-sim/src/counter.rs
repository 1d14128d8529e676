//! The fringe counter: the x4 up/down count of the squared photodiode signals, both as a hardware
//! encoder timer reports it and as the sampled edge stream a software decoder would read.
//!
//! # Model
//!
//! The comparators of [`crate::photodiode`] square channel A (~cos psi_H) and channel B
//! (~sin psi_H). For increasing psi_H the pair `(A, B)` runs through the Gray sequence
//! `10 -> 11 -> 01 -> 00 -> 10`, and the x4 decoder counts **up** on every edge of it (set
//! [`CounterConfig::reverse`] to swap the channels' roles, which flips the sign). With ideal
//! comparators the count therefore equals `floor(psi_H / (pi/2))` relative to its start.
//!
//! - [`QuadratureCounter`] is the hardware encoder timer (TIM in encoder mode 3), computed without
//!   sampling: each noise-free comparator is an ideal comparator behind a backlash on the phase
//!   ([`crate::photodiode::EdgeGeometry`]), so the number of edges it has produced is a floor
//!   function of its backlashed phase, and the count is the sum over both channels. Exact for any
//!   path of psi_H as long as psi_H moves monotonically between two calls of
//!   [`QuadratureCounter::advance_to`] (with hysteresis, a reversal between calls that does not
//!   show in the samples would be missed; without hysteresis the count depends on the end point
//!   only). In practice: call it at each integrator step and at the exact turnarounds, where
//!   psi_H reverses. The register wraps at 16 or 32 bits ([`CounterWidth`]).
//! - [`EdgeSampler`] samples the comparator outputs at a fixed rate (e.g. 10 MHz), from a
//!   closure `psi_H(t)`: what a software decoder reading the pins by DMA gets. The comparators see
//!   the noisy analog levels here, one noise draw per channel per sample, so noise near a
//!   threshold makes them chatter unless hysteresis suppresses it. At the peak beat rate of
//!   ~590 kHz there are ~2.4 M edges/s, so a state lasts ~420 ns: the sampler must see every
//!   state at least once, i.e. run well above 2.4 MHz (unequal quadrants from quadrature or
//!   threshold errors shorten some states); at 2 MHz it skips states, which shows up as illegal
//!   (two-bit) transitions.
//! - [`StateDecoder`] is the hardware decoder fed by such a sampled stream, with the timer's
//!   digital input filter (an edge is accepted after N equal consecutive samples, so pulses
//!   shorter than N samples are ignored).
//!
//! [`latch_turnaround`] builds the firmware's `TurnaroundSample` from the counter, the ADC and the
//! capture timer at one instant.
//!
//! Glitches for tests: [`QuadratureCounter::inject_counts`] adds spurious counts to the register,
//! [`QuadratureCounter::miss_next_edges`] drops edges (the net effect of a missed edge: the
//! register stays one count behind), and [`EdgeSampler::inject_glitch`] inverts a channel for a
//! few samples of the sampled stream.
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
//! - The continuous counter assumes the comparators' edges alternate A, B, A, B around a fringe;
//!   [`QuadratureCounter::new`] refuses configurations where hysteresis bands, threshold errors
//!   and quadrature error make them overlap (the decoder would then see out-of-order edges).
//! - No comparator noise in the continuous counter; use the sampled path for chatter.
//! - A real missed edge leaves the decoder's stored state stale, so the next edge of the other
//!   channel may count with the wrong sign; the model applies only the net one-count loss.
//! - A real encoder timer facing a two-bit jump counts something implementation-defined; the
//!   [`StateDecoder`] counts nothing and records an illegal transition.
//! - The latch reads counter, both ADC channels and the timer at the same instant; real firmware
//!   sees interrupt latency and an ADC conversion time between them.

use core::f64::consts::{PI, TAU};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::clock::CaptureTimer;
use crate::photodiode::{gaussian_v, Comparator, EdgeGeometry, PhotodiodeConfig, Photodiodes};
use firmware::sample::{TurnaroundKind, TurnaroundSample};

/// Width of the encoder timer's counter register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CounterWidth {
    /// 16-bit timer (TIM1/3/4/8 on the F405): wraps at 65536.
    Bits16,
    /// 32-bit timer (TIM2/TIM5): wraps at 2^32.
    Bits32,
}

impl CounterWidth {
    /// Mask of the register's bits.
    pub fn mask(self) -> u32 {
        match self {
            Self::Bits16 => 0xFFFF,
            Self::Bits32 => u32::MAX,
        }
    }
}

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
    /// As pin bits: bit 0 = A, bit 1 = B.
    pub fn bits(self) -> u8 {
        u8::from(self.a) | (u8::from(self.b) << 1)
    }

    /// From pin bits: bit 0 = A, bit 1 = B.
    pub fn from_bits(bits: u8) -> Self {
        Self {
            a: bits & 1 != 0,
            b: bits & 2 != 0,
        }
    }

    /// Position in the up-counting Gray sequence `10, 11, 01, 00` (0..4).
    fn gray_position(self) -> u8 {
        match (self.a, self.b) {
            (true, false) => 0,
            (true, true) => 1,
            (false, true) => 2,
            (false, false) => 3,
        }
    }

    /// Steps from `self` to `next`: `Some(+1 | 0 | -1)`, or `None` for a two-bit jump.
    pub fn step_to(self, next: Self) -> Option<i8> {
        match (next.gray_position() + 4 - self.gray_position()) % 4 {
            0 => Some(0),
            1 => Some(1),
            3 => Some(-1),
            _ => None,
        }
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
            width: CounterWidth::Bits32,
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

/// Which squared signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    A,
    B,
}

/// Invert `channel` of the sampled stream for samples `start_index .. start_index + len_samples`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Glitch {
    pub start_index: u64,
    pub len_samples: u64,
    pub channel: Channel,
}

/// The comparator outputs sampled at a fixed rate from `psi_H(t)`.
///
/// Sample `i` is taken at `t0_s + i / sample_rate_hz` (computed from the index, so no rounding
/// accumulates).
#[derive(Clone, Debug)]
pub struct EdgeSampler {
    levels: PhotodiodeConfig,
    comparators: [Comparator; 2],
    rng: ChaCha8Rng,
    sample_rate_hz: f64,
    t0_s: f64,
    next_index: u64,
    glitches: Vec<Glitch>,
}

impl EdgeSampler {
    /// A sampler at `sample_rate_hz` whose first sample is at `t0_s`. The comparators start in
    /// the state a [`QuadratureCounter`] started at `psi_h0_rad` reports.
    pub fn new(
        photodiodes: &PhotodiodeConfig,
        sample_rate_hz: f64,
        t0_s: f64,
        psi_h0_rad: f64,
        seed: u64,
    ) -> Self {
        if let Err(e) = photodiodes.validate() {
            panic!("invalid photodiode config: {e:?}");
        }
        assert!(sample_rate_hz > 0.0, "sample rate must be positive");
        let [ga, gb] = photodiodes.edge_geometry();
        Self {
            levels: *photodiodes,
            comparators: [
                Comparator::new(&photodiodes.a, ga.state_without_history(psi_h0_rad)),
                Comparator::new(&photodiodes.b, gb.state_without_history(psi_h0_rad)),
            ],
            rng: ChaCha8Rng::seed_from_u64(seed),
            sample_rate_hz,
            t0_s,
            next_index: 0,
            glitches: Vec::new(),
        }
    }

    /// Time of sample `index` (s).
    pub fn sample_time_s(&self, index: u64) -> f64 {
        self.t0_s + index as f64 / self.sample_rate_hz
    }

    /// Index of the next sample.
    pub fn next_index(&self) -> u64 {
        self.next_index
    }

    /// Invert a channel for a few samples (applied after the comparator).
    pub fn inject_glitch(&mut self, glitch: Glitch) {
        self.glitches.push(glitch);
    }

    /// Take the next sample.
    pub fn next_state(&mut self, psi_h: &mut impl FnMut(f64) -> f64) -> QuadratureState {
        let index = self.next_index;
        self.next_index += 1;
        let [va, vb] = self.levels.levels_v(psi_h(self.sample_time_s(index)));
        let noise = self.levels.noise_rms_v;
        let mut state = QuadratureState {
            a: self.comparators[0].update(va + gaussian_v(&mut self.rng, noise)),
            b: self.comparators[1].update(vb + gaussian_v(&mut self.rng, noise)),
        };
        self.glitches
            .retain(|g| g.start_index.saturating_add(g.len_samples) > index);
        for g in self.glitches.iter().filter(|g| g.start_index <= index) {
            match g.channel {
                Channel::A => state.a = !state.a,
                Channel::B => state.b = !state.b,
            }
        }
        state
    }

    /// Fill `out` with the next `out.len()` samples.
    pub fn fill(&mut self, psi_h: &mut impl FnMut(f64) -> f64, out: &mut [QuadratureState]) {
        for slot in out {
            *slot = self.next_state(psi_h);
        }
    }

    /// Fill `out` with the next samples as pin bits (bit 0 = A, bit 1 = B), like a DMA of the
    /// GPIO input register.
    pub fn fill_bits(&mut self, psi_h: &mut impl FnMut(f64) -> f64, out: &mut [u8]) {
        for slot in out {
            *slot = self.next_state(psi_h).bits();
        }
    }

    /// The samples from the next one up to (excluding) time `until_s`.
    pub fn states_until<'a, F: FnMut(f64) -> f64 + 'a>(
        &'a mut self,
        mut psi_h: F,
        until_s: f64,
    ) -> impl Iterator<Item = QuadratureState> + 'a {
        core::iter::from_fn(move || {
            (self.sample_time_s(self.next_index) < until_s).then(|| self.next_state(&mut psi_h))
        })
    }
}

/// A hardware encoder timer fed by sampled comparator states, with its digital input filter.
#[derive(Clone, Debug)]
pub struct StateDecoder {
    register: EncoderRegister,
    reverse: bool,
    filter_samples: u32,
    filtered: QuadratureState,
    run: [u32; 2],
    illegal_transitions: u64,
}

impl StateDecoder {
    /// A decoder in `initial_state`; an input change is accepted after `filter_samples` equal
    /// consecutive samples (0 or 1: no filter).
    pub fn new(config: CounterConfig, filter_samples: u32, initial_state: QuadratureState) -> Self {
        Self {
            register: EncoderRegister::new(config.width, config.initial_count),
            reverse: config.reverse,
            filter_samples: filter_samples.max(1),
            filtered: initial_state,
            run: [0; 2],
            illegal_transitions: 0,
        }
    }

    /// Feed one sample.
    pub fn push(&mut self, input: QuadratureState) {
        let mut next = self.filtered;
        for (k, (raw, level)) in [(input.a, &mut next.a), (input.b, &mut next.b)]
            .into_iter()
            .enumerate()
        {
            if raw == *level {
                self.run[k] = 0;
            } else {
                self.run[k] += 1;
                if self.run[k] >= self.filter_samples {
                    *level = raw;
                    self.run[k] = 0;
                }
            }
        }
        match self.filtered.step_to(next) {
            Some(step) => {
                let step = i64::from(step);
                self.register.add(if self.reverse { -step } else { step });
            }
            None => self.illegal_transitions += 1,
        }
        self.filtered = next;
    }

    /// The raw register.
    pub fn count(&self) -> u32 {
        self.register.raw()
    }

    /// The filtered state the decoder holds.
    pub fn state(&self) -> QuadratureState {
        self.filtered
    }

    /// Two-bit jumps seen (each counted as zero).
    pub fn illegal_transitions(&self) -> u64 {
        self.illegal_transitions
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
    }
}

/// `floor(psi_h_rad / (pi/2))`: the ideal-comparator count relative to `psi_H = 0`.
pub fn ideal_quadrant_index(psi_h_rad: f64) -> i64 {
    (psi_h_rad / (PI / 2.0)).floor() as i64
}
