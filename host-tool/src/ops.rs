//! Multi-command operations: what the subcommands do beyond one exchange, on any link.

use crate::capture::{Capture, RateScale};
use crate::client::{Answer, Client, ClientError};
use crate::link::Link;
use firmware::protocol::stream::StreamRecord;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// A stop flag that is never set, for runs nobody interrupts.
pub static NEVER: AtomicBool = AtomicBool::new(false);

/// Longest wait for an unlock window the client accepts from an `ERR 14` (the board's window
/// period, `AccessConfig::DEFAULT.window_period_ms`, plus a margin for the link).
pub const UNLOCK_WINDOW_WAIT_MAX: Duration = Duration::from_millis(
    firmware::protocol::access::AccessConfig::DEFAULT.window_period_ms as u64 + 1_000,
);

/// Unlocks protected commands with `key` (hex, as the board expects it). After wrong keys the
/// board checks attempts only in its windows: on an `ERR 14` the client waits the time it names
/// (at most [`UNLOCK_WINDOW_WAIT_MAX`]) and tries again, three times at most, so the key holder
/// is in at the next window whatever wrong keys others sent.
pub fn unlock<L: Link>(client: &mut Client<L>, key: &str) -> Result<Answer, ClientError> {
    let mut tries = 0;
    loop {
        let refused = match client.command(&format!("unlock {key}")) {
            Err(ClientError::Device(e)) if e.code == 14 && tries < 3 => e,
            other => return other,
        };
        let wait_ms = crate::output::fields(&refused.text)
            .into_iter()
            .find(|(k, _)| k == "wait_ms")
            .and_then(|(_, v)| v.parse::<u64>().ok())
            .map(Duration::from_millis)
            .filter(|wait| *wait <= UNLOCK_WINDOW_WAIT_MAX);
        let Some(wait) = wait_ms else {
            return Err(ClientError::Device(refused));
        };
        client.pause(wait)?;
        tries += 1;
    }
}

/// The board's scale factor and capture-timer frequency from `id`, for rates in deg/h.
/// `timer_hz` overrides the board's (firmware older than the `timer_hz` field needs it).
pub fn rate_scale<L: Link>(
    client: &mut Client<L>,
    timer_hz: Option<f64>,
) -> Result<RateScale, ClientError> {
    let id = client.command("id")?;
    let timer_hz = match timer_hz {
        Some(hz) => hz,
        None => id.parse_field("timer_hz")?,
    };
    Ok(RateScale {
        scale_factor_arcsec: id.parse_field("sf_arcsec")?,
        timer_hz,
    })
}

/// One calibration run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrateOptions {
    /// Dither cycles fed into the fit (`cal start <cycles>`, 1..=3 600 000).
    pub cycles: u32,
    /// Cycles discarded before them (`cal start ... <warmup>`).
    pub warmup_cycles: u32,
    /// Between two `cal status` polls.
    pub poll: Duration,
    /// A run whose cycle count does not move for this long has failed (signal lost?).
    pub stall_timeout: Duration,
}

impl CalibrateOptions {
    /// A run of `cycles` after `warmup_cycles`, polled every 250 ms, failed after 10 s stalled.
    pub fn new(cycles: u32, warmup_cycles: u32) -> Self {
        Self {
            cycles,
            warmup_cycles,
            poll: Duration::from_millis(250),
            stall_timeout: Duration::from_secs(10),
        }
    }
}

/// Longest wait for the dither drive to lock before a calibration (a cold start searches the
/// resonance over 280-620 Hz: about 1.2 s; a fault's back-off doubles up to 32 s).
pub const DRIVE_LOCK_TIMEOUT: Duration = Duration::from_secs(40);

/// Polls `status` until the dither drive reports `drive=locked`, at most `timeout` on the
/// link's clock; an error names the drive's state if it does not lock.
pub fn wait_for_drive_lock<L: Link>(
    client: &mut Client<L>,
    timeout: Duration,
    poll: Duration,
) -> Result<(), ClientError> {
    let start = client.elapsed();
    loop {
        let status = client.command("status")?;
        match status.field("drive") {
            Some("locked") => return Ok(()),
            // Firmware without a dither drive reports no `drive=` field: nothing to wait for.
            None => return Ok(()),
            Some(_) if client.elapsed() - start > timeout => {
                return Err(unexpected(&status, "the dither drive did not lock"));
            }
            Some(_) => client.pause(poll)?,
        }
    }
}

