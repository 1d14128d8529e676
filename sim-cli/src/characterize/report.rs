//! The report of `rlg-sim characterize`: `report.md` (configuration, the figures side by side
//! with units and how each was measured, the conclusions, the procedure, the limits), the
//! CSVs of the raw points and the Allan deviations, and the SVG figures.
//!
//! The conclusions are sentences chosen by the numbers ([`conclusions`]): whether compensation
//! removed the dead band (compensation off has failing points, compensation on none), and
//! whether random-noise dither added random walk (its ARW against the compensated one, and by
//! what factor); when the numbers do not show it, the sentence says so.

use super::charts;
use super::figures::THRESHOLD_TOLERANCE;
use super::noise::{StaticFigures, BIAS_STABILITY_BLOCK_S};
use super::procedure::{ConfigurationResult, Outcome};
use super::{DeadBandTheory, Plan};
use crate::allan::fit::Term;
use crate::allan::output as allan_output;
use hal_sim::params::GyroParams;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Slugs of the three `--compare` configurations (the conclusions look for them).
pub const SLUG_OFF: &str = "comp_off";
/// Compensation on.
pub const SLUG_ON: &str = "comp_on";
/// Random-noise dither.
pub const SLUG_NOISE: &str = "noise_dither";

/// What the report states besides the results.
#[derive(Clone, Debug)]
pub struct Context {
    /// The command line that made it.
    pub command: String,
    /// The gyro.
    pub params: GyroParams,
    /// The plan.
    pub plan: Plan,
    /// The dead band in theory.
    pub theory: DeadBandTheory,
    /// The board's description (drive, latch, sync, pick-off).
    pub board: String,
    /// The calibration's result, if one was made.
    pub calibration: Option<String>,
}

fn num(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "n/a".into()
    }
}

