//! The serial protocol end to end on the simulated board: the firmware's parser, executor,
//! calibration session and flash store, driven by text lines as a technician or the host tool
//! would send them. Seeded; every exchange is one line in, exactly one line out.

mod device_support;

use device_support::{boot_with_key, exchange, field, KEY};
use firmware::protocol::parse::crc16;
use firmware::protocol::stream::{decode_frame, GapCounter};
use hal_sim::device::{SimDevice, SIM_IDENTITY};
use hal_sim::flash::{CalibrationFlash, PowerCut};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;

/// Powers the simulated board up and waits, as a technician does, until `status` shows the
/// dither drive locked (the board's start-up from the ringing dither takes about 1.1 s; 3 s at
/// most here), then half a second for the locked loop to settle.
fn boot(flash: CalibrationFlash, rate_deg_h: f64, boot_count: u32) -> SimDevice {
    let params = GyroParams {
        seed: 31 + boot_count as u64,
        ..GyroParams::default()
    };
    let mut dev = boot_with_key(params, rate_deg_h, flash, boot_count);
    while field(&ask(&mut dev, "status"), "drive") != "locked" {
        assert!(dev.time_s() < 3.0, "the drive did not lock");
        dev.run_for(0.1);
    }
    dev.run_for(0.5);
    dev
}

/// Sends one line as a person at a terminal does (no CRC), returns the answer line (without
/// `\r\n`); asserts exactly one answer. A state-changing command is echoed for confirmation
/// (`ERR 18 ... cmd=`): the echo is checked and `yes` sent, and its answer returned.
fn ask(dev: &mut SimDevice, line: &str) -> String {
    let answer = ask_once(dev, line);
    match answer.strip_prefix("ERR 18 confirm (send yes) cmd=") {
        Some(echo) => {
            let parsed = firmware::protocol::parse::parse(line).unwrap();
            assert_eq!(firmware::protocol::parse::parse(echo), Ok(parsed), "{line}");
            ask_once(dev, "yes")
        }
        None => answer,
    }
}

/// One line, its one answer line (waiting up to 3 simulated seconds for it: a `store` answers
/// when its flash stall is over).
fn ask_once(dev: &mut SimDevice, line: &str) -> String {
    let out = exchange(dev, format!("{line}\n").as_bytes());
    let lines: Vec<&str> = out.split_terminator("\r\n").collect();
    assert_eq!(lines.len(), 1, "one answer to {line:?}: {out:?}");
    lines[0].to_string()
}

/// A simulated board booted without a key is a new board: no key unlocks it (the old
/// published development key included), `status` says `key=unprovisioned`; `key provision`
/// sets the key once, after which it unlocks and a second provisioning is refused.
#[test]
fn an_unprovisioned_board_accepts_no_key_until_provisioned_once() {
    let params = GyroParams {
        seed: 5,
        ..GyroParams::default()
    };
    let input = InputProfile::constant(0.0);
    let flash = CalibrationFlash::default();
    let mut dev = SimDevice::boot(params, input, SIM_IDENTITY, flash, 0).unwrap();
    assert!(ask(&mut dev, "status").ends_with(" key=unprovisioned"));
    assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("ERR 16 no key provisioned"));
    assert!(ask(&mut dev, "unlock c0ffee42").starts_with("ERR 3 "));
    assert!(ask(&mut dev, "set a 300").starts_with("ERR 9 "));
    assert_eq!(
        ask(&mut dev, &format!("key provision {KEY}")),
        "OK key=provisioned"
    );
    assert!(ask(&mut dev, "status").ends_with(" key=provisioned"));
    assert!(
        ask(&mut dev, "set a 300").starts_with("ERR 9 "),
        "still locked"
    );
    let other = KEY.replace('a', "b");
    assert!(ask(&mut dev, &format!("key provision {other}")).starts_with("ERR 11 "));
    assert!(ask(&mut dev, &format!("unlock {other}")).starts_with("ERR 15 "));
    assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    assert_eq!(ask(&mut dev, "set a 300"), "OK a=300");
}

