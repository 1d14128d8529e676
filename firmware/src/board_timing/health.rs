//! The board's health as the protocol reports it: the power-up self-test's outcomes and the
//! timing faults raised now. `status` carries one word of it (`board=`), `selftest` all of it.

use super::monitor::TimingFaults;
use super::selftest::{Outcome, SelfTestReport};

/// The self-test's report and the timing faults raised now.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardHealth {
    /// The power-up self-test.
    pub selftest: SelfTestReport,
    /// The rate monitors' faults and the lost clock.
    pub timing: TimingFaults,
    /// The board runs in QEMU, which cannot pass [`super::selftest::QEMU_UNMODELLED`]
    /// (`selftest` says so).
    pub emulated: bool,
}

/// `status`'s `board=` word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HealthWord {
    /// Every check passed and no timing fault is raised.
    Ok,
    /// The pick-off check (the half-drive sweep) is still running.
    Testing,
    /// No self-test ran (no board: the QEMU serial example, the fuzzer).
    Untested,
    /// A timing fault is raised: its name (`drive_tick`, `clock_lost`, ...).
    Timing(&'static str),
    /// A self-test check failed: its name (`clock`, `pickoff`, ...).
    Failed(&'static str),
}

impl core::fmt::Display for HealthWord {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Ok => f.write_str("ok"),
            Self::Testing => f.write_str("testing"),
            Self::Untested => f.write_str("untested"),
            Self::Timing(name) | Self::Failed(name) => f.write_str(name),
        }
    }
}

impl BoardHealth {
    /// No board: nothing tested, nothing watched.
    pub const UNTESTED: Self = Self {
        selftest: SelfTestReport::NOT_RUN,
        timing: TimingFaults(0),
        emulated: false,
    };

    /// The one word `status` shows: a failed check first (it keeps the drive off), then a
    /// timing fault (the output is invalid), then a check still running, else `ok`.
    pub fn word(&self) -> HealthWord {
        if let Some((check, _)) = self.selftest.first_failure() {
            return HealthWord::Failed(check.word());
        }
        if let Some(name) = self.timing.first_word() {
            return HealthWord::Timing(name);
        }
        let outcomes = &self.selftest.0;
        if outcomes.iter().all(|&o| o == Outcome::NotRun) {
            HealthWord::Untested
        } else if outcomes.contains(&Outcome::Running) {
            HealthWord::Testing
        } else {
            HealthWord::Ok
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board_timing::monitor::Event;
    use crate::board_timing::selftest::Check;

    #[test]
    fn the_status_word_puts_failures_first() {
        let mut h = BoardHealth::UNTESTED;
        assert_eq!(h.word(), HealthWord::Untested);
        h.selftest = SelfTestReport([Outcome::Pass; 5]);
        assert_eq!(h.word().to_string(), "ok");
        h.selftest.set(Check::Pickoff, Outcome::Running);
        assert_eq!(h.word().to_string(), "testing");
        h.timing = TimingFaults::of(Event::DriveTick);
        assert_eq!(h.word().to_string(), "drive_tick");
        h.selftest.set(Check::Triggers, Outcome::Fail("dac"));
        assert_eq!(h.word().to_string(), "triggers");
    }
}
