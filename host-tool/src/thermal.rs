//! `rlg-cal thermal`: a thermal calibration on a board, from a log of its fixed-rate output
//! against the temperature it reports, while the block goes through a chamber's ramps or steps.
//!
//! The board streams its records (`stream output`) and, in thermal frames, the block's
//! temperature and rate (the firmware's `OutputStreamDecoder` gives each record its own). The
//! operator states the gyro's true input at rest (`--input-rate-deg-h`: the Earth rate on its
//! sensitive axis, outside the dead band) and, for the scale factor, the rate of a rate table
//! run at +R and -R at some temperatures (`--table-rate-deg-h`). Nothing else about the run is
//! assumed: the log is read as it is ([`fit_log`]).
//!
//! # Reading the log
//!
//! - **Blocks**: 0.1 s of records; each block's mean rate (1 deg/h of noise from the output's
//!   white angle noise) says whether the gyro was at rest (within [`REST_TOLERANCE_DEG_H`] of
//!   the input), on the table at +R or -R (within [`TABLE_TOLERANCE`] of R0 +- R), or in
//!   between. A block is used only when every block within [`CLASS_MARGIN_S`] of it has its
//!   class (the table's accelerations and the first instants after them are left out).
//! - **The rate estimate**: the board's temperature rate is the slope of its last 2 s of
//!   results, so after a change of the chamber's ramp it lags for up to 2 s, and the model's
//!   rate term would then correct with the wrong rate. A record is left out of the bias fit
//!   within [`RATE_SETTLE_S`] after a 0.5 s window whose mean reported rate moved by more than
//!   [`RATE_STEP_C_PER_MIN`] from the window before (a chamber ramping at a few °C/min never
//!   does).
//! - **Bias**: the used rest records go to the firmware's `BiasFit` (the integrated angle
//!   error against the integrated regressors, one offset per unbroken stretch), the error of
//!   each being its increment minus `input x dt`.
//! - **Scale factor**: each run of +R blocks next to a run of -R blocks (at most
//!   [`PAIR_GAP_S`] apart) is one point: the least-squares slopes of the two runs' integrated
//!   angles, `(rate+ - rate-) / 2R - 1` (the bias cancels), at the mean temperature of both.
//!   Without a table rate the scale-factor terms are 0 (not calibrated, and said so).
//! - **The model**: `firmware::thermal::fit::model_of`, with its checks (span, records, rate
//!   spread, plausibility); a refusal says why and nothing is sent to the board. It holds over
//!   the log's temperatures (the records left out lie at most a few tenths of a °C beyond the
//!   fitted ones, at the ends of a chamber's holds).

use crate::client::{Answer, Client, ClientError};
use crate::link::Link;
use firmware::protocol::output_frame::{OutputStreamDecoder, OutputStreamFrame};
use firmware::signal::output::record::OutputRecord;
use firmware::thermal::fit::{fit_scale, model_of, BiasFit, BiasResult};
use firmware::thermal::model::ThermalModel;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// A block's length, s.
pub const BLOCK_S: f64 = 0.1;
/// A rest block's mean rate within this of the input, deg/h (the block's noise is about
/// 1 deg/h; a table turning at 10 deg/s is 36 000).
pub const REST_TOLERANCE_DEG_H: f64 = 50.0;
/// A table block's mean rate within this fraction of R of R0 +- R.
pub const TABLE_TOLERANCE: f64 = 0.01;
/// Blocks within this of another class are not used, s.
pub const CLASS_MARGIN_S: f64 = 0.5;
/// The reported rate's windows, s.
pub const RATE_WINDOW_S: f64 = 0.5;
/// A window's mean rate moving by more than this from the one before marks a change of
/// ramp, °C/min (the estimate's noise is about 0.2 °C/min).
pub const RATE_STEP_C_PER_MIN: f64 = 3.0;
/// After a change of ramp, records are left out of the bias fit for this long, s.
pub const RATE_SETTLE_S: f64 = 3.0;
/// A +R run and a -R run at most this far apart make one scale-factor point, s.
pub const PAIR_GAP_S: f64 = 2.0;

