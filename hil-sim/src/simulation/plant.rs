//! The true actuator, in `f64`: mechanics, coil, magnetic circuit with flux fringing, end
//! stops and (optionally) iron saturation, plus a fixed-step RK4 integrator.
//!
//! # Model
//!
//! Position `x` \[m\], velocity `v` \[m/s\], coil current `i` \[A\], coil voltage `u` \[V\].
//! Every airgap `k` has its own surface model `S_k(g)` ([`Surface`]):
//!
//! ```text
//! rho_gap(g) = g * rho_x(g),  rho_x(g) = sum_k 1 / (mu0 S_k(g))     airgap reluctance   [1/H]
//! rho(g)     = rho_gap(g) + rho_0                                    total reluctance    [1/H]
//! L(g)       = N^2 / rho(g)                                          inductance          [H]
//! mu_frozen(g) = N^2 rho_x(g) / rho(g)^2                 paper: S frozen when differentiating
//! mu_energy(g) = -dL/dg = N^2 rho_gap'(g) / rho(g)^2,   rho_gap'(g) = sum_k (S_k - g S_k') / (mu0 S_k^2)
//! ```
//!
//! Two position conventions ([`Convention`]), as in the core:
//!
//! * `paper` (as printed): `x` is the airgap, `g = x`; the magnetic force `+mu i^2 / 2` acts
//!   along `+x` (it opens the gap, which a reluctance force does not do in reality);
//!   `i' = (u - R i + v i mu) / L`.
//! * `physical`: `x` is the stroke from the spring's rest position, `g = g0 - x`; the force
//!   `+mu i^2 / 2` acts along `+x` and closes the gap; `i' = (u - R i - v i mu) / L`.
//!
//! In both, `m v' = F_mag - K x - F0 - lambda v` (`F0` the spring's preload, its force
//! at `x = 0`).
//!
//! Two force models ([`ForceModel`]):
//!
//! * `frozen` (the paper): the electrical state is the current `i`, the force coefficient is
//!   `mu_frozen` in the force and in the back-EMF, exactly the printed equations.
//! * `energy_consistent`: the electrical state is the flux linkage `psi` \[Wb\],
//!   `psi' = u - R i`, `i = psi / L(g)`, force `mu_energy i^2 / 2` (in the `physical`
//!   convention this is `-dW/dg` at constant flux, so energy is conserved; in the `paper`
//!   convention the printed direction is kept and only the magnitude changes). With a
//!   constant surface both models coincide.
//!
//! # Iron saturation (optional, the paper's future work)
//!
//! Only with the `energy_consistent` model (flux is the state, so the current stays
//! explicit). The flux per turn is `phi = psi / N`, the iron flux density `B = phi / A_fe`,
//! and the iron-path reluctance rises with `|B|` from `rho_0` towards `rho_0 + rho_sat`
//! (iron at `mu_r -> 1`):
//!
//! ```text
//! b = |B| / B_sat
//! rho_fe(B) = rho_0 + rho_sat * b^p / (1 + b^p)
//! i = phi * (rho_gap(g) + rho_fe(B)) / N                     (monotone in phi)
//! F = phi^2 rho_gap'(g) / 2        (along +x; does not depend on rho_fe)
//! ```
//!
//! [`Saturation`] holds `A_fe`, `B_sat`, `p` and `rho_sat`. The force follows from the
//! magnetic energy `W(psi, g) = phi^2 rho_gap(g) / 2 + int phi rho_fe(phi) dphi`, whose
//! second term does not depend on the gap.
//!
//! # End stops
//!
//! The armature stays in `0 <= x <= stroke`. At a stop the contact force cancels any
//! acceleration into the stop (no penetration); after every integration substep a position
//! past a stop is put back on it and a velocity into the stop is zeroed. That velocity is
//! recorded as the impact (landing) speed; it is the velocity at the end of the substep in
//! which the contact happened, so its error is of the order of one substep of acceleration.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use crate::simulation::Error;

/// Permeability of free space `4 pi 1e-7` \[H/m\].
pub const MU0_H_PER_M: f64 = 4.0e-7 * PI;

/// The airgap surface seen by the flux, as a function of the gap (paper, section II-B).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Surface {
    /// Constant surface (fringing coefficient times pole face) \[m^2\].
    Constant {
        /// Surface `S` \[m^2\].
        s_m2: f64,
    },
    /// Rectangular pole `a x b` with fringing: `S(g) = (a + k g)(b + k g)` (paper: `k = 1`).
    Rectangular {
        /// Pole side `a` \[m\].
        a_m: f64,
        /// Pole side `b` \[m\].
        b_m: f64,
        /// Fringing spread: growth of each side per metre of gap, `k` \[-\].
        spread: f64,
    },
}

impl Surface {
    /// `S(g)` \[m^2\].
    #[inline]
    #[must_use]
    pub fn area_m2(&self, g_m: f64) -> f64 {
        match *self {
            Surface::Constant { s_m2 } => s_m2,
            Surface::Rectangular { a_m, b_m, spread } => {
                (a_m + spread * g_m) * (b_m + spread * g_m)
            }
        }
    }

