//! The mass and the friction fitted to the moves between the holds.

use ema::device::commission::Report;

use super::{pull, Circuit, Holds, Spring};

/// The armature's mass and friction measured by [`fit_armature`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Armature {
    /// Moving mass \[kg\].
    pub mass_kg: f64,
    /// Viscous friction \[N s/m\].
    pub friction_n_s_per_m: f64,
    /// The stiffness the spring's fit missed, as the moves read it (`K` in
    /// [`fit_armature`]) \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Two standard errors of the mass, from the fit's own scatter over the moves
    /// (the jackknife, each move left out in turn; NaN with a single move) \[kg\].
    pub mass_uncertainty_kg: f64,
    /// Two standard errors of the friction, the same way \[N s/m\].
    pub friction_uncertainty_n_s_per_m: f64,
    /// Moves fitted.
    pub moves: usize,
}

/// A move has settled once its position stays within this share of the move of its
/// target: [`fit_armature`] fits each move up to then.
pub const SETTLED_SHARE: f64 = 0.02;

/// A move that comes this near a stop (as a share of the stroke) may have touched it,
/// where the equation of motion [`fit_armature`] fits does not hold: it is left out.
pub const STOP_SHARE: f64 = 0.01;

/// The mass and the friction from the moves between the holds ([`Holds::moves`], the
/// first, from the open stop, left out), with the `spring` measured from their windows,
/// the commissioning's `report` and the magnetic `circuit` measured; `None` when no move
/// can be fitted.
///
/// Over a move, the equation of motion integrated twice from its start is
/// `m (x - x0 - v0 t) + c ∫(x - x0) + K ∫∫(x - x0) + e t^2 / 2 = ∫∫(F - K' x - F0)`:
/// `F` the magnet's pull read from the current and the measured circuit
/// ([`fit_spring`](super::fit_spring)'s), `K'` and `F0` the spring's fit, `K` what that
/// fit missed, `e` the force's error at the start. Both sides are integrals of the
/// readings, whose noise they average out. `m`, `c` and `K` are common to the moves; each
/// move has its own start `x0` and velocity `v0` (a loop that limit-cycles about a hold
/// starts no move at rest) and `e`; all by least squares, each move up to where it has
/// settled ([`SETTLED_SHARE`]: later readings carry the force's error at the end, which
/// only grows in the double integral).
///
/// The board's capture averages over its ticks, the current as its root mean square: a
/// sliding-mode current that alternates from tick to tick would, sampled, integrate to a
/// pull off by its ripple, and its mean would miss the ripple's share of the pull.
///
/// The fit's uncertainty is its scatter over the moves, by the jackknife: the fit again
/// with each move left out in turn, `var = (n - 1) / n sum (theta_k - mean)^2`. The
/// residuals of a double integral are correlated along a move, so the normal equations'
/// own covariance, which takes them as independent, would read the error many times too
/// small; the moves are independent of one another (each its own start, speed and force
/// error), so their scatter is what the fit's error is made of.
#[must_use]
#[expect(clippy::cast_precision_loss)]
pub fn fit_armature(
    report: &Report,
    circuit: Circuit,
    spring: &Spring,
    holds: &Holds,
) -> Option<Armature> {
    let stroke_m = circuit.stroke_m;
    let force = pull(report, circuit);
    let near_stop = |x: f64| x < STOP_SHARE * stroke_m || x > (1.0 - STOP_SHARE) * stroke_m;
    let usable: Vec<usize> = (1..holds.moves.len())
        .filter(|&k| {
            !holds.moves[k]
                .iter()
                .any(|&(y, i)| near_stop(force(y, i).0))
        })
        .collect();
    let moves = usable.len();
    if moves == 0 {
        return None;
    }
    let dt = holds.move_dt_s;
    // Each move's rows: the three common unknowns m, c, K, then its own x0, v0, e.
    let mut blocks: Vec<Vec<([f64; 6], f64)>> = Vec::new();
    for &k in &usable {
        let seg = &holds.moves[k];
        let (x0, x1) = (spring.holds.get(k - 1)?.0, spring.holds.get(k)?.0);
        let settled = seg
            .iter()
            .rposition(|&(y, i)| (force(y, i).0 - x1).abs() > SETTLED_SHARE * (x1 - x0).abs())
            .unwrap_or(0);
        // Trapezoidal integrals from the move's start.
        let (mut f1, mut f2, mut j1, mut j2) = (0.0, 0.0, 0.0, 0.0);
        let mut last: Option<(f64, f64)> = None;
        let mut block = Vec::new();
        for (n, &(y, i)) in seg.iter().take(settled + 1).enumerate() {
            let (x, f) = force(y, i);
            let net = f - spring.n_per_m * x - spring.preload_n;
            let dx = x - x0;
            if let Some((net0, dx0)) = last {
                let f1_next = f1 + 0.5 * dt * (net0 + net);
                f2 += 0.5 * dt * (f1 + f1_next);
                f1 = f1_next;
                let j1_next = j1 + 0.5 * dt * (dx0 + dx);
                j2 += 0.5 * dt * (j1 + j1_next);
                j1 = j1_next;
            }
            last = Some((net, dx));
            let t = n as f64 * dt;
            block.push(([dx, j1, j2, 1.0, t, 0.5 * t * t], f2));
        }
        blocks.push(block);
    }
    let theta = fit_moves(&blocks.iter().collect::<Vec<_>>())?;
    if theta[0].is_nan() || theta[0] <= 0.0 {
        return None;
    }
    // The jackknife over the moves: NaN where a move left out leaves nothing to fit.
    let (mass_uncertainty_kg, friction_uncertainty_n_s_per_m) = if moves < 2 {
        (f64::NAN, f64::NAN)
    } else {
        let leave_one_out: Vec<[f64; 2]> = (0..moves)
            .map(|out| {
                let rest: Vec<_> = (0..moves)
                    .filter(|&k| k != out)
                    .map(|k| &blocks[k])
                    .collect();
                fit_moves(&rest).map_or([f64::NAN; 2], |t| [t[0], t[1]])
            })
            .collect();
        let n = moves as f64;
        let uncertainty = |p: usize| {
            let mean = leave_one_out.iter().map(|t| t[p]).sum::<f64>() / n;
            let var = (n - 1.0) / n
                * leave_one_out
                    .iter()
                    .map(|t| (t[p] - mean).powi(2))
                    .sum::<f64>();
            2.0 * var.sqrt()
        };
        (uncertainty(0), uncertainty(1))
    };
    Some(Armature {
        mass_kg: theta[0],
        friction_n_s_per_m: theta[1],
        stiffness_n_per_m: theta[2],
        mass_uncertainty_kg,
        friction_uncertainty_n_s_per_m,
        moves,
    })
}

