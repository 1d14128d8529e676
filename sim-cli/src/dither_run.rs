//! The dither drive on the simulated gyro: the firmware's controller
//! (`firmware::dither::DitherController`, through hal-sim's `FirmwareDrive`) drives the driven
//! resonator from rest, with the resonance drifting, the pick-off failing, or random-noise
//! dither on; one row per dither cycle with the simulator's truth beside the firmware's view.
//!
//! No readout runs here: the drive needs only the pick-off (the readout's side of a driven
//! dither is the harness's, `hal_sim::harness::DriveSource::Firmware`). The run ticks the
//! controller at the board's drive rate and samples the truth every nominal dither period:
//! the peak amplitude from the resonator's state (`hypot(theta, theta' / w0)`, exact for the
//! free oscillation the drive sustains), the resonance f0 at that instant, and the frequency the
//! firmware drives and its state.

use firmware::dither::{DitherConfig, DitherState, FaultKind};
use firmware::profile::BoardProfile;
use hal_sim::board::{BoardConfig, SimBoard};
use hal_sim::dither::resonator::{ResonatorParams, TemperatureDrift, TemperatureProfile};
use hal_sim::drive_loop::FirmwareDrive;
use hal_sim::gyro::Gyro;
use hal_sim::input::InputProfile;
use hal_sim::params::{DitherModel, GyroParams};
use host_cli::range::Range;

/// One dither run.
#[derive(Clone, Debug, PartialEq)]
pub struct DitherRunOptions {
    /// Resonance f0 at the start, Hz ([`RESONANCE_HZ`]).
    pub resonance_hz: f64,
    /// Quality factor ([`Q_FACTOR`]).
    pub q_factor: f64,
    /// Amplitude setpoint, arcsec ([`setpoint_arcsec_range`]).
    pub setpoint_arcsec: f64,
    /// Linear drift of f0 over the run, Hz ([`RESONANCE_DRIFT_HZ`]).
    pub resonance_drift_hz: f64,
    /// The pick-off signal disappears at this time, s (within the run).
    pub pickoff_lost_at_s: Option<f64>,
    /// Random-noise dither depth, percent ([`NOISE_PERCENT`]).
    pub noise_percent: f64,
    /// Simulated seconds ([`SECONDS`]).
    pub seconds: f64,
    /// Seed of the pick-off noise and the noise dither.
    pub seed: u64,
}

/// Valid starting resonance: inside the firmware's start-up search
/// (`BoardProfile::dither_search_hz`) with a margin, so the search finds it.
pub const RESONANCE_HZ: Range<f64> = Range::closed("--dither-hz", 300.0, 600.0, "Hz");
/// Valid quality factors of the resonator.
pub const Q_FACTOR: Range<f64> = Range::closed("--q-factor", 100.0, 1e5, "");
/// Valid drift of the resonance over a run.
pub const RESONANCE_DRIFT_HZ: Range<f64> = Range::closed("--resonance-drift-hz", -10.0, 10.0, "Hz");
/// Valid random-noise dither depths (`dither` and the board's `--dither-noise-percent`).
pub const NOISE_PERCENT: Range<f64> = Range::closed("--dither-noise-percent", 0.0, 50.0, "%");
/// Valid run lengths.
pub const SECONDS: Range<f64> = Range::closed("--seconds", 1e-3, 3600.0, "s");

/// Valid amplitude setpoints: the firmware drive's own range (`DitherConfig`).
pub fn setpoint_arcsec_range() -> Range<f64> {
    let (min, max) = DitherConfig::for_profile(&BoardProfile::F405).setpoint_range_arcsec;
    Range::closed(
        "--dither-amplitude-arcsec",
        min.into(),
        max.into(),
        "arcsec",
    )
}

impl DitherRunOptions {
    /// The default gyro's dither (`GyroParams::DEFAULT`: the board profile's nominal frequency
    /// and amplitude), Q = 1000, no drift, no fault, no noise dither, 5 s, seed 1.
    pub const DEFAULT: Self = Self {
        resonance_hz: GyroParams::DEFAULT.dither_hz,
        q_factor: 1000.0,
        setpoint_arcsec: GyroParams::DEFAULT.dither_amplitude_arcsec,
        resonance_drift_hz: 0.0,
        pickoff_lost_at_s: None,
        noise_percent: 0.0,
        seconds: 5.0,
        seed: 1,
    };
}