    /// `dS/dg` \[m^2/m\].
    #[inline]
    #[must_use]
    pub fn slope_m(&self, g_m: f64) -> f64 {
        match *self {
            Surface::Constant { .. } => 0.0,
            Surface::Rectangular { a_m, b_m, spread } => {
                spread * (a_m + spread * g_m) + spread * (b_m + spread * g_m)
            }
        }
    }

    fn validate(&self, k: usize) -> Result<(), Error> {
        let name = |f: &str| format!("plant.gaps[{k}].{f}");
        match *self {
            Surface::Constant { s_m2 } => positive(&name("s_m2"), s_m2),
            Surface::Rectangular { a_m, b_m, spread } => {
                positive(&name("a_m"), a_m)?;
                positive(&name("b_m"), b_m)?;
                non_negative(&name("spread"), spread)
            }
        }
    }
}

/// Which force coefficient the true plant uses (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForceModel {
    /// The paper: surface frozen when differentiating, current is the electrical state.
    #[default]
    Frozen,
    /// `mu = -dL/dg` including `dS/dg`, flux linkage is the electrical state.
    EnergyConsistent,
}

/// What the position coordinate means (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Convention {
    /// As printed: `x` is the airgap, the force acts along `+x` (opens the gap).
    #[default]
    Paper,
    /// `x` is the stroke, the airgap is `gap_at_zero_m - x`, the force closes the gap.
    Physical {
        /// Airgap at `x = 0` \[m\].
        gap_at_zero_m: f64,
    },
}

impl Convention {
    /// Airgap \[m\] at position `x_m` (never negative).
    #[inline]
    #[must_use]
    pub fn gap_m(&self, x_m: f64) -> f64 {
        match *self {
            Convention::Paper => x_m,
            Convention::Physical { gap_at_zero_m } => gap_at_zero_m - x_m,
        }
        .max(0.0)
    }

    /// `dg/dx`: `+1` (paper) or `-1` (physical).
    #[must_use]
    pub const fn gap_per_position(&self) -> f64 {
        match self {
            Convention::Paper => 1.0,
            Convention::Physical { .. } => -1.0,
        }
    }

    /// The core's convention with the same meaning.
    #[must_use]
    #[expect(clippy::cast_possible_truncation)]
    pub fn to_core(&self) -> ema::control::model::Convention {
        match *self {
            Convention::Paper => ema::control::model::Convention::Paper,
            Convention::Physical { gap_at_zero_m } => ema::control::model::Convention::Physical {
                gap_at_zero_m: gap_at_zero_m as f32,
            },
        }
    }

    /// The same convention as the core's.
    #[must_use]
    pub fn from_core(c: &ema::control::model::Convention) -> Self {
        match *c {
            ema::control::model::Convention::Paper => Convention::Paper,
            ema::control::model::Convention::Physical { gap_at_zero_m } => Convention::Physical {
                gap_at_zero_m: f64::from(gap_at_zero_m),
            },
        }
    }
}

/// Iron saturation (see the module documentation for the equations).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Saturation {
    /// Iron cross-section `A_fe` the flux density is taken over \[m^2\].
    pub area_m2: f64,
    /// Flux density `B_sat` at which half of `rho_sat` is added \[T\].
    pub b_sat_t: f64,
    /// Steepness `p` of the knee \[-\].
    pub exponent: f64,
    /// Reluctance added in full saturation `rho_sat` (the iron path at `mu_r = 1`,
    /// `l_fe / (mu0 A_fe)`) \[1/H\].
    pub rho_sat_per_h: f64,
}

impl Saturation {
    /// A plausible electrical-steel knee for the default actuator: the 7 mm x 7 mm pole
    /// (`A_fe = 49 mm^2`), `B_sat = 1.5 T`, `p = 10`, and a 100 mm iron path
    /// (`rho_sat = 0.1 / (mu0 49e-6) = 1.62e9 1/H`). At the paper's start-up peak (21 A at
    /// 1 mm) the flux is 19 % below the linear `L i` (`B` = 0.87 T instead of 1.07 T): the
    /// iron then adds 6.6e6 1/H to the 2.8e7 1/H of the airgaps.
    #[must_use]
    pub fn typical() -> Self {
        let area_m2 = 49.0e-6;
        Self {
            area_m2,
            b_sat_t: 1.5,
            exponent: 10.0,
            rho_sat_per_h: 0.1 / (MU0_H_PER_M * area_m2),
        }
    }

    /// Iron-path reluctance at flux per turn `phi_wb` \[1/H\] (without `rho_0`).
    #[inline]
    #[must_use]
    pub fn added_reluctance_per_h(&self, phi_wb: f64) -> f64 {
        let b = (phi_wb / self.area_m2).abs() / self.b_sat_t;
        let bp = b.powf(self.exponent);
        self.rho_sat_per_h * bp / (1.0 + bp)
    }

