//! The thermal calibration and IEEE Std 647's bias and scale factor over temperature on the
//! simulated gyro, with the firmware in the loop: the board reads its simulated TMP117 through
//! the firmware's driver, the fits are the firmware's (`firmware::thermal::fit`), and the
//! board applies the model it would store.
//!
//! # Runs
//!
//! Every run is the board of [`crate::experiment`] ([`start_run`]) with the block on a
//! temperature profile; the profile starts [`ThermalPlan::lead_s`] into the run (the firmware's
//! drive locks and settles first), and every record after that is kept ([`Row`]: the board's
//! increment, the true one, the temperature and rate the record carries, its status).
//!
//! - **Bias calibration**: up and down ramps between the plan's extremes with holds, the gyro
//!   at the constant calibration input; the records' angle error (board minus true) goes to
//!   [`BiasFit`] with the temperature and rate the board reported. A lost or invalid record
//!   starts a new stretch, and so do the records within [`TRANSIENT_S`] after a change of the
//!   ramp's slope: the board's rate estimate lags there by up to its 2 s window, and a fit fed
//!   those records bends its cubic to make up for the rate term's error (measured: the
//!   static bias at -15 and +55 °C then off by 0.02-0.04 deg/h).
//! - **Soaks** (the scale-factor calibration, and the check at other temperatures): a level per
//!   soak of [`SOAK_PERIOD_S`]: a 2 s transition, 3 s to settle (the rate estimate's 2 s
//!   window), 5 s at the static input (the bias: the least-squares slope of the integrated
//!   angle error, since the output's noise is white in angle; the static input is Earth rate,
//!   outside the dead band, where the gyro would lock at rest), then the table at +R and -R
//!   for 2.5 s each
//!   (the scale factor from both, so the bias cancels: `(m+ - m-) / (t+ - t-) - 1`, the first
//!   0.3 s after each step of the table left out).
//! - **Ramp check**: a ramp at another rate than the calibration's, model off and on; the
//!   bias of 5 s windows, those within [`TRANSIENT_S`] after a change of slope (where the rate
//!   estimate lags by half its window) marked.
//!
//! The profiles are compressed in time (2 °C/s where a thermal chamber ramps at about
//! 1 °C/min) so that the whole procedure is minutes of gyro time; docs/physics.md section 13
//! gives the measured figures.

use crate::experiment::{start_run, BoardSetup};
use firmware::signal::compensation::CompensationSettings;
use firmware::signal::output::record::OutputStatus;
use firmware::thermal::fit::{fit_scale, model_of, BiasFit, BiasResult};
use firmware::thermal::model::ThermalModel;
use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;

/// Records within this of a change of the profile's slope are the rate estimate's transient, s.
pub const TRANSIENT_S: f64 = 3.0;
/// One soak: transition, settling, static, +R, -R, s.
pub const SOAK_PERIOD_S: f64 = 15.0;
const SOAK_TRANSITION_S: f64 = 2.0;
const SOAK_STATIC_FROM_S: f64 = 5.0;
const SOAK_TABLE_FROM_S: f64 = 10.0;
const SOAK_TABLE_HALF_S: f64 = 2.5;
/// After each step of the table, left out of the scale factor's stretches, s.
const TABLE_SETTLE_S: f64 = 0.3;
/// The bias windows of the ramp check, s.
pub const BIAS_WINDOW_S: f64 = 5.0;

/// What the thermal procedures run.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalPlan {
    /// T_ref of the fitted model, °C (the calibration of a and b is made there).
    pub reference_c: f64,
    /// Run time before the profile starts (the drive's lock and settling), s.
    pub lead_s: f64,
    /// The bias calibration's profile, knots `(s after the lead, °C)`.
    pub calibration_knots: Vec<(f64, f64)>,
    /// The ramp check's profile, knots `(s after the lead, °C)`.
    pub check_knots: Vec<(f64, f64)>,
    /// The scale-factor calibration's soak levels, °C.
    pub calibration_soaks_c: Vec<f64>,
    /// The check's soak levels, °C (`thermal.csv`'s rows): away from the calibration's.
    pub check_soaks_c: Vec<f64>,
    /// The input during the ramps (a static gyro: Earth rate on the paper's axis), deg/h.
    pub static_input_deg_h: f64,
    /// The table's rate during the soaks, deg/h (10 deg/s: 1 ppm is 0.036 deg/h).
    pub table_deg_h: f64,
}

