//! `rlg-sim characterize`: the flags into a plan and configurations, the preconditions, the
//! run ([`rlg_sim::characterize::procedure::run`]), the report and the exit status.
//!
//! Preconditions first, before any simulation: every flag in its range (exit 2), the output
//! folder created and every static CSV created in it (an unwritable folder is exit 2 at
//! once). Then the calibration (only when a configuration compensates), then the runs. Ctrl-C
//! stops the runs (points under way finish, static records end at the next sync period),
//! keeps the static CSVs and writes `scale_factor.csv` of the points done, and exits 130
//! without a report (its figures would be of an incomplete test).

use crate::args::{self, CharacterizeArgs, OnOff};
use crate::{calibrate_board, use_jobs};
use firmware::signal::compensation::CompensationSettings;
use host_cli::progress;
use host_cli::{out, outln, Failure};
use rlg_sim::characterize::report::{self, Context};
use rlg_sim::characterize::summary::{self, SLUG_NOISE, SLUG_OFF, SLUG_ON};
use rlg_sim::characterize::{dead_band_theory, procedure, Configuration};
use rlg_sim::experiment::{BoardSetup, DitherDrive};
use std::io::Write;
use std::sync::atomic::Ordering;

/// The configurations to run: the three of `--compare`, or the one the flags describe.
/// `settings` is the calibrated compensation (used by the configurations that compensate).
fn configurations(
    args: &CharacterizeArgs,
    setup: BoardSetup,
    settings: CompensationSettings,
) -> Vec<Configuration> {
    let off = CompensationSettings::default();
    let config = |name: String, slug: &str, setup, settings| Configuration {
        name,
        slug: slug.into(),
        setup,
        settings,
    };
    if args.compare {
        let noisy = BoardSetup {
            drive: DitherDrive::ClosedLoop {
                noise_percent: args.compare_noise_percent,
            },
            ..setup
        };
        return vec![
            config("compensation off".into(), SLUG_OFF, setup, off),
            config("compensation on".into(), SLUG_ON, setup, settings),
            config(
                format!("random-noise dither {} %", args.compare_noise_percent),
                SLUG_NOISE,
                noisy,
                off,
            ),
        ];
    }
    let noise = match setup.drive {
        DitherDrive::ClosedLoop { noise_percent } if noise_percent > 0.0 => {
            format!(", random-noise dither {noise_percent} %")
        }
        _ => String::new(),
    };
    match args.compensation {
        OnOff::On => vec![config(
            format!("compensation on{noise}"),
            SLUG_ON,
            setup,
            settings,
        )],
        OnOff::Off => vec![config(
            format!("compensation off{noise}"),
            SLUG_OFF,
            setup,
            off,
        )],
    }
}

fn board_text(args: &CharacterizeArgs) -> String {
    let b = &args.board;
    format!(
        "{} dither drive, {} latch, fixed-rate output on a {} Hz sync, pick-off gain error {}, \
         lag {} us",
        match b.dither_drive {
            args::DitherDrive::ClosedLoop => "the firmware's closed-loop",
            args::DitherDrive::Ideal => "the prescribed (ideal) sine",
        },
        match b.latch {
            args::LatchArg::Scheduled => "scheduled",
            args::LatchArg::Exact => "exact",
        },
        b.sync_hz,
        b.pickoff_gain_error,
        b.pickoff_lag_us
    )
}

