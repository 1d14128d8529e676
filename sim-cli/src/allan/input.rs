//! The recorded rate: a CSV of `rlg-sim record` or `rlg-cal record` read into a uniform series.
//!
//! Columns are found by name in the header: `t_s` and `delta_angle_arcsec` are required,
//! `valid` is optional (absent: every row with an angle is valid); other columns are ignored,
//! so both tools' files read the same. The rate of a row is its increment over the sample
//! period, `delta_angle_arcsec / period_s` (arcsec/s = deg/h).
//!
//! The period is the median spacing of the first 1000 rows; every spacing must then be a whole
//! multiple of it within 1 % (+ 2 us for the files' 6 decimals), else the file is refused
//! naming the line: the Allan deviation assumes uniform sampling. A spacing of k
//! periods (k > 1: rows nobody wrote) is k - 1 missing samples, counted and marked by one NaN
//! (memory stays linear in the rows, whatever the jump). The final period is the span over
//! the sample periods, so print rounding averages out.
//!
//! Gaps: a row with `valid` 0 or an empty angle (`rlg-cal record`'s lost records), and every
//! missing sample, is stored as NaN. Nothing is interpolated and no angle is spliced across a
//! gap: the estimator ([`super::estimator`]) uses only the runs of valid samples between them.

use std::io::BufRead;

/// The rate series: one entry per sample period, NaN where there is no valid sample (a run of
/// missing samples, rows nobody wrote, is one NaN: a gap marker, whatever its length).
#[derive(Clone, Debug, PartialEq)]
pub struct RateRecord {
    /// The sample period, s.
    pub period_s: f64,
    /// Rate per sample, deg/h (NaN: invalid or lost; one NaN for a run of missing samples).
    pub rates_deg_h: Vec<f64>,
    /// Data rows read.
    pub rows: u64,
    /// Rows marked invalid (`valid` 0) or without an angle.
    pub invalid_rows: u64,
    /// Samples no row stood for (spacings of several periods).
    pub missing_samples: u64,
}

impl RateRecord {
    /// Valid samples.
    pub fn valid_samples(&self) -> usize {
        self.rates_deg_h.iter().filter(|r| r.is_finite()).count()
    }

    /// The runs of consecutive valid samples, as index ranges.
    pub fn segments(&self) -> Vec<std::ops::Range<usize>> {
        let mut out = Vec::new();
        let mut start = None;
        for (i, r) in self.rates_deg_h.iter().enumerate() {
            match (r.is_finite(), start) {
                (true, None) => start = Some(i),
                (false, Some(s)) => {
                    out.push(s..i);
                    start = None;
                }
                _ => {}
            }
        }
        if let Some(s) = start {
            out.push(s..self.rates_deg_h.len());
        }
        out
    }
}

/// One parsed row: time, and the angle if the row is valid.
type Row = (f64, Option<f64>);

struct Columns {
    t: usize,
    delta: usize,
    valid: Option<usize>,
}

fn columns(header: &str) -> Result<Columns, String> {
    let names: Vec<&str> = header.trim().split(',').map(str::trim).collect();
    let find = |name: &str| names.iter().position(|n| *n == name);
    Ok(Columns {
        t: find("t_s").ok_or("the header has no `t_s` column")?,
        delta: find("delta_angle_arcsec").ok_or("the header has no `delta_angle_arcsec` column")?,
        valid: find("valid"),
    })
}

fn parse_row(line: &str, cols: &Columns, line_no: u64) -> Result<Row, String> {
    let fields: Vec<&str> = line.trim().split(',').map(str::trim).collect();
    let field = |i: usize, name: &str| {
        fields
            .get(i)
            .copied()
            .ok_or_else(|| format!("line {line_no}: no `{name}` field"))
    };
    let number = |text: &str, name: &str| {
        text.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("line {line_no}: `{name}` is not a finite number: {text:?}"))
    };
    let t = number(field(cols.t, "t_s")?, "t_s")?;
    let valid = match cols.valid {
        Some(i) => match field(i, "valid")? {
            "1" => true,
            "0" => false,
            other => {
                return Err(format!(
                    "line {line_no}: `valid` must be 0 or 1, got {other:?}"
                ))
            }
        },
        None => true,
    };
    let delta = field(cols.delta, "delta_angle_arcsec")?;
    let angle = if !valid || delta.is_empty() {
        None
    } else {
        Some(number(delta, "delta_angle_arcsec")?)
    };
    Ok((t, angle))
}

fn median_spacing(rows: &[(u64, Row)]) -> Result<f64, String> {
    let mut dt: Vec<f64> = rows.windows(2).map(|w| w[1].1 .0 - w[0].1 .0).collect();
    if dt.is_empty() {
        return Err("the record has fewer than 2 rows".into());
    }
    dt.sort_by(f64::total_cmp);
    let period = dt[dt.len() / 2];
    if period > 0.0 {
        Ok(period)
    } else {
        Err(format!(
            "`t_s` does not increase (median spacing {period} s)"
        ))
    }
}

/// Accumulates rows into samples, checking the spacing.
struct Series {
    period_s: f64,
    first_t: Option<f64>,
    last_t: f64,
    record: RateRecord,
    angles: Vec<f64>,
    /// Sample periods from the first row to the last (missing ones included).
    samples: u64,
}