/// The least squares fit of [`fit_armature`]'s equation to the moves' `blocks` (each
/// row the common unknowns' three coefficients and the move's own three, and the
/// right-hand side): `m`, `c`, `K`, then each move's `x0`, `v0` and `e`.
fn fit_moves(blocks: &[&Vec<([f64; 6], f64)>]) -> Option<Vec<f64>> {
    let unknowns = 3 + 3 * blocks.len();
    let rows: Vec<(Vec<f64>, f64)> = blocks
        .iter()
        .enumerate()
        .flat_map(|(u, block)| {
            block.iter().map(move |(c, y)| {
                let mut r = vec![0.0; unknowns];
                r[..3].copy_from_slice(&c[..3]);
                r[3 + 3 * u..6 + 3 * u].copy_from_slice(&c[3..]);
                (r, *y)
            })
        })
        .collect();
    least_squares(&rows, unknowns)
}

/// Least squares `theta` of `y = r . theta` over `rows`, by the normal equations with the
/// columns scaled to unit norm, solved by Gauss-Jordan elimination with partial pivoting;
/// `None` when they are singular.
pub(super) fn least_squares(rows: &[(Vec<f64>, f64)], unknowns: usize) -> Option<Vec<f64>> {
    let scale: Vec<f64> = (0..unknowns)
        .map(|c| rows.iter().map(|(r, _)| r[c] * r[c]).sum::<f64>().sqrt())
        .collect();
    if scale.iter().any(|s| s.is_nan() || *s <= 0.0) {
        return None;
    }
    // The normal equations, each row with its right-hand side last.
    let mut a: Vec<Vec<f64>> = (0..unknowns)
        .map(|p| {
            let mut row: Vec<f64> = (0..unknowns)
                .map(|q| rows.iter().map(|(r, _)| r[p] * r[q]).sum::<f64>() / (scale[p] * scale[q]))
                .collect();
            row.push(rows.iter().map(|(r, y)| r[p] * y).sum::<f64>() / scale[p]);
            row
        })
        .collect();
    for c in 0..unknowns {
        let pivot = (c..unknowns).max_by(|&p, &q| a[p][c].abs().total_cmp(&a[q][c].abs()))?;
        a.swap(c, pivot);
        let lead = a[c].clone();
        if lead[c].is_nan() || lead[c].abs() <= 1e-12 {
            return None;
        }
        for (p, row) in a.iter_mut().enumerate() {
            if p != c {
                let f = row[c] / lead[c];
                for (v, l) in row.iter_mut().zip(&lead).skip(c) {
                    *v -= f * l;
                }
            }
        }
    }
    Some(
        a.iter()
            .zip(&scale)
            .enumerate()
            .map(|(c, (row, s))| row[unknowns] / row[c] / s)
            .collect(),
    )
}
