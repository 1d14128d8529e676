//! docs/protocol.md is the contract an integrator writes a client from: its tables are checked
//! here against the firmware, so the two cannot drift apart.
//!
//! - "Limits": every row's value against the firmware constant it names;
//! - "Commands": every form parses, its "protected" and "CRC or `yes`" columns are the
//!   executor's rules, and every command the board's `help` lists has a row;
//! - "The answers' fields": each command's live answer on the simulated board has exactly the
//!   fields listed, in order; so do the `OK` answers of the examples;
//! - "Error codes": code and text of every `ErrorCode`, in order;
//! - the frame layouts: the firmware's own frames decoded by the tables' offsets and types give
//!   the fields back, and the sizes are the tables' sums; the flag tables are the firmware's
//!   named bits;
//! - the `help` example is the board's answer.

mod device_support;

use device_support::{boot_with_key, exchange, field, KEY};
use firmware::protocol::confirm::needs_confirmation;
use firmware::protocol::execute::{unlock_rule, UnlockRule};
use firmware::protocol::parse::{crc16, parse};
use firmware::protocol::ErrorCode;
use firmware::signal::lockin::CycleFlags;
use firmware::signal::output::record::{OutputRecord, OutputStatus};
use hal_sim::device::SimDevice;
use hal_sim::flash::CalibrationFlash;
use hal_sim::params::GyroParams;

fn doc() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md"))
        .expect("docs/protocol.md")
}

/// The text from the heading `heading` (a whole line) to the next heading of its level or
/// above.
fn section<'a>(doc: &'a str, heading: &str) -> &'a str {
    let start = doc
        .find(&format!("\n{heading}\n"))
        .unwrap_or_else(|| panic!("no heading {heading:?}"))
        + 1;
    let level = heading.chars().take_while(|&c| c == '#').count();
    let rest = &doc[start + heading.len()..];
    let end = rest
        .match_indices("\n#")
        .find(|(i, _)| {
            let hashes = rest[i + 1..].chars().take_while(|&c| c == '#').count();
            hashes <= level && rest[i + 1 + hashes..].starts_with(' ')
        })
        .map_or(rest.len(), |(i, _)| i);
    &doc[start..start + heading.len() + end]
}

/// A table's cells (`\|` is a literal bar inside a cell).
fn cells(line: &str) -> Vec<String> {
    let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
    let mut out = vec![String::new()];
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                chars.next();
                out.last_mut().unwrap().push('|');
            }
            '|' => out.push(String::new()),
            c => out.last_mut().unwrap().push(c),
        }
    }
    out.iter().map(|c| c.trim().to_owned()).collect()
}

/// The rows of every table in `text` whose header is `header`, in order of appearance.
fn tables(text: &str, header: &[&str]) -> Vec<Vec<Vec<String>>> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        if line.trim_start().starts_with('|') && cells(line) == header {
            let rows = lines[i + 2..]
                .iter()
                .take_while(|l| l.trim_start().starts_with('|'))
                .map(|l| cells(l))
                .collect();
            found.push(rows);
        }
    }
    assert!(!found.is_empty(), "no table {header:?}");
    found
}

/// The `code spans` of a cell.
fn spans(cell: &str) -> Vec<String> {
    cell.split('`')
        .enumerate()
        .filter(|(i, _)| i % 2 == 1)
        .map(|(_, s)| s.to_owned())
        .collect()
}