impl ThermalPlan {
    /// -20 to +60 °C: calibration ramps at +-2 °C/s with holds; checked on one ramp from -20
    /// to +60 °C at 0.5 °C/s (30 °C/min: another rate than the calibration's, still 30 times a
    /// chamber's usual 1 °C/min) and at eight soaks from -15 to +55 °C; the scale factor
    /// calibrated at five soaks 20 °C apart.
    pub fn default_plan() -> Self {
        Self {
            reference_c: 25.0,
            lead_s: 8.0,
            calibration_knots: vec![
                (2.0, -20.0),
                (4.0, -20.0),
                (44.0, 60.0),
                (46.0, 60.0),
                (86.0, -20.0),
            ],
            check_knots: vec![(2.0, -20.0), (162.0, 60.0)],
            calibration_soaks_c: vec![-20.0, 0.0, 20.0, 40.0, 60.0],
            check_soaks_c: (0..8).map(|i| -15.0 + 10.0 * i as f64).collect(),
            static_input_deg_h: crate::experiment::PAPER_RANGE_DEG_H,
            table_deg_h: 36_000.0,
        }
    }

    /// Gyro-seconds of [`run`] (calibration and both checks, model off and on).
    pub fn gyro_seconds(&self) -> f64 {
        let ramp = |k: &[(f64, f64)]| self.lead_s + k.last().map_or(0.0, |l| l.0) + 2.0;
        let soaks = |n: usize| self.lead_s + SOAK_PERIOD_S * n as f64;
        ramp(&self.calibration_knots)
            + soaks(self.calibration_soaks_c.len())
            + 2.0 * (ramp(&self.check_knots) + soaks(self.check_soaks_c.len()))
    }
}

/// One output record as the procedures use it.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    /// The latch that ended the record, s of run time.
    pub t_s: f64,
    /// Its period, s.
    pub dt_s: f64,
    /// The board's increment, arcsec.
    pub measured_arcsec: f64,
    /// The true input angle over the period, arcsec.
    pub true_arcsec: f64,
    /// The temperature the record carries, °C.
    pub temp_c: Option<f64>,
    /// Its rate, °C/min.
    pub rate_c_per_min: Option<f64>,
    /// The record's status.
    pub status: OutputStatus,
}

impl Row {
    fn valid(&self) -> bool {
        self.status.contains(OutputStatus::VALID)
    }
}

/// One soak's figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoakPoint {
    /// The level, °C.
    pub temperature_c: f64,
    /// The bias over the static stretch, deg/h.
    pub bias_deg_h: f64,
    /// The scale-factor error from the +R and -R stretches, ppm.
    pub scale_factor_ppm: f64,
}

/// The calibration's result.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// The model (checked: `ThermalModel::check`).
    pub model: ThermalModel,
    /// The bias fit behind it.
    pub bias: BiasResult,
    /// The soaks the scale factor was fitted on (model off).
    pub soaks: Vec<SoakPoint>,
}

/// The ramp check, model off and on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RampCheck {
    /// RMS of the 5 s windows' bias clear of the ramps' changes, model off, deg/h.
    pub raw_rms_deg_h: f64,
    /// The same, model on.
    pub corrected_rms_deg_h: f64,
    /// RMS over every window, model off, deg/h.
    pub raw_rms_all_deg_h: f64,
    /// RMS over every window, model on, deg/h.
    pub corrected_rms_all_deg_h: f64,
    /// Every record of the corrected run after the lead says it was corrected.
    pub corrected_throughout: bool,
}

/// One check soak, model off and on: a row of `thermal.csv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoakCheck {
    /// The level, °C.
    pub temperature_c: f64,
    /// Bias, model off, deg/h.
    pub bias_raw_deg_h: f64,
    /// Bias, model on, deg/h.
    pub bias_compensated_deg_h: f64,
    /// Scale-factor error, model off, ppm.
    pub scale_factor_raw_ppm: f64,
    /// Scale-factor error, model on, ppm.
    pub scale_factor_compensated_ppm: f64,
}

/// Everything [`run`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalOutcome {
    /// The calibration.
    pub calibration: Calibration,
    /// The ramp check.
    pub ramp: RampCheck,
    /// The soak check, one per level.
    pub soaks: Vec<SoakCheck>,
}