/// One output record as the calibration reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRecord {
    /// The record's latch time, s from the first record.
    pub t_s: f64,
    /// Its period, s.
    pub dt_s: f64,
    /// Its increment, arcsec (0 when invalid).
    pub arcsec: f64,
    /// Valid, and not after a lost record (the chain unbroken).
    pub valid: bool,
    /// The temperature it carries, °C.
    pub temp_c: Option<f64>,
    /// The temperature's rate it carries, °C/min.
    pub rate_c_per_min: Option<f64>,
}

/// The log being recorded: records with their times, gaps marked.
#[derive(Clone, Debug, Default)]
pub struct ThermalLog {
    records: Vec<LogRecord>,
    first_ticks: Option<u64>,
    last_sequence: Option<u64>,
    /// Records missing between the sequence numbers received.
    pub lost: u64,
}

impl ThermalLog {
    /// One record from the stream (with its thermal values), the board's timer and scale
    /// factor. A record after a gap is marked not valid (its period is not its own).
    pub fn push(&mut self, r: &OutputRecord, timer_hz: f64, scale_factor_arcsec: f64) {
        let t0 = *self.first_ticks.get_or_insert(r.time_ticks);
        let gap = self
            .last_sequence
            .is_some_and(|s| r.sequence != s.wrapping_add(1));
        if let Some(s) = self.last_sequence.filter(|&s| r.sequence > s) {
            self.lost += r.sequence - s - 1;
        }
        self.last_sequence = Some(r.sequence);
        self.records.push(LogRecord {
            t_s: r.time_ticks.saturating_sub(t0) as f64 / timer_hz,
            dt_s: f64::from(r.period_ticks) / timer_hz,
            arcsec: r.delta_angle_fringes() * scale_factor_arcsec,
            valid: r.is_valid() && !gap,
            temp_c: r.temperature_c(),
            rate_c_per_min: r.temperature_rate_c_per_min(),
        });
    }

    /// The records so far.
    pub fn records(&self) -> &[LogRecord] {
        &self.records
    }
}

/// What the operator states about the run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalOptions {
    /// The gyro's true input at rest, deg/h.
    pub input_rate_deg_h: f64,
    /// The table's rate when it turns (+R and -R), deg/h; `None`: no scale-factor part.
    pub table_rate_deg_h: Option<f64>,
    /// T_ref of the model, °C.
    pub reference_c: f64,
}

/// Where the gyro was in a block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Rest,
    Plus,
    Minus,
    Other,
}

/// One scale-factor point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScalePoint {
    /// Mean temperature of the two runs, °C.
    pub temperature_c: f64,
    /// The scale-factor error, ppm.
    pub ppm: f64,
}

/// The calibration's result.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalFit {
    /// The model (checked).
    pub model: ThermalModel,
    /// The bias fit.
    pub bias: BiasResult,
    /// The scale-factor points (empty without a table rate).
    pub scale_points: Vec<ScalePoint>,
    /// Records in the log, and used for the bias.
    pub records: usize,
    /// Rest records used for the bias fit.
    pub bias_records: u64,
}

/// Why the log gave no model.
#[derive(Clone, Debug, PartialEq)]
pub struct Refused(pub String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// The least-squares slope of the integrated angle of `records`, arcsec/s (= deg/h).
fn slope_of(records: &[&LogRecord]) -> Option<f64> {
    let mut angle = 0.0;
    let points: Vec<(f64, f64)> = records
        .iter()
        .map(|r| {
            angle += r.arcsec;
            (r.t_s, angle)
        })
        .collect();
    let n = points.len() as f64;
    if n < 2.0 {
        return None;
    }
    let (mt, ma) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (stt, sta) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mt) * (p.0 - mt), b + (p.0 - mt) * (p.1 - ma))
    });
    (stt > 0.0).then(|| sta / stt)
}