#[test]
fn limits_are_the_firmwares() {
    use firmware::protocol::access::AccessConfig;
    let access = AccessConfig::DEFAULT;
    let doc = doc();
    let rows = &tables(&doc, &["limit", "value", "firmware constant"])[0];
    assert!(rows.len() >= 10, "{} rows", rows.len());
    for row in rows {
        let value: f64 = row[1].parse().unwrap_or_else(|_| panic!("{row:?}"));
        let constant = row[2].as_str();
        let code = match constant {
            "`protocol::line::MAX_LINE`" => firmware::protocol::line::MAX_LINE as f64,
            "`protocol::respond::MAX_RESPONSE`" => firmware::protocol::respond::MAX_RESPONSE as f64,
            "`protocol::SERIAL_BAUD`" => f64::from(firmware::protocol::SERIAL_BAUD),
            "`protocol::parse::MAX_COEFFICIENT_RAD_PER_S`" => {
                f64::from(firmware::protocol::parse::MAX_COEFFICIENT_RAD_PER_S)
            }
            "`protocol::parse::MAX_CAL_CYCLES`" => {
                f64::from(firmware::protocol::parse::MAX_CAL_CYCLES)
            }
            "`u16::MAX`" => f64::from(u16::MAX),
            "`protocol::stream::MAX_FRAME`" => firmware::protocol::stream::MAX_FRAME as f64,
            "`protocol::output_frame::MAX_OUTPUT_FRAME`" => {
                firmware::protocol::output_frame::MAX_OUTPUT_FRAME as f64
            }
            "`storage::STORE_STALL_MAX_MS`" => f64::from(firmware::storage::STORE_STALL_MAX_MS),
            "`protocol::access::AccessConfig::DEFAULT.unlock_timeout_ms` / 1000" => {
                f64::from(access.unlock_timeout_ms) / 1000.0
            }
            "`protocol::access::AccessConfig::DEFAULT.free_attempts`" => {
                f64::from(access.free_attempts)
            }
            "`protocol::access::AccessConfig::DEFAULT.window_period_ms` / 1000" => {
                f64::from(access.window_period_ms) / 1000.0
            }
            "`protocol::access::AccessConfig::DEFAULT.window_open_ms`" => {
                f64::from(access.window_open_ms)
            }
            other => panic!("a limit of an unknown constant: {other}"),
        };
        assert_eq!(value, code, "limit {:?}", row[0]);
    }
}

#[test]
fn error_codes_are_the_firmwares() {
    let doc = doc();
    let rows = &tables(&doc, &["code", "text", "when"])[0];
    let documented: Vec<(u8, &str)> = rows
        .iter()
        .map(|r| (r[0].parse().unwrap(), r[1].as_str()))
        .collect();
    let code: Vec<(u8, &str)> = ErrorCode::ALL
        .iter()
        .map(|c| (c.code(), c.text()))
        .collect();
    assert_eq!(documented, code);
}

/// A command form of the table with its placeholders filled in (`[...]` optional parts kept).
fn instantiate(form: &str) -> String {
    let filled = form
        .replace("[<warmup>]", "100")
        .replace("[<n>]", "10")
        .replace("<rad/s>", "1.5")
        .replace("<cycles>", "3000")
        .replace("<arcsec>", "450")
        .replace("<percent>", "5")
        .replace("<name> <value>", "b1 0.002")
        .replace("<key>", &"0".repeat(32));
    assert!(
        !filled.contains('<'),
        "a placeholder the test does not know: {form}"
    );
    filled
}

