//! Wall time of 0.5 s of closed loop at a 20 kHz ISR with the averaged bridge: the
//! product's practical law (`Scenario::product(20e3, 24.0)`) with ideal sensors, so the
//! trajectory is deterministic and smooth, integrated with the fewest RK4 substeps per
//! period within 1e-4 of a 1 us RK4 solution (`hil_sim::analysis::accuracy::BENCH_SUBSTEPS`, one
//! per period; test `the_bench_substep_count_is_the_fewest_within_1e_4_of_a_1_us_solution`).
//! The scenario files' 10 substeps are measured beside it.
//!
//! `cargo bench -p hil-sim`

use criterion::{criterion_group, criterion_main, Criterion};
use hil_sim::analysis::accuracy::{bench_scenario, BENCH_SUBSTEPS};

fn closed_loop(c: &mut Criterion) {
    let mut group =
        c.benchmark_group("closed loop 0.5 s at 20 kHz, practical law, averaged bridge");
    let validated = bench_scenario().expect("the product's settings derive");
    group.bench_function(
        format!("{BENCH_SUBSTEPS} RK4 substep per period (validated)"),
        |b| b.iter(|| hil_sim::run(std::hint::black_box(&validated))),
    );
    let ten = bench_scenario()
        .expect("the product's settings derive")
        .with_substeps(10);
    group.bench_function("10 RK4 substeps per period (scenario files)", |b| {
        b.iter(|| hil_sim::run(std::hint::black_box(&ten)))
    });
    group.finish();
}

criterion_group!(benches, closed_loop);
criterion_main!(benches);
