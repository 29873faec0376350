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
    // m, c, K; then x0, v0 and e of each move.
    let unknowns = 3 + 3 * moves;
    let dt = holds.move_dt_s;
    let mut rows: Vec<(Vec<f64>, f64)> = Vec::new();
    for (u, &k) in usable.iter().enumerate() {
        let seg = &holds.moves[k];
        let (x0, x1) = (spring.holds.get(k - 1)?.0, spring.holds.get(k)?.0);
        let settled = seg
            .iter()
            .rposition(|&(y, i)| (force(y, i).0 - x1).abs() > SETTLED_SHARE * (x1 - x0).abs())
            .unwrap_or(0);
        // Trapezoidal integrals from the move's start.
        let (mut f1, mut f2, mut j1, mut j2) = (0.0, 0.0, 0.0, 0.0);
        let mut last: Option<(f64, f64)> = None;
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
            let mut r = vec![0.0; unknowns];
            r[0] = dx;
            r[1] = j1;
            r[2] = j2;
            r[3 + 3 * u] = 1.0;
            r[4 + 3 * u] = t;
            r[5 + 3 * u] = 0.5 * t * t;
            rows.push((r, f2));
        }
    }
    let theta = least_squares(&rows, unknowns)?;
    if theta[0].is_nan() || theta[0] <= 0.0 {
        return None;
    }
    Some(Armature {
        mass_kg: theta[0],
        friction_n_s_per_m: theta[1],
        stiffness_n_per_m: theta[2],
        moves,
    })
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