#[test]
fn the_command_table_is_the_parsers_and_the_executors() {
    let doc = doc();
    let rows = &tables(&doc, &["command", "what", "protected", "CRC or `yes`"])[0];
    let mut heads = Vec::new();
    for row in rows {
        let forms = spans(&row[0]);
        assert!(!forms.is_empty(), "{row:?}");
        for form in forms {
            let line = instantiate(&form);
            let command = parse(&line).unwrap_or_else(|e| panic!("{form}: {e:?}"));
            let dynamic = "while it would solve";
            let unlock = match row[2].as_str() {
                "yes" => UnlockRule::Always,
                "" => UnlockRule::Never,
                d if d == dynamic => UnlockRule::WhileItWouldSolve,
                other => panic!("{form}: protected {other:?}"),
            };
            assert_eq!(unlock_rule(&command), unlock, "{form}: protected");
            let confirm = match row[3].as_str() {
                "yes" => true,
                "" => false,
                // The executor adds `cal result` while it would close the pooled runs.
                d if d == dynamic && line == "cal result" => false,
                other => panic!("{form}: CRC or yes {other:?}"),
            };
            assert_eq!(needs_confirmation(&command), confirm, "{form}: CRC or yes");
            let words: Vec<&str> = line.split(' ').collect();
            heads.push(words[0].to_owned());
            if words.len() > 1 {
                heads.push(format!("{} {}", words[0], words[1]));
            }
        }
    }
    // Every command of the board's `help` has a row: `word`, and `word sub` for `word{sub|..}`
    // (required) and `word[sub|..]` (optional).
    let mut dev = ready();
    let help = ask(&mut dev, "help");
    let list = help.strip_prefix("OK commands: ").expect(&help);
    for entry in list.split(' ') {
        let (word, subs) = match entry.find(['{', '[']) {
            Some(i) => (
                &entry[..i],
                Some(entry[i + 1..].trim_end_matches(['}', ']'])),
            ),
            None => (entry.split('<').next().unwrap(), None),
        };
        assert!(heads.iter().any(|h| h == word), "`{word}` has no row");
        for sub in subs.into_iter().flat_map(|s| s.split('|')) {
            let sub: String = sub
                .chars()
                .take_while(|c| c.is_ascii_alphabetic())
                .collect();
            let full = format!("{word} {sub}");
            assert!(heads.contains(&full), "`{full}` has no row");
        }
    }
}

/// A board at 13.888 deg/h, locked, its stripping converged, unlocked.
fn ready() -> SimDevice {
    let params = GyroParams {
        seed: 11,
        ..GyroParams::default()
    };
    let mut dev = boot_with_key(params, 13.888, CalibrationFlash::default(), 0);
    while field(&ask(&mut dev, "status"), "drive") != "locked" {
        assert!(dev.time_s() < 3.0, "the drive did not lock");
        dev.run_for(0.1);
    }
    dev.run_for(1.0);
    assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    dev
}

/// One line with its CRC; the answer without the suffix (a `store` waits for its stall).
fn ask(dev: &mut SimDevice, line: &str) -> String {
    let text = exchange(
        dev,
        format!("{line}*{:04X}\n", crc16(line.as_bytes())).as_bytes(),
    );
    let line = text.trim_end();
    line.rsplit_once('*')
        .map_or(line, |(body, _)| body)
        .to_owned()
}

/// An `OK` answer's words: a field's key, or a bare word.
fn keys(answer: &str) -> Vec<String> {
    answer
        .strip_prefix("OK ")
        .unwrap_or_else(|| panic!("not OK: {answer}"))
        .split(' ')
        .map(|w| w.split_once('=').map_or(w, |(k, _)| k).to_owned())
        .collect()
}

/// Whether `keys` are `spec`'s words (a word `a|b` allows either).
fn matches_spec(keys: &[String], spec: &[&str]) -> bool {
    keys.len() == spec.len()
        && keys
            .iter()
            .zip(spec)
            .all(|(k, s)| s.split('|').any(|alt| alt == k))
}

/// The fields table: command -> its first code span's words.
fn fields_table(doc: &str) -> Vec<(String, Vec<String>)> {
    tables(doc, &["command", "fields"])[0]
        .iter()
        .map(|r| {
            let command = spans(&r[0]).remove(0);
            let spec = spans(&r[1]).remove(0);
            (command, spec.split(' ').map(str::to_owned).collect())
        })
        .collect()
}

