//! The reads: `help`, `id`, `status`, `get`. They change nothing and never need an unlock.
//!
//! `status` also reports what other groups hold (tracking on, where the coefficients came
//! from, locked or not); the executor passes those in as a [`StatusFlags`] value, so this
//! module depends on no other group's state.

use super::ok_with;
use super::provenance::{Source, SourceText};
use crate::board_timing::monitor::{Event, TimingFaults};
use crate::board_timing::selftest::{Check, Outcome, SelfTestReport, QEMU_UNMODELLED};
use crate::protocol::link::{DeviceLink, Identity};
use crate::protocol::parse::Coefficient;
use crate::protocol::respond::Response;
use crate::signal::compensation::Coefficients;

const HELP: &str =
    "commands: id status selftest output{status} get{a|b|coeffs} set{a|b}<rad/s> comp{on|off} track{on|off} \
cal{start<n>[<warmup>]|status|abort|result|accept} store reload defaults stream{on[<n>]|output|off} \
dither{on|off|amp<arcsec>|noise<percent>|status} thermal[model|set<name><value>|apply|on|off] \
unlock<key> lock key{provision<key>} help";

/// What `status` reports of the executor's own state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatusFlags {
    /// Online tracking of a and b runs (`track=on`).
    pub tracking: bool,
    /// Where the coefficients in force came from (`coeffs=`).
    pub source: Source,
    /// Protected commands are allowed now (`locked=no`).
    pub unlocked: bool,
    /// The board has a key (`key=provisioned`; else `key=unprovisioned`).
    pub key_provisioned: bool,
}

/// `help`.
pub fn help() -> Response {
    ok_with(format_args!("{HELP}"))
}

/// `id`.
pub fn identify(id: &Identity) -> Response {
    ok_with(format_args!(
        "fw={} build={} board={} serial={} sf_arcsec={} timer_hz={}",
        id.firmware_version,
        id.build,
        id.board,
        id.serial_number,
        id.scale_factor_arcsec,
        id.capture_timer_hz
    ))
}

/// `status`.
pub fn status<D: DeviceLink>(id: &Identity, device: &mut D, flags: StatusFlags) -> Response {
    let s = device.status();
    let settings = device.active_settings();
    let amplitude_arcsec = s.dither_amplitude_rad * id.scale_factor_arcsec / core::f32::consts::TAU;
    let drive = super::dither::state_word(device.dither_status().state);
    ok_with(format_args!(
        "signal={} drive={} board={} dither_hz={:.3} dither_amp_arcsec={:.2} rate_deg_h={:.4} turnarounds={} \
cycles={} counter_glitches={} phase_glitches={} signal_lost={} missed={} dropped={} comp={} track={} \
coeffs={} locked={} key={}",
        if s.signal_ok { "ok" } else { "lost" },
        drive,
        device.board_health().word(),
        s.dither_hz,
        amplitude_arcsec,
        s.rate_deg_per_h,
        s.turnarounds,
        s.cycles,
        s.counter_glitches,
        s.phase_glitches,
        s.signal_lost,
        s.missed_turnarounds,
        s.cycles_dropped,
        if settings.enabled { "on" } else { "off" },
        if flags.tracking { "on" } else { "off" },
        SourceText(flags.source),
        if flags.unlocked { "no" } else { "yes" },
        if flags.key_provisioned {
            "provisioned"
        } else {
            "unprovisioned"
        },
    ))
}

/// `output status`: the fixed-rate output's dither stripping (`strip=converged|learning`, the
/// taps on the modelled dither in phase and in quadrature in fringes per pick-off code, the
/// fit's relative standard deviation in ppm: in decimal, so the image carries no exponential
/// float formatting) and the records made since boot (the next record's sequence number).
pub fn output_status<D: DeviceLink>(device: &mut D) -> Response {
    let s = device.status();
    ok_with(format_args!(
        "strip={} strip_k={:.7} strip_k_quad={:.7} strip_k_std_ppm={:.2} records={}",
        if s.strip.converged {
            "converged"
        } else {
            "learning"
        },
        s.strip.k,
        s.strip.k_quadrature,
        s.strip.k_std_rel * 1e6,
        s.output_records,
    ))
}

/// `selftest`: each power-up check (`pass`, `fail:<what>`, `running`, `not_run`), the timing
/// faults raised now (`watch=ok` or their names), the drive's state, and on the emulator the
/// checks it cannot pass (`unmodelled=`).
pub fn selftest<D: DeviceLink>(device: &mut D) -> Response {
    let health = device.board_health();
    let drive = super::dither::state_word(device.dither_status().state);
    ok_with(format_args!(
        "{} watch={} drive={}{}",
        Checks(&health.selftest),
        Watch(health.timing),
        drive,
        Unmodelled(health.emulated),
    ))
}

