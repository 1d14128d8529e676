//! The report of `rlg-sim characterize`: `report.md` (configuration, the figures side by side
//! with units and how each was measured, the conclusions, the procedure, the limits), the
//! CSVs of the raw points and the Allan deviations, and the SVG figures.
//! The table and the conclusions are [`super::summary`]'s.

use super::charts;
use super::figures::THRESHOLD_TOLERANCE;
use super::noise::BIAS_STABILITY_BLOCK_S;
use super::procedure::{ConfigurationResult, Outcome};
use super::summary::{conclusions, num, table};
use super::{DeadBandTheory, Plan};
use crate::allan::output as allan_output;
use crate::thermal::procedure::{ThermalOutcome, ThermalPlan};
use hal_sim::params::GyroParams;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

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
    /// `--thermal`: bias and scale factor over temperature, and the plan that gave them.
    pub thermal: Option<(ThermalOutcome, ThermalPlan)>,
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
    if let Some((thermal, thermal_plan)) = &ctx.thermal {
        s.push_str(&super::thermal::markdown(thermal, thermal_plan));
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
         random noise, the readout's quantisation) and the temperature it is given \
         (`--temperature-profile`, `--thermal`): no random drift, so the bias instability \
         and rate random walk of a real gyro do not appear; the bias instability here is \
         whatever floor the readout and the dither leave.\n\
         - A threshold is only as fine as the tested rates; each rate's output carries the \
         record's noise (about ARW x 60 / sqrt({sec} s) deg/h).\n\
         - A static record of {stat} s resolves tau up to a third of it; bias instability \
         needs hours (`--static-seconds`).\n\
         - A rate at which the board closes no dither cycle fails the command (nothing is \
         extrapolated); the readout keeps cycles up to about 0.99 of the peak dither rate \
         (305 deg/s for the default set), where the two halves of a dither period split \
         0.1 / 1.9.\n",
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
    if let Some((thermal, _)) = &ctx.thermal {
        put("thermal.csv".into(), super::thermal::csv(thermal))?;
        let t = format!("Bias and scale factor over temperature: {title}");
        put(
            "thermal.svg".into(),
            super::thermal::chart(thermal, &t).to_svg(),
        )?;
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
