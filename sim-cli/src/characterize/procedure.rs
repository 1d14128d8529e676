//! The runs of the characterisation: every input rate of the plan and one static record per
//! configuration, independent runs on all cores (rayon, as `sweep`).
//!
//! A rate point is [`measure_rate`] (the board of [`crate::experiment`], the least-squares
//! slope of the fixed-rate output's angle over `seconds_per_point` after the warm-up and the
//! drive's lock), converted to deg/h at the scale factor the board is configured with. The
//! static record is [`record_run::record`] at zero input, decimated
//! ([`super::noise::Decimator`]) and written to the configuration's static CSV as it comes
//! (`t_s,delta_angle_arcsec,valid`, what `rlg-sim allan` reads), so a long record interrupted
//! keeps what it produced.
//!
//! The static records are queued first (the longest jobs; with 2 cores and 3 configurations
//! the points fill in around them). Stop ([`Outcome::interrupted`]): points not started are
//! skipped, the static records end at the next sync period; what was done is returned.

use super::figures::{scale_factor, threshold, RatePoint, ScaleFactor, Threshold};
use super::noise::{rate_record, static_figures, Decimator, StaticFigures, StaticSample};
use super::{planned_rates, Configuration, Plan};
use crate::experiment::{measure_rate, RunLength, DRIVE_SETTLE_S};
use crate::record_run;
use hal_sim::params::GyroParams;
use rayon::prelude::*;
use std::io::Write;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// The static CSV's header.
pub const STATIC_CSV_HEADER: &str = "t_s,delta_angle_arcsec,valid";

/// Everything measured for one configuration.
#[derive(Clone, Debug)]
pub struct ConfigurationResult {
    /// The configuration.
    pub configuration: Configuration,
    /// The measured points, by input rate.
    pub points: Vec<RatePoint>,
    /// The static record's figures (`None`: not recorded, interrupted before it started).
    pub static_figures: Option<StaticFigures>,
    /// Scale factor, non-linearity, asymmetry (`None` with fewer than 2 linear-range points).
    pub scale_factor: Option<ScaleFactor>,
    /// Threshold and dead band, against the fitted scale factor and the static bias.
    pub threshold: Option<Threshold>,
}

/// What a characterisation produced.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// One per configuration, in the order given.
    pub results: Vec<ConfigurationResult>,
    /// Stopped before the end: some points or records are missing or short.
    pub interrupted: bool,
}

/// The simulated seconds the plan runs per configuration (for a progress bar): each point's
/// warm-up, drive settling and record, and the static record.
pub fn gyro_seconds(plan: &Plan) -> f64 {
    let points = 2 * (plan.range_points + plan.dense_points);
    let per_run = plan.warmup_s.max(DRIVE_SETTLE_S) + plan.seconds_per_point;
    points as f64 * per_run + plan.static_s
}

#[derive(Clone, Copy)]
enum Job {
    Static(usize),
    Point(usize, usize),
}

enum Done {
    Static(usize, Option<Box<StaticFigures>>),
    Point(usize, RatePoint),
    Skipped,
}

/// Runs `plan` for every configuration. `static_out[i]` receives configuration `i`'s static
/// record as CSV; `progress` is told the simulated seconds done as they complete; `stop`
/// ends the run early. Errs on the first failed run (the simulator's or the CSV's error).
pub fn run(
    params: &GyroParams,
    plan: &Plan,
    configurations: &[Configuration],
    static_out: Vec<Box<dyn Write + Send>>,
    progress: &(dyn Fn(f64) + Sync),
    stop: &AtomicBool,
) -> Result<Outcome, String> {
    let theory = super::dead_band_theory(params).ok_or("invalid gyro parameters")?;
    let rates = planned_rates(plan, theory.envelope_deg_h);
    let static_out: Vec<Mutex<Box<dyn Write + Send>>> =
        static_out.into_iter().map(Mutex::new).collect();
    if static_out.len() != configurations.len() {
        return Err("one static output per configuration".into());
    }
    let jobs: Vec<Job> = (0..configurations.len())
        .map(Job::Static)
        .chain(
            (0..configurations.len()).flat_map(|c| (0..rates.len()).map(move |i| Job::Point(c, i))),
        )
        .collect();
    let done: Vec<Done> = jobs
        .par_iter()
        .with_max_len(1)
        .map(|&job| {
            if stop.load(Ordering::SeqCst) {
                return Ok(Done::Skipped);
            }
            match job {
                Job::Static(c) => {
                    let mut out = static_out[c].lock().map_err(|_| "static output poisoned")?;
                    let figures = static_record(
                        params,
                        plan,
                        &configurations[c],
                        &mut **out,
                        progress,
                        stop,
                    )?;
                    Ok(Done::Static(c, figures.map(Box::new)))
                }
                Job::Point(c, i) => {
                    let point = measure_point(params, plan, &configurations[c], rates[i])?;
                    progress(plan.warmup_s.max(DRIVE_SETTLE_S) + plan.seconds_per_point);
                    Ok(Done::Point(c, point))
                }
            }
        })
        .collect::<Result<_, String>>()?;
    let mut results: Vec<ConfigurationResult> = configurations
        .iter()
        .map(|c| ConfigurationResult {
            configuration: c.clone(),
            points: Vec::new(),
            static_figures: None,
            scale_factor: None,
            threshold: None,
        })
        .collect();
    let mut complete = true;
    for d in done {
        match d {
            Done::Static(c, figures) => {
                complete &= figures.is_some();
                results[c].static_figures = figures.map(|f| *f);
            }
            Done::Point(c, p) => results[c].points.push(p),
            Done::Skipped => complete = false,
        }
    }
    let sf = params.scale_factor_arcsec;
    for r in &mut results {
        r.points
            .sort_by(|a, b| a.input_deg_h.total_cmp(&b.input_deg_h));
        r.scale_factor = scale_factor(&r.points, sf);
        if let Some(s) = &r.scale_factor {
            let bias = r
                .static_figures
                .as_ref()
                .map_or(s.line.intercept, |f| f.bias_deg_h);
            r.threshold = Some(threshold(&r.points, s.line.slope, bias));
        }
    }
    Ok(Outcome {
        results,
        interrupted: !complete || stop.load(Ordering::SeqCst),
    })
}

