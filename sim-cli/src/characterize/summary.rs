//! The figures side by side and the conclusions of `rlg-sim characterize` (what `report.md`
//! tabulates and stdout prints).
//!
//! The conclusions are sentences chosen by the numbers ([`conclusions`]): whether compensation
//! removed the dead band (compensation off has failing points, compensation on none), and
//! whether random-noise dither added random walk (its ARW against the compensated one, and by
//! what factor); when the numbers do not show it, the sentence says so.

use super::noise::StaticFigures;
use super::procedure::ConfigurationResult;
use crate::allan::fit::Term;
use std::fmt::Write as _;

/// Slugs of the three `--compare` configurations (the conclusions look for them).
pub const SLUG_OFF: &str = "comp_off";
/// Compensation on.
pub const SLUG_ON: &str = "comp_on";
/// Random-noise dither.
pub const SLUG_NOISE: &str = "noise_dither";

/// A number with `digits` decimals, `n/a` when not finite.
pub fn num(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "n/a".into()
    }
}

/// A number in scientific notation, 4 digits.
pub fn sci(v: f64) -> String {
    format!("{v:.3e}")
}

fn term(t: Option<Term>) -> String {
    match t {
        Some(t) if t.high > 1e3 * t.value => {
            format!("{} [{}, unbounded]", sci(t.value), sci(t.low))
        }
        Some(t) => format!(
            "{} [{}, {}]{}",
            sci(t.value),
            sci(t.low),
            sci(t.high),
            if t.significant {
                ""
            } else {
                " (not significant)"
            }
        ),
        None => "not resolved".into(),
    }
}

/// The threshold cell: `<= smallest` when every rate resolves.
pub fn threshold_text(r: &ConfigurationResult) -> String {
    match &r.threshold {
        Some(t) if t.below_smallest_tested => format!("<= {}", num(t.smallest_tested_deg_h, 3)),
        Some(t) => t
            .threshold_deg_h
            .map_or("none: even the largest rate fails".into(), |v| num(v, 3)),
        None => "n/a".into(),
    }
}

fn dead_band_text(r: &ConfigurationResult) -> String {
    match &r.threshold {
        Some(t) if t.dead_band_negative_deg_h == 0.0 && t.dead_band_positive_deg_h == 0.0 => {
            "none found".into()
        }
        Some(t) => format!(
            "-{} .. +{}",
            num(t.dead_band_negative_deg_h, 3),
            num(t.dead_band_positive_deg_h, 3)
        ),
        None => "n/a".into(),
    }
}

fn static_cell(r: &ConfigurationResult, f: impl Fn(&StaticFigures) -> String) -> String {
    r.static_figures.as_ref().map_or("n/a".into(), f)
}

/// The figures side by side, a Markdown table (also printed on stdout).
pub fn table(results: &[ConfigurationResult]) -> String {
    type Row<'a> = (
        &'a str,
        &'a str,
        Box<dyn Fn(&ConfigurationResult) -> String>,
        &'a str,
    );
    let sf = |f: fn(&super::figures::ScaleFactor) -> String| {
        move |r: &ConfigurationResult| r.scale_factor.as_ref().map_or("n/a".into(), f)
    };
    let rows: Vec<Row> = vec![
        (
            "scale factor",
            "arcsec/pulse",
            Box::new(sf(|s| format!("{:.7}", s.scale_factor_arcsec))),
            "least-squares line of output vs input over the linear-range points",
        ),
        (
            "scale-factor error",
            "ppm",
            Box::new(sf(|s| num(s.error_ppm, 3))),
            "measured vs the simulator's scale factor, (SF/SF_true - 1) 1e6",
        ),
        (
            "non-linearity",
            "ppm of full scale",
            Box::new(sf(|s| num(s.nonlinearity_ppm, 3))),
            "largest abs(residual) from the line, over the linear-range points",
        ),
        (
            "asymmetry",
            "ppm",
            Box::new(sf(|s| s.asymmetry_ppm.map_or("n/a".into(), |a| num(a, 3)))),
            "(SF+ - SF-) / mean, each side's own least-squares line",
        ),
        (
            "bias",
            "deg/h",
            Box::new(|r| static_cell(r, |f| num(f.bias_deg_h, 5))),
            "mean output of the static record",
        ),
        (
            "bias stability",
            "deg/h",
            Box::new(|r| {
                static_cell(r, |f| {
                    format!(
                        "{} ({} s)",
                        f.bias_stability_deg_h.map_or("n/a".into(), |b| num(b, 5)),
                        num(f.bias_stability_block_s, 1)
                    )
                })
            }),
            "std of consecutive block means of the static record",
        ),
        (
            "threshold",
            "deg/h",
            Box::new(threshold_text),
            "smallest abs(input) from which every tested rate is within 50 % of SF x input",
        ),
        (
            "dead band",
            "deg/h",
            Box::new(dead_band_text),
            "largest abs(input) failing the 50 % criterion, each sign",
        ),
        (
            "angle random walk N",
            "deg/sqrt(h)",
            Box::new(|r| static_cell(r, |f| term(f.arw()))),
            "IEEE 952 fit to the static record's Allan deviation [--confidence interval]",
        ),
        (
            "ADEV at 1 s",
            "deg/h",
            Box::new(|r| static_cell(r, |f| f.adev_1s_deg_h.map_or("n/a".into(), sci))),
            "overlapping Allan deviation of the static record, log-log between octaves",
        ),
        (
            "ARW upper bound",
            "deg/sqrt(h)",
            Box::new(|r| static_cell(r, |f| f.arw_bound_deg_rt_h.map_or("n/a".into(), sci))),
            "the ARW term forced into the fit beside the terms found: coefficient + 2 sigma",
        ),
        (
            "bias instability B",
            "deg/h",
            Box::new(|r| static_cell(r, |f| term(f.bias_instability()))),
            "IEEE 952 fit: the flicker floor over 0.664",
        ),
    ];
    let mut s = String::from("| figure | unit |");
    for r in results {
        let _ = write!(s, " {} |", r.configuration.name);
    }
    s.push_str(" how measured |\n|---|---|");
    for _ in results {
        s.push_str("---|");
    }
    s.push_str("---|\n");
    for (name, unit, cell, how) in rows {
        let _ = write!(s, "| {name} | {unit} |");
        for r in results {
            let _ = write!(s, " {} |", cell(r));
        }
        let _ = writeln!(s, " {how} |");
    }
    s
}

