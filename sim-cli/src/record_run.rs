//! `rlg-sim record`: the board's fixed-rate output at a constant input rate, one row per sync
//! period, with the simulator's truth beside it.
//!
//! The run is [`crate::experiment::start_constant_rate`] (the same board as the sweep's: the
//! dither, the latch, the sync, the compensation settings the caller calibrated) stepped half
//! cycle by half cycle; each output record the firmware made (`Readout::on_output_latch`)
//! becomes a [`RecordRow`]: the board's increment and the true input angle over the same sync
//! period, both in arcsec. The board's increment is in fringes; the row converts it with the
//! gyro's scale factor (what a calibrated board applies).
//!
//! Rows go to the caller as they come (it writes them to disk), and the caller may stop the
//! run between half cycles ([`std::ops::ControlFlow::Break`]): an interrupted run keeps every
//! row it produced.

use crate::experiment::{start_constant_rate, BoardSetup, ExperimentError};
use firmware::signal::compensation::CompensationSettings;
use firmware::signal::output::strip::StripStatus;
use hal_sim::params::GyroParams;
use std::ops::ControlFlow;

/// One sync period of the board's output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordRow {
    /// The sync edge that ended the period, s.
    pub t_s: f64,
    /// The board's stripped, compensated angle increment, arcsec (0 when invalid).
    pub delta_angle_arcsec: f64,
    /// The true input angle over the same period, arcsec.
    pub true_delta_angle_arcsec: f64,
    /// The board's validity bit.
    pub valid: bool,
    /// The record's sequence number.
    pub sequence: u64,
    /// The block's temperature the record carries (the board's sensor), °C.
    pub temperature_c: Option<f64>,
}

/// What a record run saw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordSummary {
    /// Rows produced.
    pub rows: u64,
    /// Rows whose validity bit was clear.
    pub invalid_rows: u64,
    /// RMS of (board - true) over the valid rows, arcsec.
    pub rms_error_arcsec: f64,
    /// The stripping coefficient at the end of the run.
    pub strip: StripStatus,
    /// Simulated seconds recorded.
    pub recorded_s: f64,
    /// True if the caller stopped the run early.
    pub interrupted: bool,
}

/// Runs the board at `rate_deg_h` for `seconds` after the warm-up and hands every sync
/// period's row to `on_row`, which may stop the run.
pub fn record(
    params: &GyroParams,
    setup: BoardSetup,
    rate_deg_h: f64,
    warmup_s: f64,
    seconds: f64,
    settings: CompensationSettings,
    mut on_row: impl FnMut(&RecordRow) -> ControlFlow<()>,
) -> Result<RecordSummary, ExperimentError> {
    if setup.sync_hz.is_none() {
        return Err(ExperimentError::Simulator(
            "a record needs a sync (output latches)".into(),
        ));
    }
    let (mut harness, start_s) =
        start_constant_rate(params, setup, rate_deg_h, warmup_s, settings)?;
    let sf = params.scale_factor_arcsec;
    let end_s = start_s + seconds;
    let mut previous_truth: Option<f64> = None;
    let (mut rows, mut invalid, mut sum_sq, mut valid_n) = (0u64, 0u64, 0.0f64, 0u64);
    let mut interrupted = false;
    let mut last_t = start_s;
    while harness.time_s() < end_s {
        harness.step();
        for (latch, out) in harness.outputs() {
            let truth0 = previous_truth.replace(latch.true_angle_arcsec);
            if latch.t_s <= start_s || latch.t_s > end_s {
                continue;
            }
            let Some(truth0) = truth0 else { continue };
            let row = RecordRow {
                t_s: latch.t_s,
                delta_angle_arcsec: out.delta_angle_fringes() * sf,
                true_delta_angle_arcsec: latch.true_angle_arcsec - truth0,
                valid: out.is_valid(),
                sequence: out.sequence,
                temperature_c: out.temperature_c(),
            };
            rows += 1;
            last_t = latch.t_s;
            if row.valid {
                let e = row.delta_angle_arcsec - row.true_delta_angle_arcsec;
                sum_sq += e * e;
                valid_n += 1;
            } else {
                invalid += 1;
            }
            if on_row(&row).is_break() {
                interrupted = true;
            }
        }
        if interrupted {
            break;
        }
    }
    let config = *harness.config();
    Ok(RecordSummary {
        rows,
        invalid_rows: invalid,
        rms_error_arcsec: if valid_n > 0 {
            (sum_sq / valid_n as f64).sqrt()
        } else {
            f64::NAN
        },
        strip: harness.readout().strip_status(&config),
        recorded_s: last_t - start_s,
        interrupted,
    })
}