/// Waits for the dither drive to lock ([`wait_for_drive_lock`]: the board refuses `cal start`
/// before), starts a run, polls `cal status` until it is complete (reporting `(done, total)`
/// cycles), and returns `cal result` (an `ERR 12` if the fit is refused).
pub fn calibrate<L: Link>(
    client: &mut Client<L>,
    options: &CalibrateOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Answer, ClientError> {
    calibrate_until(client, options, progress, &NEVER)
}

/// [`calibrate`], stopped when `stop` is set: a run already started is abandoned on the board
/// (`cal abort`, so it does not go on calibrating for nobody), then
/// [`ClientError::Interrupted`].
pub fn calibrate_until<L: Link>(
    client: &mut Client<L>,
    options: &CalibrateOptions,
    progress: &mut dyn FnMut(u64, u64),
    stop: &AtomicBool,
) -> Result<Answer, ClientError> {
    let interrupted = || ClientError::Interrupted {
        what: "the calibration (the board was sent `cal abort`)".into(),
    };
    let total = options.cycles as u64 + options.warmup_cycles as u64;
    wait_for_drive_lock(client, DRIVE_LOCK_TIMEOUT, options.poll)?;
    if stop.load(Ordering::SeqCst) {
        return Err(ClientError::Interrupted {
            what: "before the calibration started".into(),
        });
    }
    client.command(&format!(
        "cal start {} {}",
        options.cycles, options.warmup_cycles
    ))?;
    let (mut last_done, mut last_change) = (u64::MAX, client.elapsed());
    loop {
        client.pause(options.poll)?;
        if stop.load(Ordering::SeqCst) {
            client.command("cal abort")?;
            return Err(interrupted());
        }
        let status = client.command("cal status")?;
        match status.field("cal") {
            Some("running") => {
                let left = status.parse_field::<u64>("warmup_left")?
                    + status.parse_field::<u64>("cycles_left")?;
                let done = total.saturating_sub(left);
                progress(done, total);
                if done != last_done {
                    (last_done, last_change) = (done, client.elapsed());
                } else if client.elapsed() - last_change > options.stall_timeout {
                    return Err(unexpected(
                        &status,
                        "the run makes no progress (signal lost?)",
                    ));
                }
            }
            Some("run_done") => {
                progress(total, total);
                break;
            }
            _ => return Err(unexpected(&status, "the run ended without completing")),
        }
    }
    client.command("cal result")
}

fn unexpected(answer: &Answer, what: &str) -> ClientError {
    ClientError::Unexpected {
        command: answer.command.clone(),
        answer: answer.text.clone(),
        what: what.to_owned(),
    }
}

/// Streams every `divider`-th cycle for `duration` on the link's clock, then stops the stream
/// (also after an error); `progress` gets the elapsed fraction.
pub fn stream<L: Link>(
    client: &mut Client<L>,
    divider: u16,
    duration: Duration,
    progress: &mut dyn FnMut(f64),
) -> Result<Capture, ClientError> {
    let mut each = |_: &StreamRecord| ControlFlow::Continue(());
    stream_until(client, divider, duration, progress, &mut each, &NEVER)
}

/// [`stream`], handing each valid record to `on_record` as it arrives, and ending early (as if
/// the time were up: the stream stopped, the frames in flight kept) when `stop` is set; the
/// caller tells an interrupted capture by the flag. `on_record` returning `Break` (its output
/// cannot be written) ends the stream too, and no record is handed to it after.
pub fn stream_until<L: Link>(
    client: &mut Client<L>,
    divider: u16,
    duration: Duration,
    progress: &mut dyn FnMut(f64),
    on_record: &mut dyn FnMut(&StreamRecord) -> ControlFlow<()>,
    stop: &AtomicBool,
) -> Result<Capture, ClientError> {
    let mut capture = Capture::new(divider);
    let on_chunk = &mut |chunk: &[u8], _received: Duration| match capture.push_chunk(chunk) {
        Some(record) => on_record(record),
        None => ControlFlow::Continue(()),
    };
    let command = format!("stream on {divider}");
    chunks_until(client, &command, duration, progress, on_chunk, stop)?;
    Ok(capture)
}

/// The board's fixed-rate output for `duration` (`stream output`): every chunk to `on_chunk`
/// as it arrives, with the link's clock then, ending early when `stop` is set or `on_chunk`
/// returns `Break`.
pub fn record_until<L: Link>(
    client: &mut Client<L>,
    duration: Duration,
    progress: &mut dyn FnMut(f64),
    on_chunk: &mut dyn FnMut(&[u8], Duration) -> ControlFlow<()>,
    stop: &AtomicBool,
) -> Result<(), ClientError> {
    chunks_until(client, "stream output", duration, progress, on_chunk, stop)
}

/// One binary stream (`command` switches it on) for `duration`, until `stop`, or until
/// `on_chunk` returns `Break`: every 0x00-delimited chunk to `on_chunk` as it arrives, with the
/// link's clock then; the stream is switched off and the frames in flight handed over (unless
/// `on_chunk` wants no more) before it returns.
fn chunks_until<L: Link>(
    client: &mut Client<L>,
    command: &str,
    duration: Duration,
    progress: &mut dyn FnMut(f64),
    on_chunk: &mut dyn FnMut(&[u8], Duration) -> ControlFlow<()>,
    stop: &AtomicBool,
) -> Result<(), ClientError> {
    client.command(command)?;
    let start = client.elapsed();
    let mut wanted = true;
    // Hands the frames received to `on_chunk` while it wants them; false once it does not.
    let mut hand_over = |client: &mut Client<L>| {
        let received = client.elapsed();
        for chunk in client.take_frames() {
            wanted = wanted && on_chunk(&chunk, received).is_continue();
        }
        wanted
    };
    let result = (|| -> Result<(), ClientError> {
        loop {
            let elapsed = client.elapsed().saturating_sub(start);
            if elapsed >= duration || stop.load(Ordering::SeqCst) {
                return Ok(());
            }
            progress(elapsed.as_secs_f64() / duration.as_secs_f64());
            client.poll((duration - elapsed).min(Duration::from_millis(100)))?;
            if !hand_over(client) {
                return Ok(());
            }
        }
    })();
    let stopped = client.command("stream off");
    hand_over(client);
    result?;
    stopped?;
    Ok(())
}