/// One input rate: the board's fixed-rate output, deg/h.
fn measure_point(
    params: &GyroParams,
    plan: &Plan,
    configuration: &Configuration,
    rate: super::PlannedRate,
) -> Result<RatePoint, String> {
    let length = RunLength {
        warmup_s: plan.warmup_s,
        record_s: plan.seconds_per_point,
    };
    let m = measure_rate(
        params,
        configuration.setup,
        rate.rate_deg_h,
        length,
        configuration.settings,
    )
    .map_err(|e| format!("{} at {} deg/h: {e}", configuration.name, rate.rate_deg_h))?;
    let output_hz = m
        .output_hz
        .ok_or("the board has no fixed-rate output (no sync)")?;
    Ok(RatePoint {
        input_deg_h: rate.rate_deg_h,
        output_deg_h: output_hz * params.scale_factor_arcsec,
        linear_range: rate.linear_range,
    })
}

/// The static record of one configuration, written to `out` as it comes; its figures, or
/// `None` when stopped before a sample was recorded.
fn static_record(
    params: &GyroParams,
    plan: &Plan,
    configuration: &Configuration,
    out: &mut dyn Write,
    progress: &(dyn Fn(f64) + Sync),
    stop: &AtomicBool,
) -> Result<Option<StaticFigures>, String> {
    let sync_hz = configuration
        .setup
        .sync_hz
        .ok_or("the static record needs the board's sync")?;
    let io = |e: std::io::Error| format!("{} static record: {e}", configuration.name);
    writeln!(out, "{STATIC_CSV_HEADER}").map_err(io)?;
    let mut decimator = Decimator::for_periods((plan.static_s * sync_hz).ceil() as u64);
    let mut samples: Vec<StaticSample> = Vec::new();
    let mut write_error = None;
    let (mut rows, mut reported_s) = (0u64, 0.0f64);
    record_run::record(
        params,
        configuration.setup,
        0.0,
        plan.warmup_s,
        plan.static_s,
        configuration.settings,
        |row| {
            rows += 1;
            if let Some(s) = decimator.push(row.t_s, row.delta_angle_arcsec, row.valid) {
                let line = writeln!(
                    out,
                    "{:.6},{:.6},{}",
                    s.t_s,
                    s.delta_angle_arcsec,
                    u8::from(s.valid)
                );
                if let Err(e) = line {
                    write_error = Some(e);
                    return ControlFlow::Break(());
                }
                samples.push(s);
            }
            let done_s = rows as f64 / sync_hz;
            if done_s - reported_s >= 1.0 {
                progress(done_s - reported_s);
                reported_s = done_s;
            }
            if stop.load(Ordering::Relaxed) {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        },
    )
    .map_err(|e| format!("{} static record: {e}", configuration.name))?;
    progress((plan.static_s - reported_s).max(0.0));
    out.flush().map_err(io)?;
    if let Some(e) = write_error {
        return Err(io(e));
    }
    if samples.len() < 3 {
        return Ok(None);
    }
    let span_s = samples[samples.len() - 1].t_s - samples[0].t_s;
    let period_s = span_s / (samples.len() - 1) as f64;
    let figures = static_figures(
        &rate_record(&samples, period_s),
        plan.confidence,
        super::noise::FIT_FROM_DITHER_PERIODS / params.dither_hz,
    );
    Ok((!stop.load(Ordering::Relaxed)).then_some(figures))
}
