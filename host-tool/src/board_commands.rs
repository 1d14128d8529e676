//! The subcommands that talk to a board, on any link: one exchange with its answer printed, or
//! the long runs (`calibrate`, `stream`, `record`, `console`).
//!
//! The long runs check their preconditions first ([`prepare`]: output files created, the key
//! present for a protected step), then ask the board `id`, and stop cleanly on Ctrl-C or
//! SIGTERM (`host_cli::interrupt`): `calibrate` sends `cal abort`, `stream` keeps every frame
//! received (its CSV is written row by row), draws its SVG and prints its summary; exit 130.

use crate::cli::{CalibrateArgs, Command, OnOff, RecordArgs, StreamArgs, ThermalArgs};
use host_cli::output_file::{create as create_output, create_optional, Output};
use host_cli::progress::{self, set_fraction};
use host_cli::{interrupt, Failure};
use rlg_cal::capture::CsvRows;
use rlg_cal::client::{Client, ClientError};
use rlg_cal::link::Link;
use rlg_cal::ops::{self, CalibrateOptions};
use rlg_cal::output::Format;
use rlg_cal::output_capture::OutputRows;
use std::io::Write;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Duration;

/// A file of a long run could not be written (quietly when it is a pipe whose reader went).
fn write_failed(path: &Path, e: std::io::Error) -> Failure {
    Failure::io(format_args!("cannot write {}", path.display()), e)
}

/// Longest wait for the board's `id` before a long run.
const PROBE_TIMEOUT: Duration = Duration::from_secs(1);

/// The output files of a long run, created before it starts.
#[derive(Default)]
pub struct Outputs {
    pub csv: Option<Output>,
    pub svg: Option<Output>,
}

/// The preconditions that need no board and that clap has not checked (the ranges of the
/// arguments it has: `ranges.rs`): output files, the key for a protected step. Exit 2 on any.
pub fn prepare(command: &Command, have_key: bool) -> Result<Outputs, Failure> {
    match command {
        Command::Stream(args) => Ok(Outputs {
            csv: Some(create_output(&args.csv)?),
            svg: create_optional(args.svg.as_deref())?,
        }),
        Command::Record(args) => Ok(Outputs {
            csv: Some(create_output(&args.csv)?),
            svg: None,
        }),
        Command::Thermal(args) if args.apply && !have_key => Err(Failure::Usage(
            "thermal --apply needs the unlock key (--key-file or RLG_KEY): `thermal set` is \
             protected"
                .into(),
        )),
        Command::Thermal(args) => Ok(Outputs {
            csv: create_optional(args.csv.as_deref())?,
            svg: None,
        }),
        Command::Calibrate(_) if !have_key => Err(Failure::Usage(
            "calibrate needs the unlock key (--key-file or RLG_KEY): `cal start` takes the \
             board's time and is protected"
                .into(),
        )),
        Command::Unlock { key: Some(_) } => Err(Failure::Usage(crate::cli::key_on_command_line(
            "unlock",
            "--key-file PATH or RLG_KEY",
        ))),
        Command::Unlock { .. } | Command::KeyProvision if !have_key => Err(Failure::Usage(
            "the key comes from --key-file PATH or RLG_KEY (never from the command line)".into(),
        )),
        Command::Send { words } if carries_a_key(words) => Err(Failure::Usage(
            "`send` does not take `unlock` or `key provision`: their key would stand on the \
             command line; use `rlg-cal unlock` or `rlg-cal key-provision` with --key-file or \
             RLG_KEY"
                .into(),
        )),
        _ => Ok(Outputs::default()),
    }
}

/// Whether a `send` line is `unlock ...` or `key ...`: lines whose key would stand on the
/// command line.
fn carries_a_key(words: &[String]) -> bool {
    let line = words.join(" ");
    let first = line.split_whitespace().next().unwrap_or("");
    first.eq_ignore_ascii_case("unlock") || first.eq_ignore_ascii_case("key")
}

/// What a session with a board carries besides the client.
pub struct Session {
    pub key: Option<String>,
    pub format: Format,
    pub outputs: Outputs,
}

/// The commands that talk to a board.
pub struct Device<'a, L: Link> {
    client: &'a mut Client<L>,
    session: Session,
}

fn on_off(state: OnOff) -> &'static str {
    match state {
        OnOff::On => "on",
        OnOff::Off => "off",
    }
}

fn value_name<T: clap::ValueEnum>(v: &T) -> String {
    v.to_possible_value()
        .map(|p| p.get_name().to_owned())
        .unwrap_or_default()
}

impl<'a, L: Link> Device<'a, L> {
    pub fn new(client: &'a mut Client<L>, session: Session) -> Self {
        Self { client, session }
    }