/// One run: the block on `knots` and the gyro on `input` (times after the lead), for
/// `duration_s` after the lead.
struct RunSpec<'a> {
    knots: &'a [(f64, f64)],
    input: InputProfile,
    duration_s: f64,
}

impl<'a> RunSpec<'a> {
    /// The ramps: the static input, 2 s past the last knot.
    fn ramps(plan: &ThermalPlan, knots: &'a [(f64, f64)]) -> Self {
        Self {
            knots,
            input: InputProfile::constant(plan.static_input_deg_h),
            duration_s: knots.last().map_or(0.0, |k| k.0) + 2.0,
        }
    }
}

/// The rows of one run, `model` in force from the start: every record after the lead.
fn rows(
    params: &GyroParams,
    setup: BoardSetup,
    settings: CompensationSettings,
    plan: &ThermalPlan,
    spec: &RunSpec,
    model: Option<ThermalModel>,
) -> Result<Vec<Row>, String> {
    let shifted: Vec<(f64, f64)> = spec
        .knots
        .iter()
        .map(|&(t, c)| (t + plan.lead_s, c))
        .collect();
    let profile = TemperatureProfile::knots(&shifted).map_err(|e| format!("{e:?}"))?;
    let end_s = plan.lead_s + spec.duration_s;
    let input = spec.input.clone();
    let params = params.with_temperature(profile);
    let (mut h, start_s) =
        start_run(&params, setup, input, 0.0, settings).map_err(|e| e.to_string())?;
    if start_s > plan.lead_s {
        return Err(format!(
            "the board was not ready {} s into the run (at {start_s:.1} s)",
            plan.lead_s
        ));
    }
    h.set_thermal_model(model);
    let sf = params.scale_factor_arcsec;
    let mut out = Vec::new();
    let mut last: Option<(f64, f64)> = None;
    h.run_until(end_s, |h, _| {
        for (latch, record) in h.outputs() {
            if let Some((t0, a0)) = last.filter(|_| latch.t_s > plan.lead_s) {
                out.push(Row {
                    t_s: latch.t_s - plan.lead_s,
                    dt_s: latch.t_s - t0,
                    measured_arcsec: record.delta_angle_fringes() * sf,
                    true_arcsec: latch.true_angle_arcsec - a0,
                    temp_c: record.temperature_c(),
                    rate_c_per_min: record.temperature_rate_c_per_min(),
                    status: record.status,
                });
            }
            last = Some((latch.t_s, latch.true_angle_arcsec));
        }
    });
    Ok(out)
}

/// The soaks' profile knots and table input for `levels`.
fn soak_profile(plan: &ThermalPlan, levels: &[f64]) -> (Vec<(f64, f64)>, InputProfile) {
    let mut knots = vec![(0.0, levels.first().copied().unwrap_or(plan.reference_c))];
    let mut steps = Vec::new();
    for (i, &level) in levels.iter().enumerate() {
        let start = SOAK_PERIOD_S * i as f64;
        if i > 0 {
            knots.push((start, levels[i - 1]));
            knots.push((start + SOAK_TRANSITION_S, level));
        }
        let table_from = plan.lead_s + start + SOAK_TABLE_FROM_S;
        let at_rest = plan.static_input_deg_h;
        steps.push((table_from, at_rest + plan.table_deg_h));
        steps.push((table_from + SOAK_TABLE_HALF_S, at_rest - plan.table_deg_h));
        steps.push((table_from + 2.0 * SOAK_TABLE_HALF_S, at_rest));
    }
    (knots, InputProfile::steps(plan.static_input_deg_h, &steps))
}

/// The least-squares slope of the integrated `(measured or true)` over the valid rows in
/// `from..to` (s after the lead): measured and true, per s.
fn stretch_slopes(rows: &[Row], from: f64, to: f64) -> (f64, f64) {
    let (mut m, mut t) = (0.0, 0.0);
    let (mut pm, mut pt) = (Vec::new(), Vec::new());
    for r in rows
        .iter()
        .filter(|r| r.t_s > from && r.t_s < to && r.valid())
    {
        m += r.measured_arcsec;
        t += r.true_arcsec;
        pm.push((r.t_s, m));
        pt.push((r.t_s, t));
    }
    (slope(&pm), slope(&pt))
}