impl Default for DitherRunOptions {
    /// [`DitherRunOptions::DEFAULT`].
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl DitherRunOptions {
    /// Every field against its stated range; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        RESONANCE_HZ.check(self.resonance_hz)?;
        Q_FACTOR.check(self.q_factor)?;
        setpoint_arcsec_range().check(self.setpoint_arcsec)?;
        RESONANCE_DRIFT_HZ.check(self.resonance_drift_hz)?;
        NOISE_PERCENT.check(self.noise_percent)?;
        SECONDS.check(self.seconds)?;
        match self.pickoff_lost_at_s {
            Some(t) if !(t.is_finite() && (0.0..=self.seconds).contains(&t)) => {
                Err("--pickoff-lost-at-s must be within the run (0..=--seconds)".into())
            }
            _ => Ok(()),
        }
    }

    /// The driven resonator: at rest, f0 drifting linearly by `resonance_drift_hz` over the
    /// run (a temperature ramp of 1 K per Hz at 1 Hz/K).
    pub fn resonator(&self) -> Result<ResonatorParams, String> {
        let temperature = if self.resonance_drift_hz == 0.0 {
            TemperatureDrift::NONE
        } else {
            let ramp = TemperatureProfile::ramp(
                0.0,
                25.0,
                self.seconds,
                25.0 + self.resonance_drift_hz.abs(),
            )
            .map_err(|e| e.to_string())?;
            TemperatureDrift {
                profile: ramp,
                f0_hz_per_c: self.resonance_drift_hz.signum(),
                ..TemperatureDrift::NONE
            }
        };
        Ok(ResonatorParams {
            f0_hz: self.resonance_hz,
            q: self.q_factor,
            temperature,
            ..ResonatorParams::default()
        })
    }
}

/// One dither cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DitherRow {
    /// Simulated time, s.
    pub t_s: f64,
    /// The true peak amplitude, arcsec (simulator).
    pub amplitude_arcsec: f64,
    /// The true resonance f0, Hz (simulator).
    pub resonance_hz: f64,
    /// The frequency the firmware drives, Hz (0 with the drive off).
    pub drive_hz: f64,
    /// The firmware's state.
    pub state: DitherState,
}

impl DitherRow {
    /// The state as the CSV writes it: `off`, `starting`, `locked`, `fault`.
    pub fn state_word(&self) -> &'static str {
        firmware::protocol::commands::dither::state_word(self.state)
    }
}

/// What a run shows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DitherSummary {
    /// First time from which the amplitude stays within 1 % of the setpoint (until the end or
    /// a fault), s.
    pub settle_s: Option<f64>,
    /// Largest amplitude above the setpoint, percent of it.
    pub overshoot_percent: f64,
    /// First time the firmware reports `locked`, s.
    pub locked_s: Option<f64>,
    /// RMS of the amplitude's error after the settle time (and before a fault), percent of the
    /// setpoint.
    pub amplitude_rms_error_percent: f64,
    /// Largest |drive frequency - resonance| while locked, Hz.
    pub max_frequency_error_hz: f64,
    /// First time the firmware reports `fault`, s, and which.
    pub fault_s: Option<f64>,
    /// The first fault's kind.
    pub fault: Option<FaultKind>,
    /// The true peak amplitude at the end, arcsec.
    pub final_amplitude_arcsec: f64,
    /// The drive's amplitude at the end, fraction of the DAC's half range (0: drive safe).
    pub final_drive_level: f64,
}

