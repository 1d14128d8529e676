//! The simulated board: the gyro and the peripherals assembled into what the firmware's two
//! interrupts receive.
//!
//! Per half dither cycle, [`SimBoard::next_half_cycle`] returns
//! - the photodiode conversions taken since the previous turnaround by the free-running ADC
//!   (regular conversions at [`BoardConfig::lissajous_rate_hz`], not synchronised with the
//!   dither, as on the board: the samples land at all phases of the fringe, even inside the dead
//!   band where the phase at any fixed point of the dither cycle repeats), and
//! - the [`TurnaroundSample`] latched at the turnaround (encoder register, both ADC channels,
//!   capture timer), built by [`latch_turnaround`].
//!
//! The latch instant is the exact turnaround (the zero of dither plus input rate) plus a
//! configurable timing error and jitter, standing in for the board's capture/compare scheduling
//! (PHYSICS.md pitfall 2: aim for ~1 us). The gyro's truth (turnaround phase, per-traversal
//! lock-in error) stays available through [`SimBoard::gyro`] for tests.

use crate::clock::CaptureTimer;
use crate::counter::{latch_turnaround, CounterConfig, QuadratureCounter};
use crate::gyro::Gyro;
use crate::params::GyroParams;
use crate::photodiode::{PhotodiodeConfig, Photodiodes};
use firmware::sample::TurnaroundSample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Capture-timer frequency of the STM32F405's 32-bit TIM2/TIM5 (APB1 timer clock), Hz.
pub const TIMER_HZ: f64 = 84e6;

/// The board around the gyro.
#[derive(Clone, Debug)]
pub struct BoardConfig {
    pub photodiodes: PhotodiodeConfig,
    pub counter: CounterConfig,
    /// Capture-timer frequency, Hz.
    pub timer_hz: f64,
    /// Rate of the free-running photodiode conversions for the Lissajous fit, Hz.
    pub lissajous_rate_hz: f64,
    /// Constant error of the latch instant against the true turnaround, s.
    pub latch_offset_s: f64,
    /// RMS jitter of the latch instant, s.
    pub latch_jitter_rms_s: f64,
    /// Drift of the photodiode phase offset eps (thermal, ageing), rad/s, applied from t = 0
    /// until `eps_drift_until_s`: the photodiodes see psi - eps(t).
    pub eps_drift_rad_per_s: f64,
    pub eps_drift_until_s: f64,
    pub seed: u64,
}

impl BoardConfig {
    /// The default board for a gyro: realistic photodiodes (offsets, unequal gains, quadrature
    /// error, noise, 12-bit ADC), a 32-bit encoder timer, an exact latch.
    pub fn for_gyro(params: &GyroParams) -> Self {
        Self {
            photodiodes: PhotodiodeConfig::default(),
            counter: CounterConfig::default(),
            timer_hz: TIMER_HZ,
            lissajous_rate_hz: 12_345.0,
            latch_offset_s: 0.0,
            latch_jitter_rms_s: 0.0,
            eps_drift_rad_per_s: 0.0,
            eps_drift_until_s: 0.0,
            seed: params.seed ^ 0xB0A2_D5EE_D000_0001,
        }
    }
}

/// Why a board cannot be built.
#[derive(Debug)]
pub enum BoardError {
    Counter(crate::counter::CounterError),
    Photodiodes(crate::photodiode::PhotodiodeConfigError),
    Config(&'static str),
}

/// The simulated board.
pub struct SimBoard {
    gyro: Gyro,
    config: BoardConfig,
    eps_rad: f64,
    photodiodes: Photodiodes,
    counter: QuadratureCounter,
    timer: CaptureTimer,
    rng: ChaCha8Rng,
    next_lissajous_s: f64,
    time_s: f64,
}

impl SimBoard {
    pub fn new(mut gyro: Gyro, config: BoardConfig) -> Result<Self, BoardError> {
        config
            .photodiodes
            .validate()
            .map_err(BoardError::Photodiodes)?;
        if !(config.timer_hz > 0.0 && config.lissajous_rate_hz > 0.0) {
            return Err(BoardError::Config(
                "timer and Lissajous rates must be positive",
            ));
        }
        if !(config.latch_offset_s.is_finite() && config.latch_jitter_rms_s >= 0.0) {
            return Err(BoardError::Config("latch timing must be finite"));
        }
        let eps_rad = gyro.params().eps_rad;
        let psi_h0 = gyro.advance_to(0.0) - eps_rad;
        let counter = QuadratureCounter::new(&config.photodiodes, config.counter, psi_h0)
            .map_err(BoardError::Counter)?;
        Ok(Self {
            photodiodes: Photodiodes::new(config.photodiodes, config.seed),
            rng: ChaCha8Rng::seed_from_u64(config.seed.wrapping_add(1)),
            timer: CaptureTimer::new(config.timer_hz),
            next_lissajous_s: 0.5 / config.lissajous_rate_hz,
            time_s: 0.0,
            eps_rad,
            counter,
            config,
            gyro,
        })
    }

    /// Runs to the next turnaround: fills `lissajous` with the conversions taken on the way and
    /// returns the turnaround latch.
    pub fn next_half_cycle(&mut self, lissajous: &mut Vec<(u16, u16)>) -> TurnaroundSample {
        lissajous.clear();
        let turnaround = self.gyro.upcoming_turnaround();
        let jitter: f64 = if self.config.latch_jitter_rms_s > 0.0 {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            z * self.config.latch_jitter_rms_s
        } else {
            0.0
        };
        let latch_s = (turnaround.time_s + self.config.latch_offset_s + jitter).max(self.time_s);
        while self.next_lissajous_s < latch_s {
            let psi_h =
                self.gyro.advance_to(self.next_lissajous_s) - self.eps_at(self.next_lissajous_s);
            self.counter.advance_to(psi_h);
            let codes = self.photodiodes.sample_codes(psi_h);
            lissajous.push((codes.a_code, codes.b_code));
            self.next_lissajous_s += 1.0 / self.config.lissajous_rate_hz;
        }
        let psi_h = self.gyro.advance_to(latch_s) - self.eps_at(latch_s);
        self.time_s = latch_s;
        latch_turnaround(
            turnaround.kind,
            latch_s,
            psi_h,
            &mut self.counter,
            &mut self.photodiodes,
            &self.timer,
        )
    }

    /// The photodiode phase offset at `t_s`, rad.
    pub fn eps_at(&self, t_s: f64) -> f64 {
        self.eps_rad + self.config.eps_drift_rad_per_s * t_s.min(self.config.eps_drift_until_s)
    }

    /// Simulated time of the last latch, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The gyro, with its truth.
    pub fn gyro(&self) -> &Gyro {
        &self.gyro
    }

    /// Drains the gyro's log of completed traversals (the truth about lock-in, for tests).
    pub fn take_traversals(&mut self) -> Vec<crate::gyro::Traversal> {
        self.gyro.take_traversals()
    }

    /// The counter, for glitch injection in tests.
    pub fn counter_mut(&mut self) -> &mut QuadratureCounter {
        &mut self.counter
    }
}