/// The least-squares slope of `(t, y)` (NaN with fewer than two points).
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mt, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (stt, sty) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mt) * (p.0 - mt), b + (p.0 - mt) * (p.1 - my))
    });
    sty / stt
}

/// Each soak's bias and scale-factor error.
fn soak_points(rows: &[Row], levels: &[f64]) -> Vec<SoakPoint> {
    levels
        .iter()
        .enumerate()
        .map(|(i, &level)| {
            let start = SOAK_PERIOD_S * i as f64;
            let (m, t) =
                stretch_slopes(rows, start + SOAK_STATIC_FROM_S, start + SOAK_TABLE_FROM_S);
            let plus = start + SOAK_TABLE_FROM_S;
            let minus = plus + SOAK_TABLE_HALF_S;
            let (mp, tp) = stretch_slopes(rows, plus + TABLE_SETTLE_S, minus);
            let (mm, tm) = stretch_slopes(rows, minus + TABLE_SETTLE_S, minus + SOAK_TABLE_HALF_S);
            SoakPoint {
                temperature_c: level,
                // 1 deg/h = 1 arcsec/s.
                bias_deg_h: m - t,
                scale_factor_ppm: ((mp - mm) / (tp - tm) - 1.0) * 1e6,
            }
        })
        .collect()
}

/// The bias of each [`BIAS_WINDOW_S`] window of valid rows, deg/h, with whether the window is
/// clear of the rate's transients after `knots`' changes of slope.
fn window_biases(rows: &[Row], knots: &[(f64, f64)]) -> Vec<(f64, bool)> {
    let near_knot = |t: f64| near_knot(knots, t);
    let mut out = Vec::new();
    let mut points: Vec<(f64, f64)> = Vec::new();
    let (mut err, mut start, mut clear) = (0.0, None, true);
    for r in rows {
        let s = *start.get_or_insert(r.t_s);
        if r.valid() {
            err += r.measured_arcsec - r.true_arcsec;
            points.push((r.t_s, err));
            clear &= !near_knot(r.t_s);
        }
        if r.t_s - s >= BIAS_WINDOW_S {
            out.push((slope(&points), clear));
            points.clear();
            (start, clear) = (None, true);
        }
    }
    out
}