/// Runs the drive; `on_row` gets every dither cycle in time order (to write them as they come).
pub fn run(
    options: &DitherRunOptions,
    mut on_row: impl FnMut(&DitherRow),
) -> Result<DitherSummary, String> {
    options.validate()?;
    let resonator = options.resonator()?;
    let params = GyroParams {
        dither_hz: options.resonance_hz,
        dither_amplitude_arcsec: options.setpoint_arcsec,
        dither_model: DitherModel::Driven(resonator),
        seed: options.seed,
        ..GyroParams::default()
    };
    let gyro = Gyro::new(params, InputProfile::constant(0.0)).map_err(|e| e.to_string())?;
    let mut board =
        SimBoard::new(gyro, BoardConfig::for_gyro(&params)).map_err(|e| format!("{e:?}"))?;
    let mut drive =
        FirmwareDrive::new(&BoardProfile::F405, resonator.dac).map_err(|e| format!("{e:?}"))?;
    drive
        .set_setpoints(
            options.setpoint_arcsec as f32,
            options.noise_percent as f32,
            options.seed as u32,
        )
        .map_err(|(what, e)| format!("{what}: {e:?}"))?;
    let period_s = 1.0 / options.resonance_hz;
    let rows = (options.seconds / period_s).floor() as u64;
    let mut rows_seen: Vec<DitherRow> = Vec::with_capacity(rows as usize);
    let mut summary = DitherSummary::default();
    for k in 1..=rows {
        let t = k as f64 * period_s;
        if let Some(lost) = options.pickoff_lost_at_s {
            if t - period_s < lost && t >= lost {
                // The loss starts at `lost`: run the ticks up to it first.
                drive
                    .run_until(&mut board, lost)
                    .map_err(|e| format!("{e:?}"))?;
                board.pickoff_mut().set_lost(true);
            }
        }
        drive
            .run_until(&mut board, t)
            .map_err(|e| format!("{e:?}"))?;
        let state = board
            .gyro()
            .dither_state(t)
            .ok_or("the dither is not driven")?;
        let (f0, _) = resonator.f0_q_at(t);
        let w0 = core::f64::consts::TAU * f0;
        let status = drive.controller().status(drive.config());
        let driving = status.drive_level > 0.0;
        let row = DitherRow {
            t_s: t,
            amplitude_arcsec: state.angle_arcsec.hypot(state.rate_arcsec_per_s / w0),
            resonance_hz: f0,
            drive_hz: if driving {
                f64::from(status.frequency_hz)
            } else {
                0.0
            },
            state: status.state,
        };
        on_row(&row);
        rows_seen.push(row);
        summary.final_drive_level = f64::from(status.drive_level);
        summary.final_amplitude_arcsec = row.amplitude_arcsec;
    }
    summarise(options, &rows_seen, &mut summary);
    Ok(summary)
}

fn summarise(options: &DitherRunOptions, rows: &[DitherRow], s: &mut DitherSummary) {
    let set = options.setpoint_arcsec;
    let first_fault = rows.iter().find_map(|r| match r.state {
        DitherState::Fault(kind) => Some((r.t_s, kind)),
        _ => None,
    });
    s.fault_s = first_fault.map(|(t, _)| t);
    s.fault = first_fault.map(|(_, kind)| kind);
    s.locked_s = rows
        .iter()
        .find(|r| r.state == DitherState::Locked)
        .map(|r| r.t_s);
    let healthy: Vec<&DitherRow> = rows
        .iter()
        .take_while(|r| !matches!(r.state, DitherState::Fault(_)))
        .collect();
    s.overshoot_percent = healthy
        .iter()
        .map(|r| 100.0 * (r.amplitude_arcsec / set - 1.0))
        .fold(0.0, f64::max);
    // Settled from the first row after the last one outside 1 % (among the healthy rows).
    let last_out = healthy
        .iter()
        .rposition(|r| (r.amplitude_arcsec / set - 1.0).abs() > 0.01);
    let settled_from = last_out.map_or(0, |i| i + 1);
    if settled_from < healthy.len() {
        s.settle_s = Some(healthy[settled_from].t_s);
        let errors: Vec<f64> = healthy[settled_from..]
            .iter()
            .map(|r| r.amplitude_arcsec / set - 1.0)
            .collect();
        let ms = errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64;
        s.amplitude_rms_error_percent = 100.0 * ms.sqrt();
    }
    s.max_frequency_error_hz = healthy
        .iter()
        .filter(|r| r.state == DitherState::Locked)
        .map(|r| (r.drive_hz - r.resonance_hz).abs())
        .fold(0.0, f64::max);
}

