//! The RK4 substep counts, measured against a 1 us RK4 solution (see `hil_sim::accuracy`
//! for why open loop).

use hil_sim::accuracy::{
    bench_scenario, fewest_substeps, Reference, BENCH_SUBSTEPS, TOLERANCE_REL,
};
use hil_sim::Scenario;

/// The benchmark loop (product law, 20 kHz, averaged, ideal sensors, 0.5 s): one 50 us
/// RK4 step per period stays within 1e-4 of the 1 us solution. Measured: 2.1e-8 of the
/// stroke in position and 5.7e-7 of the peak current (6.27 A); 10 substeps: 2e-12 and
/// 4.4e-11.
#[test]
fn the_bench_substep_count_is_the_fewest_within_1_e_4_of_a_1_us_solution() {
    let sc = bench_scenario();
    assert_eq!(sc.integration.substeps, BENCH_SUBSTEPS);
    let a = fewest_substeps(&sc.clone().with_substeps(10), 10, TOLERANCE_REL).unwrap();
    assert_eq!(a.substeps, BENCH_SUBSTEPS);
    assert!(a.within(TOLERANCE_REL) && a.position_rel < 1e-7, "{a:?}");
    assert!(a.within(TOLERANCE_REL) && a.current_rel < 5e-6, "{a:?}");
    assert!(
        a.current_rel > 1e-8,
        "{a:?}: the comparison must see the step size"
    );
}

/// The search is not a formality: the paper's sign law at 20 kHz moves the current by
/// 15 A per period and needs more substeps (measured: 3 substeps 1.4e-4 of the peak
/// current, 5 substeps 1.7e-5).
#[test]
fn the_chattering_paper_law_needs_more_substeps() {
    let sc = Scenario::paper(20_000.0)
        .with_current_trip_a(100.0)
        .with_duration_s(0.5);
    let a = fewest_substeps(&sc, 10, TOLERANCE_REL).unwrap();
    assert!((4..=5).contains(&a.substeps), "{a:?}");
    assert!(a.within(TOLERANCE_REL));
    let r = Reference::new(&sc).unwrap();
    let one = r.accuracy(1).unwrap();
    assert!(one.current_rel > 1e-3, "{one:?}");
}
