//! Simulation speed at the default accuracy with the docs/physics.md parameter set: one
//! iteration simulates 0.1 gyro-second (78 dither cycles, 156 traversals) at the paper's
//! 13.888 deg/h. Criterion's throughput is in gyro-milliseconds per second; the lines printed
//! first are the same figure in gyro-seconds per wall-second (and per CPU-second of the
//! thread, which is what a free core would do on a loaded machine) from 4 s runs, for the
//! prescribed sine (`ideal`) and the driven resonator.
//!
//! The driven cases hold the same dither (450 arcsec at 389 Hz) with the open-loop drive of
//! the parameters, a new drive segment every half cycle (where the angle crosses zero, as a
//! firmware updating at the pick-off's edges would), pushed two periods ahead while the gyro
//! advances half a cycle at a time; `driven_at_turnarounds` puts the segment starts at the
//! turnarounds instead (inside the near regions: more, shorter near pieces).

use criterion::{criterion_group, BatchSize, Criterion, Throughput};
use hal_sim::dither::open_loop::OpenLoopDrive;
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::gyro::{measure_speed, Gyro};
use hal_sim::input::InputProfile;
use hal_sim::params::{AmplitudeModulation, GyroParams};

const GYRO_S: f64 = 0.1;

fn driven(p: GyroParams) -> GyroParams {
    p.with_steady_driven_dither(ResonatorParams::default())
}

/// Runs a driven gyro to `GYRO_S`, feeding `drive` two periods ahead, half a cycle at a time.
fn run_driven(mut g: Gyro, mut drive: OpenLoopDrive) -> f64 {
    let (step, lead) = (0.5 / 389.0, g.drive_lead_s());
    let mut t = 0.0;
    while t < GYRO_S {
        t = (t + step).min(GYRO_S);
        drive.keep_ahead(&mut g, t + lead).unwrap();
        g.advance_to(t);
    }
    g.t_s()
}

fn bench_phase(c: &mut Criterion) {
    let mut group = c.benchmark_group("phase");
    group.throughput(Throughput::Elements((GYRO_S * 1000.0) as u64));
    group.sample_size(20);
    let input = || InputProfile::rotary_table(22.2, 0.0);
    let noisy = GyroParams {
        arw_deg_per_rt_h: 0.01,
        amplitude_jitter: AmplitudeModulation::jitter(0.002),
        ..Default::default()
    };
    // The noise alone: what `driven_noise` is to be compared with.
    let noise_only = GyroParams {
        arw_deg_per_rt_h: 0.01,
        ..Default::default()
    };
    for (name, params) in [
        ("steady_dither", GyroParams::default()),
        ("noise_and_jitter", noisy),
        ("noise", noise_only),
    ] {
        group.bench_function(name, |b| {
            b.iter_batched(
                || Gyro::new(params, input()).unwrap(),
                |mut g| g.advance_to(GYRO_S),
                BatchSize::LargeInput,
            )
        });
    }
    let steady = driven(GyroParams::default());
    let at_rate_peaks = steady.open_loop_drive().unwrap();
    let r = *steady.resonator().unwrap();
    let at_turnarounds = at_rate_peaks.with_boundaries_at_drive_phase(
        core::f64::consts::FRAC_PI_2 - r.dac_to_angle(at_rate_peaks.freq_hz(), 0.0).arg(),
    );
    // The driven dither ignores the amplitude jitter: only the noise is left.
    let driven_noise = driven(noisy);
    for (name, params, drive) in [
        ("driven", steady, at_rate_peaks),
        ("driven_at_turnarounds", steady, at_turnarounds),
        (
            "driven_noise",
            driven_noise,
            driven_noise.open_loop_drive().unwrap(),
        ),
    ] {
        group.bench_function(name, |b| {
            b.iter_batched(
                || Gyro::new(params, input()).unwrap(),
                |g| run_driven(g, drive),
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench_phase);

fn main() {
    for (name, params) in [
        ("ideal", GyroParams::default()),
        ("driven", driven(GyroParams::default())),
    ] {
        let s = measure_speed(params, InputProfile::rotary_table(22.2, 0.0), 4.0)
            .expect("the default parameters are valid");
        let cpu = s
            .gyro_s_per_cpu_s
            .map_or("n/a".to_string(), |c| format!("{c:.1}"));
        println!(
            "hal-sim phase ({name}): {:.1} gyro-seconds per wall-second, {cpu} per CPU-second \
             (default params, one core)",
            s.gyro_s_per_wall_s
        );
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
