//! A power cut at every single step of a save (each byte programmed, each page erased)
//! leaves the old parameter set or the new one, never a mix: the board's own start
//! ([`ema::device::boot`]) on the simulated flash, cut at each step in turn, then started
//! again.
//!
//! Two geometries: the chip's (two 16 KiB sectors: a save appends a record), and small
//! pages that force the store to close a page, erase the other and carry the set over,
//! with the cut save starting at every position in the page's cycle.

use bench::flash::{Flash, PAGE, PAGES};
use ema::control::actuator::Actuator;
use ema::device::boot;
use ema::device::params::{Board, Params};
use ema::device::protocol::Source;
use ema::device::store::Store;

const BOARD: Board = Board {
    rate_hz: 20_000.0,
    current_zero_code: None,
};

fn set(k: u32) -> Params {
    let mut p = Params::new(Actuator::PRODUCT);
    p.actuator.tuning.as_mut().unwrap().margin = 0.5 + 0.001 * k as f32;
    p.actuator.coil.peak_time_s = 0.1 + 0.001 * k as f32;
    p
}

/// Starts a board on `flash` (saving `save` first when given); returns the parameters
/// it runs with and the flash.
fn start<const P: usize>(
    flash: Flash<P>,
    range: std::ops::Range<u32>,
    save: Option<&Params>,
) -> (Params, Source<'static>, Flash<P>) {
    let mut store = Store::new(flash, range).unwrap();
    let defaults = Params::new(Actuator::PRODUCT);
    let b = boot(&mut store, &defaults, &BOARD, save).unwrap();
    (b.params, b.source, store.release())
}

/// Cuts the save of `new` over a flash holding `old` at every step; returns (steps cut,
/// old sets recovered, new sets recovered, pages the uncut save erased).
fn cut_everywhere<const P: usize>(
    base: &Flash<P>,
    range: std::ops::Range<u32>,
    old: &Params,
    new: &Params,
) -> (u64, u64, u64, u64) {
    // How many steps the save takes, uncut.
    let before = base.steps();
    let (p, _, after) = start(base.clone(), range.clone(), Some(new));
    assert_eq!(&p, new);
    let steps = after.steps() - before;
    let erased = after.erases() - base.erases();
    assert!(steps > 50, "{steps}");
    let (mut olds, mut news) = (0, 0);
    for k in 0..steps {
        let mut f = base.clone();
        f.cut_after(k);
        let (_, _, mut dead) = start(f, range.clone(), Some(new));
        assert!(dead.is_dead(), "step {k} of {steps} did not cut");
        dead.power_on();
        let (p, source, _) = start(dead, range.clone(), None);
        assert_eq!(source, Source::Stored, "cut at step {k} of {steps}");
        if &p == old {
            olds += 1;
        } else if &p == new {
            news += 1;
        } else {
            panic!("cut at step {k} of {steps}: a set that is neither");
        }
    }
    (steps, olds, news, erased)
}

#[test]
fn a_cut_at_any_step_of_a_save_leaves_the_old_set_or_the_new_one() {
    let range = 0..u32::try_from(PAGE * PAGES).unwrap();
    let (old, new) = (set(1), set(2));
    let (_, _, base) = start(Flash::default(), range.clone(), Some(&old));
    let (steps, olds, news, _) = cut_everywhere(&base, range, &old, &new);
    println!(
        "chip geometry: {steps} steps cut one at a time: {olds} old sets and {news} new sets recovered"
    );
    assert_eq!(olds + news, steps);
    // The new set counts only once its record is whole: until its last byte, the old one.
    assert!(olds >= steps - 2, "{olds} of {steps}");
    // The e2e test cuts at steps 0, 7, 60 and 100: all within a save.
    assert!(steps > 100, "{steps}");
}

#[test]
fn a_cut_during_a_page_change_leaves_the_old_set_or_the_new_one() {
    // 512-byte pages hold two records: saves close pages, erase and carry over.
    let page = 512;
    let range = 0..u32::try_from(2 * page).unwrap();
    let mut total = (0, 0, 0);
    let mut flash = Flash::<512>::new(2);
    let mut erasing_saves = 0;
    for k in 0..6 {
        let (old, new) = (set(10 + k), set(11 + k));
        let (_, _, f) = start(flash, range.clone(), Some(&old));
        let (steps, olds, news, erased) = cut_everywhere(&f, range.clone(), &old, &new);
        assert_eq!(olds + news, steps);
        total = (total.0 + steps, total.1 + olds, total.2 + news);
        if erased > 0 {
            erasing_saves += 1;
        }
        flash = f;
    }
    println!(
        "512-byte pages, six saves in a row ({erasing_saves} of them erasing a page): {} steps cut one at a time: {} old sets and {} new sets recovered",
        total.0, total.1, total.2
    );
    // Some of those saves erased a page and carried the set over: their cuts fall in
    // the erase and the carry-over as well.
    assert!(erasing_saves >= 1, "no save erased a page");
    assert_eq!(total.1 + total.2, total.0);
}
