//! `rlg-sim`: the simulated ring laser gyro with the readout firmware's signal chain in the loop.
//!
//! `rlg-sim sweep` reproduces the paper's experiment (Fan et al., Chin. Opt. Lett. 10, 061403,
//! Figs. 3 and 4); `rlg-sim speed` measures the simulator; `rlg-sim allan` computes the Allan
//! deviation and the noise terms of a recorded rate (`rlg_sim::allan`); `rlg-sim
//! characterize` runs the IEEE Std 647 procedures and writes their report
//! (`rlg_sim::characterize`); `rlg-sim completions <shell>` prints a shell completion script.
//! Results go to stdout, diagnostics and errors to stderr; the exit statuses are
//! `host_cli::exit`'s, listed in `rlg-sim --help` (`args::Cli`).

mod args;
mod characterize_cmd;
mod flag_ranges;

use args::{
    AllanArgs, BoardArgs, CalibrationArgs, Cli, Command, DitherArgs, GyroArgs, RecordArgs,
    SpeedArgs, SweepArgs,
};
use clap::Parser;
use firmware::signal::compensation::CompensationSettings;
use hal_sim::gyro::measure_speed;
use hal_sim::input::InputProfile;
use hal_sim::params::{AmplitudeModulation, GyroParams};
use host_cli::output_file::{self, check_folder};
use host_cli::progress::steps as progress;
use host_cli::{out, outln, Failure};
use rayon::prelude::*;
use rlg_sim::dither_run::{self, DitherRunOptions};
use rlg_sim::experiment::{
    calibrate, measure_board_speed, measure_rate, settings_from_fit, BoardSetup, DitherDrive,
    Latch, RunLength,
};
use rlg_sim::record_run;
use rlg_sim::report::{self, SweepRow};
use std::io::Write;
use std::ops::ControlFlow;
use std::process::ExitCode;
use std::sync::atomic::Ordering;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match cli.command {
        Command::Sweep(args) => sweep(&args),
        Command::Speed(args) => speed(&args),
        Command::Dither(args) => dither(&args),
        Command::Record(args) => record(&args),
        Command::Allan(args) => allan(&args),
        Command::Characterize(args) => characterize_cmd::characterize(&args),
        Command::Completions(args) => host_cli::completions::print::<Cli>(&args),
    };
    host_cli::exit::exit("rlg-sim", outcome)
}

impl GyroArgs {
    fn params(&self) -> Result<GyroParams, Failure> {
        let params = GyroParams {
            scale_factor_arcsec: self.scale_factor_arcsec,
            dither_hz: self.dither_hz,
            dither_amplitude_arcsec: self.dither_amplitude_arcsec,
            lock_in_deg_per_h: self.lock_in_deg_h,
            eps_rad: self.eps_rad,
            arw_deg_per_rt_h: self.arw_deg_rt_h,
            amplitude_jitter: AmplitudeModulation::jitter(self.amplitude_jitter),
            seed: self.seed,
            thermal: self.thermal.gyro_thermal(),
            ..GyroParams::default()
        };
        params
            .derive()
            .map_err(|e| Failure::Usage(format!("invalid gyro parameters: {e:?}")))?;
        Ok(params)
    }
}

/// Runs the parallel points on `jobs` threads (`--jobs`; at least one), or one per core.
fn use_jobs(jobs: Option<usize>) -> Result<(), Failure> {
    if let Some(jobs) = jobs {
        rayon::ThreadPoolBuilder::new()
            .num_threads(jobs.max(1))
            .build_global()
            .map_err(|e| Failure::Run(format!("thread pool: {e}")))?;
    }
    Ok(())
}