    /// Prints one command's result (its fields and sections) in the session's format.
    fn print(&self, fields: &[(String, String)], sections: &[(&str, Vec<(String, String)>)]) {
        // A closed stdout (`| head`) is not an error of the run.
        let _ = writeln!(
            std::io::stdout(),
            "{}",
            self.session.format.render(fields, sections)
        );
    }

    /// A precondition of a long run: the board answers `id`, within a second at most (a board
    /// answers in milliseconds; a silent port is a connection error, exit 3, before the run).
    fn probe(&mut self) -> Result<(), Failure> {
        let timeout = self.client.timeout();
        self.client.set_timeout(timeout.min(PROBE_TIMEOUT));
        let answered = self.client.command("id");
        self.client.set_timeout(timeout);
        answered?;
        Ok(())
    }

    /// Unlocks first when a key was given.
    fn unlocked(&mut self) -> Result<&mut Self, Failure> {
        if let Some(key) = &self.session.key {
            ops::unlock(self.client, key)?;
        }
        Ok(self)
    }

    /// One exchange, answer printed.
    fn ask(&mut self, line: &str) -> Result<(), Failure> {
        let answer = self.client.command(line)?;
        self.print(&answer.fields(), &[]);
        Ok(())
    }

    pub fn run(&mut self, command: &Command) -> Result<(), Failure> {
        match command {
            Command::Id => self.ask("id"),
            Command::Status => self.ask("status"),
            Command::Get { which } => self.ask(&format!("get {}", value_name(which))),
            Command::Set { which, value } => self
                .unlocked()?
                .ask(&format!("set {} {value}", value_name(which))),
            Command::Comp { state } => self.unlocked()?.ask(&format!("comp {}", on_off(*state))),
            Command::Track { state } => self.unlocked()?.ask(&format!("track {}", on_off(*state))),
            Command::Unlock { .. } => {
                let key = self.session.key.clone().unwrap_or_default();
                let answer = ops::unlock(self.client, &key)?;
                self.print(&answer.fields(), &[]);
                Ok(())
            }
            Command::KeyProvision => self.provision(),
            Command::Lock => self.ask("lock"),
            Command::Store => self.unlocked()?.ask("store"),
            Command::Reload => self.unlocked()?.ask("reload"),
            Command::Defaults => self.unlocked()?.ask("defaults"),
            Command::Send { words } => self.ask(&words.join(" ")),
            Command::Calibrate(args) => self.calibrate(args),
            Command::Stream(args) => self.stream(args),
            Command::Record(args) => self.record(args),
            Command::Thermal(args) => self.thermal(args),
            Command::Console => {
                if let Some(key) = &self.session.key {
                    ops::unlock(self.client, key)?;
                }
                rlg_cal::console::run(self.client).map_err(Failure::from)
            }
            Command::Sweep(_) | Command::ServeSim(_) | Command::Completions(_) => {
                unreachable!("handled before connecting")
            }
        }
    }

    /// `key provision` with the session's key, checked here first: a key the board would
    /// refuse as a number (not 32 hex digits, or all ones) is a usage error, never sent.
    fn provision(&mut self) -> Result<(), Failure> {
        let text = self.session.key.clone().unwrap_or_default();
        let key = firmware::protocol::key::Key::parse_hex(&text).ok_or_else(|| {
            Failure::Usage("the key is 32 hex digits (128 bits), not all f".into())
        })?;
        let answer = self
            .client
            .command(&format!("key provision {}", key.hex()))?;
        self.print(&answer.fields(), &[]);
        Ok(())
    }

    fn calibrate(&mut self, args: &CalibrateArgs) -> Result<(), Failure> {
        let stop = interrupt::install();
        // The board answers, and a wrong key is refused, before the run.
        self.probe()?;
        // `cal start` takes the board's time: protected like the rest.
        self.unlocked()?;
        let options = CalibrateOptions {
            poll: Duration::from_millis(args.poll_ms.max(10)),
            ..CalibrateOptions::new(args.cycles, args.warmup)
        };
        let bar = progress::steps(args.cycles as u64 + args.warmup as u64, false, "cycles");
        let mut announced = false;
        let result = ops::calibrate_until(
            self.client,
            &options,
            &mut |done, total| {
                if !std::mem::replace(&mut announced, true) {
                    bar.suspend(|| {
                        eprintln!(
                            "rlg-cal: the calibration runs on the board: {} cycles after {} of \
                             warm-up (Ctrl-C aborts it there).",
                            args.cycles, args.warmup
                        )
                    });
                }
                bar.set_length(total);
                bar.set_position(done);
            },
            stop,
        );
        bar.finish_and_clear();
        let fit = result?;
        let mut sections = Vec::new();
        if args.accept {
            sections.push(("accept", self.client.command("cal accept")?.fields()));
        }
        if args.store {
            sections.push(("store", self.client.command("store")?.fields()));
        }
        self.print(&fit.fields(), &sections);
        Ok(())
    }