/// Each record's block index, the blocks' classes, and whether each block is used.
fn classify(records: &[LogRecord], options: &ThermalOptions) -> (Vec<usize>, Vec<Class>) {
    let block_of: Vec<usize> = records.iter().map(|r| (r.t_s / BLOCK_S) as usize).collect();
    let blocks = block_of.last().map_or(0, |b| b + 1);
    let (mut angle, mut time, mut any_invalid) =
        (vec![0.0; blocks], vec![0.0; blocks], vec![false; blocks]);
    for (r, &b) in records.iter().zip(&block_of) {
        angle[b] += r.arcsec;
        time[b] += r.dt_s;
        any_invalid[b] |= !r.valid;
    }
    let r0 = options.input_rate_deg_h;
    let mut class: Vec<Class> = (0..blocks)
        .map(|b| {
            if any_invalid[b] || time[b] <= 0.0 {
                return Class::Other;
            }
            let rate = angle[b] / time[b];
            match options.table_rate_deg_h {
                _ if (rate - r0).abs() <= REST_TOLERANCE_DEG_H => Class::Rest,
                Some(table) if (rate - r0 - table).abs() <= TABLE_TOLERANCE * table => Class::Plus,
                Some(table) if (rate - r0 + table).abs() <= TABLE_TOLERANCE * table => Class::Minus,
                _ => Class::Other,
            }
        })
        .collect();
    // A block is used only when its neighbours within the margin share its class.
    let margin = (CLASS_MARGIN_S / BLOCK_S).round() as usize;
    let raw = class.clone();
    for (b, c) in class.iter_mut().enumerate() {
        let from = b.saturating_sub(margin);
        let to = (b + margin).min(blocks.saturating_sub(1));
        if raw[from..=to].iter().any(|&n| n != raw[b]) {
            *c = Class::Other;
        }
    }
    (block_of, class)
}

/// Whether each record lies within [`RATE_SETTLE_S`] after a change of the reported rate.
fn rate_unsettled(records: &[LogRecord]) -> Vec<bool> {
    let windows = records
        .last()
        .map_or(0, |r| (r.t_s / RATE_WINDOW_S) as usize + 1);
    let (mut sum, mut n) = (vec![0.0; windows], vec![0.0; windows]);
    for r in records {
        if let Some(rate) = r.rate_c_per_min {
            let w = (r.t_s / RATE_WINDOW_S) as usize;
            sum[w] += rate;
            n[w] += 1.0;
        }
    }
    let mean: Vec<Option<f64>> = sum
        .iter()
        .zip(&n)
        .map(|(s, n)| (*n > 0.0).then(|| s / n))
        .collect();
    // The end of each window whose mean moved (or that follows one without a rate).
    let moved: Vec<f64> = mean
        .windows(2)
        .enumerate()
        .filter(|(_, w)| match (w[0], w[1]) {
            (Some(a), Some(b)) => (b - a).abs() > RATE_STEP_C_PER_MIN,
            (None, Some(_)) => true,
            _ => false,
        })
        .map(|(i, _)| (i + 2) as f64 * RATE_WINDOW_S)
        .collect();
    records
        .iter()
        .map(|r| {
            moved
                .iter()
                .any(|&m| r.t_s >= m - RATE_WINDOW_S && r.t_s < m + RATE_SETTLE_S)
        })
        .collect()
}