fn sweep(args: &SweepArgs) -> Result<(), Failure> {
    args.validate().map_err(Failure::Usage)?;
    let params = args.gyro.params()?;
    // Preconditions: the outputs can be created (they are, empty, and written at the end).
    output_file::create_optional(args.csv.as_deref())?;
    output_file::create_optional(args.svg.as_deref())?;
    // Ctrl-C: the points under way finish, the rest are skipped, and what was done is written.
    let stop = host_cli::interrupt::install();
    use_jobs(args.jobs)?;
    // Step 2 of the paper: calibrate outside the dead band.
    let setup = args.board.setup();
    let settings = calibrate_board(
        &params,
        &args.calibration,
        setup,
        args.warmup_seconds,
        args.quiet,
    )?;
    if stop.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(Failure::Interrupted(
            "during the calibration: nothing measured".into(),
        ));
    }
    let sf = params.scale_factor_arcsec;

    // Steps 3 and 4: record across the range with the fitted coefficients applied.
    let rates = args.rates_deg_h();
    let bar = progress(rates.len() as u64, args.quiet, "sweep");
    let length = RunLength {
        warmup_s: args.warmup_seconds,
        record_s: args.seconds_per_point,
    };
    let rows: Result<Vec<Option<SweepRow>>, String> = rates
        .par_iter()
        .map(|&rate| {
            if stop.load(std::sync::atomic::Ordering::SeqCst) {
                return Ok(None);
            }
            let m =
                measure_rate(&params, setup, rate, length, settings).map_err(|e| e.to_string())?;
            bar.inc(1);
            Ok(Some(SweepRow {
                input_deg_h: rate,
                ideal_hz: rate / sf,
                uncompensated_hz: m.uncompensated_hz,
                compensated_hz: m.board_output_hz(),
            }))
        })
        .collect();
    bar.finish_and_clear();
    let rows: Vec<SweepRow> = rows.map_err(Failure::Run)?.into_iter().flatten().collect();
    out!("{}", report::table(&rows, sf))?;
    let worst = |f: fn(&SweepRow) -> f64| {
        rows.iter()
            .map(|r| (f(r) - r.ideal_hz).abs() * sf)
            .fold(0.0, f64::max)
    };
    outln!(
        "max |output - ideal|: uncompensated {:.4} deg/h, compensated {:.5} deg/h",
        worst(|r| r.uncompensated_hz),
        worst(|r| r.compensated_hz)
    )?;
    if let Some(path) = &args.csv {
        report::write_csv(path, &rows).map_err(|e| Failure::io(path.display(), e))?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.svg {
        let title = format!(
            "Dynamic lock-in compensation: Omega_L {} deg/h, dither {} arcsec at {} Hz",
            args.gyro.lock_in_deg_h, args.gyro.dither_amplitude_arcsec, args.gyro.dither_hz
        );
        std::fs::write(path, report::figure(&rows, sf, &title).to_svg())
            .map_err(|e| Failure::io(path.display(), e))?;
        eprintln!("wrote {}", path.display());
    }
    if rows.len() < rates.len() {
        return Err(Failure::Interrupted(format!(
            "{} of {} input rates done (those are written)",
            rows.len(),
            rates.len()
        )));
    }
    Ok(())
}

/// The paper's Step 2 on the board `setup` describes (what `sweep` and `record` both do):
/// prints the fit, returns the compensation settings it gives.
fn calibrate_board(
    params: &GyroParams,
    cal: &CalibrationArgs,
    setup: BoardSetup,
    warmup_s: f64,
    quiet: bool,
) -> Result<CompensationSettings, Failure> {
    let sf = params.scale_factor_arcsec;
    let cal_rates = cal.rates_deg_h();
    let bar = progress(1, quiet, "calibration");
    let cal_length = RunLength {
        warmup_s,
        record_s: cal.calibration_seconds,
    };
    let fit = calibrate(params, setup, &cal_rates, cal_length)
        .map_err(|e| Failure::Run(e.to_string()))?;
    bar.inc(1);
    bar.finish_and_clear();
    let settings = settings_from_fit(&fit).map_err(|e| Failure::Run(e.to_string()))?;
    let truth = params
        .derive()
        .map_err(|e| Failure::Usage(format!("{e:?}")))?;
    eprintln!(
        "calibration at {:?} deg/h, {} cycles: a = {:.4} rad/s (+-{:.2e}), b = {:.4} rad/s (+-{:.2e})",
        cal_rates, fit.cycles, fit.a_rad_per_s, fit.a_std_rad_per_s, fit.b_rad_per_s, fit.b_std_rad_per_s
    );
    eprintln!(
        "  Omega_L = {:.3} deg/h (true {:.3}), eps = {:.5} rad (true {:.5}), variance reduction {:.6}, condition {:.3}",
        fit.lock_in_rad_per_s * sf / std::f64::consts::TAU,
        truth.omega_l_rad_per_s * sf / std::f64::consts::TAU,
        fit.eps_rad,
        params.eps_rad,
        fit.variance_reduction,
        fit.condition_number
    );
    Ok(settings)
}

