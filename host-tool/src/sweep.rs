//! A rotary-table sweep on the simulated board, in process, through the protocol.
//!
//! The gyro's sensitive axis lies horizontal on a table at latitude `L`; at azimuth `alpha` it
//! sees `Omega_E cos(L) cos(alpha)` of the Earth rate (hal-sim's `InputProfile::rotary_table`).
//! For each azimuth the board is powered up on the same simulated flash, left until its dither
//! drive locks and then to settle, and
//! its rate read from the stream (mean compensated and raw rate over the streamed cycles) or
//! from `status` (the board's own one-second averages). With a calibration, the board is first
//! calibrated at one azimuth through the protocol (`unlock`, `cal start`, `cal result`,
//! `cal accept`, `store`), so every later boot runs with the stored coefficients; a fit the
//! board refuses ends the sweep with the board's `ERR 12` and its reason.
//!
//! A stop request (Ctrl-C) ends the sweep after the azimuth being measured: the report holds
//! the points done and says it was interrupted.

use crate::capture::RateScale;
use crate::client::{Answer, Client, ClientError};
use crate::link::SimLink;
use crate::ops::{self, CalibrateOptions};
use crate::sim::{self, SimInput};
use hal_sim::flash::CalibrationFlash;
use hal_sim::input::earth_rate_on_horizontal_axis_deg_per_h;
use hal_sim::units::EARTH_RATE_SOLAR_DEG_PER_H;
use host_cli::plot::{Figure, Panel, Series, Style};
use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Between two `status` polls while waiting for the dither drive to lock (simulated time).
const LOCK_POLL: Duration = Duration::from_millis(100);

/// Where the measured rate comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RateSource {
    /// Mean over the streamed cycles (compensated and raw).
    Stream,
    /// Mean of `status`'s `rate_deg_h` (one-second averages), polled once a second.
    Status,
}

/// What the sweep does.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepOptions {
    /// Geographic latitude of the table, deg.
    pub latitude_deg: f64,
    /// Azimuths of the sensitive axis to measure at, deg from north, in order.
    pub azimuths_deg: Vec<f64>,
    /// Before measuring, after power-up (simulated time).
    pub settle: Duration,
    /// Measuring time per azimuth (simulated; whole seconds for [`RateSource::Status`]).
    pub measure: Duration,
    /// Where the measured rate comes from.
    pub rate_from: RateSource,
    /// Stream every n-th cycle.
    pub divider: u16,
    /// Calibrate first at this azimuth.
    pub calibrate: Option<(CalibrateOptions, f64)>,
    /// Seed of the simulated gyro's random processes (the same at every azimuth).
    pub seed: u64,
}

/// One azimuth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepPoint {
    /// Azimuth of the sensitive axis, deg from north.
    pub azimuth_deg: f64,
    /// The Earth rate the axis sees, Omega_E cos(L) cos(alpha), deg/h.
    pub expected_deg_per_h: f64,
    /// The board's output (compensated when compensation is on).
    pub measured_deg_per_h: f64,
    /// Before compensation (stream only).
    pub raw_deg_per_h: Option<f64>,
    /// Stream frames received (0 when the rate comes from `status`).
    pub frames: usize,
    /// Stream frames lost, from the sequence gaps (0 from `status`).
    pub lost_frames: u64,
}

/// What a sweep measured.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepReport {
    /// Geographic latitude of the table, deg.
    pub latitude_deg: f64,
    /// `cal result` of the calibration run, if one was made.
    pub calibration: Option<Answer>,
    /// One point per azimuth, in the order of [`SweepOptions::azimuths_deg`] (the first ones
    /// only, when interrupted).
    pub points: Vec<SweepPoint>,
    /// A stop request ended the sweep before its last azimuth.
    pub interrupted: bool,
}

/// Runs the sweep; `progress` gets a line per step; `stop` ends it after the current azimuth.
pub fn sweep(
    options: &SweepOptions,
    progress: &mut dyn FnMut(&str),
    stop: &AtomicBool,
) -> Result<SweepReport, ClientError> {
    let mut flash = CalibrationFlash::default();
    let mut boot_count = 0;
    let table = |azimuth_deg| SimInput::RotaryTable {
        latitude_deg: options.latitude_deg,
        azimuth_deg,
    };
    let mut calibration = None;
    // The boards of this run live only in this process: a key of their own.
    let key = sim::fresh_key();
    if let Some((cal, azimuth)) = &options.calibrate {
        progress(&format!("calibrating at azimuth {azimuth} deg"));
        let device = sim::boot(table(*azimuth), options.seed, flash, boot_count, Some(key))?;
        boot_count += 1;
        let mut client = Client::new(SimLink::new(device));
        ops::wait_for_drive_lock(&mut client, ops::DRIVE_LOCK_TIMEOUT, LOCK_POLL)?;
        client.pause(options.settle)?;
        ops::unlock(&mut client, &sim::key_hex(&key))?;
        calibration = Some(ops::calibrate_until(
            &mut client,
            cal,
            &mut |_, _| {},
            stop,
        )?);
        client.command("cal accept")?;
        client.command("store")?;
        flash = client.into_link().into_device().power_off();
    }
    let mut points = Vec::new();
    for &azimuth_deg in &options.azimuths_deg {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let device = sim::boot(
            table(azimuth_deg),
            options.seed,
            flash,
            boot_count,
            Some(key),
        )?;
        boot_count += 1;
        let mut client = Client::new(SimLink::new(device));
        ops::wait_for_drive_lock(&mut client, ops::DRIVE_LOCK_TIMEOUT, LOCK_POLL)?;
        client.pause(options.settle)?;
        let mut point = measure(&mut client, options)?;
        point.azimuth_deg = azimuth_deg;
        point.expected_deg_per_h = earth_rate_on_horizontal_axis_deg_per_h(
            EARTH_RATE_SOLAR_DEG_PER_H,
            options.latitude_deg.to_radians(),
            azimuth_deg.to_radians(),
        );
        progress(&format!(
            "azimuth {azimuth_deg:>6.1} deg: expected {:+.4} deg/h, measured {:+.4} deg/h",
            point.expected_deg_per_h, point.measured_deg_per_h
        ));
        points.push(point);
        flash = client.into_link().into_device().power_off();
    }
    Ok(SweepReport {
        latitude_deg: options.latitude_deg,
        calibration,
        interrupted: points.len() < options.azimuths_deg.len(),
        points,
    })
}