#[test]
fn a_fresh_board_identifies_itself_and_runs_on_defaults() {
    let mut dev = boot(CalibrationFlash::default(), 10.0, 0);
    dev.run_for(0.5);
    let id = ask(&mut dev, "id");
    assert!(
        id.starts_with("OK fw=") && id.contains("serial=4242"),
        "{id}"
    );
    let status = ask(&mut dev, "status");
    assert_eq!(field(&status, "coeffs"), "defaults:erased");
    assert_eq!(field(&status, "comp"), "off");
    assert_eq!(field(&status, "locked"), "yes");
    assert_eq!(field(&status, "signal"), "ok");
    // The measured dither: 389 Hz (f32 status field, 0.1 %), 450 arcsec: the drive locks
    // within 0.2 % of its setpoint and its locked loop settles the rest over about a second,
    // so 0.25 % (1.1 arcsec) half a second after the lock.
    assert_eq!(field(&status, "drive"), "locked");
    assert!(
        (field(&status, "dither_hz").parse::<f64>().unwrap() - 389.0).abs() < 0.4,
        "{status}"
    );
    assert!(
        (field(&status, "dither_amp_arcsec").parse::<f64>().unwrap() - 450.0).abs() < 1.1,
        "{status}"
    );
    // The drive's own view, and the fringe count's independent check of the pick-off's gain:
    // the pick-off is nominal here, so its amplitude and the count's agree (to 0.3 %: one
    // half cycle's fit against the count's last excursion).
    let dither = ask(&mut dev, "dither status");
    assert!(dither.starts_with("OK state=locked "), "{dither}");
    let gain: f64 = field(&dither, "pickoff_gain").parse().unwrap();
    assert!((gain - 1.0).abs() < 0.003, "{dither}");
    assert_eq!(ask(&mut dev, "get coeffs").split(' ').nth(1), Some("a=0"));
    assert!(ask(&mut dev, "help").starts_with("OK commands:"));
}

/// The technician's workflow: unlock, calibrate outside the dead band, check the fit, accept,
/// store; after a power cycle the board comes up with the stored coefficients.
#[test]
fn calibrate_accept_store_and_survive_a_power_cycle() {
    let mut dev = boot(CalibrationFlash::default(), 13.888, 0);
    dev.run_for(0.6);
    assert!(
        ask(&mut dev, "set a 300").starts_with("ERR 9 "),
        "locked at reset"
    );
    assert!(
        ask(&mut dev, "unlock 1234").starts_with("ERR 3 "),
        "no 128-bit key"
    );
    assert!(ask(&mut dev, &format!("unlock {}", KEY.replace('3', "4"))).starts_with("ERR 15 "));
    assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    assert!(ask(&mut dev, "cal start 3000 100").starts_with("OK cal=running"));
    assert!(
        ask(&mut dev, "set a 300").starts_with("ERR 10 "),
        "busy during a run"
    );
    assert!(ask(&mut dev, "cal result").starts_with("ERR 10 "));
    dev.run_for(8.5);
    assert!(ask(&mut dev, "cal status").starts_with("OK cal=run_done"));
    let result = ask(&mut dev, "cal result");
    assert!(result.starts_with("OK a="), "{result}");
    // Omega_L within 1 % of the simulator's truth (200 deg/h); eps (0.3 rad) within three of
    // its standard errors, which the fit's a_std and b_std give: at 3000 cycles that is about
    // 0.003 rad, 1 % of eps, so a 1 % bound would fail one seed in three.
    let lock_in: f64 = field(&result, "lock_in_deg_h").parse().unwrap();
    let eps: f64 = field(&result, "eps_rad").parse().unwrap();
    let num = |k: &str| field(&result, k).parse::<f64>().unwrap();
    let (a, b, a_std, b_std) = (num("a"), num("b"), num("a_std"), num("b_std"));
    let eps_std = (a * b_std).hypot(b * a_std) / (a * a + b * b);
    assert!((lock_in / 200.0 - 1.0).abs() < 0.01, "{result}");
    assert!(
        (eps - 0.3).abs() < 3.0 * eps_std,
        "{result}: eps std {eps_std}"
    );
    let accepted = ask(&mut dev, "cal accept");
    assert!(
        accepted.starts_with("OK a=") && accepted.ends_with("comp=on"),
        "{accepted}"
    );
    assert_eq!(field(&ask(&mut dev, "status"), "coeffs"), "unsaved");
    let stored = ask(&mut dev, "store");
    assert!(stored.starts_with("OK stored seq=1"), "{stored}");
    let coeffs = ask(&mut dev, "get coeffs");

    let mut dev = boot(dev.power_off(), 13.888, 1);
    dev.run_for(0.2);
    assert_eq!(
        ask(&mut dev, "get coeffs"),
        coeffs,
        "the stored coefficients come back"
    );
    let status = ask(&mut dev, "status");
    assert_eq!(field(&status, "coeffs"), "flash:1");
    assert_eq!(field(&status, "comp"), "on");
    assert_eq!(field(&status, "locked"), "yes", "locked again after reset");
}