    fn validate(&self) -> Result<(), Error> {
        positive("plant.saturation.area_m2", self.area_m2)?;
        positive("plant.saturation.b_sat_t", self.b_sat_t)?;
        positive("plant.saturation.exponent", self.exponent)?;
        non_negative("plant.saturation.rho_sat_per_h", self.rho_sat_per_h)
    }
}

/// Parameters of the true actuator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Moving mass `m` \[kg\].
    pub mass_kg: f64,
    /// Spring constant `K` \[N/m\].
    pub spring_n_per_m: f64,
    /// Spring force at `x = 0`, `F0` \[N\] (0 when left out of a file).
    #[serde(default)]
    pub preload_n: f64,
    /// Viscous friction `lambda` \[N s/m\].
    pub friction_n_s_per_m: f64,
    /// Coil resistance `R` \[ohm\].
    pub resistance_ohm: f64,
    /// Coil turns `N` \[-\].
    pub turns: f64,
    /// Iron-path reluctance `rho_0` \[1/H\].
    pub rho0_per_h: f64,
    /// The airgaps in series, one surface model each.
    pub gaps: Vec<Surface>,
    /// Force model (`frozen` when left out of a file).
    #[serde(default)]
    pub force: ForceModel,
    /// Position convention (`paper` when left out of a file).
    #[serde(default)]
    pub convention: Convention,
    /// Stroke: end stops at `0` and `stroke_m` \[m\].
    pub stroke_m: f64,
    /// Iron saturation, if modelled (needs `force = energy_consistent`).
    #[serde(default)]
    pub saturation: Option<Saturation>,
}

/// Side of the default square pole \[m\].
pub const PAPER_POLE_SIDE_M: f64 = 7.0e-3;
/// Fringing coefficient of the default geometry \[-\].
pub const PAPER_FRINGING_COEFFICIENT: f64 = 1.16;

impl Params {
    /// The paper's actuator (Table I) with the core's default geometry
    /// (`ema::control::model::Plant::paper()`): two equal gaps of constant surface
    /// `1.16 x 49 mm^2`, so `rho_x = 2 / (mu0 56.84 mm^2) = 2.8e10 1/(H m)`,
    /// `rho_0 = 630 1/H`, `N = 70`, `m = 0.1 kg`, `K = 120 N/m`, `lambda = 5 N s/m`,
    /// `R = 0.4 ohm`, 4 mm stroke, `paper` convention, `frozen` force, no saturation.
    #[must_use]
    pub fn paper() -> Self {
        let s = Surface::Constant {
            s_m2: PAPER_FRINGING_COEFFICIENT * PAPER_POLE_SIDE_M * PAPER_POLE_SIDE_M,
        };
        Self {
            mass_kg: 0.1,
            spring_n_per_m: 120.0,
            preload_n: 0.0,
            friction_n_s_per_m: 5.0,
            resistance_ohm: 0.4,
            turns: 70.0,
            rho0_per_h: 630.0,
            gaps: vec![s, s],
            force: ForceModel::Frozen,
            convention: Convention::Paper,
            stroke_m: 4.0e-3,
            saturation: None,
        }
    }

    /// Whether an airgap's surface grows with the gap (a pole whose sides spread): a real
    /// magnet of such a plant pulls with its growth included
    /// ([`ForceModel::EnergyConsistent`]); the frozen-surface force leaves it out.
    #[must_use]
    pub fn surface_grows(&self) -> bool {
        self.gaps
            .iter()
            .any(|s| matches!(s, Surface::Rectangular { spread, .. } if *spread > 0.0))
    }

