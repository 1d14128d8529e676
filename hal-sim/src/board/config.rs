//! The simulated board's settings: how the turnaround latch is timed ([`LatchTiming`]) and
//! everything else around the gyro ([`BoardConfig`]: photodiodes, pick-off, counter, timer,
//! latch errors, eps drift, the sync), with the firmware's profile and readout settings that
//! follow from them.

use crate::counter::CounterConfig;
use crate::params::GyroParams;
use crate::photodiode::PhotodiodeConfig;
use crate::pickoff::PickoffConfig;
use firmware::profile::BoardProfile;
use firmware::readout::ReadoutConfig;

/// How the turnaround latch is timed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum LatchTiming {
    /// At the exact turnaround (zero of dither plus input rate).
    #[default]
    Exact,
    /// From the pick-off comparator's edges through the firmware's scheduler, as on the board.
    Scheduled {
        /// Comparator threshold, arcsec of pick-off (dither angle) at the pick-off's nominal
        /// sensitivity (the threshold is the voltage of that angle,
        /// [`PickoffConfig::threshold_v`]); 0 = a zero-crossing detector. The half-interval
        /// prediction cancels it.
        comparator_offset_arcsec: f64,
        /// Pick-off path (comparator, input filter, resynchronisation): edge to capture, ticks.
        /// The scheduler subtracts the same value (a calibrated board).
        pickoff_delay_ticks: u32,
        /// Compare match to the sampling instant (ADC trigger latency + sampling time), ticks.
        /// The scheduler subtracts the same value.
        aperture_delay_ticks: u32,
        /// Apply the input-rate shift Omega_i/|psi_ddot| (false: latch at the pick-off's
        /// extremum, docs/physics.md pitfall 3).
        rate_shift: bool,
    },
}

impl LatchTiming {
    /// Scheduled from the pick-off with the board profile's delays ([`BoardProfile::F405`]:
    /// pick-off path and ADC aperture) and the rate shift on.
    pub const fn scheduled(comparator_offset_arcsec: f64) -> Self {
        Self::Scheduled {
            comparator_offset_arcsec,
            pickoff_delay_ticks: BoardProfile::F405.pickoff_delay_ticks,
            aperture_delay_ticks: BoardProfile::F405.aperture_delay_ticks,
            rate_shift: true,
        }
    }
}

/// The board around the gyro.
#[derive(Clone, Debug)]
pub struct BoardConfig {
    /// The photodiode channels, their ADC and comparators.
    pub photodiodes: PhotodiodeConfig,
    /// The dither pick-off, its ADC channel and (through the latch timing) its comparator.
    pub pickoff: PickoffConfig,
    /// The encoder timer (register width, start value, direction).
    pub counter: CounterConfig,
    /// Capture-timer frequency, Hz.
    pub timer_hz: f64,
    /// Rate of the free-running photodiode conversions for the Lissajous fit, Hz.
    pub lissajous_rate_hz: f64,
    /// How the latch instant is found.
    pub latch: LatchTiming,
    /// Constant error of the latch instant, s: against the true turnaround ([`LatchTiming::Exact`])
    /// or the scheduled sampling instant ([`LatchTiming::Scheduled`]: a residual uncalibrated
    /// delay).
    pub latch_offset_s: f64,
    /// RMS jitter of the latch instant, s (on top, in both modes).
    pub latch_jitter_rms_s: f64,
    /// Drift of the photodiode phase offset eps (thermal, ageing), rad/s, applied from t = 0
    /// until `eps_drift_until_s`: the photodiodes see psi - eps(t).
    pub eps_drift_rad_per_s: f64,
    /// End of the eps drift, s.
    pub eps_drift_until_s: f64,
    /// Seed of the board's noise (photodiodes, latch jitter).
    pub seed: u64,
    /// The sync input: output latches at this rate, Hz (100..=2000 for a navigation
    /// computer's sync; `None`: no output latches).
    pub sync_hz: Option<f64>,
    /// The gyro's nominal scale factor as the board is provisioned with it (its data sheet),
    /// arcsec per fringe: the firmware's starting stripping coefficient and its rate unit.
    pub scale_factor_arcsec: f64,
}

impl BoardConfig {
    /// The default board for a gyro: realistic photodiodes (offsets, unequal gains, quadrature
    /// error, noise, 12-bit ADC), the encoder and capture timers of [`BoardProfile::F405`], an
    /// exact latch.
    pub fn for_gyro(params: &GyroParams) -> Self {
        Self {
            photodiodes: PhotodiodeConfig::default(),
            pickoff: PickoffConfig::default(),
            counter: CounterConfig::default(),
            timer_hz: f64::from(BoardProfile::F405.timer_hz),
            lissajous_rate_hz: 12_345.0,
            latch: LatchTiming::Exact,
            latch_offset_s: 0.0,
            latch_jitter_rms_s: 0.0,
            eps_drift_rad_per_s: 0.0,
            eps_drift_until_s: 0.0,
            seed: params.seed ^ 0xB0A2_D5EE_D000_0001,
            sync_hz: None,
            scale_factor_arcsec: params.scale_factor_arcsec,
        }
    }
}

impl BoardConfig {
    /// The firmware's profile of this board: [`BoardProfile::F405`] with this board's timer
    /// clock, counter width and (when scheduled) latch delays, i.e. a firmware configured for the
    /// simulated hardware. The scheduler's and the readout's settings come from it.
    pub fn profile(&self) -> BoardProfile {
        let f405 = BoardProfile::F405;
        let (pickoff_delay_ticks, aperture_delay_ticks) = match self.latch {
            LatchTiming::Scheduled {
                pickoff_delay_ticks,
                aperture_delay_ticks,
                ..
            } => (pickoff_delay_ticks, aperture_delay_ticks),
            LatchTiming::Exact => (f405.pickoff_delay_ticks, f405.aperture_delay_ticks),
        };
        BoardProfile {
            timer_hz: self.timer_hz.round() as u32,
            scale_factor_arcsec: self.scale_factor_arcsec,
            counter_width: self.counter.width,
            pickoff_delay_ticks,
            aperture_delay_ticks,
            ..f405
        }
    }

    /// The firmware's readout settings for this board and a dither near `dither_hz`.
    pub fn readout_config(&self, dither_hz: f64) -> ReadoutConfig {
        self.profile().readout_config(dither_hz)
    }
}