fn measure(
    client: &mut Client<SimLink>,
    options: &SweepOptions,
) -> Result<SweepPoint, ClientError> {
    let mut point = SweepPoint {
        azimuth_deg: 0.0,
        expected_deg_per_h: 0.0,
        measured_deg_per_h: f64::NAN,
        raw_deg_per_h: None,
        frames: 0,
        lost_frames: 0,
    };
    match options.rate_from {
        RateSource::Stream => {
            let scale: RateScale = ops::rate_scale(client, None)?;
            let capture = ops::stream(client, options.divider, options.measure, &mut |_| {})?;
            let (compensated, raw) = capture.mean_rates(&scale);
            point.measured_deg_per_h = compensated;
            point.raw_deg_per_h = Some(raw);
            point.frames = capture.records.len();
            point.lost_frames = capture.lost();
        }
        RateSource::Status => {
            let readings = options.measure.as_secs().max(1);
            let mut sum = 0.0;
            for _ in 0..readings {
                client.pause(Duration::from_secs(1))?;
                sum += client.command("status")?.parse_field::<f64>("rate_deg_h")?;
            }
            point.measured_deg_per_h = sum / readings as f64;
        }
    }
    Ok(point)
}

impl SweepReport {
    /// One row per azimuth.
    pub fn write_csv(&self, mut out: impl Write) -> io::Result<()> {
        writeln!(
            out,
            "azimuth_deg,expected_deg_h,measured_deg_h,error_deg_h,raw_deg_h,frames,lost_frames"
        )?;
        for p in &self.points {
            let raw = p
                .raw_deg_per_h
                .map(|r| format!("{r:.6}"))
                .unwrap_or_default();
            writeln!(
                out,
                "{},{:.6},{:.6},{:.6},{raw},{},{}",
                p.azimuth_deg,
                p.expected_deg_per_h,
                p.measured_deg_per_h,
                p.measured_deg_per_h - p.expected_deg_per_h,
                p.frames,
                p.lost_frames
            )?;
        }
        out.flush()
    }

    /// Measured and expected rate over azimuth, with the error below.
    pub fn svg(&self) -> String {
        let series =
            |label: &str, color, style, pick: &dyn Fn(&SweepPoint) -> Option<f64>| Series {
                label: label.to_owned(),
                points: self
                    .points
                    .iter()
                    .filter_map(|p| pick(p).map(|v| (p.azimuth_deg, v)))
                    .collect(),
                color,
                style,
            };
        let mut rates = vec![
            series("expected", "#444444", Style::DashedLine, &|p| {
                Some(p.expected_deg_per_h)
            }),
            series("measured", "#1f77b4", Style::LineAndMarkers, &|p| {
                Some(p.measured_deg_per_h)
            }),
        ];
        if self.points.iter().any(|p| p.raw_deg_per_h.is_some()) {
            rates.push(series("raw", "#d62728", Style::Markers, &|p| {
                p.raw_deg_per_h
            }));
        }
        Figure {
            title: format!(
                "Rotary-table sweep at latitude {} deg{}",
                self.latitude_deg,
                if self.calibration.is_some() {
                    " (calibrated)"
                } else {
                    ""
                }
            ),
            x_label: "table azimuth (deg)".into(),
            panels: vec![
                Panel {
                    title: "rate".into(),
                    y_label: "deg/h".into(),
                    series: rates,
                    weight: 2.0,
                },
                Panel {
                    title: "measured - expected".into(),
                    y_label: "deg/h".into(),
                    series: vec![series("error", "#1f77b4", Style::LineAndMarkers, &|p| {
                        Some(p.measured_deg_per_h - p.expected_deg_per_h)
                    })],
                    weight: 1.0,
                },
            ],
            width_px: 900.0,
            height_px: 650.0,
            axes: host_cli::plot::Axes::Linear,
        }
        .to_svg()
    }
}