/// The thermal model of a log (see the module docs).
pub fn fit_log(records: &[LogRecord], options: &ThermalOptions) -> Result<ThermalFit, Refused> {
    let (block_of, class) = classify(records, options);
    let unsettled = rate_unsettled(records);
    let mut fit = BiasFit::new(options.reference_c);
    let (mut log_min_c, mut log_max_c) = (f64::INFINITY, f64::NEG_INFINITY);
    for ((r, &b), &moving) in records.iter().zip(&block_of).zip(&unsettled) {
        if let Some(temp) = r.temp_c.filter(|_| r.valid) {
            (log_min_c, log_max_c) = (log_min_c.min(temp), log_max_c.max(temp));
        }
        let rest = class[b] == Class::Rest;
        match (rest && !moving, r.temp_c, r.rate_c_per_min) {
            (true, Some(temp), Some(rate)) => {
                let error = r.arcsec - options.input_rate_deg_h * r.dt_s;
                fit.push(r.dt_s, temp, rate, error);
            }
            _ => fit.break_stretch(),
        }
    }
    let mut bias = fit
        .solve()
        .map_err(|e| Refused(format!("bias fit refused: {}", e.text())))?;
    (bias.min_c, bias.max_c) = (log_min_c, log_max_c);
    let scale_points = match options.table_rate_deg_h {
        Some(table) => scale_points(records, &block_of, &class, table),
        None => Vec::new(),
    };
    let scale = if options.table_rate_deg_h.is_some() {
        let points: Vec<(f64, f64)> = scale_points
            .iter()
            .map(|p| (p.temperature_c, p.ppm))
            .collect();
        fit_scale(options.reference_c, &points)
            .map_err(|e| Refused(format!("scale-factor fit refused: {}", e.text())))?
    } else {
        [0.0; 3]
    };
    let model = model_of(options.reference_c, &bias, scale)
        .map_err(|e| Refused(format!("thermal model refused: {}", e.text())))?;
    Ok(ThermalFit {
        model,
        bias_records: bias.records,
        bias,
        scale_points,
        records: records.len(),
    })
}

/// The scale-factor points: each run of +R blocks paired with the next run of -R blocks (or
/// the other way round) at most [`PAIR_GAP_S`] apart.
fn scale_points(
    records: &[LogRecord],
    block_of: &[usize],
    class: &[Class],
    table_deg_h: f64,
) -> Vec<ScalePoint> {
    // Runs of one table class: (class, first block, last block).
    let mut runs: Vec<(Class, usize, usize)> = Vec::new();
    for (b, &c) in class.iter().enumerate() {
        if c != Class::Plus && c != Class::Minus {
            continue;
        }
        match runs.last_mut() {
            Some(run) if run.0 == c && run.2 + 1 == b => run.2 = b,
            _ => runs.push((c, b, b)),
        }
    }
    let of_run = |run: &(Class, usize, usize)| -> Vec<&LogRecord> {
        records
            .iter()
            .zip(block_of)
            .filter(|(_, &b)| b >= run.1 && b <= run.2)
            .map(|(r, _)| r)
            .collect()
    };
    let gap_blocks = (PAIR_GAP_S / BLOCK_S).round() as usize;
    let mut points = Vec::new();
    let mut i = 0;
    while i + 1 < runs.len() {
        let (a, b) = (runs[i], runs[i + 1]);
        if a.0 != b.0 && b.1 <= a.2 + gap_blocks {
            let (ra, rb) = (of_run(&a), of_run(&b));
            if let (Some(sa), Some(sb)) = (slope_of(&ra), slope_of(&rb)) {
                let (plus, minus) = if a.0 == Class::Plus {
                    (sa, sb)
                } else {
                    (sb, sa)
                };
                let temps: Vec<f64> = ra.iter().chain(&rb).filter_map(|r| r.temp_c).collect();
                if !temps.is_empty() {
                    points.push(ScalePoint {
                        temperature_c: temps.iter().sum::<f64>() / temps.len() as f64,
                        ppm: ((plus - minus) / (2.0 * table_deg_h) - 1.0) * 1e6,
                    });
                }
            }
            i += 2;
        } else {
            i += 1;
        }
    }
    points
}

