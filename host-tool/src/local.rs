//! The subcommands that run their own simulated board: `sweep` (in process, on simulated
//! time) and `serve-sim` (in real time, for other programs). Neither takes a connection from
//! the environment; `serve-sim` takes `--tcp` as the address to listen on.

use crate::cli::{ConnectionArgs, RateFrom, ServeArgs, SweepArgs};
use hal_sim::flash::CalibrationFlash;
use hal_sim::thermal::ThermalCoefficients;
use host_cli::output_file::create_optional;
use host_cli::{interrupt, Failure};
use rlg_cal::client::ClientError;
use rlg_cal::ops::CalibrateOptions;
use rlg_cal::serve::{self, PtyEndpoint, ServeOptions, TcpEndpoint};
use rlg_cal::sim::{self, SimInput};
use rlg_cal::sweep::{self, RateSource, SweepOptions};
use std::io::Write;
use std::net::TcpListener;
use std::time::Duration;

pub fn sweep(args: &SweepArgs, connection: &ConnectionArgs) -> Result<(), Failure> {
    if connection.given() {
        return Err(Failure::Usage(
            "sweep runs its own simulated board: --port, --tcp and --sim do not apply".into(),
        ));
    }
    let seconds = |s: f64, name: &str| {
        if s >= 0.0 && s.is_finite() {
            Ok(Duration::from_secs_f64(s))
        } else {
            Err(Failure::Usage(format!("{name} must be a time >= 0")))
        }
    };
    let options = SweepOptions {
        latitude_deg: args.latitude,
        azimuths_deg: args.azimuths.clone(),
        settle: seconds(args.settle, "--settle")?,
        measure: seconds(args.seconds, "--seconds")?,
        rate_from: match args.rate_from {
            RateFrom::Stream => RateSource::Stream,
            RateFrom::Status => RateSource::Status,
        },
        divider: args.divider,
        calibrate: args.calibrate.then(|| {
            (
                CalibrateOptions::new(args.cal_cycles, args.cal_warmup),
                args.cal_azimuth,
            )
        }),
        seed: args.seed,
    };
    let csv = create_optional(args.csv.as_deref())?;
    let svg = create_optional(args.svg.as_deref())?;
    let stop = interrupt::install();
    let report = sweep::sweep(&options, &mut |line| eprintln!("{line}"), stop)?;
    if let Some(fit) = &report.calibration {
        host_cli::outln!("# calibration: {}", fit.text)?;
    }
    report
        .write_csv(std::io::stdout().lock())
        .map_err(|e| Failure::io("stdout", e))?;
    let write_failed = |path: &std::path::Path, e: std::io::Error| {
        Failure::io(format_args!("cannot write {}", path.display()), e)
    };
    if let Some(out) = csv {
        report
            .write_csv(&out.file)
            .map_err(|e| write_failed(&out.path, e))?;
    }
    if let Some(out) = svg {
        (&out.file)
            .write_all(report.svg().as_bytes())
            .map_err(|e| write_failed(&out.path, e))?;
    }
    if report.interrupted {
        return Err(Failure::from(ClientError::Interrupted {
            what: format!(
                "the sweep after {} of {} azimuths (those are written)",
                report.points.len(),
                options.azimuths_deg.len()
            ),
        }));
    }
    Ok(())
}

/// The input of the served board in words, with units.
fn describe(input: &SimInput) -> String {
    match *input {
        SimInput::Constant { rate_deg_per_h } => {
            format!("a constant input rate of {rate_deg_per_h} deg/h")
        }
        SimInput::RotaryTable {
            latitude_deg,
            azimuth_deg,
        } => format!(
            "Earth rate on a rotary table at latitude {latitude_deg} deg, azimuth {azimuth_deg} deg"
        ),
    }
}

pub fn serve(args: &ServeArgs, connection: &ConnectionArgs) -> Result<(), Failure> {
    if connection.port.is_some() || connection.sim {
        return Err(Failure::Usage(
            "serve-sim runs its own simulated board: --port and --sim do not apply".into(),
        ));
    }
    if connection.tcp.is_some() == args.pty {
        return Err(Failure::Usage(
            "serve-sim needs one of --tcp HOST:PORT (port 0: any free port) or --pty".into(),
        ));
    }
    if !(args.speed > 0.0 && args.speed.is_finite()) {
        return Err(Failure::Usage("--speed must be positive".into()));
    }
    let input = match args.azimuth {
        Some(azimuth_deg) => SimInput::RotaryTable {
            latitude_deg: args.latitude,
            azimuth_deg,
        },
        None => SimInput::Constant {
            rate_deg_per_h: args.rate,
        },
    };
    if args.board_key.is_some() {
        return Err(Failure::Usage(crate::cli::key_on_command_line(
            "--board-key",
            "--board-key-file PATH or RLG_SIM_BOARD_KEY",
        )));
    }
    let from_file = args
        .board_key_file
        .as_deref()
        .map(crate::cli::read_key_file)
        .transpose()
        .map_err(Failure::Usage)?;
    let board_key = sim::board_key(from_file.as_deref()).map_err(Failure::Usage)?;
    let gyro = sim::gyro(args.seed, args.temperature_profile);
    let device = sim::boot_gyro(
        gyro,
        input.profile(),
        CalibrationFlash::default(),
        0,
        board_key,
    )
    .map_err(|e| Failure::Run(e.to_string()))?;
    let options = ServeOptions {
        speed: args.speed,
        max_duration: args.seconds.map(Duration::from_secs_f64),
    };
    let stop = interrupt::install();
    let announce =
        |where_: &str| {
            // The address for a program that reads it; nobody reading is no reason to stop.
            let _ = host_cli::outln!("{where_}");
            let _ = std::io::stdout().flush();
            eprintln!(
            "rlg-cal: a simulated board is served on {where_}: {}, {}, running at {} times real \
             time; {}. Ctrl-C stops it.",
            describe(&input),
            if args.temperature_profile.is_some() {
                "its block on the --temperature-profile given".to_owned()
            } else {
                format!("its block at {} C", ThermalCoefficients::DEFAULT.reference_c)
            },
            args.speed,
            if board_key.is_some() {
                "its key is the one given (--board-key-file or RLG_SIM_BOARD_KEY)"
            } else {
                "it has no key yet: `key provision <32 hex digits>` sets one, once"
            }
        );
        };
    let served = if let Some(address) = &connection.tcp {
        let listener = TcpListener::bind(address)
            .map_err(|e| Failure::Connect(format!("cannot listen on {address}: {e}")))?;
        let local = listener
            .local_addr()
            .map_err(|e| Failure::Connect(e.to_string()))?;
        let mut endpoint =
            TcpEndpoint::new(listener).map_err(|e| Failure::Connect(e.to_string()))?;
        announce(&local.to_string());
        serve::serve(device, &mut endpoint, &options, stop)
    } else {
        let mut endpoint =
            PtyEndpoint::open().map_err(|e| Failure::Connect(format!("pty: {e}")))?;
        announce(&endpoint.path().display().to_string());
        serve::serve(device, &mut endpoint, &options, stop)
    };
    served.map_err(|e| Failure::Connect(format!("serving: {e}")))?;
    if interrupt::requested() {
        return Err(Failure::from(ClientError::Interrupted {
            what: "serve-sim stopped; the simulated board is gone".into(),
        }));
    }
    Ok(())
}