    /// The nominal actuator a controller configuration describes (its `f32` values widened
    /// to `f64`), with the given force model. `gaps` equal airgaps of the core's surface
    /// model.
    #[must_use]
    pub fn from_core(plant: &ema::control::model::Plant, force: ForceModel) -> Self {
        use ema::control::model::Fringing;
        let m = &plant.magnetics;
        let surface = match m.fringing {
            Fringing::Coefficient { alpha, pole_m2 } => Surface::Constant {
                s_m2: f64::from(alpha) * f64::from(pole_m2),
            },
            Fringing::Rectangular { a_m, b_m, spread } => Surface::Rectangular {
                a_m: f64::from(a_m),
                b_m: f64::from(b_m),
                spread: f64::from(spread),
            },
        };
        // A gap count is a small positive integer stored as f32 in the core.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = f64::from(m.gaps).round().max(1.0) as usize;
        Self {
            mass_kg: f64::from(plant.mass_kg),
            spring_n_per_m: f64::from(plant.spring_n_per_m),
            preload_n: f64::from(plant.preload_n),
            friction_n_s_per_m: f64::from(plant.friction_n_s_per_m),
            resistance_ohm: f64::from(plant.resistance_ohm),
            turns: f64::from(m.turns),
            rho0_per_h: f64::from(m.rho0_per_h),
            gaps: vec![surface; n],
            force,
            convention: Convention::from_core(&plant.convention),
            stroke_m: f64::from(plant.stroke_m),
            saturation: None,
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// The first bad parameter, by name, with its value.
    pub fn validate(&self) -> Result<(), Error> {
        positive("plant.mass_kg", self.mass_kg)?;
        non_negative("plant.spring_n_per_m", self.spring_n_per_m)?;
        non_negative("plant.preload_n", self.preload_n)?;
        non_negative("plant.friction_n_s_per_m", self.friction_n_s_per_m)?;
        positive("plant.resistance_ohm", self.resistance_ohm)?;
        positive("plant.turns", self.turns)?;
        positive("plant.rho0_per_h", self.rho0_per_h)?;
        positive("plant.stroke_m", self.stroke_m)?;
        if self.gaps.is_empty() {
            return Err(Error::param("plant.gaps", 0.0, "needs at least one airgap"));
        }
        for (k, s) in self.gaps.iter().enumerate() {
            s.validate(k)?;
            // Positive surface over the whole stroke.
            let (g0, g1) = self.gap_range_m();
            for g in [g0, g1] {
                if s.area_m2(g).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    return Err(Error::param(
                        format!("plant.gaps[{k}]"),
                        s.area_m2(g),
                        "surface must stay positive over the stroke",
                    ));
                }
            }
        }
        if let Convention::Physical { gap_at_zero_m } = self.convention {
            if !(gap_at_zero_m.is_finite() && gap_at_zero_m > self.stroke_m) {
                return Err(Error::param(
                    "plant.convention.gap_at_zero_m",
                    gap_at_zero_m,
                    "must exceed plant.stroke_m (residual gap at full stroke)",
                ));
            }
        }
        if let Some(sat) = &self.saturation {
            sat.validate()?;
            if self.force != ForceModel::EnergyConsistent {
                return Err(Error::param(
                    "plant.saturation",
                    f64::NAN,
                    "needs force = \"energy_consistent\" (flux linkage as the state)",
                ));
            }
        }
        Ok(())
    }

    /// Airgap \[m\] at position `x_m`.
    #[inline]
    #[must_use]
    pub fn gap_m(&self, x_m: f64) -> f64 {
        self.convention.gap_m(x_m)
    }

    /// Every airgap's surface `scale` times what it is (flux fringing off the model): a
    /// constant surface scaled, a rectangular pole's sides by `sqrt(scale)`.
    pub fn scale_surfaces(&mut self, scale: f64) {
        let side = scale.sqrt();
        for s in &mut self.gaps {
            match s {
                Surface::Constant { s_m2 } => *s_m2 *= scale,
                Surface::Rectangular { a_m, b_m, .. } => {
                    *a_m *= side;
                    *b_m *= side;
                }
            }
        }
    }

    /// `(min, max)` airgap over the stroke \[m\].
    #[must_use]
    pub fn gap_range_m(&self) -> (f64, f64) {
        let a = self.gap_m(0.0);
        let b = self.gap_m(self.stroke_m);
        (a.min(b), a.max(b))
    }

    /// `rho_x(g) = sum 1 / (mu0 S_k(g))` \[1/(H m)\].
    #[must_use]
    pub fn rho_x_per_h_m(&self, g_m: f64) -> f64 {
        self.gaps
            .iter()
            .map(|s| 1.0 / (MU0_H_PER_M * s.area_m2(g_m)))
            .sum()
    }

    /// `(rho_gap(g), rho_gap'(g), rho_x(g))` \[1/H, 1/(H m), 1/(H m)\].
    #[inline]
    fn gap_reluctance(&self, g_m: f64) -> (f64, f64, f64) {
        let mut rho_x = 0.0;
        let mut d_rho = 0.0;
        for s in &self.gaps {
            let a = s.area_m2(g_m);
            let inv = 1.0 / (MU0_H_PER_M * a);
            rho_x += inv;
            d_rho += inv * (1.0 - g_m * s.slope_m(g_m) / a);
        }
        (g_m * rho_x, d_rho, rho_x)
    }

    /// Total reluctance `rho(g)` without saturation \[1/H\].
    #[must_use]
    pub fn reluctance_per_h(&self, g_m: f64) -> f64 {
        self.gap_reluctance(g_m).0 + self.rho0_per_h
    }

    /// Small-signal (unsaturated) inductance `L(g) = N^2 / rho(g)` \[H\].
    #[must_use]
    pub fn inductance_h(&self, g_m: f64) -> f64 {
        self.turns * self.turns / self.reluctance_per_h(g_m)
    }

    /// The paper's frozen-surface force coefficient `N^2 rho_x(g) / rho(g)^2` \[H/m\].
    #[must_use]
    pub fn mu_frozen_h_per_m(&self, g_m: f64) -> f64 {
        let (rg, _, rho_x) = self.gap_reluctance(g_m);
        let rho = rg + self.rho0_per_h;
        self.turns * self.turns * rho_x / (rho * rho)
    }

    /// The energy-consistent force coefficient `-dL/dg` \[H/m\].
    #[must_use]
    pub fn mu_energy_h_per_m(&self, g_m: f64) -> f64 {
        let (rg, d_rho, _) = self.gap_reluctance(g_m);
        let rho = rg + self.rho0_per_h;
        self.turns * self.turns * d_rho / (rho * rho)
    }

    /// The force coefficient of this plant's force model (unsaturated) \[H/m\]: the `mu` a
    /// controller's bounds must bracket.
    #[must_use]
    pub fn mu_h_per_m(&self, g_m: f64) -> f64 {
        match self.force {
            ForceModel::Frozen => self.mu_frozen_h_per_m(g_m),
            ForceModel::EnergyConsistent => self.mu_energy_h_per_m(g_m),
        }
    }

    /// The spring's pull toward `-x` at `x_m`, `K x + F0` \[N\].
    #[inline]
    #[must_use]
    pub fn spring_force_n(&self, x_m: f64) -> f64 {
        self.spring_n_per_m * x_m + self.preload_n
    }

    /// Current \[A\] that holds `x_m` against the spring, unsaturated:
    /// `sqrt(2 (K x + F0) / mu)` (0 where the spring needs no magnetic force).
    #[must_use]
    pub fn holding_current_a(&self, x_m: f64) -> f64 {
        let f = self.spring_force_n(x_m);
        if f <= 0.0 {
            0.0
        } else {
            (2.0 * f / self.mu_h_per_m(self.gap_m(x_m))).sqrt()
        }
    }

    /// The integration state for position, velocity and current (the flux linkage is
    /// computed from the current for the energy-consistent model, by bisection when the
    /// iron saturates).
    #[must_use]
    pub fn state(&self, x_m: f64, v_mps: f64, i_a: f64) -> State {
        let e = match self.force {
            ForceModel::Frozen => i_a,
            ForceModel::EnergyConsistent => self.flux_linkage_wb(self.gap_m(x_m), i_a),
        };
        State {
            y: [x_m.clamp(0.0, self.stroke_m), v_mps, e, 0.0, 0.0, 0.0],
        }
    }

    /// Flux linkage `psi` \[Wb\] at gap `g_m` and current `i_a` (inverts
    /// `i(psi)`; exact without saturation).
    fn flux_linkage_wb(&self, g_m: f64, i_a: f64) -> f64 {
        let lin = self.inductance_h(g_m) * i_a;
        if self.saturation.is_none() || i_a == 0.0 {
            return lin;
        }
        // i(psi) is odd and increasing, and |i(lin)| >= |i_a|: bisect on [0, lin].
        let (mut lo, mut hi) = (0.0_f64, lin);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if (self.current_from_flux(g_m, mid) - i_a) * i_a.signum() < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Coil current \[A\] from the flux linkage at gap `g_m`.
    #[inline]
    fn current_from_flux(&self, g_m: f64, psi_wb: f64) -> f64 {
        let n = self.turns;
        let phi = psi_wb / n;
        let iron = self.rho0_per_h
            + self
                .saturation
                .as_ref()
                .map_or(0.0, |s| s.added_reluctance_per_h(phi));
        let (rg, _, _) = self.gap_reluctance(g_m);
        phi * (rg + iron) / n
    }

    /// Coil current \[A\] in state `s`.
    #[inline]
    #[must_use]
    pub fn current_a(&self, s: &State) -> f64 {
        match self.force {
            ForceModel::Frozen => s.y[2],
            ForceModel::EnergyConsistent => self.current_from_flux(self.gap_m(s.y[0]), s.y[2]),
        }
    }

    /// Flux linkage \[Wb\] in state `s` (`L(g) i` for the frozen model).
    #[must_use]
    pub fn flux_linkage_of(&self, s: &State) -> f64 {
        match self.force {
            ForceModel::Frozen => self.inductance_h(self.gap_m(s.y[0])) * s.y[2],
            ForceModel::EnergyConsistent => s.y[2],
        }
    }

    /// Magnetic force along `+x` \[N\] and coil current \[A\] at position `x_m` with
    /// electrical state `e`; also `di/dt` terms for the frozen model: returns
    /// `(force_n, i_a, l_h, mu_h_per_m)`.
    #[inline]
    fn electromagnetics(&self, x_m: f64, e: f64) -> (f64, f64, f64, f64) {
        let g = self.gap_m(x_m);
        let (rg, d_rho, rho_x) = self.gap_reluctance(g);
        let n2 = self.turns * self.turns;
        match self.force {
            ForceModel::Frozen => {
                let rho = rg + self.rho0_per_h;
                let mu = n2 * rho_x / (rho * rho);
                let l = n2 / rho;
                (0.5 * e * e * mu, e, l, mu)
            }
            ForceModel::EnergyConsistent => {
                let phi = e / self.turns;
                let iron = self.rho0_per_h
                    + self
                        .saturation
                        .as_ref()
                        .map_or(0.0, |s| s.added_reluctance_per_h(phi));
                let i = phi * (rg + iron) / self.turns;
                (0.5 * phi * phi * d_rho, i, 0.0, 0.0)
            }
        }
    }

    /// Time derivative of the state under the electrical input `input`.
    #[inline]
    fn derivative(&self, y: &[f64; 6], input: &Input) -> [f64; 6] {
        let (x, v, e) = (y[0], y[1], y[2]);
        let (force, i, l, mu) = self.electromagnetics(x, e);
        let mut a = (force - self.spring_force_n(x) - self.friction_n_s_per_m * v) / self.mass_kg;
        // Contact: a stop cancels any acceleration into it.
        if x <= 0.0 && v <= 0.0 {
            a = a.max(0.0);
        } else if x >= self.stroke_m && v >= 0.0 {
            a = a.min(0.0);
        }
        let u = input.u0_v - input.r_ohm * i;
        let de = match self.force {
            ForceModel::Frozen => {
                // dg/dt = (dg/dx) v; back-EMF i dL/dt = -i mu dg/dt.
                let gdot = self.convention.gap_per_position() * v;
                (u - self.resistance_ohm * i + gdot * i * mu) / l
            }
            ForceModel::EnergyConsistent => u - self.resistance_ohm * i,
        };
        [v, a, de, input.vs_v * input.bus_gain * i, u, u * u]
    }

    /// One fixed RK4 step of `y` over `h_s` under `input`.
    #[inline]
    fn rk4(&self, y: &[f64; 6], input: &Input, h_s: f64) -> [f64; 6] {
        let k1 = self.derivative(y, input);
        let k2 = self.derivative(&axpy(y, 0.5 * h_s, &k1), input);
        let k3 = self.derivative(&axpy(y, 0.5 * h_s, &k2), input);
        let k4 = self.derivative(&axpy(y, h_s, &k3), input);
        let mut next = [0.0; 6];
        for (j, n) in next.iter_mut().enumerate() {
            *n = y[j] + h_s / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
        }
        next
    }

    /// One fixed RK4 step of `h_s` under `input`, then the end stops. When the coil
    /// freewheels (`input.freewheel`) and the current would cross zero inside the step, the
    /// crossing is located (bisection on the RK4 map, to 1e-12 of the step), the step is
    /// taken up to it, the current set to exactly 0 and the rest of the step taken with the
    /// coil open: the diodes block, so the current stays at 0 without chatter and the
    /// energy and voltage integrals stop at the crossing. Returns an impact, if the step
    /// ended one.
    pub(crate) fn step(&self, s: &mut State, input: &Input, h_s: f64) -> Option<Impact> {
        let e0 = s.y[2];
        let mut next = self.rk4(&s.y, input, h_s);
        if input.freewheel && e0 != 0.0 && next[2].signum() != e0.signum() {
            let (mut lo, mut hi) = (0.0, h_s);
            while hi - lo > 1e-12 * h_s {
                let mid = 0.5 * (lo + hi);
                if self.rk4(&s.y, input, mid)[2].signum() == e0.signum() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let mut at_zero = self.rk4(&s.y, input, hi);
            at_zero[2] = 0.0;
            let open = Input {
                vs_v: input.vs_v,
                ..Input::default()
            };
            next = self.rk4(&at_zero, &open, h_s - hi);
            next[2] = 0.0;
        }
        let mut impact = None;
        if next[0] < 0.0 {
            next[0] = 0.0;
            if next[1] < 0.0 {
                impact = Some(Impact {
                    at_stroke_end: false,
                    speed_mps: -next[1],
                });
                next[1] = 0.0;
            }
        } else if next[0] > self.stroke_m {
            next[0] = self.stroke_m;
            if next[1] > 0.0 {
                impact = Some(Impact {
                    at_stroke_end: true,
                    speed_mps: next[1],
                });
                next[1] = 0.0;
            }
        }
        s.y = next;
        impact
    }
}

#[inline]
fn axpy(y: &[f64; 6], h: f64, k: &[f64; 6]) -> [f64; 6] {
    let mut out = *y;
    for (o, d) in out.iter_mut().zip(k) {
        *o += h * d;
    }
    out
}

/// Integration state: position, velocity, electrical state (current for the frozen model,
/// flux linkage for the energy-consistent one) and three running integrals (energy drawn
/// from the source, `int u dt`, `int u^2 dt`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    pub(crate) y: [f64; 6],
}

impl State {
    /// Position \[m\].
    #[must_use]
    pub const fn x_m(&self) -> f64 {
        self.y[0]
    }
    /// Velocity \[m/s\].
    #[must_use]
    pub const fn v_mps(&self) -> f64 {
        self.y[1]
    }
    /// Electrical state: current \[A\] (frozen) or flux linkage \[Wb\] (energy-consistent).
    #[must_use]
    pub const fn electrical(&self) -> f64 {
        self.y[2]
    }
    /// Energy drawn from the supply's source since the start \[J\].
    #[must_use]
    pub const fn energy_j(&self) -> f64 {
        self.y[3]
    }
    /// `int u dt` since the start \[V s\].
    #[must_use]
    pub const fn volt_seconds(&self) -> f64 {
        self.y[4]
    }
    /// `int u^2 dt` since the start \[V^2 s\].
    #[must_use]
    pub const fn volt_sq_seconds(&self) -> f64 {
        self.y[5]
    }
}

/// An armature hitting an end stop.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Impact {
    /// `true` at the stroke end, `false` at `x = 0`.
    pub at_stroke_end: bool,
    /// Speed into the stop just before it was zeroed \[m/s\].
    pub speed_mps: f64,
}

/// The electrical input over one substep, affine in the coil current:
/// `u = u0 - r i` \[V\]; the bus current is `bus_gain i` \[A\] and the source power
/// `vs bus_gain i` \[W\]. `freewheel` marks the diode-conduction state, where the current
/// stops at its zero crossing.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Input {
    /// Voltage at zero current \[V\].
    pub u0_v: f64,
    /// Resistance in series seen by the coil (supply internal resistance, scaled by the
    /// duty) \[ohm\].
    pub r_ohm: f64,
    /// Bus current per coil ampere \[-\].
    pub bus_gain: f64,
    /// Source (open-circuit) supply voltage \[V\].
    pub vs_v: f64,
    /// Diodes conducting (coast with current).
    pub freewheel: bool,
}