/// Bad input of every kind gets its own ERR, changes nothing, and the next good line works.
#[test]
fn bad_input_is_answered_and_changes_nothing() {
    let mut dev = boot(CalibrationFlash::default(), 5.0, 0);
    dev.run_for(0.2);
    ask(&mut dev, &format!("unlock {KEY}"));
    let before = ask(&mut dev, "get coeffs");
    let cases: [(&[u8], &str); 9] = [
        (b"frobnicate", "ERR 1 "),
        (b"set a", "ERR 2 "),
        (b"set a twelve", "ERR 3 "),
        (b"set a NaN", "ERR 4 "),
        (b"set b -inf", "ERR 4 "),
        (b"set a 1e9", "ERR 5 "),
        (b"get a*0000", "ERR 6 "),
        (&[b'x'; 300], "ERR 7 "),
        (b"set a \x00\xff\x13", "ERR 8 "),
    ];
    for (line, want) in cases {
        dev.receive(line);
        dev.receive(b"\r\n");
        let out = String::from_utf8(dev.take_output()).unwrap();
        assert!(
            out.starts_with(want) && out.matches("\r\n").count() == 1,
            "{line:?}: {out:?}"
        );
    }
    // A partial line is not answered until it ends.
    dev.receive(b"get ");
    assert!(dev.take_output().is_empty());
    dev.receive(b"coeffs\n");
    assert_eq!(
        String::from_utf8(dev.take_output()).unwrap().trim_end(),
        before
    );
    // Random line noise: one answer per non-empty line at most, never a panic.
    let mut x = 0x1234_5678_9ABC_DEF0u64;
    let noise: Vec<u8> = (0..20_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if x.is_multiple_of(40) {
                b'\n'
            } else {
                (x >> 32) as u8
            }
        })
        .collect();
    dev.receive(&noise);
    dev.receive(b"\n");
    let _ = dev.take_output();
    assert_eq!(ask(&mut dev, "get coeffs"), before);
}

/// A request with a CRC suffix gets an answer with one, over the answer's text.
#[test]
fn checksummed_requests_get_checksummed_answers() {
    let mut dev = boot(CalibrationFlash::default(), 5.0, 0);
    let answer = ask(&mut dev, &format!("get a*{:04X}", crc16(b"get a")));
    let (body, crc) = answer.rsplit_once('*').expect("crc suffix");
    assert_eq!(
        u16::from_str_radix(crc, 16).unwrap(),
        crc16(body.as_bytes())
    );
    assert_eq!(body, "OK a=0");
}

/// Streaming: one frame per cycle at divider 1, sequence numbers without gaps, P1/P2 present;
/// the answer that starts the stream and a text command's answer while streaming are both
/// between 0x00 delimiters (one rule: a host splits at 0x00 from the first byte after its
/// `stream` command).
#[test]
fn streaming_frames_are_complete_and_numbered() {
    let mut dev = boot(CalibrationFlash::default(), 5.0, 0);
    dev.run_for(0.6);
    dev.receive(b"stream on 1\n");
    let start = String::from_utf8(dev.take_output()).unwrap();
    assert!(
        start.starts_with("\0OK stream=on") && start.ends_with("\r\n\0"),
        "{start:?}"
    );
    dev.run_for(1.0);
    dev.receive(b"status\n");
    let bytes = dev.take_output();
    let (mut gaps, mut frames, mut texts) = (GapCounter::default(), 0, 0);
    for chunk in bytes.split(|&b| b == 0).filter(|c| !c.is_empty()) {
        match decode_frame(chunk) {
            Ok(frame) => {
                gaps.observe(frame.sequence);
                frames += 1;
                assert!(frame.p1_s.abs() < 1e-4 && frame.duration_ticks > 200_000);
            }
            Err(_) => {
                assert!(
                    chunk.starts_with(b"OK signal="),
                    "{:?}",
                    String::from_utf8_lossy(chunk)
                );
                texts += 1;
            }
        }
    }
    assert!(
        (385..=392).contains(&frames),
        "{frames} frames in 1 s at 389 Hz"
    );
    assert_eq!((gaps.lost, texts), (0, 1));
}

