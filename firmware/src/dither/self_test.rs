//! The power-up check that the pick-off answers the drive: a sweep of the search range at a
//! low drive, which must make the pick-off ring.
//!
//! The drive and the pick-off meet only through the dither's mechanics, which answer in a band
//! of f0 / Q (0.4 Hz at Q = 1000) somewhere in the 280-620 Hz search range: a fixed-frequency
//! probe would see nothing unless it hit f0. A sweep at 300 Hz/s leaves a ring at f0 of about
//! R / sqrt(rate) whatever Q is (`super::startup`): 50-100 arcsec at the full drive, half of
//! that at [`SELF_TEST_DRIVE_FRACTION`] of it, 60-120 codes against the ring threshold of 20.
//! Half the drive keeps the first power-on gentle (a resonance far stronger than expected rings
//! to half of what the start-up's full-drive sweep would give) and still proves the whole
//! chain: DAC, drive amplifier, piezo, dither spring, pick-off, its amplifier, ADC3. On the
//! controller's test model it passes with a drive 5x weaker than nominal (`tests`); a quarter
//! drive would fail below 0.4x, rejecting gyros the start-up itself can drive.
//!
//! Outcomes ([`PickoffCheck`]):
//! - **pass**: a half cycle's peak-to-peak above twice the ring threshold (the start-up's own
//!   test for a ring); the start-up follows at once if the drive is wanted on, listening
//!   first, so it catches the ring the sweep left instead of sweeping again;
//! - **rail**: samples at 0 or full scale (a pick-off pinned, or far too sensitive);
//! - **flat**: [`FLAT_HALF_CYCLES`] half cycles in a row with a peak-to-peak of at most
//!   `FaultLimits::flat_codes` (a live pick-off's noise alone, ~1 code rms, spans more): a dead
//!   converter or an open input held at one level;
//! - **no response**: the range swept up and down (2.3 s at most) without a ring: a dead
//!   pick-off, an open drive, a resonance outside the range.
//!
//! A failed check inhibits the drive (`DitherState::Inhibited`) until a reset: `dither on` is
//! refused, and `status` and `selftest` name the check.

/// The self-test's sweep drive, as a fraction of the drive limit.
pub const SELF_TEST_DRIVE_FRACTION: f32 = 0.5;

/// Half cycles in a row with a flat pick-off that fail the check (about 10 ms at 400 Hz).
pub const FLAT_HALF_CYCLES: u16 = 8;

/// Why the pick-off check failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PickoffFailure {
    /// Samples at an ADC rail.
    Rail,
    /// No variation at all: a dead converter or input.
    Flat,
    /// The sweep made no ring.
    NoResponse,
}

impl PickoffFailure {
    /// The failure as one word (`selftest`, `status`).
    pub fn word(self) -> &'static str {
        match self {
            Self::Rail => "rail",
            Self::Flat => "flat",
            Self::NoResponse => "no_response",
        }
    }
}

/// The pick-off check's outcome.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PickoffCheck {
    /// Not run (the board's other checks failed first, or no board: the QEMU serial example).
    NotRun,
    /// The sweep is under way.
    Running,
    /// The pick-off rang.
    Pass,
    /// It did not: the drive is inhibited.
    Fail(PickoffFailure),
}