impl Input {
    /// Coil voltage \[V\] at current `i_a`.
    #[must_use]
    pub fn coil_voltage_v(&self, i_a: f64) -> f64 {
        self.u0_v - self.r_ohm * i_a
    }
}

pub(crate) fn positive(name: &str, v: f64) -> Result<(), Error> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::param(name, v, "must be finite and positive"))
    }
}

pub(crate) fn non_negative(name: &str, v: f64) -> Result<(), Error> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::param(name, v, "must be finite and not negative"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        ((a - b) / b).abs()
    }

    #[test]
    fn hand_values_of_the_paper_actuator() {
        let p = Params::paper();
        p.validate().unwrap();
        // rho_x = 2 / (mu0 * 1.16 * 49e-6) = 2.8001e10.
        assert!(rel(p.rho_x_per_h_m(0.0), 2.8e10) < 1e-4);
        // L(1 mm) = 4900 / (2.8e7 + 630) = 175.0 uH.
        assert!(
            rel(p.inductance_h(1e-3), 175.0e-6) < 1e-3,
            "{}",
            p.inductance_h(1e-3)
        );
        // mu(3 mm) = 4900 * 2.8e10 / (8.4e7 + 630)^2 = 0.019444.
        assert!(rel(p.mu_frozen_h_per_m(3e-3), 0.019_44) < 1e-3);
        // Equilibrium at 3 mm: K x = mu i^2 / 2 -> i = sqrt(2 * 0.36 / 0.019444) = 6.085 A.
        assert!(
            rel(p.holding_current_a(3e-3), 6.085) < 1e-3,
            "{}",
            p.holding_current_a(3e-3)
        );
    }

    #[test]
    fn matches_the_core_default_plant() {
        let core = ema::control::model::Plant::paper();
        let ours = Params::paper();
        let widened = Params::from_core(&core, ForceModel::Frozen);
        for g in [0.0, 1e-3, 2.5e-3, 4e-3] {
            let c = f64::from(core.magnetics.inductance_h(g as f32));
            assert!(rel(ours.inductance_h(g), c) < 1e-5, "L at {g}");
            assert!(rel(widened.inductance_h(g), c) < 1e-5, "L at {g}");
            let c = f64::from(core.magnetics.force_coefficient_h_per_m(g as f32));
            assert!(rel(ours.mu_frozen_h_per_m(g), c) < 1e-5, "mu at {g}");
        }
        assert_eq!(widened.gaps.len(), 2);
    }

    fn rectangular() -> Params {
        let s = Surface::Rectangular {
            a_m: 7e-3,
            b_m: 6e-3,
            spread: 1.0,
        };
        Params {
            gaps: vec![s, Surface::Constant { s_m2: 60e-6 }],
            force: ForceModel::EnergyConsistent,
            ..Params::paper()
        }
    }

    #[test]
    fn energy_consistent_mu_is_minus_dl_dg() {
        let p = rectangular();
        for g in [0.2e-3, 1e-3, 2e-3, 3.5e-3] {
            let h = 1e-9;
            let dl = (p.inductance_h(g + h) - p.inductance_h(g - h)) / (2.0 * h);
            assert!(rel(p.mu_energy_h_per_m(g), -dl) < 1e-6, "at {g}");
            // With a growing surface the frozen coefficient is larger.
            assert!(p.mu_frozen_h_per_m(g) > p.mu_energy_h_per_m(g));
        }
        // Constant surfaces: both coincide.
        let c = Params::paper();
        assert!(rel(c.mu_energy_h_per_m(2e-3), c.mu_frozen_h_per_m(2e-3)) < 1e-12);
    }

    /// Without a supply the energy-consistent plant conserves energy: mechanical work
    /// done by the magnet equals the magnetic energy released (physical convention, no
    /// resistance loss through a short step with zero voltage and zero resistance).
    #[test]
    fn energy_consistent_force_conserves_energy() {
        let p = Params {
            convention: Convention::Physical {
                gap_at_zero_m: 4.5e-3,
            },
            resistance_ohm: 1e-12,
            friction_n_s_per_m: 0.0,
            spring_n_per_m: 0.0,
            ..rectangular()
        };
        let mut s = p.state(1e-3, 0.0, 10.0);
        let w = |s: &State| {
            let i = p.current_a(s);
            0.5 * s.y[2] * i + 0.5 * p.mass_kg * s.y[1] * s.y[1]
        };
        let w0 = w(&s);
        let input = Input::default();
        for _ in 0..2000 {
            p.step(&mut s, &input, 1e-6);
        }
        assert!(s.x_m() > 1.001e-3, "the magnet pulls along +x");
        assert!(rel(w(&s), w0) < 1e-7, "{} vs {w0}", w(&s));
    }

    #[test]
    fn saturation_lowers_the_current_gain_of_flux() {
        let p = Params {
            force: ForceModel::EnergyConsistent,
            saturation: Some(Saturation::typical()),
            ..Params::paper()
        };
        p.validate().unwrap();
        let g = 1e-3;
        // Small current: essentially linear.
        let s = p.state(g, 0.0, 0.1);
        assert!(rel(p.current_a(&s), 0.1) < 1e-9);
        assert!(rel(s.electrical(), p.inductance_h(g) * 0.1) < 1e-6);
        // 21 A at 1 mm: linear flux L i / N = 5.25e-5 Wb (B = 1.07 T). Self-consistently
        // the flux is 0.809 of that: B = 0.866 T, (0.866/1.5)^10 = 0.0041, the iron adds
        // 1.62e9 * 0.0041 = 6.6e6 1/H to the 2.8e7 of the gap: 2.8e7 / 3.46e7 = 0.809.
        let s = p.state(g, 0.0, 21.0);
        assert!(rel(p.current_a(&s), 21.0) < 1e-9);
        let ratio = s.electrical() / (p.inductance_h(g) * 21.0);
        assert!((ratio - 0.809).abs() < 0.005, "{ratio}");
        // Saturation needs the flux state.
        let bad = Params {
            force: ForceModel::Frozen,
            ..p
        };
        assert_eq!(bad.validate().unwrap_err().name(), "plant.saturation");
    }

    #[test]
    fn end_stops_hold_and_record_the_landing_speed() {
        let p = Params::paper();
        // No current, released at 0.5 mm moving towards 0 at 0.1 m/s.
        let mut s = p.state(0.5e-3, -0.1, 0.0);
        let mut impacts = vec![];
        for _ in 0..20_000 {
            if let Some(i) = p.step(&mut s, &Input::default(), 1e-6) {
                impacts.push(i);
            }
        }
        assert_eq!(s.x_m(), 0.0);
        assert_eq!(s.v_mps(), 0.0);
        assert_eq!(impacts.len(), 1);
        let hit = impacts[0];
        assert!(!hit.at_stroke_end);
        // x'' = -1200 x - 50 x' from (0.5 mm, -0.1 m/s): x = e^(-25 t)(A cos wt + B sin wt)
        // with w = sqrt(575), A = 5e-4, B = (-0.1 + 25 A)/w; x = 0 at w t = atan(-A/B) =
        // 0.13619 (t = 5.679 ms), where the speed is 0.076628 m/s.
        assert!(
            (hit.speed_mps - 0.076_628).abs() < 2e-5,
            "{}",
            hit.speed_mps
        );
    }

    #[test]
    fn freewheeling_current_stops_at_zero_without_chatter() {
        let p = Params::paper();
        let mut s = p.state(2e-3, 0.0, 5.0);
        // Coast against 150 V + 2 x 0.7 V: di/dt = -151.4 / L, about -1.6 A/us at 2 mm.
        for k in 0..100 {
            let i = p.current_a(&s);
            let input = if i == 0.0 {
                Input::default()
            } else {
                Input {
                    u0_v: -i.signum() * 151.4,
                    freewheel: true,
                    bus_gain: -i.signum(),
                    vs_v: 150.0,
                    ..Input::default()
                }
            };
            p.step(&mut s, &input, 0.5e-6);
            if k > 20 {
                assert_eq!(p.current_a(&s), 0.0, "step {k}");
            }
        }
        // Energy went back into the supply.
        assert!(s.energy_j() < 0.0);
    }
}