#[test]
fn the_answers_fields_are_the_boards() {
    let doc = doc();
    let table = fields_table(&doc);
    let mut dev = ready();
    // The lines that produce each row's answer, in an order that works on one board.
    let script: &[(&str, &str)] = &[
        ("id", "id"),
        ("status", "status"),
        ("output status", "output status"),
        ("selftest", "selftest"),
        ("dither status", "dither status"),
        ("get coeffs", "get coeffs"),
        ("set a", "set a 300"),
        ("set b", "set b 600"),
        ("comp on", "comp on"),
        ("track on", "track on"),
        ("track off", "track off"),
        ("defaults", "defaults"),
        ("dither amp", "dither amp 450"),
        ("cal start", "cal start 2500"),
        ("cal result", "cal result"),
        ("cal accept", "cal accept"),
        ("store", "store"),
        ("reload", "reload"),
        ("stream on", "stream on 1"),
        ("stream output", "stream output"),
        ("stream off", "stream off"),
        ("lock", "lock"),
        ("unlock", "unlock KEY"),
    ];
    let mut checked = 0;
    for (command, line) in script {
        if *command == "cal result" {
            while field(&ask(&mut dev, "cal status"), "cal") != "run_done" {
                dev.run_for(0.5);
            }
        }
        let line = line.replace("KEY", KEY);
        let answer = ask(&mut dev, &line);
        if *command == "stream on" {
            // Frames follow at once: the next chunk after the answer is binary.
            dev.take_output();
        }
        let Some((_, spec)) = table.iter().find(|(c, _)| c == command) else {
            continue;
        };
        let spec: Vec<&str> = spec.iter().map(String::as_str).collect();
        assert!(
            matches_spec(&keys(&answer), &spec),
            "`{line}`: {answer}\n  documented: {spec:?}"
        );
        checked += 1;
    }
    // Every row of the table but `help` was asked.
    let asked: Vec<&str> = script.iter().map(|(c, _)| *c).collect();
    for (command, _) in &table {
        assert!(
            command == "help" || asked.contains(&command.as_str()),
            "the row `{command}` is not checked"
        );
    }
    assert!(checked + 1 >= table.len(), "{checked} of {}", table.len());
}

/// Every `OK` answer of the examples has the fields of its command's row (examples whose
/// command has no row of its own, such as `comp off` or `cal status`, are not checked); and the
/// `help` example is the board's answer.
#[test]
fn the_examples_answer_as_the_table_says() {
    let doc = doc();
    let table = fields_table(&doc);
    let mut last_command: Option<String> = None;
    let mut echoed: Option<String> = None;
    let mut checked = 0;
    for line in doc.lines() {
        if let Some(cmd) = line.strip_prefix("> ") {
            // `yes` answers for the command the board echoed.
            last_command = match cmd.trim() {
                "yes" => echoed.take(),
                cmd => Some(cmd.to_owned()),
            };
            continue;
        }
        if let Some((_, cmd)) = line.split_once("< ERR 18 confirm (send yes) cmd=") {
            echoed = Some(cmd.trim().to_owned());
        }
        let Some(answer) = line.strip_prefix("< OK ") else {
            continue;
        };
        let Some(cmd) = last_command.take() else {
            continue;
        };
        let answer = format!("OK {}", answer.rsplit_once('*').map_or(answer, |(b, _)| b));
        let words: Vec<&str> = cmd.split(' ').collect();
        let row = table.iter().find(|(c, _)| {
            let c: Vec<&str> = c.split(' ').collect();
            c.len() <= words.len() && c[..] == words[..c.len()]
        });
        let Some((command, spec)) = row else {
            continue;
        };
        if command == "help" {
            continue;
        }
        let spec: Vec<&str> = spec.iter().map(String::as_str).collect();
        assert!(
            matches_spec(&keys(&answer), &spec),
            "example `{cmd}`: {answer}\n  documented: {spec:?}"
        );
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} examples checked");
    let mut dev = ready();
    let help = ask(&mut dev, "help");
    assert!(
        doc.lines()
            .any(|l| l.strip_prefix("< ") == Some(help.as_str())),
        "the help example is not the board's: {help}"
    );
}