/// `clock=pass timers=pass ...`.
struct Checks<'a>(&'a SelfTestReport);

impl core::fmt::Display for Checks<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, check) in Check::ALL.into_iter().enumerate() {
            let sep = if i == 0 { "" } else { " " };
            match self.0.outcome(check) {
                Outcome::Pass => write!(f, "{sep}{}=pass", check.word())?,
                Outcome::Fail(why) => write!(f, "{sep}{}=fail:{why}", check.word())?,
                Outcome::Running => write!(f, "{sep}{}=running", check.word())?,
                Outcome::NotRun => write!(f, "{sep}{}=not_run", check.word())?,
            }
        }
        Ok(())
    }
}

/// `ok`, or the raised timing faults' names separated by commas.
struct Watch(TimingFaults);

impl core::fmt::Display for Watch {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.0.is_empty() {
            return f.write_str("ok");
        }
        let mut sep = "";
        for event in Event::ALL {
            if self.0.contains(TimingFaults::of(event)) {
                write!(f, "{sep}{}", event.word())?;
                sep = ",";
            }
        }
        if self.0.contains(TimingFaults::CLOCK_LOST) {
            write!(f, "{sep}clock_lost")?;
        }
        Ok(())
    }
}

/// ` unmodelled=clock,...` on the emulator, nothing on a board.
struct Unmodelled(bool);

impl core::fmt::Display for Unmodelled {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if !self.0 {
            return Ok(());
        }
        f.write_str(" unmodelled=")?;
        for (i, check) in QEMU_UNMODELLED.into_iter().enumerate() {
            let sep = if i == 0 { "" } else { "," };
            write!(f, "{sep}{}", check.word())?;
        }
        Ok(())
    }
}

/// `get a`, `get b`, `get coeffs` (`None`).
pub fn get<D: DeviceLink>(id: &Identity, device: &mut D, which: Option<Coefficient>) -> Response {
    let c = device.active_settings().coefficients;
    match which {
        Some(Coefficient::A) => ok_with(format_args!("a={}", c.a_rad_per_s())),
        Some(Coefficient::B) => ok_with(format_args!("b={}", c.b_rad_per_s())),
        None => ok_with(format_args!(
            "a={} b={} lock_in_deg_h={} eps_rad={}",
            c.a_rad_per_s(),
            c.b_rad_per_s(),
            lock_in_deg_h(&c, id),
            eps_rad(&c)
        )),
    }
}

/// Lock-in rate hypot(a, b) in deg/h.
fn lock_in_deg_h(c: &Coefficients, id: &Identity) -> f32 {
    let (a, b) = (c.a_rad_per_s(), c.b_rad_per_s());
    libm::hypotf(a, b) * id.scale_factor_arcsec / core::f32::consts::TAU
}