/// Runs `rlg-sim characterize`.
pub fn characterize(args: &CharacterizeArgs) -> Result<(), Failure> {
    args.validate().map_err(Failure::Usage)?;
    let params = args.gyro.params()?;
    let plan = args.plan();
    let theory = dead_band_theory(&params)
        .ok_or_else(|| Failure::Usage("invalid gyro parameters".into()))?;
    let setup = args.board.setup();
    // Preconditions: the folder and every static CSV (the names do not depend on the
    // calibration).
    let out = &args.out;
    std::fs::create_dir_all(out)
        .map_err(|e| Failure::Usage(format!("--out {}: {e}", out.display())))?;
    let slugs: Vec<String> = configurations(args, setup, CompensationSettings::default())
        .into_iter()
        .map(|c| c.slug)
        .collect();
    let mut static_out: Vec<Box<dyn Write + Send>> = Vec::new();
    for slug in &slugs {
        let path = out.join(format!("static_{slug}.csv"));
        let file = host_cli::output_file::create(&path)?.file;
        static_out.push(Box::new(std::io::BufWriter::new(file)));
    }
    let stop = host_cli::interrupt::install();
    use_jobs(args.jobs)?;
    let compensates = args.compare || args.compensation == OnOff::On;
    let (settings, calibration) = if compensates {
        let s = calibrate_board(
            &params,
            &args.calibration,
            setup,
            args.warmup_seconds,
            args.quiet,
        )?;
        let text = format!(
            "at {:?} deg/h, {} s each",
            args.calibration.rates_deg_h(),
            args.calibration.calibration_seconds
        );
        (s, Some(text))
    } else {
        (CompensationSettings::default(), None)
    };
    if stop.load(Ordering::SeqCst) {
        return Err(Failure::Interrupted(
            "during the calibration: nothing measured".into(),
        ));
    }
    let configurations = configurations(args, setup, settings);
    let total_s = procedure::gyro_seconds(&plan) * configurations.len() as f64;
    let bar = progress::steps((total_s * 10.0).ceil() as u64, args.quiet, "gyro 0.1 s");
    let started = std::time::Instant::now();
    let outcome = procedure::run(
        &params,
        &plan,
        &configurations,
        static_out,
        &|s| bar.inc((s * 10.0).round() as u64),
        stop,
    )
    .map_err(Failure::Run)?;
    bar.finish_and_clear();
    let io = |e: std::io::Error| Failure::io(format_args!("--out {}", out.display()), e);
    if outcome.interrupted {
        report::write_points(out, &outcome).map_err(io)?;
        let points: usize = outcome.results.iter().map(|r| r.points.len()).sum();
        return Err(Failure::Interrupted(format!(
            "{points} rates measured (scale_factor.csv) and the static records so far \
             (static_*.csv) kept in {}; no report",
            out.display()
        )));
    }
    let command = std::iter::once("rlg-sim".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let ctx = Context {
        command,
        params,
        plan,
        theory,
        board: board_text(args),
        calibration,
        thermal: None,
    };
    let thermal = if args.thermal {
        let thermal_plan = rlg_sim::thermal::procedure::ThermalPlan::default_plan();
        let thermal_s = thermal_plan.gyro_seconds();
        eprintln!("bias and scale factor over temperature: {thermal_s:.0} gyro-seconds");
        let thermal_setup = BoardSetup {
            drive: match setup.drive {
                DitherDrive::ClosedLoop { .. } => DitherDrive::ClosedLoop { noise_percent: 0.0 },
                ideal => ideal,
            },
            ..setup
        };
        let outcome =
            rlg_sim::thermal::procedure::run(&params, thermal_setup, settings, &thermal_plan)
                .map_err(Failure::Run)?;
        Some((outcome, thermal_plan))
    } else {
        None
    };
    let ctx = Context { thermal, ..ctx };
    let written = report::write(out, &outcome, &ctx).map_err(io)?;
    out!("{}", summary::table(&outcome.results))?;
    for c in summary::conclusions(&outcome.results) {
        outln!("\n{c}")?;
    }
    if let Some((thermal, _)) = &ctx.thermal {
        let r = &thermal.ramp;
        let worst = |f: fn(&rlg_sim::thermal::procedure::SoakCheck) -> f64| {
            thermal
                .soaks
                .iter()
                .map(f)
                .map(f64::abs)
                .fold(0.0, f64::max)
        };
        outln!(
            "\nover temperature: ramp bias rms {:.5} -> {:.5} deg/h with the model; soaks: bias \
             worst {:.5} -> {:.5} deg/h, scale factor worst {:.3} -> {:.3} ppm",
            r.raw_rms_all_deg_h,
            r.corrected_rms_all_deg_h,
            worst(|p| p.bias_raw_deg_h),
            worst(|p| p.bias_compensated_deg_h),
            worst(|p| p.scale_factor_raw_ppm),
            worst(|p| p.scale_factor_compensated_ppm)
        )?;
    }
    eprintln!(
        "{:.0} gyro-seconds in {:.1} s; wrote {} files to {}",
        total_s,
        started.elapsed().as_secs_f64(),
        written.len() + slugs.len(),
        out.display()
    );
    Ok(())
}