/// Reads a little-endian value of the documented type at `at`, as f64 (exactly, for the
/// values the test uses).
fn read(payload: &[u8], at: usize, ty: &str) -> f64 {
    let b = |n: usize| -> Vec<u8> { payload[at..at + n].to_vec() };
    match ty {
        "u8" => f64::from(payload[at]),
        "u16" => f64::from(u16::from_le_bytes(b(2).try_into().unwrap())),
        "i16" => f64::from(i16::from_le_bytes(b(2).try_into().unwrap())),
        "u32" => f64::from(u32::from_le_bytes(b(4).try_into().unwrap())),
        "i32" => f64::from(i32::from_le_bytes(b(4).try_into().unwrap())),
        "f32" => f64::from(f32::from_le_bytes(b(4).try_into().unwrap())),
        "u64" => u64::from_le_bytes(b(8).try_into().unwrap()) as f64,
        "i64" => i64::from_le_bytes(b(8).try_into().unwrap()) as f64,
        other => panic!("type {other}"),
    }
}

fn size_of(ty: &str) -> usize {
    match ty {
        "u8" => 1,
        "u16" | "i16" => 2,
        "u32" | "i32" | "f32" => 4,
        "u64" | "i64" => 8,
        other => panic!("type {other}"),
    }
}

/// Decodes `frame` (COBS, CRC) by the layout `rows` and checks every field against `expected`
/// by name; returns the payload's documented size.
fn check_layout(rows: &[Vec<String>], frame: &[u8], expected: &dyn Fn(&str) -> f64) -> usize {
    let size: usize = rows
        .iter()
        .map(|r| size_of(spans(&r[1]).first().map_or(&r[1], |s| s)))
        .sum();
    let mut payload = vec![0u8; size];
    firmware::protocol::cobs::decode(&frame[..frame.len() - 1], &mut payload)
        .unwrap_or_else(|e| panic!("the documented {size}-byte payload: {e:?}"));
    let mut next = 0;
    for row in rows {
        let offset: usize = row[0].parse().unwrap();
        let ty = row[1].as_str();
        let name = spans(&row[2]).remove(0);
        assert_eq!(offset, next, "{name}: the fields are contiguous");
        next += size_of(ty);
        assert_eq!(read(&payload, offset, ty), expected(&name), "field {name}");
    }
    size
}