/// A power cut in the middle of a store: the command fails, and after the reboot the board
/// has either the previous calibration or the new one, never garbage.
#[test]
fn a_power_cut_during_store_keeps_a_valid_calibration() {
    let mut dev = boot(CalibrationFlash::default(), 5.0, 0);
    ask(&mut dev, &format!("unlock {KEY}"));
    ask(&mut dev, "set a 100");
    assert!(ask(&mut dev, "store").starts_with("OK stored seq=1"));
    ask(&mut dev, "set a 222");
    dev.flash_mut().arm_power_cut(PowerCut::AfterBytes(30));
    assert!(ask(&mut dev, "store").starts_with("ERR 13 "));
    let mut dev = boot(dev.power_off(), 5.0, 1);
    let a: f64 = field(&ask(&mut dev, "get a"), "a").parse().unwrap();
    assert_eq!(a, 100.0, "the torn record is ignored");
    assert_eq!(field(&ask(&mut dev, "status"), "coeffs"), "flash:1");
}

/// `track on` (protected) lets the firmware learn a and b by itself outside the dead band: a
/// fresh board (a = b = 0, compensation off) converges to the simulator's truth within 1 % and
/// turns the compensation on; `status` reports it and the source becomes "unsaved".
#[test]
fn tracking_learns_the_coefficients_from_scratch() {
    let mut dev = boot(CalibrationFlash::default(), 13.888, 0);
    dev.run_for(0.6);
    assert!(ask(&mut dev, "track on").starts_with("ERR 9 "));
    ask(&mut dev, &format!("unlock {KEY}"));
    assert!(ask(&mut dev, "track on").starts_with("OK track=on"));
    dev.run_for(20.0);
    let coeffs = ask(&mut dev, "get coeffs");
    let lock_in: f64 = field(&coeffs, "lock_in_deg_h").parse().unwrap();
    let eps: f64 = field(&coeffs, "eps_rad").parse().unwrap();
    assert!((lock_in / 200.0 - 1.0).abs() < 0.01, "{coeffs}");
    assert!((eps - 0.3).abs() < 0.01, "{coeffs}");
    let status = ask(&mut dev, "status");
    assert_eq!(
        (field(&status, "track"), field(&status, "comp")),
        ("on", "on")
    );
    assert_eq!(field(&status, "coeffs"), "unsaved");
    assert!(ask(&mut dev, "track off").starts_with("OK track=off"));
}

/// Every command that changes coefficients, compensation or flash is refused while locked,
/// and changes nothing; every read works.
#[test]
fn every_protected_command_needs_the_unlock() {
    let mut dev = boot(CalibrationFlash::default(), 5.0, 0);
    let before = ask(&mut dev, "get coeffs");
    for cmd in [
        "set a 1",
        "set b 1",
        "comp on",
        "comp off",
        "track on",
        "cal accept",
        "store",
        "reload",
        "defaults",
        "dither off",
        "dither on",
        "dither amp 400",
        "dither noise 10",
    ] {
        assert!(
            ask(&mut dev, cmd).starts_with("ERR 9 "),
            "{cmd} while locked"
        );
    }
    for cmd in [
        "id",
        "status",
        "get a",
        "get coeffs",
        "cal status",
        "help",
        "stream off",
        "dither status",
    ] {
        assert!(
            ask(&mut dev, cmd).starts_with("OK"),
            "{cmd} needs no unlock"
        );
    }
    assert_eq!(ask(&mut dev, "get coeffs"), before);
    assert_eq!(field(&ask(&mut dev, "status"), "coeffs"), "defaults:erased");
}