/// The protocol lines that put `model` in force on a board: one `thermal set` per coefficient
/// (in `ThermalModel::NAMES`' order, each value as f32 prints it, so the board holds exactly
/// it), then `thermal apply`.
pub fn model_lines(model: &ThermalModel) -> Vec<String> {
    ThermalModel::NAMES
        .iter()
        .zip(model.values())
        .map(|(name, value)| format!("thermal set {name} {value:e}"))
        .chain(std::iter::once("thermal apply".to_owned()))
        .collect()
}

/// Records the board's output with its temperatures for `duration` on the link's clock (or
/// until `stop`): the log, and the frames that were not valid ones.
pub fn record_log<L: Link>(
    client: &mut Client<L>,
    duration: Duration,
    progress: &mut dyn FnMut(f64),
    stop: &AtomicBool,
) -> Result<(ThermalLog, u64), ClientError> {
    let scale = crate::ops::rate_scale(client, None)?;
    let mut log = ThermalLog::default();
    let mut decoder = OutputStreamDecoder::default();
    let mut bad = 0u64;
    crate::ops::record_until(
        client,
        duration,
        progress,
        &mut |chunk, _| {
            match decoder.decode(chunk) {
                Ok(OutputStreamFrame::Record(r)) => {
                    log.push(&r, scale.timer_hz, scale.scale_factor_arcsec)
                }
                Ok(OutputStreamFrame::Thermal(_)) => {}
                Err(_) => bad += 1,
            }
            std::ops::ControlFlow::Continue(())
        },
        stop,
    )?;
    Ok((log, bad))
}