#[test]
fn the_frame_layouts_decode_the_firmwares_frames() {
    use firmware::protocol::output_frame::{encode_output_frame, MAX_OUTPUT_FRAME, OUTPUT_PAYLOAD};
    use firmware::protocol::stream::{encode_frame, StreamRecord, FRAME_PAYLOAD, MAX_FRAME};
    use firmware::protocol::thermal_frame::{
        encode_thermal_frame, ThermalFrame, THERMAL_FRAME, THERMAL_PAYLOAD,
    };
    let doc = doc();
    let layouts = tables(&doc, &["offset", "type", "field", "meaning"]);
    assert_eq!(
        layouts.len(),
        3,
        "the cycle frame's, the output frame's and the thermal frame's"
    );
    let cycle = StreamRecord {
        sequence: 0x0102_0304,
        end_phase_q32: -0x0123_4567_89AB,
        raw_increment_q32: 0x0002_0000_0000_0003,
        compensated_increment_q32: -0x0001_0000_0000_0005,
        p1_s: 1.5e-3,
        p2_s: -2.25e-4,
        duration_ticks: 215_938,
        flags: 0b1_0100,
    };
    let mut frame = [0u8; MAX_FRAME];
    let n = encode_frame(&cycle, &mut frame);
    let size = check_layout(&layouts[0], &frame[..n], &|name| match name {
        "sequence" => f64::from(cycle.sequence),
        "end_phase" => cycle.end_phase_q32 as f64,
        "raw_increment" => cycle.raw_increment_q32 as f64,
        "compensated_increment" => cycle.compensated_increment_q32 as f64,
        "p1" => f64::from(cycle.p1_s),
        "p2" => f64::from(cycle.p2_s),
        "duration" => f64::from(cycle.duration_ticks),
        "flags" => f64::from(cycle.flags),
        other => panic!("an unknown field: {other}"),
    });
    assert_eq!((size, n), (FRAME_PAYLOAD, MAX_FRAME));
    let streaming = section(&doc, "## Streaming");
    assert!(streaming.contains(&format!("little-endian, {FRAME_PAYLOAD} bytes")));
    assert!(streaming.contains(&format!("\n- {MAX_FRAME} bytes on the wire")));
    let output = OutputRecord {
        sequence: 0x0102_0304_0506,
        time_ticks: 0x0000_0001_2345_6789,
        period_ticks: 84_001,
        delta_angle_q16: -123_456,
        angle_q16: 0x0000_0012_3456_789A,
        rate_deg_per_h: 15.25,
        status: OutputStatus(0x1417),
        temperature_q7: -1234,
        temperature_rate_centi_c_per_min: 321,
    };
    let mut frame = [0u8; MAX_OUTPUT_FRAME];
    let n = encode_output_frame(&output, &mut frame);
    let size = check_layout(&layouts[1], &frame[..n], &|name| match name {
        "sequence" => output.sequence as f64,
        "time" => output.time_ticks as f64,
        "period" => f64::from(output.period_ticks),
        "delta_angle" => f64::from(output.delta_angle_q16),
        "angle" => output.angle_q16 as f64,
        "rate" => f64::from(output.rate_deg_per_h),
        "status" => f64::from(output.status.0),
        other => panic!("an unknown field: {other}"),
    });
    assert_eq!((size, n), (OUTPUT_PAYLOAD, MAX_OUTPUT_FRAME));
    let fixed = section(&doc, "### The fixed-rate output: `stream output`");
    assert!(fixed.contains(&format!("little-endian, {OUTPUT_PAYLOAD} bytes")));
    assert!(fixed.contains(&format!("frame_bytes={MAX_OUTPUT_FRAME}`")));
    let thermal = ThermalFrame::of(&output);
    let mut frame = [0u8; THERMAL_FRAME];
    let n = encode_thermal_frame(&thermal, &mut frame);
    let size = check_layout(&layouts[2], &frame[..n], &|name| match name {
        "from_sequence" => thermal.from_sequence as f64,
        "temperature" => f64::from(thermal.temperature_q7),
        "temperature_rate" => f64::from(thermal.rate_centi_c_per_min),
        other => panic!("an unknown field: {other}"),
    });
    assert_eq!((size, n), (THERMAL_PAYLOAD, THERMAL_FRAME));
    assert!(fixed.contains(&format!(
        "the payload, little-endian, {THERMAL_PAYLOAD} bytes"
    )));
    assert!(fixed.contains(&format!("({THERMAL_FRAME} bytes on the wire)")));
}

#[test]
fn the_flag_tables_are_the_firmwares() {
    let doc = doc();
    let flags = tables(&doc, &["bit", "flag", "meaning"]);
    assert_eq!(
        flags.len(),
        2,
        "the cycle frame's flags and the output status bits"
    );
    let documented = |rows: &[Vec<String>]| -> Vec<(u32, String)> {
        rows.iter()
            .map(|r| (r[0].parse().unwrap(), spans(&r[1]).remove(0)))
            .collect()
    };
    let cycle: Vec<(u32, String)> = CycleFlags::NAMED
        .iter()
        .map(|(name, f)| (f.0.trailing_zeros(), name.to_string()))
        .collect();
    let output: Vec<(u32, String)> = OutputStatus::NAMED
        .iter()
        .map(|(name, f)| (f.0.trailing_zeros(), name.to_string()))
        .collect();
    assert_eq!(documented(&flags[0]), cycle);
    assert_eq!(documented(&flags[1]), output);
    // Each named flag is one bit, all different.
    for named in [
        CycleFlags::NAMED.map(|(_, f)| u32::from(f.0)).to_vec(),
        OutputStatus::NAMED.map(|(_, f)| u32::from(f.0)).to_vec(),
    ] {
        let all = named.iter().fold(0, |a, b| a | b);
        assert!(named.iter().all(|b| b.count_ones() == 1));
        assert_eq!(all.count_ones() as usize, named.len());
    }
}