fn sci(v: f64) -> String {
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

fn threshold_text(r: &ConfigurationResult) -> String {
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

/// `scale_factor.csv`: every measured point of every configuration.
pub fn points_csv(results: &[ConfigurationResult]) -> String {
    let mut s = String::from(
        "configuration,input_deg_h,output_deg_h,linear_range,residual_ppm_fs,resolved\n",
    );
    for r in results {
        let line = r.scale_factor.as_ref();
        let bias = r
            .static_figures
            .as_ref()
            .map(|f| f.bias_deg_h)
            .or(line.map(|l| l.line.intercept));
        for p in &r.points {
            let residual = match line {
                Some(l) if p.linear_range => format!(
                    "{:.6}",
                    (p.output_deg_h - l.line.at(p.input_deg_h))
                        / (l.line.slope * l.full_scale_deg_h)
                        * 1e6
                ),
                _ => String::new(),
            };
            let resolved = match (line, bias) {
                (Some(l), Some(b)) => {
                    u8::from(super::figures::resolved(p, l.line.slope, b)).to_string()
                }
                _ => String::new(),
            };
            let _ = writeln!(
                s,
                "{},{:.6},{:.6},{},{residual},{resolved}",
                r.configuration.slug,
                p.input_deg_h,
                p.output_deg_h,
                u8::from(p.linear_range)
            );
        }
    }
    s
}

/// The Markdown report.
pub fn markdown(outcome: &Outcome, ctx: &Context) -> String {
    let p = &ctx.params;
    let plan = &ctx.plan;
    let mut s =
        String::from("# Gyro characterisation: IEEE Std 647 procedures on the simulated gyro\n\n");
    let _ = writeln!(
        s,
        "Made by `{}` (same seed, same numbers). The simulated gyro with the board firmware's \
         signal chain in the loop; every figure is measured from the board's fixed-rate output.\n",
        ctx.command
    );
    let _ = writeln!(s, "## Configuration\n");
    let _ = writeln!(
        s,
        "- Gyro: scale factor {} arcsec/pulse, lock-in Omega_L {} deg/h, dither {} arcsec at {} \
         Hz, eps {} rad, ARW {} deg/sqrt(h), seed {}.",
        p.scale_factor_arcsec,
        p.lock_in_deg_per_h,
        p.dither_amplitude_arcsec,
        p.dither_hz,
        p.eps_rad,
        p.arw_deg_per_rt_h,
        p.seed
    );
    let _ = writeln!(s, "- Board: {}.", ctx.board);
    for r in &outcome.results {
        let c = &r.configuration;
        let comp = if c.settings.enabled {
            format!(
                "compensation on (a = {:.4}, b = {:.4} rad/s)",
                c.settings.coefficients.a_rad_per_s(),
                c.settings.coefficients.b_rad_per_s()
            )
        } else {
            "compensation off".into()
        };
        let noise = match c.setup.drive {
            crate::experiment::DitherDrive::ClosedLoop { noise_percent } if noise_percent > 0.0 => {
                format!(
                    ", random-noise dither {noise_percent} % (the firmware drive's `dither noise`)"
                )
            }
            _ => String::new(),
        };
        let _ = writeln!(s, "- `{}` ({}): {comp}{noise}.", c.slug, c.name);
    }
    if let Some(cal) = &ctx.calibration {
        let _ = writeln!(
            s,
            "- Calibration (the paper's Step 2, compensation off): {cal}."
        );
    }
    let _ = writeln!(
        s,
        "- Dead band in theory: Chow's Omega_L |J0(A)| = {} deg/h at the nominal amplitude; its \
         envelope Omega_L sqrt(2 / (pi A)) = {} deg/h places the dense points.",
        num(ctx.theory.chow_deg_h, 3),
        num(ctx.theory.envelope_deg_h, 3)
    );
    let _ = writeln!(
        s,
        "- Plan: {} linear-range rates per sign, log-spaced from {} deg/h to {} deg/s; {} dense \
         rates per sign up to {} deg/h; {} s recorded per rate after a {} s warm-up (and the \
         drive's lock + {} s); static record {} s.\n",
        plan.range_points,
        num(10.0 * ctx.theory.envelope_deg_h, 2),
        plan.max_rate_deg_s,
        plan.dense_points,
        num(2.5 * ctx.theory.envelope_deg_h, 2),
        plan.seconds_per_point,
        plan.warmup_s,
        crate::experiment::DRIVE_SETTLE_S,
        plan.static_s
    );
    let _ = writeln!(s, "## Results\n\n{}", table(&outcome.results));
    let conclusions = conclusions(&outcome.results);
    if !conclusions.is_empty() {
        let _ = writeln!(s, "## Conclusions (from the numbers above)\n");
        for c in conclusions {
            let _ = writeln!(s, "- {c}");
        }
        s.push('\n');
    }
    let _ = writeln!(
        s,
        "## Figures\n\n![scale-factor residuals](scale_factor_residuals.svg)\n\n\
         ![output near zero](dead_band.svg)\n"
    );
    if outcome.results.len() > 1 {
        let _ = writeln!(s, "![Allan deviations side by side](allan_compare.svg)\n");
    }
    for r in &outcome.results {
        let _ = writeln!(
            s,
            "![Allan deviation, {}](allan_{}.svg)\n",
            r.configuration.name, r.configuration.slug
        );
    }
    s.push_str(&procedure_text(plan));
    s
}

fn procedure_text(plan: &Plan) -> String {
    format!(
        "## Procedure\n\n\
         1. **Scale-factor test** (IEEE 647 rate-transfer test): for each input rate a run of \
         the board at that constant rate; the output is the least-squares slope of the \
         fixed-rate output's integrated angle over the {sec} s record, converted to deg/h with \
         the scale factor the board is configured with. Scale factor, its error, the \
         non-linearity (ppm of the full-scale output) and the asymmetry come from the \
         linear-range points only.\n\
         2. **Threshold / dead band**: every tested rate (dense and linear-range) is resolved \
         when |output - bias - SF x input| <= {tol} x |SF x input| (IEEE 647's threshold: the \
         output at least half of what the scale factor predicts); the threshold is the \
         smallest tested |input| from which every larger one is resolved, so it is bracketed by \
         the tested rates only.\n\
         3. **Static record**: {stat} s at zero input; the fixed-rate output (at most {max} \
         samples: whole sync periods summed) gives the bias (its mean), the bias stability \
         (std of {block} s block means, or a tenth of the record if shorter), and through \
         `rlg-sim allan`'s estimator and IEEE 952 fit the ARW and the bias instability. The \
         record is in `static_<configuration>.csv` (`rlg-sim allan --input` reads it), the \
         deviation in `allan_<configuration>.csv`.\n\
         4. **Random-noise dither** (`--compare`): the firmware drive's random amplitude noise \
         (`dither noise <percent>`: the drive's peak amplitude times 1 + depth x r, r uniform, \
         every half cycle; the resonator smooths it), the one a board with the closed-loop \
         drive has; hal-sim's noise on the prescribed sine (`random_noise_dither`) is not \
         used.\n\n\
         ## Limits\n\n\
         - The simulated gyro has only the noise it is given (`--arw-deg-rt-h`, the dither's \
         random noise, the readout's quantisation): no thermal drift, so the bias instability \
         and rate random walk of a real gyro do not appear; the bias instability here is \
         whatever floor the readout and the dither leave.\n\
         - A threshold is only as fine as the tested rates; each rate's output carries the \
         record's noise (about ARW x 60 / sqrt({sec} s) deg/h).\n\
         - A static record of {stat} s resolves tau up to a third of it; bias instability \
         needs hours (`--static-seconds`).\n\
         - The default board's readout closes no dither cycle in some runs from about 90 \
         deg/s of input and in every run from 97 deg/s (such a run fails the command; nothing \
         is extrapolated): the default maximum is 80 deg/s. The firmware's turnaround \
         sequence check (half periods within +-20 % of nominal) refuses the unequal half \
         periods a large input rate makes.\n",
        sec = plan.seconds_per_point,
        tol = THRESHOLD_TOLERANCE,
        stat = plan.static_s,
        max = super::noise::MAX_STATIC_SAMPLES,
        block = BIAS_STABILITY_BLOCK_S,
    )
}

/// Writes the report and its files into `dir`; returns the paths written.
pub fn write(dir: &Path, outcome: &Outcome, ctx: &Context) -> std::io::Result<Vec<PathBuf>> {
    let mut written = write_points(dir, outcome)?;
    let mut put = |name: String, text: String| -> std::io::Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, text)?;
        written.push(path);
        Ok(())
    };
    let title = format!(
        "Omega_L {} deg/h, dither {} arcsec at {} Hz",
        ctx.params.lock_in_deg_per_h, ctx.params.dither_amplitude_arcsec, ctx.params.dither_hz
    );
    put(
        "scale_factor_residuals.svg".into(),
        charts::residuals(
            &outcome.results,
            &format!("Scale-factor residuals: {title}"),
        )
        .to_svg(),
    )?;
    put(
        "dead_band.svg".into(),
        charts::dead_band(&outcome.results, &format!("Output near zero: {title}")).to_svg(),
    )?;
    if outcome.results.len() > 1 {
        let t = format!("Allan deviation, static records: {title}");
        if let Some(figure) = charts::allan_compare(&outcome.results, &t) {
            put("allan_compare.svg".into(), figure.to_svg())?;
        }
    }
    for r in &outcome.results {
        let slug = &r.configuration.slug;
        if let Some(Ok(a)) = r.static_figures.as_ref().map(|f| &f.allan) {
            put(format!("allan_{slug}.csv"), allan_output::csv(a))?;
            let t = format!("Allan deviation, static record: {}", r.configuration.name);
            put(
                format!("allan_{slug}.svg"),
                allan_output::figure(a, &t).to_svg(),
            )?;
        }
    }
    put("report.md".into(), markdown(outcome, ctx))?;
    Ok(written)
}

/// Writes `scale_factor.csv` alone (what an interrupted run keeps besides the static records).
pub fn write_points(dir: &Path, outcome: &Outcome) -> std::io::Result<Vec<PathBuf>> {
    let path = dir.join("scale_factor.csv");
    std::fs::write(&path, points_csv(&outcome.results))?;
    Ok(vec![path])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::synthetic::{NoiseTerms, Synthetic};
    use crate::characterize::figures::{scale_factor, threshold, RatePoint};
    use crate::characterize::noise::{rate_record, static_figures, StaticSample};
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
        let samples: Vec<StaticSample> = Synthetic::new(terms, period, seed)
            .rates(100_000)
            .iter()
            .enumerate()
            .map(|(i, r)| StaticSample {
                t_s: (i + 1) as f64 * period,
                delta_angle_arcsec: r * period,
                valid: true,
            })
            .collect();
        static_figures(&rate_record(&samples, period), 0.95)
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
