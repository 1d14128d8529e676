//! `rlg-sim allan` as a user runs it: a record with a lost row in `rlg-cal record`'s columns,
//! the table, the CSV and the SVG; bad files and flags refused with the line or the flag.

mod support;
/// Records with known noise terms: the library's test-only generator, the same file.
#[path = "../src/allan/synthetic.rs"]
mod synthetic;

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;
use support::{rlg_sim, text};
use synthetic::{NoiseTerms, Synthetic};

fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("rlg-sim-allan-{}-{name}", std::process::id()))
}

/// 2^18 samples at 400 Hz of white rate noise of `arw` in `rlg-cal record`'s columns; row
/// `lost` is a lost record (valid 0, no angle).
fn write_record(path: &PathBuf, arw: f64, lost: usize) {
    let period = 0.0025;
    let terms = NoiseTerms {
        arw_deg_rt_h: arw,
        ..NoiseTerms::default()
    };
    let rates = Synthetic::new(terms, period, 21).rates(1 << 18);
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    writeln!(out, "t_s,delta_angle_arcsec,valid,sequence,status").unwrap();
    for (k, r) in rates.iter().enumerate() {
        let t = k as f64 * period;
        if k == lost {
            writeln!(out, "{t:.6},,0,{k},lost").unwrap();
        } else {
            writeln!(out, "{t:.6},{:.9},1,{k},0001", r * period).unwrap();
        }
    }
}

/// The whole command: exit 0, the gap stated, the CSV's exact columns with one row per octave
/// from the period to a third of the record, ARW within 5 % of the truth, and an SVG with the
/// fitted terms and their slopes.
#[test]
fn allan_reads_a_record_with_a_lost_row_and_writes_table_csv_and_svg() {
    let (input, csv, svg) = (scratch("in.csv"), scratch("out.csv"), scratch("out.svg"));
    write_record(&input, 0.003, 1000);
    let (out, _) = rlg_sim(&[
        "allan",
        "--input",
        input.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stdout.contains("1 invalid or lost rows") && stdout.contains("2 runs of valid samples"),
        "{stdout}"
    );
    assert!(stdout.contains("no angle spliced across a gap"), "{stdout}");
    let table = std::fs::read_to_string(&csv).unwrap();
    let mut lines = table.lines();
    assert_eq!(
        lines.next(),
        Some("tau_s,adev_deg_h,ci_low_deg_h,ci_high_deg_h")
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    // The longer run has 2^18 - 1001 samples: octaves 1 .. 2^16 samples.
    assert_eq!(rows.len(), 17);
    assert!((rows[0][0] - 0.0025).abs() < 1e-9 && (rows[16][0] - 163.84).abs() < 1e-6);
    for r in &rows {
        assert!(r[2] < r[1] && r[1] < r[3], "{r:?}");
    }
    let arw_line = stdout
        .lines()
        .find(|l| l.contains("angle random walk N ="))
        .unwrap();
    let arw: f64 = arw_line.split_whitespace().nth(5).unwrap().parse().unwrap();
    assert!((arw / 0.003 - 1.0).abs() < 0.05, "{arw_line}");
    let figure = std::fs::read_to_string(&svg).unwrap();
    assert!(figure.contains("slope -1/2: N = "), "ARW line missing");
    for p in [input, csv, svg] {
        let _ = std::fs::remove_file(p);
    }
}

/// A record whose spacing changes is refused with the line (exit 1) and changes nothing (an
/// existing output file keeps its content); a missing input and an out-of-range or negative
/// confidence are usage errors naming the flag (exit 2), at once.
#[test]
fn allan_refuses_bad_records_and_flags() {
    let (input, kept) = (scratch("uneven.csv"), scratch("kept.csv"));
    let uneven = "t_s,delta_angle_arcsec\n0,1\n0.01,1\n0.02,1\n0.035,1\n";
    std::fs::write(&input, uneven).unwrap();
    std::fs::write(&kept, "earlier result\n").unwrap();
    let path = input.to_str().unwrap();
    let (out, _) = rlg_sim(&["allan", "--input", path, "--csv", kept.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("line 5") && stderr.contains("uniform"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
    assert_eq!(std::fs::read_to_string(&kept).unwrap(), "earlier result\n");
    for (args, says) in [
        (
            vec!["--input", "/nonexistent/x.csv"],
            "--input /nonexistent/x.csv",
        ),
        (
            vec!["--input", path, "--confidence", "1.5"],
            "'--confidence <CONFIDENCE>': 1.5 is outside 0.5..=0.999",
        ),
        (
            vec!["--input", path, "--confidence", "-0.5"],
            "'--confidence <CONFIDENCE>': -0.5 is outside 0.5..=0.999",
        ),
        (
            vec!["--input", path, "--csv", "/nonexistent/dir/a.csv"],
            "/nonexistent/dir/a.csv",
        ),
    ] {
        let mut all = vec!["allan"];
        all.extend(args.iter().copied());
        let (out, took) = rlg_sim(&all);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(took < Duration::from_secs(1), "{took:?}");
    }
    let _ = std::fs::remove_file(input);
    let _ = std::fs::remove_file(kept);
}
