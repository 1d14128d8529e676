//! `rlg-sim characterize` as a user runs it: bad flags and an unwritable --out refused with
//! exit 2 before anything runs; a short run writes the report and its files, and the same seed
//! writes the same numbers; Ctrl-C keeps the static record written so far and exits 130.

mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use support::{rlg_sim, text};

fn scratch(name: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("rlg-sim-char-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&p);
    p
}

/// A small plan: 2 + 2 rates per sign of 0.5 s, a 10 s static record, no calibration.
const SHORT: [&str; 13] = [
    "characterize",
    "--quiet",
    "--compensation",
    "off",
    "--range-points",
    "2",
    "--dense-points",
    "2",
    "--seconds-per-point",
    "0.5",
    "--static-seconds",
    "10",
    "--max-rate-deg-s=0.1",
];

/// Each out-of-range flag: exit 2 within a second, the message names the flag and its range,
/// and the --out folder is not created.
#[test]
fn bad_flags_exit_2_naming_the_flag_before_anything_runs() {
    let out = scratch("bad");
    let out_arg = out.to_str().unwrap();
    let cases: [(&[&str], &str); 9] = [
        (
            &["--max-rate-deg-s", "500"],
            "'--max-rate-deg-s <MAX_RATE_DEG_S>': 500 is outside 0.1..=300 deg/s",
        ),
        (
            &["--dense-points", "1"],
            "'--dense-points <DENSE_POINTS>': 1 is outside 2..=50",
        ),
        (
            &["--range-points", "51"],
            "'--range-points <RANGE_POINTS>': 51 is outside 2..=50",
        ),
        (
            &["--static-seconds", "5"],
            "'--static-seconds <STATIC_SECONDS>': 5 is outside 10..=360000 s",
        ),
        (
            &["--seconds-per-point", "-1"],
            "'--seconds-per-point <SECONDS_PER_POINT>': -1 is outside 0.5..=3600 s",
        ),
        (
            &["--confidence", "2"],
            "'--confidence <CONFIDENCE>': 2 is outside 0.5..=0.999",
        ),
        (
            &["--compare", "--compare-noise-percent", "60"],
            "'--compare-noise-percent <COMPARE_NOISE_PERCENT>': 60 is outside 1..=50 %",
        ),
        (
            &["--compare", "--dither-noise-percent", "5"],
            "--dither-noise-percent must be 0",
        ),
        (
            &["--compare", "--dither-drive", "ideal", "--latch", "exact"],
            "--compare needs --dither-drive closed-loop",
        ),
    ];
    for (flags, message) in cases {
        let mut args = vec!["characterize", "--out", out_arg];
        args.extend_from_slice(flags);
        let (o, took) = rlg_sim(&args);
        let stderr = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {stderr}");
        assert!(stderr.contains(message), "{flags:?}: {stderr}");
        assert!(took < Duration::from_secs(2), "{flags:?}: {took:?}");
        assert!(!out.exists(), "{flags:?} created {}", out.display());
    }
}

/// --out under a regular file cannot be created: exit 2 at once (no calibration, no run),
/// naming --out.
#[test]
fn an_unwritable_out_exits_2_before_the_run() {
    let file = scratch("file");
    std::fs::write(&file, "not a folder").unwrap();
    let out = file.join("report");
    let (o, took) = rlg_sim(&["characterize", "--compare", "--out", out.to_str().unwrap()]);
    let stderr = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--out"), "{stderr}");
    assert!(!stderr.contains("calibration at"), "{stderr}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    std::fs::remove_file(file).unwrap();
}

fn read(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A short run writes the report, the CSVs and the figures; run twice with the same seed,
/// every number is the same (the points, the static record, the Allan deviation, the table).
#[test]
fn a_short_run_writes_the_report_and_the_same_seed_the_same_numbers() {
    let dirs = [scratch("run1"), scratch("run2")];
    let mut tables = Vec::new();
    for dir in &dirs {
        let mut args = SHORT.to_vec();
        args.extend_from_slice(&["--out", dir.to_str().unwrap()]);
        let (o, _) = rlg_sim(&args);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        tables.push(text(&o.stdout));
        for name in [
            "report.md",
            "scale_factor.csv",
            "static_comp_off.csv",
            "allan_comp_off.csv",
            "allan_comp_off.svg",
            "scale_factor_residuals.svg",
            "dead_band.svg",
        ] {
            assert!(dir.join(name).is_file(), "{name} missing");
        }
        let report = read(dir, "report.md");
        for part in [
            "## Configuration",
            "## Results",
            "| threshold | deg/h |",
            "## Procedure",
            "## Limits",
        ] {
            assert!(report.contains(part), "{part}: {report}");
        }
        // 2 x (2 + 2) rates; about 10 s of static record at 1 kHz.
        assert_eq!(read(dir, "scale_factor.csv").lines().count(), 1 + 8);
        let rows = read(dir, "static_comp_off.csv").lines().count() - 1;
        assert!((9_900..=10_001).contains(&rows), "{rows} rows");
    }
    assert_eq!(tables[0], tables[1]);
    assert!(
        tables[0].contains("| scale factor | arcsec/pulse |"),
        "{}",
        tables[0]
    );
    for name in [
        "scale_factor.csv",
        "static_comp_off.csv",
        "allan_comp_off.csv",
    ] {
        assert_eq!(read(&dirs[0], name), read(&dirs[1], name), "{name}");
    }
    for dir in dirs {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

/// Ctrl-C during a long static record: exit 130, the static CSV keeps the rows so far (whole
/// lines), scale_factor.csv the rates done, and no report is written.
#[test]
fn sigint_keeps_the_static_record_so_far() {
    let dir = scratch("int");
    let mut args = SHORT.to_vec();
    args[11] = "3000";
    args.extend_from_slice(&["--out", dir.to_str().unwrap(), "--jobs", "1"]);
    let child = Command::new(env!("CARGO_BIN_EXE_rlg-sim"))
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let csv = dir.join("static_comp_off.csv");
    let started = Instant::now();
    while std::fs::metadata(&csv).map_or(0, |m| m.len()) < 20_000 {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no static rows"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    // SAFETY: a signal to our own child process.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    let o = child.wait_with_output().unwrap();
    let stderr = text(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("no report"), "{stderr}");
    let rows = read(&dir, "static_comp_off.csv");
    assert!(rows.ends_with('\n'));
    assert!(rows.lines().count() > 500, "{} lines", rows.lines().count());
    assert!(dir.join("scale_factor.csv").is_file());
    assert!(!dir.join("report.md").exists());
    std::fs::remove_dir_all(dir).unwrap();
}

/// `--thermal` on the default board (the firmware's closed-loop drive, compensation
/// calibrated): thermal.csv with exactly the documented columns, one row per check soak
/// (-15..+55 °C), thermal.svg, and the report's section; the model takes the soaks' bias and
/// scale factor down (measured: bias worst 0.078 -> 0.0007 deg/h, scale factor 19.5 ->
/// 0.03 ppm; bounds 0.005 deg/h and 1 ppm, the acceptance's 10 ppm far above).
#[test]
fn thermal_adds_bias_and_scale_factor_over_temperature() {
    let dir = scratch("thermal");
    let args = [
        "characterize",
        "--quiet",
        "--range-points",
        "2",
        "--dense-points",
        "2",
        "--seconds-per-point",
        "0.5",
        "--static-seconds",
        "10",
        "--max-rate-deg-s=0.1",
        "--calibration-seconds",
        "5",
        "--thermal",
        "--out",
        dir.to_str().unwrap(),
    ];
    let (o, _) = rlg_sim(&args);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let csv = read(&dir, "thermal.csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some(
            "temperature_c,bias_raw_deg_h,bias_compensated_deg_h,scale_factor_raw_ppm,\
             scale_factor_compensated_ppm"
        )
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let temps: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(temps, [-15.0, -5.0, 5.0, 15.0, 25.0, 35.0, 45.0, 55.0]);
    let worst = |i: usize| rows.iter().map(|r| r[i].abs()).fold(0.0, f64::max);
    assert!(worst(1) > 0.05 && worst(2) < 0.005, "{csv}");
    assert!(worst(3) > 10.0 && worst(4) < 1.0, "{csv}");
    assert!(read(&dir, "thermal.svg").starts_with("<svg"));
    let report = read(&dir, "report.md");
    assert!(report.contains("## Bias and scale factor over temperature (IEEE 647)"));
    assert!(report.contains("![bias and scale factor over temperature](thermal.svg)"));
    assert!(text(&o.stdout).contains("over temperature: ramp bias rms"));
    std::fs::remove_dir_all(dir).unwrap();
}