/// The backscatter phase asymmetry: atan2(b, a) - pi/4, rad.
fn eps_rad(c: &Coefficients) -> f32 {
    libm::atan2f(c.b_rad_per_s(), c.a_rad_per_s()) - core::f32::consts::FRAC_PI_4
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::{text, MemDevice, ID};
    use crate::protocol::link::DeviceStatus;

    #[test]
    fn help_lists_every_command_word() {
        let line = text(help());
        for word in [
            "id", "status", "get", "set", "comp", "track", "cal", "store", "reload",
        ] {
            assert!(line.contains(word), "{word} missing from {line}");
        }
        assert!(line.starts_with("OK commands: "));
    }

    #[test]
    fn id_reports_the_identity() {
        assert_eq!(
            text(identify(&ID)).trim_end(),
            "OK fw=1.2.3 build=test board=sim serial=4242 sf_arcsec=2 timer_hz=84000000"
        );
    }

    #[test]
    fn status_reports_the_snapshot_and_the_flags() {
        let mut device = MemDevice {
            status: DeviceStatus {
                signal_ok: true,
                dither_hz: 389.0,
                dither_amplitude_rad: core::f32::consts::TAU * 100.0,
                turnarounds: 10,
                cycles: 5,
                counter_glitches: 1,
                phase_glitches: 2,
                signal_lost: 3,
                missed_turnarounds: 4,
                rate_deg_per_h: 15.0,
                cycles_dropped: 6,
                strip: crate::signal::output::strip::StripStatus {
                    k: 0.2144199,
                    k_quadrature: -0.0001234,
                    k_std_rel: 2.1e-5,
                    updates: 9000,
                    converged: true,
                },
                output_records: 12345,
            },
            ..MemDevice::default()
        };
        let flags = StatusFlags {
            tracking: true,
            source: Source::Flash { sequence: 3 },
            unlocked: false,
            key_provisioned: false,
        };
        assert_eq!(
            text(status(&ID, &mut device, flags)).trim_end(),
            "OK signal=ok drive=locked board=untested dither_hz=389.000 dither_amp_arcsec=200.00 rate_deg_h=15.0000 \
turnarounds=10 cycles=5 counter_glitches=1 phase_glitches=2 signal_lost=3 missed=4 dropped=6 \
comp=off track=on coeffs=flash:3 locked=yes key=unprovisioned"
        );
        assert_eq!(
            text(output_status(&mut device)).trim_end(),
            "OK strip=converged strip_k=0.2144199 strip_k_quad=-0.0001234 strip_k_std_ppm=21.00 \
records=12345"
        );
    }

    /// `status` and `output status` at their longest (every counter at its maximum, the longest
    /// word of each field, a rate of 1000 deg/s, the longest source) fit the answer buffer with
    /// the CRC suffix: never cut. Measured: printed.
    #[test]
    fn status_at_its_longest_fits_the_answer_buffer() {
        use crate::protocol::respond::MAX_RESPONSE;
        use crate::storage::DefaultsReason;
        let mut device = MemDevice {
            status: DeviceStatus {
                signal_ok: false,
                dither_hz: -9999.999,
                dither_amplitude_rad: -core::f32::consts::TAU * 9999.0,
                turnarounds: u32::MAX,
                cycles: u32::MAX,
                counter_glitches: u32::MAX,
                phase_glitches: u32::MAX,
                signal_lost: u32::MAX,
                missed_turnarounds: u32::MAX,
                rate_deg_per_h: -3.6e6,
                cycles_dropped: u32::MAX,
                strip: crate::signal::output::strip::StripStatus {
                    k: -1234.5678,
                    k_quadrature: -1234.5678,
                    k_std_rel: -f32::MAX / 1e6, // the most digits in ppm
                    updates: u32::MAX,
                    converged: false,
                },
                output_records: u64::MAX,
            },
            ..MemDevice::default()
        };
        device.drive.controller.inhibit();
        device.health.timing = TimingFaults::of(Event::OutputLatch);
        let flags = StatusFlags {
            tracking: false,
            source: Source::Defaults(DefaultsReason::OtherGyro {
                stored_serial: u32::MAX,
            }),
            unlocked: false,
            key_provisioned: false,
        };
        for (name, answer) in [
            ("status", status(&ID, &mut device, flags)),
            ("output status", output_status(&mut device)),
        ] {
            let line = answer.finish(true);
            println!(
                "{name} at its longest: {} bytes of {MAX_RESPONSE}",
                line.len()
            );
            assert!(!line.contains('~'), "{name} was cut: {line}");
            assert!(
                line.len() <= MAX_RESPONSE - 8,
                "{name}: {} bytes",
                line.len()
            );
        }
    }

    /// `selftest` without a board: every check not run; with a board's report, each check's
    /// outcome, the raised timing faults, and on the emulator what it cannot pass.
    #[test]
    fn selftest_reports_each_check() {
        let mut device = MemDevice::default();
        assert_eq!(
            text(selftest(&mut device)).trim_end(),
            "OK clock=not_run timers=not_run timer_clock=not_run triggers=not_run \
pickoff=not_run watch=ok drive=locked"
        );
        let mut report = SelfTestReport([Outcome::Pass; 5]);
        report.set(Check::Clock, Outcome::Fail("hse"));
        report.set(Check::Pickoff, Outcome::NotRun);
        device.health = crate::board_timing::health::BoardHealth {
            selftest: report,
            timing: TimingFaults(TimingFaults::of(Event::DriveTick).0 | TimingFaults::CLOCK_LOST.0),
            emulated: true,
        };
        assert_eq!(
            text(selftest(&mut device)).trim_end(),
            "OK clock=fail:hse timers=pass timer_clock=pass triggers=pass pickoff=not_run \
watch=drive_tick,clock_lost drive=locked unmodelled=clock,timer_clock,triggers,pickoff"
        );
    }

    #[test]
    fn get_reads_the_coefficients_in_force() {
        let mut device = MemDevice::default();
        device.settings.coefficients = Coefficients::from_rad_per_s(0.5, 0.5).unwrap();
        assert_eq!(
            text(get(&ID, &mut device, Some(Coefficient::A))).trim_end(),
            "OK a=0.5"
        );
        assert_eq!(
            text(get(&ID, &mut device, Some(Coefficient::B))).trim_end(),
            "OK b=0.5"
        );
        let all = text(get(&ID, &mut device, None));
        assert!(all.starts_with("OK a=0.5 b=0.5 lock_in_deg_h="), "{all}");
        // a = b: the asymmetry is zero.
        assert!(all.trim_end().ends_with("eps_rad=0"), "{all}");
    }
}