    /// `rlg-cal thermal`: the log, the fit, and with --apply / --store the model on the board.
    fn thermal(&mut self, args: &ThermalArgs) -> Result<(), Failure> {
        use rlg_cal::thermal::{apply_model, fit_log, record_log, ThermalOptions};
        let stop = interrupt::install();
        let csv = std::mem::take(&mut self.session.outputs).csv;
        self.probe()?;
        if args.apply {
            // A wrong key is refused before the run, not after it.
            self.unlocked()?;
        }
        eprintln!(
            "rlg-cal: recording the output and the block's temperature for {} s (run the \
             chamber's ramps or steps now; Ctrl-C stops and fits what was recorded).",
            args.seconds
        );
        let bar = progress::fraction(false, "thermal log");
        let (log, bad) = record_log(
            self.client,
            Duration::from_secs_f64(args.seconds),
            &mut |fraction| set_fraction(&bar, fraction),
            stop,
        )?;
        bar.finish_and_clear();
        if let Some(out) = csv {
            let mut w = std::io::BufWriter::new(out.file);
            let rows =
                std::iter::once("t_s,delta_angle_arcsec,valid,temperature_c,rate_c_min".to_owned())
                    .chain(log.records().iter().map(|r| {
                        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
                        format!(
                            "{:.6},{:.6},{},{},{}",
                            r.t_s,
                            r.arcsec,
                            u8::from(r.valid),
                            opt(r.temp_c),
                            opt(r.rate_c_per_min)
                        )
                    }));
            for row in rows {
                writeln!(w, "{row}").map_err(|e| write_failed(&out.path, e))?;
            }
            w.flush().map_err(|e| write_failed(&out.path, e))?;
        }
        let options = ThermalOptions {
            input_rate_deg_h: args.input_rate_deg_h,
            table_rate_deg_h: args.table_rate_deg_h,
            reference_c: args.reference_c,
        };
        let fit = fit_log(log.records(), &options).map_err(|e| Failure::Run(e.to_string()))?;
        let m = &fit.model;
        let mut fields: Vec<(String, String)> = vec![
            ("records".into(), fit.records.to_string()),
            ("lost".into(), log.lost.to_string()),
            ("bad".into(), bad.to_string()),
            ("bias_records".into(), fit.bias_records.to_string()),
            ("rate_fitted".into(), fit.bias.rate_fitted.to_string()),
            ("scale_points".into(), fit.scale_points.len().to_string()),
        ];
        fields.extend(
            firmware::thermal::model::ThermalModel::NAMES
                .iter()
                .zip(m.values())
                .map(|(k, v)| ((*k).to_owned(), format!("{v:e}"))),
        );
        if args.table_rate_deg_h.is_none() {
            eprintln!(
                "rlg-cal: no --table-rate-deg-h: the scale factor is not calibrated (s0..s2 = 0)"
            );
        }
        let mut sections = Vec::new();
        if args.apply {
            // The unlock of the start has long expired (5 minutes idle) after a chamber's run.
            self.unlocked()?;
            sections.push(("apply", apply_model(self.client, m)?.fields()));
        }
        if args.store {
            sections.push(("store", self.client.command("store")?.fields()));
        }
        self.print(&fields, &sections);
        Ok(())
    }