/// Puts `model` in force on the board ([`model_lines`]; the board must be unlocked) and checks
/// that the board holds it: `thermal model` answers each coefficient within 2 f32 ulps of the
/// one sent (the board's decimal parser is within one ulp) and `thermal=on`. The answer to
/// `thermal model`.
pub fn apply_model<L: Link>(
    client: &mut Client<L>,
    model: &ThermalModel,
) -> Result<Answer, ClientError> {
    for line in model_lines(model) {
        client.command(&line)?;
    }
    let answer = client.command("thermal model")?;
    let mismatch = |what: String| ClientError::Unexpected {
        command: answer.command.clone(),
        answer: answer.text.clone(),
        what,
    };
    if answer.field("thermal") != Some("on") {
        return Err(mismatch("the model is not on".into()));
    }
    for (name, sent) in ThermalModel::NAMES.iter().zip(model.values()) {
        let held: f32 = answer.parse_field(name)?;
        let ulps = (held.to_bits() as i64 - sent.to_bits() as i64).abs();
        if held != sent && (held.signum() != sent.signum() || ulps > 2) {
            return Err(mismatch(format!("{name}: {held} held, {sent} sent")));
        }
    }
    Ok(answer)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic log (1 kHz records, white angle noise 0.07 arcsec per record): a -20..60 °C
    /// ramp at 1 °C/s with the gyro at rest, then four soaks with the table at +-10 deg/s; the
    /// gyro's bias `0.002 x + 2e-5 x^2` deg/h and scale factor `0.5 x` ppm (x = T - 25). The
    /// log gives both back within what the noise allows, and the table's runs and the ramp's
    /// start are left out of the bias.
    #[test]
    fn a_synthetic_log_gives_its_model_back() {
        let (r0, table) = (13.888, 36_000.0);
        let bias = |t: f64| {
            let x = t - 25.0;
            0.002 * x + 2e-5 * x * x
        };
        let sf = |t: f64| 0.5 * (t - 25.0) * 1e-6;
        let mut records = Vec::new();
        let mut seed = 7u64;
        let mut noise = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.07 * 12f64.sqrt()
        };
        let (dt, mut last_noise) = (1e-3, 0.0);
        let mut push = |t: f64, temp: f64, rate_c_min: f64, input: f64| {
            let n = noise();
            let arcsec = (input * (1.0 + sf(temp)) + bias(temp)) * dt + n - last_noise;
            last_noise = n;
            records.push(LogRecord {
                t_s: t,
                dt_s: dt,
                arcsec,
                valid: true,
                temp_c: Some((temp * 128.0).round() / 128.0),
                rate_c_per_min: Some(rate_c_min),
            });
        };
        let mut t = 0.0;
        // The ramp: 5 s at -20, 80 s up, 5 s at 60 (the reported rate steps at the knots).
        while t < 90.0 {
            let (temp, rate) = match t {
                t if t < 5.0 => (-20.0, 0.0),
                t if t < 85.0 => (-20.0 + (t - 5.0), 60.0),
                _ => (60.0, 0.0),
            };
            push(t, temp, rate, r0);
            t += dt;
        }
        for level in [50.0, 30.0, 10.0, -10.0] {
            let start = t;
            while t < start + 10.0 {
                let input = match t - start {
                    s if s < 4.0 => r0,
                    s if s < 7.0 => r0 + table,
                    _ => r0 - table,
                };
                push(t, level, 0.0, input);
                t += dt;
            }
        }
        let options = ThermalOptions {
            input_rate_deg_h: r0,
            table_rate_deg_h: Some(table),
            reference_c: 25.0,
        };
        let fit = fit_log(&records, &options).unwrap();
        assert_eq!(fit.scale_points.len(), 4, "{:?}", fit.scale_points);
        for p in &fit.scale_points {
            let want = sf(p.temperature_c) * 1e6;
            assert!((p.ppm - want).abs() < 0.1, "{p:?} vs {want}");
        }
        let m = fit.model;
        let worst = (-20..=60)
            .map(|t| (m.bias_deg_h(t as f32, 0.0) as f64 - bias(t as f64)).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.003, "{worst} {m:?}");
        assert!((m.scale_ppm(55.0) - 15.0).abs() < 0.2, "{m:?}");
        // The table's runs and their margins, the 5 s after each change of the reported rate
        // and the soaks' first instants are not in the bias fit.
        assert!(
            fit.bias_records < 100_000 && fit.bias_records > 70_000,
            "{}",
            fit.bias_records
        );
    }

    /// Without a table rate, the scale factor is not calibrated (zero terms); a log without
    /// enough temperature span is refused with the fit's reason.
    #[test]
    fn without_a_table_and_with_too_little_span() {
        let records: Vec<LogRecord> = (0..20_000)
            .map(|k| LogRecord {
                t_s: k as f64 * 1e-3,
                dt_s: 1e-3,
                arcsec: 13.888e-3,
                valid: true,
                temp_c: Some(25.0 + k as f64 * 1e-4),
                rate_c_per_min: Some(0.6),
            })
            .collect();
        let options = ThermalOptions {
            input_rate_deg_h: 13.888,
            table_rate_deg_h: None,
            reference_c: 25.0,
        };
        let refused = fit_log(&records, &options).unwrap_err();
        assert!(
            refused.0.contains("temperature span under 10 C"),
            "{refused}"
        );
    }

    /// The lines that put a model in force parse back to its exact values.
    #[test]
    fn the_model_lines_carry_the_exact_values() {
        let model = ThermalModel {
            reference_c: 25.0,
            min_c: -19.992188,
            max_c: 60.03125,
            bias_deg_h: [-5.635231e-5, 0.001970955, 2.008991e-5, -5.813926e-9],
            bias_deg_h_per_c_per_min: 0.0020027596,
            scale_ppm: [-0.023179466, 0.50015175, 0.0050035366],
        };
        let lines = model_lines(&model);
        assert_eq!(lines.len(), 12);
        assert_eq!(lines[11], "thermal apply");
        let values: Vec<f32> = lines[..11]
            .iter()
            .map(|l| l.rsplit(' ').next().unwrap().parse().unwrap())
            .collect();
        assert_eq!(values, model.values().to_vec());
        assert!(lines.iter().all(|l| l.len() + 6 <= 96), "{lines:?}");
    }
}