fn find<'a>(results: &'a [ConfigurationResult], slug: &str) -> Option<&'a ConfigurationResult> {
    results.iter().find(|r| r.configuration.slug == slug)
}

fn band(r: &ConfigurationResult) -> Option<f64> {
    r.threshold
        .map(|t| t.dead_band_negative_deg_h.max(t.dead_band_positive_deg_h))
}

/// The two conclusions of `--compare`, as sentences chosen by the numbers (empty without the
/// three configurations).
pub fn conclusions(results: &[ConfigurationResult]) -> Vec<String> {
    let mut out = Vec::new();
    let (Some(off), Some(on), Some(noise)) = (
        find(results, SLUG_OFF),
        find(results, SLUG_ON),
        find(results, SLUG_NOISE),
    ) else {
        return out;
    };
    if let (Some(b_off), Some(b_on), Some(t_on)) = (band(off), band(on), on.threshold) {
        let s = if b_off > 0.0 && b_on == 0.0 {
            format!(
                "Compensation removes the dead band: with compensation off the output misses the \
                 50 % criterion at rates up to {} deg/h (threshold {} deg/h), with compensation \
                 on every tested rate meets it, down to the smallest, {} deg/h.",
                num(b_off, 3),
                threshold_text(off),
                num(t_on.smallest_tested_deg_h, 3)
            )
        } else if b_off > 0.0 && b_on < b_off {
            format!(
                "Compensation narrows the dead band from {} to {} deg/h but does not remove it \
                 at the tested rates.",
                num(b_off, 3),
                num(b_on, 3)
            )
        } else if b_off == 0.0 {
            format!(
                "No dead band was found with compensation off at the tested rates (smallest {} \
                 deg/h): this run does not show compensation removing one.",
                num(t_on.smallest_tested_deg_h, 3)
            )
        } else {
            format!(
                "Compensation did not narrow the dead band: {} deg/h with it off, {} deg/h on.",
                num(b_off, 3),
                num(b_on, 3)
            )
        };
        out.push(s);
    }
    let arw = |r: &ConfigurationResult| r.static_figures.as_ref()?.arw_for_comparison();
    if let (Some((n_noise, noise_bound)), Some((n_on, on_bound))) = (arw(noise), arw(on)) {
        let kind = |bound: bool| {
            if bound {
                "upper bound: the ARW term forced into the fit, + 2 sigma"
            } else {
                "fitted"
            }
        };
        let ratio = n_noise / n_on;
        let s = if !noise_bound && ratio > 1.0 {
            format!(
                "Random-noise dither adds random walk: its ARW, {} deg/sqrt(h) ({}), is {}{:.1} \
                 times the compensated gyro's {} deg/sqrt(h) ({}).",
                sci(n_noise),
                kind(noise_bound),
                if on_bound { "at least " } else { "" },
                ratio,
                sci(n_on),
                kind(on_bound)
            )
        } else {
            format!(
                "This run does not show random-noise dither adding random walk: its ARW {} \
                 deg/sqrt(h) ({}) against the compensated gyro's {} deg/sqrt(h) ({}), ratio {:.2}.",
                sci(n_noise),
                kind(noise_bound),
                sci(n_on),
                kind(on_bound),
                ratio
            )
        };
        out.push(s);
    } else {
        out.push("The ARW could not be compared: a static record has no Allan deviation.".into());
    }
    if let (Some(b_noise), Some(b_off)) = (band(noise), band(off)) {
        let noisy = if b_noise == 0.0 {
            "leaves no dead band at the tested rates".to_string()
        } else {
            format!("leaves a dead band of {} deg/h", num(b_noise, 3))
        };
        out.push(format!(
            "Random-noise dither (compensation off) {noisy}, against {} deg/h with the plain \
             dither.",
            num(b_off, 3)
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::synthetic::{NoiseTerms, Synthetic};
    use crate::characterize::figures::{scale_factor, threshold, RatePoint};
    use crate::characterize::noise::{rate_record, samples_from_rates, static_figures};
    use crate::characterize::Configuration;
    use crate::experiment::BoardSetup;
    use firmware::signal::compensation::CompensationSettings;

    /// White rate noise of `arw` plus quantisation of 0.5 arcsec at 100 Hz for 1000 s.
    fn static_record(arw: f64, seed: u64) -> StaticFigures {
        let period = 0.01;
        let terms = NoiseTerms {
            arw_deg_rt_h: arw,
            quantisation_arcsec: 0.5,
            ..NoiseTerms::default()
        };
        let rates = Synthetic::new(terms, period, seed).rates(100_000);
        let samples = samples_from_rates(&rates, period);
        static_figures(&rate_record(&samples, period), 0.95, 0.0)
    }

    /// A gyro with Chow's dead band of `band` deg/h (0: linear), tested at 0.5..10 deg/h and
    /// the linear range.
    fn result(slug: &str, band: f64, arw: f64) -> ConfigurationResult {
        let rates = [0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 10.0, 100.0, 10_000.0];
        let points: Vec<RatePoint> = rates
            .iter()
            .flat_map(|&r| [r, -r])
            .map(|x: f64| RatePoint {
                input_deg_h: x,
                output_deg_h: if x.abs() <= band {
                    0.0
                } else {
                    x.signum() * (x * x - band * band).sqrt()
                },
                linear_range: x.abs() >= 100.0,
            })
            .collect();
        let sf = scale_factor(&points, 1.8655).unwrap();
        let static_figures = static_record(arw, 5);
        ConfigurationResult {
            configuration: Configuration {
                name: slug.into(),
                slug: slug.into(),
                setup: BoardSetup::board(0.0, 1000.0),
                settings: CompensationSettings::default(),
            },
            threshold: Some(threshold(&points, sf.line.slope, 0.0)),
            points,
            static_figures: Some(static_figures),
            scale_factor: Some(sf),
        }
    }

    /// The sentences follow the numbers: a band removed, narrowed, or not there; a random
    /// walk added or not.
    #[test]
    fn the_conclusions_follow_the_numbers() {
        let said = conclusions(&[
            result(SLUG_OFF, 3.36, 0.0),
            result(SLUG_ON, 0.0, 0.0),
            result(SLUG_NOISE, 0.0, 0.003),
        ]);
        assert!(
            said[0].starts_with("Compensation removes the dead band"),
            "{said:?}"
        );
        assert!(said[0].contains("up to 3.000 deg/h"), "{said:?}");
        assert!(
            said[1].starts_with("Random-noise dither adds random walk"),
            "{said:?}"
        );
        let said = conclusions(&[
            result(SLUG_OFF, 3.36, 0.0),
            result(SLUG_ON, 1.5, 0.003),
            result(SLUG_NOISE, 0.0, 0.003),
        ]);
        assert!(said[0].starts_with("Compensation narrows the dead band from 3.000 to 1.000"));
        assert!(said[1].starts_with("This run does not show"), "{said:?}");
        let said = conclusions(&[
            result(SLUG_OFF, 0.0, 0.0),
            result(SLUG_ON, 0.0, 0.0),
            result(SLUG_NOISE, 0.0, 0.0),
        ]);
        assert!(said[0].starts_with("No dead band was found"), "{said:?}");
        assert!(said[1].starts_with("This run does not show"), "{said:?}");
        // Without the three configurations: no conclusions.
        assert!(conclusions(&[result(SLUG_ON, 0.0, 0.0)]).is_empty());
    }
}
