//! Where the coefficients in force came from, and the fit behind them: the state that `status`
//! and `reload` report and that `store` writes next to the coefficients.
//!
//! Every command that changes the coefficients changes this too: `set`, `comp`, `defaults` and
//! a tracking update make them [`Source::Unsaved`] (all but `comp` also drop the fit, which no
//! longer describes them), `cal accept` keeps the new fit, `store` and `reload` tie them to a
//! flash record again.

use crate::storage::{DefaultsReason, FitSummary, LoadOutcome, LoadReport};

/// Where the coefficients in force came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The stored record, unchanged since it was loaded or stored.
    Flash {
        /// Its sequence number.
        sequence: u32,
    },
    /// The defaults, since boot or `reload` (and why: nothing stored, a reset, ...).
    Defaults(DefaultsReason),
    /// Changed since the last store or load.
    Unsaved,
}

impl Source {
    /// The source after `load` reported `report`.
    pub fn of(report: &LoadReport) -> Self {
        match report.outcome {
            LoadOutcome::Loaded { sequence } => Self::Flash { sequence },
            LoadOutcome::Defaults { reason } => Self::Defaults(reason),
        }
    }
}

/// The coefficients' source and fit, and the boot count a stored record carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Provenance {
    /// Where the coefficients in force came from.
    pub source: Source,
    /// The fit behind the coefficients in force (stored with them), if any.
    pub fit: Option<FitSummary>,
    /// This boot's number (from the board), written into every stored record.
    pub boot_count: u32,
}

impl Provenance {
    /// The state after boot: `load` found `report` and `fit`.
    pub fn new(report: &LoadReport, fit: Option<FitSummary>, boot_count: u32) -> Self {
        Self {
            source: Source::of(report),
            fit,
            boot_count,
        }
    }

    /// The coefficients were changed by hand or by tracking: unsaved, no fit behind them.
    pub fn changed(&mut self) {
        self.source = Source::Unsaved;
        self.fit = None;
    }
}

/// `flash:<seq>`, `defaults:<why>` or `unsaved`.
pub struct SourceText(pub Source);

impl core::fmt::Display for SourceText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Source::Flash { sequence } => write!(f, "flash:{sequence}"),
            Source::Defaults(DefaultsReason::Erased) => write!(f, "defaults:erased"),
            Source::Defaults(DefaultsReason::NoValidRecord) => {
                write!(f, "defaults:no_valid_record")
            }
            Source::Defaults(DefaultsReason::Reset { sequence }) => {
                write!(f, "defaults:reset:{sequence}")
            }
            Source::Defaults(DefaultsReason::ReadFailed) => write!(f, "defaults:read_failed"),
            Source::Defaults(DefaultsReason::OtherGyro { stored_serial }) => {
                write!(f, "defaults:other_gyro:{stored_serial}")
            }
            Source::Unsaved => write!(f, "unsaved"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::report;

    #[test]
    fn source_texts() {
        let cases = [
            (Source::Flash { sequence: 7 }, "flash:7"),
            (Source::Defaults(DefaultsReason::Erased), "defaults:erased"),
            (
                Source::Defaults(DefaultsReason::NoValidRecord),
                "defaults:no_valid_record",
            ),
            (
                Source::Defaults(DefaultsReason::Reset { sequence: 3 }),
                "defaults:reset:3",
            ),
            (
                Source::Defaults(DefaultsReason::ReadFailed),
                "defaults:read_failed",
            ),
            (
                Source::Defaults(DefaultsReason::OtherGyro { stored_serial: 17 }),
                "defaults:other_gyro:17",
            ),
            (Source::Unsaved, "unsaved"),
        ];
        for (source, text) in cases {
            assert_eq!(format!("{}", SourceText(source)), text);
        }
    }

    #[test]
    fn boot_source_follows_the_load_report() {
        let loaded = Provenance::new(&report(LoadOutcome::Loaded { sequence: 9 }), None, 4);
        assert_eq!(loaded.source, Source::Flash { sequence: 9 });
        assert_eq!(loaded.boot_count, 4);
        let reason = DefaultsReason::NoValidRecord;
        let defaults = Provenance::new(&report(LoadOutcome::Defaults { reason }), None, 0);
        assert_eq!(defaults.source, Source::Defaults(reason));
    }
}