/// `rlg-sim record`: calibrate, then write the board's fixed-rate output as it comes. The CSV
/// is created before the long work starts; rows are flushed at least once a second of wall
/// time; Ctrl-C (SIGINT) stops the run cleanly with every row so far on disk (exit 130). A CSV
/// whose reader has gone (`--csv /dev/stdout | head`) stops the run at once, exit 0.
fn record(args: &RecordArgs) -> Result<(), Failure> {
    args.validate().map_err(Failure::Usage)?;
    let params = args.gyro.params()?;
    let mut out = std::io::BufWriter::new(output_file::create(&args.csv)?.file);
    let io = |e: std::io::Error| Failure::io(args.csv.display(), e);
    // With a temperature profile, the temperature each record carries (the board's sensor;
    // empty while it has none).
    let with_temperature = args.gyro.thermal.temperature_profile.is_some();
    let header = "t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid";
    if with_temperature {
        writeln!(out, "{header},temperature_c").map_err(io)?;
    } else {
        writeln!(out, "{header}").map_err(io)?;
    }
    let stop = host_cli::interrupt::install();
    let setup = args.board.setup();
    let settings = calibrate_board(
        &params,
        &args.calibration,
        setup,
        args.warmup_seconds,
        args.quiet,
    )?;
    let bar = progress(
        (args.seconds * 10.0).ceil() as u64,
        args.quiet,
        "record (0.1 s)",
    );
    let mut last_flush = std::time::Instant::now();
    let mut write_error = None;
    let summary = record_run::record(
        &params,
        setup,
        args.rate_deg_h,
        args.warmup_seconds,
        args.seconds,
        settings,
        |row| {
            let temperature = match (with_temperature, row.temperature_c) {
                (false, _) => String::new(),
                (true, Some(c)) => format!(",{c:.4}"),
                (true, None) => ",".into(),
            };
            let line = writeln!(
                out,
                "{:.6},{:.6},{:.6},{}{temperature}",
                row.t_s,
                row.delta_angle_arcsec,
                row.true_delta_angle_arcsec,
                u8::from(row.valid)
            );
            if let Err(e) = line {
                write_error = Some(e);
                return ControlFlow::Break(());
            }
            if last_flush.elapsed().as_secs_f64() >= 1.0 {
                last_flush = std::time::Instant::now();
                bar.set_position((row.t_s * 10.0) as u64);
                if let Err(e) = out.flush() {
                    write_error = Some(e);
                    return ControlFlow::Break(());
                }
            }
            if stop.load(Ordering::Relaxed) {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        },
    )
    .map_err(|e| Failure::Run(e.to_string()))?;
    bar.finish_and_clear();
    out.flush().map_err(io)?;
    if let Some(e) = write_error {
        return Err(io(e));
    }
    let sf = params.scale_factor_arcsec;
    outln!(
        "recorded {:.1} s: {} rows ({} invalid), rms(board - true) {:.4} arcsec per row",
        summary.recorded_s,
        summary.rows,
        summary.invalid_rows,
        summary.rms_error_arcsec
    )?;
    outln!(
        "K = {:.6} fringes/code ({:.5} arcsec/code at {sf} arcsec/fringe), std {:.1e} relative, {}",
        summary.strip.k,
        f64::from(summary.strip.k) * sf,
        summary.strip.k_std_rel,
        if summary.strip.converged {
            "converged"
        } else {
            "not converged"
        }
    )?;
    eprintln!("wrote {}", args.csv.display());
    if summary.interrupted && stop.load(Ordering::Relaxed) {
        return Err(Failure::Interrupted(format!(
            "{} rows written to {}",
            summary.rows,
            args.csv.display()
        )));
    }
    Ok(())
}

impl BoardArgs {
    /// The simulated board these flags describe.
    fn setup(&self) -> BoardSetup {
        BoardSetup {
            drive: match self.dither_drive {
                args::DitherDrive::Ideal => DitherDrive::Ideal,
                args::DitherDrive::ClosedLoop => DitherDrive::ClosedLoop {
                    noise_percent: self.dither_noise_percent,
                },
            },
            latch: match self.latch {
                args::LatchArg::Scheduled => Latch::Scheduled,
                args::LatchArg::Exact => Latch::Exact,
            },
            sync_hz: Some(self.sync_hz),
            pickoff_gain_error: self.pickoff_gain_error,
            pickoff_lag_s: self.pickoff_lag_us * 1e-6,
        }
    }
}

fn speed(args: &SpeedArgs) -> Result<(), Failure> {
    let params = args.gyro.params()?;
    let (speed, what) = if args.board {
        let setup = BoardSetup::board(0.0, 1000.0);
        let speed = measure_board_speed(&params, setup, args.rate_deg_h, args.seconds)
            .map_err(|e| Failure::Run(e.to_string()))?;
        (
            speed,
            "the simulated board (firmware in the loop, 1 kHz output)",
        )
    } else {
        let speed = measure_speed(
            params,
            InputProfile::constant(args.rate_deg_h),
            args.seconds,
        )
        .map_err(|e| Failure::Usage(format!("invalid gyro parameters: {e:?}")))?;
        (speed, "the gyro")
    };
    let cpu = speed
        .gyro_s_per_cpu_s
        .map_or(String::new(), |c| format!(", {c:.1} per CPU-second"));
    outln!(
        "simulated {:.1} gyro-s of {what}: {:.1} gyro-seconds per wall-second{cpu} (one core)",
        args.seconds,
        speed.gyro_s_per_wall_s
    )?;
    Ok(())
}

fn dither(args: &DitherArgs) -> Result<(), Failure> {
    let options = DitherRunOptions {
        resonance_hz: args.dither_hz,
        q_factor: args.q_factor,
        setpoint_arcsec: args.dither_amplitude_arcsec,
        resonance_drift_hz: args.resonance_drift_hz,
        pickoff_lost_at_s: args.pickoff_lost_at_s,
        noise_percent: args.dither_noise_percent,
        seconds: args.seconds,
        seed: args.seed,
    };
    options.validate().map_err(Failure::Usage)?;
    // Preconditions before the run: the output files can be created.
    let mut csv =
        output_file::create_optional(args.csv.as_deref())?.map(|o| std::io::BufWriter::new(o.file));
    output_file::create_optional(args.svg.as_deref())?;
    let csv_failed = |e| Failure::io("writing the CSV", e);
    if let Some(w) = csv.as_mut() {
        writeln!(w, "{}", dither_run::CSV_HEADER).map_err(csv_failed)?;
    }
    let bar = progress((args.seconds * args.dither_hz) as u64, args.quiet, "dither");
    let mut rows = Vec::new();
    let mut write_error = None;
    let summary = dither_run::run(&options, |row| {
        bar.inc(1);
        if let Some(w) = csv.as_mut() {
            // Rows go to disk as they come (buffered; flushed once per ~second of gyro time).
            let written = writeln!(w, "{}", dither_run::csv_line(row)).and_then(|_| {
                if rows.len() % 400 == 399 {
                    w.flush()
                } else {
                    Ok(())
                }
            });
            if let Err(e) = written {
                write_error.get_or_insert(e);
            }
        }
        rows.push(*row);
    })
    .map_err(Failure::Run)?;
    bar.finish_and_clear();
    if let Some(e) = write_error {
        return Err(csv_failed(e));
    }
    if let Some(mut w) = csv {
        w.flush().map_err(csv_failed)?;
    }
    let opt = |v: Option<f64>| v.map_or("never".to_string(), |t| format!("{t:.3} s"));
    outln!(
        "settled within 1 % of {} arcsec at {} (overshoot {:.2} %), locked at {}",
        options.setpoint_arcsec,
        opt(summary.settle_s),
        summary.overshoot_percent,
        opt(summary.locked_s)
    )?;
    outln!(
        "amplitude error after settling: {:.4} % rms; largest |drive - resonance| while locked: {:.5} Hz",
        summary.amplitude_rms_error_percent, summary.max_frequency_error_hz
    )?;
    if summary.fault_s.is_some() || options.pickoff_lost_at_s.is_some() {
        outln!(
            "fault {} at {}; at the end: drive level {:.4} of full scale, amplitude {:.1} arcsec",
            summary
                .fault
                .map_or("none".to_string(), |k| format!("{k:?}")),
            opt(summary.fault_s),
            summary.final_drive_level,
            summary.final_amplitude_arcsec
        )?;
    }
    if let Some(path) = &args.csv {
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.svg {
        std::fs::write(path, dither_run::figure(&rows, &options).to_svg())
            .map_err(|e| Failure::io(path.display(), e))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// `rlg-sim allan`: read the record, compute, print the table; the CSV and SVG if asked.
fn allan(args: &AllanArgs) -> Result<(), Failure> {
    use rlg_sim::allan::{analyse, input, output};
    // The output paths' folders must exist; nothing is created or truncated before the input
    // has been read and analysed (a bad record changes nothing).
    for path in [&args.csv, &args.svg].into_iter().flatten() {
        check_folder(path)?;
    }
    let name = args.input.display();
    let file = std::fs::File::open(&args.input)
        .map_err(|e| Failure::Usage(format!("--input {name}: {e}")))?;
    let record = input::read_csv(std::io::BufReader::with_capacity(1 << 20, file))
        .map_err(|e| Failure::Run(format!("{name}: {e}")))?;
    let analysis = analyse(&record, args.confidence, args.min_fit_tau_s)
        .map_err(|e| Failure::Run(format!("{name}: {e}")))?;
    outln!("# {name}: {}", output::record_summary(&record))?;
    out!("{}", output::table(&analysis))?;
    let write = |path: &std::path::PathBuf, text: String| {
        std::fs::write(path, text).map_err(|e| Failure::io(path.display(), e))
    };
    if let Some(path) = &args.csv {
        write(path, output::csv(&analysis))?;
    }
    if let Some(path) = &args.svg {
        let title = format!("Allan deviation: {name}");
        write(path, output::figure(&analysis, &title).to_svg())?;
    }
    Ok(())
}