/// Whether `t_s` lies within [`TRANSIENT_S`] after one of `knots`' changes of slope.
fn near_knot(knots: &[(f64, f64)], t_s: f64) -> bool {
    knots
        .iter()
        .any(|&(k, _)| t_s >= k && t_s < k + TRANSIENT_S)
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.collect();
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// The thermal calibration (model off): the bias fit on the calibration ramps, the scale
/// factor on the calibration soaks, the model checked.
pub fn calibrate(
    params: &GyroParams,
    setup: BoardSetup,
    settings: CompensationSettings,
    plan: &ThermalPlan,
) -> Result<Calibration, String> {
    let (soak_knots, soak_input) = soak_profile(plan, &plan.calibration_soaks_c);
    let soaks = RunSpec {
        knots: &soak_knots,
        input: soak_input,
        duration_s: SOAK_PERIOD_S * plan.calibration_soaks_c.len() as f64,
    };
    let ramps = RunSpec::ramps(plan, &plan.calibration_knots);
    let (ramp_rows, soak_rows) = rayon::join(
        || rows(params, setup, settings, plan, &ramps, None),
        || rows(params, setup, settings, plan, &soaks, None),
    );
    let mut fit = BiasFit::new(plan.reference_c);
    let knots = &plan.calibration_knots;
    let (mut log_min_c, mut log_max_c) = (f64::INFINITY, f64::NEG_INFINITY);
    for r in ramp_rows? {
        if let Some(t) = r.temp_c.filter(|_| r.valid()) {
            (log_min_c, log_max_c) = (log_min_c.min(t), log_max_c.max(t));
        }
        let settled = !near_knot(knots, r.t_s);
        match (r.valid() && settled, r.temp_c, r.rate_c_per_min) {
            (true, Some(temp), Some(rate)) => {
                fit.push(r.dt_s, temp, rate, r.measured_arcsec - r.true_arcsec)
            }
            _ => fit.break_stretch(),
        }
    }
    let mut bias = fit
        .solve()
        .map_err(|e| format!("bias fit refused: {}", e.text()))?;
    // The model holds over the log's temperatures: the records left out at the holds lie up
    // to 0.3 °C beyond the fitted ones.
    (bias.min_c, bias.max_c) = (bias.min_c.min(log_min_c), bias.max_c.max(log_max_c));
    let soaks = soak_points(&soak_rows?, &plan.calibration_soaks_c);
    let points: Vec<(f64, f64)> = soaks
        .iter()
        .map(|p| (p.temperature_c, p.scale_factor_ppm))
        .collect();
    let scale = fit_scale(plan.reference_c, &points)
        .map_err(|e| format!("scale-factor fit refused: {}", e.text()))?;
    let model = model_of(plan.reference_c, &bias, scale)
        .map_err(|e| format!("thermal model refused: {}", e.text()))?;
    Ok(Calibration { model, bias, soaks })
}

/// The calibration, then the ramp and soak checks with the model off and on (four runs side
/// by side).
pub fn run(
    params: &GyroParams,
    setup: BoardSetup,
    settings: CompensationSettings,
    plan: &ThermalPlan,
) -> Result<ThermalOutcome, String> {
    use rayon::prelude::*;
    let calibration = calibrate(params, setup, settings, plan)?;
    let (soak_knots, soak_input) = soak_profile(plan, &plan.check_soaks_c);
    let soaks = RunSpec {
        knots: &soak_knots,
        input: soak_input,
        duration_s: SOAK_PERIOD_S * plan.check_soaks_c.len() as f64,
    };
    let ramps = RunSpec::ramps(plan, &plan.check_knots);
    let cases = [(false, false), (true, false), (false, true), (true, true)];
    let runs: Vec<Vec<Row>> = cases
        .par_iter()
        .map(|&(on, soak)| {
            let spec = if soak { &soaks } else { &ramps };
            rows(
                params,
                setup,
                settings,
                plan,
                spec,
                on.then_some(calibration.model),
            )
        })
        .collect::<Result<_, String>>()?;
    let raw = window_biases(&runs[0], &plan.check_knots);
    let corrected = window_biases(&runs[1], &plan.check_knots);
    let clear = |w: &[(f64, bool)]| rms(w.iter().filter(|x| x.1).map(|x| x.0));
    let all = |w: &[(f64, bool)]| rms(w.iter().map(|x| x.0));
    let ramp = RampCheck {
        raw_rms_deg_h: clear(&raw),
        corrected_rms_deg_h: clear(&corrected),
        raw_rms_all_deg_h: all(&raw),
        corrected_rms_all_deg_h: all(&corrected),
        corrected_throughout: runs[1]
            .iter()
            .filter(|r| r.t_s > 1.0)
            .all(|r| r.status.contains(OutputStatus::THERMAL_CORRECTED)),
    };
    let raw = soak_points(&runs[2], &plan.check_soaks_c);
    let corrected = soak_points(&runs[3], &plan.check_soaks_c);
    let soaks = raw
        .iter()
        .zip(&corrected)
        .map(|(r, c)| SoakCheck {
            temperature_c: r.temperature_c,
            bias_raw_deg_h: r.bias_deg_h,
            bias_compensated_deg_h: c.bias_deg_h,
            scale_factor_raw_ppm: r.scale_factor_ppm,
            scale_factor_compensated_ppm: c.scale_factor_ppm,
        })
        .collect();
    Ok(ThermalOutcome {
        calibration,
        ramp,
        soaks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The soaks' profile: each level reached 2 s into its soak, held through its static
    /// stretch and the table's +R and -R; at most 16 knots for eight levels.
    #[test]
    fn the_soak_profile_holds_each_level_through_its_measurements() {
        let plan = ThermalPlan::default_plan();
        let (knots, input) = soak_profile(&plan, &plan.check_soaks_c);
        assert!(knots.len() <= TemperatureProfile::MAX_KNOTS, "{knots:?}");
        let profile = TemperatureProfile::knots(&knots).unwrap();
        for (i, &level) in plan.check_soaks_c.iter().enumerate() {
            let start = SOAK_PERIOD_S * i as f64;
            for t in [start + 2.0, start + 7.0, start + 14.9] {
                assert_eq!(profile.at(t), level, "soak {i} at {t}");
            }
            let at = |t: f64| input.rate_deg_per_h(plan.lead_s + start + t) - 13.888;
            assert_eq!(
                (at(9.9), at(11.0), at(13.0), at(15.1)),
                (0.0, 36_000.0, -36_000.0, 0.0)
            );
        }
    }
}