    /// `rlg-cal record`: the fixed-rate output into the CSV as it comes; lost records counted
    /// and marked; Ctrl-C stops with every record received written (exit 130).
    fn record(&mut self, args: &RecordArgs) -> Result<(), Failure> {
        let stop = interrupt::install();
        let outputs = std::mem::take(&mut self.session.outputs);
        let csv = outputs.csv.expect("prepared");
        self.probe()?;
        let scale = ops::rate_scale(self.client, args.timer_hz)?;
        let mut rows = OutputRows::new(csv.file, scale).map_err(|e| write_failed(&csv.path, e))?;
        let mut row_error = None;
        eprintln!(
            "rlg-cal: recording the fixed-rate output for {} s into {} (Ctrl-C stops and keeps \
             every record received).",
            args.seconds,
            csv.path.display()
        );
        let bar = progress::fraction(false, "recording");
        let result = ops::record_until(
            self.client,
            Duration::from_secs_f64(args.seconds),
            &mut |fraction| set_fraction(&bar, fraction),
            &mut |chunk, received| match rows.push_chunk(chunk, received) {
                Ok(_) => ControlFlow::Continue(()),
                Err(e) => {
                    row_error = Some(e);
                    ControlFlow::Break(())
                }
            },
            stop,
        );
        bar.finish_and_clear();
        result?;
        if let Some(e) = row_error {
            return Err(write_failed(&csv.path, e));
        }
        let (bad, invalid, span_s) = (rows.bad_frames, rows.invalid, rows.span_s());
        let gaps = rows.finish().map_err(|e| write_failed(&csv.path, e))?;
        let interrupted = interrupt::requested();
        let summary = [
            ("records", gaps.received.to_string()),
            ("lost", gaps.lost.to_string()),
            ("bad", bad.to_string()),
            ("invalid", invalid.to_string()),
            ("restarts", (gaps.jumps + gaps.out_of_order).to_string()),
            ("span_s", format!("{span_s:.3}")),
            (
                "interrupted",
                if interrupted { "yes" } else { "no" }.to_owned(),
            ),
        ]
        .map(|(k, v)| (k.to_owned(), v));
        self.print(&summary, &[]);
        if gaps.lost > 0 {
            eprintln!(
                "rlg-cal: {} records lost (sequence gaps, marked in the CSV): the link is slower \
                 than the output (44 bytes per record)",
                gaps.lost
            );
        }
        if gaps.jumps + gaps.out_of_order > 0 {
            eprintln!(
                "rlg-cal: the sequence restarted {} times (a board reset, or a frame whose \
                 sequence or time the elapsed time does not allow): no rows for those steps",
                gaps.jumps + gaps.out_of_order
            );
        }
        if interrupted {
            return Err(Failure::from(ClientError::Interrupted {
                what: format!(
                    "the recording after {} records (all of them in {})",
                    gaps.received,
                    csv.path.display()
                ),
            }));
        }
        Ok(())
    }

    fn stream(&mut self, args: &StreamArgs) -> Result<(), Failure> {
        let stop = interrupt::install();
        let outputs = std::mem::take(&mut self.session.outputs);
        let csv = outputs.csv.expect("prepared");
        self.probe()?;
        let scale = ops::rate_scale(self.client, args.timer_hz)?;
        let mut rows =
            CsvRows::new(csv.file, args.divider, scale).map_err(|e| write_failed(&csv.path, e))?;
        let mut row_error = None;
        eprintln!(
            "rlg-cal: streaming every {} cycle(s) for {} s into {} (Ctrl-C stops and keeps \
             every frame received).",
            args.divider,
            args.seconds,
            csv.path.display()
        );
        let bar = progress::fraction(false, "streaming");
        let capture = ops::stream_until(
            self.client,
            args.divider,
            Duration::from_secs_f64(args.seconds),
            &mut |fraction| set_fraction(&bar, fraction),
            &mut |record| match rows.push(record) {
                Ok(()) => ControlFlow::Continue(()),
                Err(e) => {
                    row_error = Some(e);
                    ControlFlow::Break(())
                }
            },
            stop,
        );
        bar.finish_and_clear();
        let capture = capture?;
        if let Some(e) = row_error {
            return Err(write_failed(&csv.path, e));
        }
        rows.finish().map_err(|e| write_failed(&csv.path, e))?;
        if let Some(svg) = outputs.svg {
            let plot = capture.svg(&scale, "Streamed rate");
            let mut file = svg.file;
            file.write_all(plot.as_bytes())
                .and_then(|_| file.flush())
                .map_err(|e| write_failed(&svg.path, e))?;
        }
        let (compensated, raw) = capture.mean_rates(&scale);
        let interrupted = interrupt::requested();
        let summary = [
            ("frames", capture.records.len().to_string()),
            ("lost", capture.lost().to_string()),
            ("bad", capture.bad_frames.to_string()),
            ("mean_compensated_deg_h", format!("{compensated:.4}")),
            ("mean_raw_deg_h", format!("{raw:.4}")),
            (
                "interrupted",
                if interrupted { "yes" } else { "no" }.to_owned(),
            ),
        ]
        .map(|(k, v)| (k.to_owned(), v));
        self.print(&summary, &[]);
        if capture.lost() > 0 {
            eprintln!(
                "rlg-cal: {} frames lost (sequence gaps): use a faster link or a larger --divider",
                capture.lost()
            );
        }
        if interrupted {
            return Err(Failure::from(ClientError::Interrupted {
                what: format!(
                    "the stream after {} frames (all of them in {})",
                    capture.records.len(),
                    csv.path.display()
                ),
            }));
        }
        Ok(())
    }
}