impl Series {
    fn push(&mut self, line_no: u64, (t, angle): Row) -> Result<(), String> {
        if self.first_t.is_some() {
            let dt = t - self.last_t;
            let k = (dt / self.period_s).round();
            // 1 % of the spacing: a long gap's length is known only as well as the period.
            let tolerance = 0.01 * k.max(1.0) * self.period_s + 2e-6;
            if k < 1.0 || (dt - k * self.period_s).abs() > tolerance {
                return Err(format!(
                    "line {line_no}: t_s {t} is {dt:.9} s after the previous row, not a whole \
                     multiple of the sample period {:.9} s: the Allan deviation needs uniform \
                     sampling",
                    self.period_s
                ));
            }
            let missing = k as u64 - 1;
            self.record.missing_samples += missing;
            self.samples += missing;
            if missing > 0 {
                self.angles.push(f64::NAN);
            }
        } else {
            self.first_t = Some(t);
        }
        self.last_t = t;
        self.record.rows += 1;
        self.samples += 1;
        if angle.is_none() {
            self.record.invalid_rows += 1;
        }
        self.angles.push(angle.unwrap_or(f64::NAN));
        Ok(())
    }

    fn finish(mut self) -> RateRecord {
        let span = self.last_t - self.first_t.unwrap_or(self.last_t);
        if self.samples > 1 && span > 0.0 {
            self.period_s = span / (self.samples - 1) as f64;
        }
        let period = self.period_s;
        for a in &mut self.angles {
            *a /= period;
        }
        self.record.period_s = period;
        self.record.rates_deg_h = self.angles;
        self.record
    }
}

/// Reads a record CSV. Errors name the line and what is wrong with it.
pub fn read_csv(input: impl BufRead) -> Result<RateRecord, String> {
    let mut lines = input.lines().enumerate().map(|(i, l)| (i as u64 + 1, l));
    let (_, header) = lines.next().ok_or("the file is empty")?;
    let cols = columns(&header.map_err(|e| format!("line 1: {e}"))?)?;
    let mut rows = lines.filter_map(|(no, line)| match line {
        Ok(l) if l.trim().is_empty() => None,
        Ok(l) => Some(parse_row(&l, &cols, no).map(|r| (no, r))),
        Err(e) => Some(Err(format!("line {no}: {e}"))),
    });
    let head: Vec<(u64, Row)> = rows.by_ref().take(1000).collect::<Result<_, _>>()?;
    let period_s = median_spacing(&head)?;
    let mut series = Series {
        period_s,
        first_t: None,
        last_t: 0.0,
        record: RateRecord {
            period_s,
            rates_deg_h: Vec::new(),
            rows: 0,
            invalid_rows: 0,
            missing_samples: 0,
        },
        angles: Vec::new(),
        samples: 0,
    };
    for row in head.into_iter().map(Ok).chain(rows) {
        let (no, row) = row?;
        series.push(no, row)?;
    }
    Ok(series.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<RateRecord, String> {
        read_csv(text.as_bytes())
    }

    /// `rlg-cal record`'s lost rows (valid 0, no angle) and a row nobody wrote become NaN
    /// samples; the rates are arcsec per period in deg/h.
    #[test]
    fn lost_and_missing_rows_are_gaps() {
        let csv = "t_s,delta_angle_arcsec,valid,sequence,status\n\
                   0.000000,0.5,1,0,0001\n\
                   0.002500,,0,1,lost\n\
                   0.005000,0.25,1,2,0001\n\
                   0.010000,1.0,1,4,0001\n";
        let r = read(csv).unwrap();
        assert!((r.period_s - 0.0025).abs() < 1e-12);
        assert_eq!((r.rows, r.invalid_rows, r.missing_samples), (4, 1, 1));
        let want = [200.0, f64::NAN, 100.0, f64::NAN, 400.0];
        assert_eq!(r.rates_deg_h.len(), want.len());
        for (got, want) in r.rates_deg_h.iter().zip(want) {
            assert!(got.is_nan() == want.is_nan() && (want.is_nan() || (got - want).abs() < 1e-9));
        }
        assert_eq!(r.segments(), vec![0..1, 2..3, 4..5]);
    }

    /// A jump of a million periods (rows nobody wrote) is one gap marker: counted, not a
    /// million NaN in memory; its length need not be an exact multiple of the period from the
    /// rows' rounded times (1 % of the jump).
    #[test]
    fn a_long_gap_is_one_marker() {
        let r = read("t_s,delta_angle_arcsec\n0,1\n1,1\n2,1\n1000002.3,1\n1000003.3,1\n").unwrap();
        assert_eq!(r.missing_samples, 999_999);
        assert_eq!(r.rates_deg_h.len(), 6);
        assert_eq!(r.segments(), vec![0..3, 4..6]);
        assert!((r.period_s - 1.0).abs() < 1e-6);
    }

    /// `rlg-sim record`'s columns, without `valid` in the order of the header.
    #[test]
    fn columns_by_name_valid_optional() {
        let r = read("delta_angle_arcsec,t_s\n1,0.001\n2,0.002\n3,0.003\n").unwrap();
        assert_eq!(r.rates_deg_h.len(), 3);
        assert!((r.rates_deg_h[2] - 3000.0).abs() < 1e-6);
    }

    /// Non-uniform spacing, a missing column and garbage are refused, naming the line.
    #[test]
    fn bad_files_are_refused_with_the_line() {
        let cases = [
            ("t_s,delta_angle_arcsec\n0,1\n1,1\n2.5,1\n3.5,1\n", "line 4"),
            ("t_s,angle\n0,1\n", "delta_angle_arcsec"),
            ("t_s,delta_angle_arcsec\n0,1\n1,x\n", "line 3"),
            ("t_s,delta_angle_arcsec,valid\n0,1,1\n1,1,2\n", "line 3"),
            ("t_s,delta_angle_arcsec\n0,1\n", "fewer than 2 rows"),
            ("", "empty"),
        ];
        for (csv, want) in cases {
            let err = read(csv).unwrap_err();
            assert!(err.contains(want), "{csv:?}: {err}");
        }
    }
}
