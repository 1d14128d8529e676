//! Simulation speed at the default accuracy with the docs/physics.md parameter set: one
//! iteration simulates 0.1 gyro-second (78 dither cycles, 156 traversals) at the paper's
//! 13.888 deg/h. Criterion's throughput is in gyro-milliseconds per second; the line printed
//! first is the same figure in gyro-seconds per wall-second (and per CPU-second of the
//! thread, which is what a free core would do on a loaded machine) from a 4 s run.

use criterion::{criterion_group, BatchSize, Criterion, Throughput};
use hal_sim::gyro::{measure_speed, Gyro};
use hal_sim::input::InputProfile;
use hal_sim::params::{AmplitudeModulation, GyroParams};

const GYRO_S: f64 = 0.1;

fn bench_phase(c: &mut Criterion) {
    let mut group = c.benchmark_group("phase");
    group.throughput(Throughput::Elements((GYRO_S * 1000.0) as u64));
    group.sample_size(20);
    let cases = [
        ("steady_dither", GyroParams::default()),
        (
            "noise_and_jitter",
            GyroParams {
                arw_deg_per_rt_h: 0.01,
                amplitude_jitter: AmplitudeModulation::jitter(0.002),
                ..Default::default()
            },
        ),
    ];
    for (name, params) in cases {
        group.bench_function(name, |b| {
            b.iter_batched(
                || Gyro::new(params, InputProfile::rotary_table(22.2, 0.0)).unwrap(),
                |mut g| g.advance_to(GYRO_S),
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench_phase);

fn main() {
    let s = measure_speed(
        GyroParams::default(),
        InputProfile::rotary_table(22.2, 0.0),
        4.0,
    )
    .expect("the default parameters are valid");
    let cpu = s
        .gyro_s_per_cpu_s
        .map_or("n/a".to_string(), |c| format!("{c:.1}"));
    println!(
        "hal-sim phase: {:.1} gyro-seconds per wall-second, {cpu} per CPU-second (default params, one core)",
        s.gyro_s_per_wall_s
    );
    benches();
    Criterion::default().configure_from_args().final_summary();
}
