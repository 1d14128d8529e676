use firmware::signal::compensation::CompensationSettings;
use hal_sim::params::GyroParams;
use rlg_sim::experiment::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let closed = args.get(1).map(|s| s == "closed").unwrap_or(true);
    let jitter: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(0.0);
    let mut params = GyroParams::default();
    params.amplitude_jitter = hal_sim::params::AmplitudeModulation::jitter(jitter);
    let setup = if closed {
        BoardSetup::board(0.0, 1000.0)
    } else {
        BoardSetup {
            latch: Latch::Scheduled,
            sync_hz: Some(1000.0),
            ..BoardSetup::IDEAL
        }
    };
    let omega_l = 2.0 * std::f64::consts::PI * 200.0 / 1.8655;
    let (a, b) = (
        omega_l * (0.3f64 + std::f64::consts::FRAC_PI_4).cos(),
        omega_l * (0.3f64 + std::f64::consts::FRAC_PI_4).sin(),
    );
    let mut ys = Vec::new();
    run_constant_rate(
        &params,
        setup,
        13.888,
        RunLength {
            warmup_s: 0.5,
            record_s: 20.0,
        },
        CompensationSettings::default(),
        |_, c| {
            if c.output.flags.compensable() {
                ys.push((
                    c.raw_increment_rad() - a * c.terms.p1_s as f64 - b * c.terms.p2_s as f64,
                    c.dither_amplitude_rad as f64,
                    c.output.duration_ticks as f64,
                ));
            }
        },
        |_, _| {},
    )
    .unwrap();
    let n = ys.len() as f64;
    let m = ys.iter().map(|y| y.0).sum::<f64>() / n;
    let r: Vec<f64> = ys.iter().map(|y| y.0 - m).collect();
    let sd = (r.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    println!("cycles {} resid sd {:.3e} rad", ys.len(), sd);
    // autocorrelation
    for lag in 1..6 {
        let c: f64 = (lag..r.len()).map(|i| r[i] * r[i - lag]).sum::<f64>() / n / (sd * sd);
        print!("ac{lag}={c:.3} ");
    }
    println!();
    // correlation with amplitude differences and duration
    let amp: Vec<f64> = ys.iter().map(|y| y.1).collect();
    let dur: Vec<f64> = ys.iter().map(|y| y.2).collect();
    let corr = |x: &[f64], y: &[f64]| {
        let n = x.len() as f64;
        let mx = x.iter().sum::<f64>() / n;
        let my = y.iter().sum::<f64>() / n;
        let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
        for (p, q) in x.iter().zip(y) {
            a += (p - mx) * (q - my);
            b += (p - mx).powi(2);
            c += (q - my).powi(2);
        }
        a / (b * c).sqrt()
    };
    let d1: Vec<f64> = (1..amp.len()).map(|i| amp[i] - amp[i - 1]).collect();
    println!(
        "corr(r, d amp) {:.3}  corr(r, dur) {:.3}  amp sd {:.3e} d1 sd {:.3e} dur sd {:.3e}",
        corr(&r[1..], &d1),
        corr(&r, &dur),
        {
            let ma = amp.iter().sum::<f64>() / n;
            (amp.iter().map(|x| (x - ma).powi(2)).sum::<f64>() / n).sqrt()
        },
        {
            let md = d1.iter().sum::<f64>() / d1.len() as f64;
            (d1.iter().map(|x| (x - md).powi(2)).sum::<f64>() / d1.len() as f64).sqrt()
        },
        {
            let md = dur.iter().sum::<f64>() / n;
            (dur.iter().map(|x| (x - md).powi(2)).sum::<f64>() / n).sqrt()
        }
    );
}