/// The rotation during an erasing `store`'s pause of the readout is not lost: the encoder
/// counts on, and the first cycle after the pause carries the whole angle since the last cycle
/// before it (flagged `TURNAROUND_MISSED`). So the streamed increments add up to the total
/// phase the board reports (exactly: both are the same Q32 count), and the durations to the
/// time elapsed (to one capture-timer tick per frame). (Sector 0 is filled with damage, so the
/// store erases sector 1 first; a store without an erase does not pause the readout:
/// `store_stall.rs`.)
#[test]
fn the_angle_turned_during_a_store_stall_is_carried_into_the_stream() {
    use embedded_storage::nor_flash::NorFlash;
    let mut flash = CalibrationFlash::default();
    flash.write(0, &vec![0u8; 128 * 1024]).unwrap();
    let mut dev = boot(flash, 13.888, 0);
    assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    dev.receive(b"stream on 1\n");
    dev.run_for(0.5);
    dev.receive(format!("store*{:04X}\n", crc16(b"store")).as_bytes());
    dev.run_for(2.5);
    let bytes = dev.take_output();
    let frames: Vec<_> = bytes
        .split(|&b| b == 0)
        .filter_map(|c| decode_frame(c).ok())
        .collect();
    assert!(frames.len() > 700, "{} frames", frames.len());
    let bridged = frames.iter().filter(|f| f.flags & 4 != 0).count();
    assert!(bridged >= 1, "the cycle across the stall is flagged");
    let summed: i64 = frames[1..].iter().map(|f| f.raw_increment_q32).sum();
    let spanned = frames.last().unwrap().end_phase_q32 - frames[0].end_phase_q32;
    let lost_fringes = (spanned - summed) as f64 / firmware::units::Q32_PER_FRINGE;
    assert!(
        lost_fringes.abs() < 1e-6,
        "{lost_fringes:.3} fringes turned during the stall are missing from the stream"
    );
}

/// A store that erases stalls the board for the erase (1 s typical in the flash model): its
/// answer comes when the stall is over, not at once, and a command sent meanwhile is answered
/// after it. (Sector 0 is filled with damage, so the store erases sector 1 first.)
#[test]
fn a_store_answers_after_its_stall() {
    use embedded_storage::nor_flash::NorFlash;
    let mut flash = CalibrationFlash::default();
    flash.write(0, &vec![0u8; 128 * 1024]).unwrap();
    let mut dev = boot(flash, 5.0, 0);
    assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    let busy_before_s = dev.flash_mut().stats().busy_s;
    let sent_s = dev.time_s();
    dev.receive(format!("store*{:04X}\n", crc16(b"store")).as_bytes());
    dev.receive(b"id\n");
    assert!(dev.take_output().is_empty(), "no answer during the stall");
    let mut out = Vec::new();
    while !out.ends_with(b"\r\n") || out.split(|&b| b == b'\n').count() < 3 {
        assert!(
            dev.time_s() - sent_s < 3.0,
            "no answers within 3 s: {out:?}"
        );
        dev.run_for(0.001);
        out.extend(dev.take_output());
    }
    let answered_s = dev.time_s() - sent_s;
    let stall_s = dev.flash_mut().stats().busy_s - busy_before_s;
    assert!(stall_s >= 0.9, "the store erased: {stall_s} s");
    assert!(
        (answered_s - stall_s).abs() < 0.01,
        "answered after {answered_s:.3} s, stall {stall_s:.3} s"
    );
    let text = String::from_utf8(out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("OK stored seq=1"), "{text}");
    assert!(
        lines[1].starts_with("OK fw="),
        "then the command sent meanwhile: {text}"
    );
}

/// `thermal` on the simulated board: the sensor's temperature (the profile's 25 °C plus the
/// simulated part's +0.02 °C offset, within its noise), its rate once the window is full, no
/// model; a NACK shows as `sensor=nack` within 0.15 s, and the temperature is gone.
#[test]
fn thermal_reports_the_sensor_and_its_faults() {
    let mut dev = boot(CalibrationFlash::default(), 13.888, 0);
    dev.run_for(3.0);
    let answer = ask(&mut dev, "thermal");
    eprintln!("{answer}");
    assert!(answer.starts_with("OK temp_c="), "{answer}");
    let temp: f64 = field(&answer, "temp_c").parse().unwrap();
    assert!((temp - 25.02).abs() < 0.04, "{answer}");
    let rate: f64 = field(&answer, "rate_c_min").parse().unwrap();
    assert!(rate.abs() < 2.0, "{answer}");
    assert_eq!(field(&answer, "sensor"), "ok", "{answer}");
    assert_eq!(field(&answer, "model"), "none", "{answer}");
    dev.sensor_mut()
        .set_fault(Some(hal_sim::tmp117::SensorFault::Nack));
    dev.run_for(0.15);
    let answer = ask(&mut dev, "thermal");
    assert_eq!(field(&answer, "sensor"), "nack", "{answer}");
    assert_eq!(field(&answer, "temp_c"), "none", "{answer}");
    assert_eq!(field(&answer, "sensor_faults"), "1", "{answer}");
}