/// The CSV header of `rlg-sim dither` (scripts read these columns).
pub const CSV_HEADER: &str = "t_s,amplitude_arcsec,resonance_hz,drive_hz,state";

/// One CSV line (no newline) of a row.
pub fn csv_line(row: &DitherRow) -> String {
    format!(
        "{:.6},{:.4},{:.5},{:.5},{}",
        row.t_s,
        row.amplitude_arcsec,
        row.resonance_hz,
        row.drive_hz,
        row.state_word()
    )
}

/// The state as a level for plotting: off (or inhibited) 0, starting 1, locked 2, fault -1.
fn state_level(state: DitherState) -> f64 {
    match state {
        DitherState::Off | DitherState::Inhibited => 0.0,
        DitherState::Starting => 1.0,
        DitherState::Locked => 2.0,
        DitherState::Fault(_) => -1.0,
    }
}

/// The figure: amplitude against its setpoint, drive frequency against the resonance, and the
/// firmware's state, against time.
pub fn figure(rows: &[DitherRow], options: &DitherRunOptions) -> host_cli::plot::Figure {
    use host_cli::plot::{Figure, Panel, Series, Style};
    let pts = |f: &dyn Fn(&DitherRow) -> f64| rows.iter().map(|r| (r.t_s, f(r))).collect();
    let end = rows.last().map_or(0.0, |r| r.t_s);
    Figure {
        title: format!(
            "Dither drive from rest: f0 {} Hz (drift {:+} Hz), Q {}, setpoint {} arcsec",
            options.resonance_hz,
            options.resonance_drift_hz,
            options.q_factor,
            options.setpoint_arcsec
        ),
        x_label: "time (s)".into(),
        width_px: 900.0,
        height_px: 900.0,
        axes: host_cli::plot::Axes::Linear,
        panels: vec![
            Panel {
                title: "amplitude (simulator's truth)".into(),
                y_label: "peak amplitude (arcsec)".into(),
                weight: 2.0,
                series: vec![
                    Series {
                        label: "setpoint".into(),
                        points: vec![
                            (0.0, options.setpoint_arcsec),
                            (end, options.setpoint_arcsec),
                        ],
                        color: "#888888",
                        style: Style::DashedLine,
                    },
                    Series {
                        label: "amplitude".into(),
                        points: pts(&|r| r.amplitude_arcsec),
                        color: "#1f77b4",
                        style: Style::Line,
                    },
                ],
            },
            Panel {
                title: "frequency".into(),
                y_label: "frequency (Hz)".into(),
                weight: 2.0,
                series: vec![
                    Series {
                        label: "resonance (truth)".into(),
                        points: pts(&|r| r.resonance_hz),
                        color: "#888888",
                        style: Style::DashedLine,
                    },
                    Series {
                        label: "drive (firmware)".into(),
                        points: rows
                            .iter()
                            .filter(|r| r.drive_hz > 0.0)
                            .map(|r| (r.t_s, r.drive_hz))
                            .collect(),
                        color: "#d62728",
                        style: Style::Line,
                    },
                ],
            },
            Panel {
                title: "state (fault -1, off 0, starting 1, locked 2)".into(),
                y_label: "state".into(),
                weight: 1.0,
                series: vec![Series {
                    label: "firmware state".into(),
                    points: pts(&|r| state_level(r.state)),
                    color: "#2ca02c",
                    style: Style::Line,
                }],
            },
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The starting resonances `dither` accepts lie inside the firmware's start-up search, so
    /// the drive can find every one of them; the default run is valid.
    #[test]
    fn accepted_resonances_are_inside_the_start_up_search() {
        let (lo, hi) = BoardProfile::F405.dither_search_hz;
        assert!(lo < RESONANCE_HZ.min && RESONANCE_HZ.max < hi);
        assert_eq!(DitherRunOptions::DEFAULT.validate(), Ok(()));
        let low = DitherRunOptions {
            resonance_hz: 250.0,
            ..DitherRunOptions::DEFAULT
        };
        assert_eq!(
            low.validate().unwrap_err(),
            "--dither-hz must be in 300..=600 Hz, got 250"
        );
    }
}
