//! The actuator model of the paper (section II), in SI units and `f32`.
//!
//! State: `x1` position \[m\], `x2` velocity \[m/s\], `x3` coil current \[A\]; input `u` coil
//! voltage \[V\].
//!
//! ```text
//! rho(g) = rho_x(g) * g + rho_0        total reluctance, g = airgap    [1/H]
//! rho_x(g) = n_gaps / (mu0 * S(g))      airgap reluctance per metre      [1/(H m)]
//! L(g)   = N^2 / rho(g)                 inductance                       [H]
//! mu(g)  = N^2 * rho_x / rho(g)^2       force coefficient, F = mu x3^2/2 [H/m]
//! x1' = x2
//! x2' = (x3^2 mu / 2 - lambda x2 - K x1) / m
//! x3' = (u - R x3 + s_emf x2 x3 mu) / L
//! ```
//!
//! `S(g)` is the airgap surface seen by the flux, larger than the pole face because of flux
//! fringing ([`Fringing`]). The paper treats it as uncertain, `S_lo <= S(g) <= S_hi`
//! ([`Bounds`]), and builds bounds on `rho`, `L` and `mu` from it ([`Envelope`]).
//!
//! Two conventions for what `x1` is ([`Convention`]): `Paper` is the model exactly as
//! printed (`x1` is the airgap and the magnetic force pushes it open, `s_emf = +1`);
//! `Physical` is what a reluctance actuator does (`x1` is the stroke, the airgap is
//! `g0 - x1`, the force closes the gap along `+x1`, `s_emf = -1`). In both, the magnetic
//! force acts along `+x1`, so one law serves both.
//!
//! `mu` here is the paper's "frozen surface" coefficient (`S` taken as a constant when
//! differentiating `L`). With a surface that grows with the gap, the energy-consistent force
//! coefficient is `-dL/dg`, which the simulator models and checks against these bounds.

use crate::control::config::{self, Error, Reason};

/// Permeability of free space \[H/m\] (`4 pi 1e-7`).
pub const MU0_H_PER_M: f32 = 1.256_637_1e-6;

/// What the position coordinate `x1` means.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)
)]
pub enum Convention {
    /// As printed in the paper: `x1` is the airgap, the magnetic force acts along `+x1`
    /// (opening the gap) and the back-EMF term is `+x2 x3 mu`. For reproducing the paper.
    Paper,
    /// Physical reluctance actuator: `x1` is the stroke from the spring's rest position, the
    /// airgap is `gap_at_zero_m - x1`, the force closes the gap (acts along `+x1`) and the
    /// back-EMF term is `-x2 x3 mu`.
    Physical {
        /// Airgap when `x1 = 0` \[m\]; must exceed the stroke (residual gap at full stroke).
        gap_at_zero_m: f32,
    },
}

impl Convention {
    /// The airgap \[m\] at position `x_m`, never negative.
    #[inline]
    #[must_use]
    pub fn gap_m(&self, x_m: f32) -> f32 {
        let g = match *self {
            Convention::Paper => x_m,
            Convention::Physical { gap_at_zero_m } => gap_at_zero_m - x_m,
        };
        crate::control::math::max(g, 0.0)
    }

    /// Sign of the motional back-EMF term in `x3' = (u - R x3 + s x2 x3 mu) / L`.
    #[inline]
    #[must_use]
    pub const fn emf_sign(&self) -> f32 {
        match self {
            Convention::Paper => 1.0,
            Convention::Physical { .. } => -1.0,
        }
    }

    /// The range of airgaps \[m\] covered by positions `0..=stroke_m`, as `(min, max)`.
    #[must_use]
    pub fn gap_range_m(&self, stroke_m: f32) -> (f32, f32) {
        let a = self.gap_m(0.0);
        let b = self.gap_m(stroke_m);
        (a.min(b), a.max(b))
    }
}

/// How the airgap surface `S(g)` seen by the flux depends on the gap (paper, section II-B).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)
)]
pub enum Fringing {
    /// Weighting coefficient: `S = alpha * S_cm`, constant over the stroke.
    Coefficient {
        /// Fringing coefficient `alpha >= 1` \[-\].
        alpha: f32,
        /// Pole-face surface of the magnetic circuit `S_cm` \[m^2\].
        pole_m2: f32,
    },
    /// Rectangular pole `a x b`: `S(g) = (a + k g)(b + k g)`. The paper's formula is `k = 1`;
    /// the paper calls these formulas empirical adjustment variables, so `k` is kept as one.
    Rectangular {
        /// Pole side `a` \[m\].
        a_m: f32,
        /// Pole side `b` \[m\].
        b_m: f32,
        /// Fringing spread: growth of each pole side per metre of gap, `k >= 0` \[-\] (paper: 1).
        spread: f32,
    },
}

impl Fringing {
    /// The airgap surface `S(g)` \[m^2\] at gap `g_m`.
    #[inline]
    #[must_use]
    pub fn surface_m2(&self, g_m: f32) -> f32 {
        match *self {
            Fringing::Coefficient { alpha, pole_m2 } => alpha * pole_m2,
            Fringing::Rectangular { a_m, b_m, spread } => {
                (a_m + spread * g_m) * (b_m + spread * g_m)
            }
        }
    }

    /// `(min, max)` of `S(g)` \[m^2\] over `g` in `[g_lo, g_hi]` (`S` is monotone in `g`).
    #[must_use]
    pub fn surface_range_m2(&self, g_lo: f32, g_hi: f32) -> (f32, f32) {
        let a = self.surface_m2(g_lo);
        let b = self.surface_m2(g_hi);
        (a.min(b), a.max(b))
    }
}

/// The magnetic circuit: coil, iron path and airgaps.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Magnetics {
    /// Coil turns `N` \[-\].
    pub turns: f32,
    /// Reluctance of the iron path `rho_0` \[1/H\].
    pub rho0_per_h: f32,
    /// Number of equal airgaps in series (the paper's circuit has two) \[-\].
    pub gaps: f32,
    /// Airgap surface model.
    pub fringing: Fringing,
}

impl Magnetics {
    /// The documented default geometry, which reproduces the paper's Table I.
    ///
    /// Two equal airgaps in series, a square pole of 7 mm x 7 mm (`S_cm = 49 mm^2`) and a
    /// fringing coefficient `alpha = 1.16`, so `S = 56.84 mm^2` and
    /// `rho_x = 2 / (mu0 S) = 2.8001e10 1/(H m)` (paper: 2.8e10, within 0.003 %);
    /// `rho_0 = 630 1/H`, `N = 70`.
    #[must_use]
    pub const fn paper() -> Self {
        Self {
            turns: 70.0,
            rho0_per_h: 630.0,
            gaps: 2.0,
            fringing: Fringing::Coefficient {
                alpha: 1.16,
                pole_m2: PAPER_POLE_SIDE_M * PAPER_POLE_SIDE_M,
            },
        }
    }

    /// The same circuit with the paper's rectangular-pole fringing, `S(g) = (a + g)(b + g)`
    /// on the 7 mm x 7 mm pole.
    #[must_use]
    pub const fn paper_rectangular() -> Self {
        Self {
            fringing: Fringing::Rectangular {
                a_m: PAPER_POLE_SIDE_M,
                b_m: PAPER_POLE_SIDE_M,
                spread: 1.0,
            },
            ..Self::paper()
        }
    }

    /// `N^2` \[-\].
    #[inline]
    #[must_use]
    pub fn turns_sq(&self) -> f32 {
        self.turns * self.turns
    }

    /// Airgap reluctance per metre of gap `rho_x(g) = n_gaps / (mu0 S(g))` \[1/(H m)\].
    #[inline]
    #[must_use]
    pub fn rho_x_per_h_m(&self, g_m: f32) -> f32 {
        self.gaps / (MU0_H_PER_M * self.fringing.surface_m2(g_m))
    }

    /// Total reluctance `rho(g)` \[1/H\].
    #[inline]
    #[must_use]
    pub fn reluctance_per_h(&self, g_m: f32) -> f32 {
        self.rho_x_per_h_m(g_m) * g_m + self.rho0_per_h
    }

    /// Inductance `L(g) = N^2 / rho(g)` \[H\].
    #[inline]
    #[must_use]
    pub fn inductance_h(&self, g_m: f32) -> f32 {
        self.turns_sq() / self.reluctance_per_h(g_m)
    }

    /// Force coefficient `mu(g) = N^2 rho_x / rho(g)^2` \[H/m\] (paper, surface frozen).
    #[inline]
    #[must_use]
    pub fn force_coefficient_h_per_m(&self, g_m: f32) -> f32 {
        force_coefficient(
            self.turns_sq(),
            self.rho_x_per_h_m(g_m),
            self.rho0_per_h,
            g_m,
        )
    }

    /// Checks that every parameter is finite and physical.
    ///
    /// # Errors
    /// The first parameter that is not finite or not positive, or a fringing coefficient
    /// below 1.
    pub fn validate(&self) -> Result<(), Error> {
        config::positive("magnetics.turns", self.turns)?;
        config::positive("magnetics.rho0_per_h", self.rho0_per_h)?;
        config::positive("magnetics.gaps", self.gaps)?;
        match self.fringing {
            Fringing::Coefficient { alpha, pole_m2 } => {
                config::at_least("magnetics.fringing.alpha", alpha, 1.0)?;
                config::positive("magnetics.fringing.pole_m2", pole_m2)?;
            }
            Fringing::Rectangular { a_m, b_m, spread } => {
                config::positive("magnetics.fringing.a_m", a_m)?;
                config::positive("magnetics.fringing.b_m", b_m)?;
                config::at_least("magnetics.fringing.spread", spread, 0.0)?;
            }
        }
        Ok(())
    }
}

/// Side of the square pole of the default geometry \[m\].
pub const PAPER_POLE_SIDE_M: f32 = 7.0e-3;

/// `mu = N^2 rho_x / (rho_x g + rho_0)^2` \[H/m\].
#[inline]
fn force_coefficient(n2: f32, rho_x: f32, rho0: f32, g_m: f32) -> f32 {
    let rho = rho_x * g_m + rho0;
    n2 * rho_x / (rho * rho)
}

/// Bounds on the airgap surface, `S_lo <= S(g) <= S_hi` for every gap of the stroke \[m^2\].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Bounds {
    /// Lower bound `S_lo` \[m^2\].
    pub s_lo_m2: f32,
    /// Upper bound `S_hi` \[m^2\].
    pub s_hi_m2: f32,
}

impl Bounds {
    /// Bounds that bracket `S(g)` over the airgaps `gaps_m = (g_min, g_max)` with a relative
    /// margin: `S_lo = (1 - below) min S`, `S_hi = (1 + above) max S`.
    ///
    /// For the constant-surface model this is `S (1 +- tol)`; for a rectangular pole it also
    /// covers the growth of `S` with the gap, which is exactly the paper's idea of treating
    /// fringing as a bounded uncertainty.
    #[must_use]
    pub fn around(fringing: &Fringing, gaps_m: (f32, f32), below: f32, above: f32) -> Self {
        let (s_min, s_max) = fringing.surface_range_m2(gaps_m.0, gaps_m.1);
        Self {
            s_lo_m2: (1.0 - below) * s_min,
            s_hi_m2: (1.0 + above) * s_max,
        }
    }

    /// Checks `0 < S_lo < S_hi`, both finite.
    ///
    /// # Errors
    /// Names `bounds.s_lo_m2` or `bounds.s_hi_m2` and why.
    pub fn validate(&self) -> Result<(), Error> {
        config::positive("bounds.s_lo_m2", self.s_lo_m2)?;
        config::positive("bounds.s_hi_m2", self.s_hi_m2)?;
        if self.s_lo_m2 >= self.s_hi_m2 {
            return Err(Error {
                param: "bounds.s_lo_m2",
                value: self.s_lo_m2,
                reason: Reason::NotBelow {
                    other: "bounds.s_hi_m2",
                    limit: self.s_hi_m2,
                },
            });
        }
        Ok(())
    }
}

/// Bounds on `rho`, `L` and `mu` over the airgap, derived from the surface [`Bounds`]
/// (paper, section II-B). Immutable and validated; evaluated by the laws in the tick.
///
/// ```text
/// rho_x_lo = n / (mu0 S_hi)        rho_x_hi = n / (mu0 S_lo)
/// rho_lo(g) = rho_x_lo g + rho_0   rho_hi(g) = rho_x_hi g + rho_0
/// L_lo(g) = N^2 / rho_hi(g)        L_hi(g) = N^2 / rho_lo(g)
/// mu_lo(g), mu_hi(g) = min, max of N^2 r / (r g + rho_0)^2 over r in [rho_x_lo, rho_x_hi]
/// ```
///
/// The paper writes `mu_lo = N^2 rho_x / rho_hi^2` with an unspecified `rho_x`; the exact
/// extremes used here equal that formula with `rho_x = rho_x_hi` (resp. `rho_x_lo` for
/// `mu_hi`) whenever `g > rho_0 / rho_x_lo` (about 27 nm for the paper's actuator), and stay
/// correct below it, where `mu` is no longer monotone in `rho_x`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Envelope {
    n2: f32,
    rho0: f32,
    rho_x_lo: f32,
    rho_x_hi: f32,
}

impl Envelope {
    /// The envelope of a magnetic circuit under surface bounds.
    ///
    /// # Errors
    /// Any invalid parameter of `magnetics` or `bounds`, by name.
    pub fn new(magnetics: &Magnetics, bounds: &Bounds) -> Result<Self, Error> {
        magnetics.validate()?;
        bounds.validate()?;
        let env = Self {
            n2: magnetics.turns_sq(),
            rho0: magnetics.rho0_per_h,
            rho_x_lo: magnetics.gaps / (MU0_H_PER_M * bounds.s_hi_m2),
            rho_x_hi: magnetics.gaps / (MU0_H_PER_M * bounds.s_lo_m2),
        };
        if !(env.rho_x_lo.is_finite() && env.rho_x_hi.is_finite() && env.n2.is_finite()) {
            return Err(Error {
                param: "bounds.s_lo_m2",
                value: bounds.s_lo_m2,
                reason: Reason::NotFinite,
            });
        }
        Ok(env)
    }

    /// `rho_x` range `(rho_x_lo, rho_x_hi)` \[1/(H m)\].
    #[must_use]
    pub const fn rho_x_range(&self) -> (f32, f32) {
        (self.rho_x_lo, self.rho_x_hi)
    }

    /// The nominal model at the centre of the surface bounds, `S = (S_lo + S_hi) / 2`
    /// (`rho_x` is the harmonic mean of `rho_x_lo` and `rho_x_hi`).
    #[must_use]
    pub fn nominal(&self) -> Nominal {
        Nominal {
            n2: self.n2,
            rho0: self.rho0,
            rho_x: 2.0 * self.rho_x_lo * self.rho_x_hi / (self.rho_x_lo + self.rho_x_hi),
        }
    }

    /// The weakest magnet of the bounds: `rho_x = rho_x_hi` (smallest surface). Its force
    /// coefficient equals `mu_lo(g)` wherever `g > rho_0 / rho_x_lo`.
    #[must_use]
    #[inline(never)]
    pub fn weakest(&self) -> Nominal {
        Nominal {
            n2: self.n2,
            rho0: self.rho0,
            rho_x: self.rho_x_hi,
        }
    }

    /// Lower reluctance bound `rho_lo(g)` \[1/H\].
    #[inline]
    #[must_use]
    pub fn rho_lo(&self, g_m: f32) -> f32 {
        self.rho_x_lo * g_m + self.rho0
    }

    /// Upper reluctance bound `rho_hi(g)` \[1/H\].
    #[inline]
    #[must_use]
    pub fn rho_hi(&self, g_m: f32) -> f32 {
        self.rho_x_hi * g_m + self.rho0
    }

    /// Lower inductance bound `L_lo(g) = N^2 / rho_hi(g)` \[H\].
    #[inline]
    #[must_use]
    pub fn l_lo(&self, g_m: f32) -> f32 {
        self.n2 / self.rho_hi(g_m)
    }

    /// Upper inductance bound `L_hi(g) = N^2 / rho_lo(g)` \[H\].
    #[inline]
    #[must_use]
    pub fn l_hi(&self, g_m: f32) -> f32 {
        self.n2 / self.rho_lo(g_m)
    }

    /// Lower force-coefficient bound `mu_lo(g)` \[H/m\].
    #[inline]
    #[must_use]
    pub fn mu_lo(&self, g_m: f32) -> f32 {
        let at_lo = force_coefficient(self.n2, self.rho_x_lo, self.rho0, g_m);
        let at_hi = force_coefficient(self.n2, self.rho_x_hi, self.rho0, g_m);
        // mu(r) rises for r < rho0/g and falls above it: the minimum is at an end.
        crate::control::math::min(at_lo, at_hi)
    }

    /// Upper force-coefficient bound `mu_hi(g)` \[H/m\].
    #[inline]
    #[must_use]
    pub fn mu_hi(&self, g_m: f32) -> f32 {
        if g_m * self.rho_x_lo >= self.rho0 {
            // Whole interval on the falling side of mu(r): maximum at rho_x_lo.
            force_coefficient(self.n2, self.rho_x_lo, self.rho0, g_m)
        } else if g_m * self.rho_x_hi <= self.rho0 {
            // Whole interval on the rising side: maximum at rho_x_hi.
            force_coefficient(self.n2, self.rho_x_hi, self.rho0, g_m)
        } else {
            // The peak r = rho0/g lies inside: mu = N^2 / (4 rho0 g).
            self.n2 / (4.0 * self.rho0 * g_m)
        }
    }
}

/// A reluctance network with a constant `rho_x`: the model a controller evaluates at run
/// time. [`Envelope::nominal`] gives the one at the centre of the surface bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Nominal {
    n2: f32,
    rho0: f32,
    rho_x: f32,
}

impl Nominal {
    /// Reluctance `rho(g) = rho_x g + rho_0` \[1/H\].
    #[inline]
    #[must_use]
    pub fn reluctance_per_h(&self, g_m: f32) -> f32 {
        self.rho_x * g_m + self.rho0
    }

    /// Inductance `L(g)` \[H\].
    #[inline]
    #[must_use]
    pub fn inductance_h(&self, g_m: f32) -> f32 {
        self.n2 / (self.rho_x * g_m + self.rho0)
    }

    /// Force coefficient `mu(g)` \[H/m\].
    #[inline]
    #[must_use]
    pub fn force_coefficient_h_per_m(&self, g_m: f32) -> f32 {
        force_coefficient(self.n2, self.rho_x, self.rho0, g_m)
    }

    /// `rho_x` \[1/(H m)\].
    #[must_use]
    pub const fn rho_x_per_h_m(&self) -> f32 {
        self.rho_x
    }
}

/// Relative uncertainty of the mechanical and electrical parameters (the airgap surfaces
/// have their own [`Bounds`]): the true value lies within `nominal * (1 +- tolerance)`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Tolerance {
    /// Airgap surfaces around the nominal fringing model: the actuators that exist (the
    /// controller's [`Bounds`] may be wider, see [`crate::control::actuator`]) \[-\].
    #[cfg_attr(feature = "serde", serde(default = "default_surface"))]
    pub surface: f32,
    /// Moving mass \[-\].
    pub mass: f32,
    /// Spring constant \[-\].
    pub spring: f32,
    /// Viscous friction \[-\].
    pub friction: f32,
    /// Coil resistance (temperature) \[-\].
    pub resistance: f32,
}

#[cfg(feature = "serde")]
const fn default_surface() -> f32 {
    PAPER_SURFACE_TOLERANCE
}

impl Tolerance {
    /// The product's design case: surfaces +-20 %, mass +-10 %, spring +-10 %, friction
    /// +-50 %, resistance +-20 %.
    #[must_use]
    pub const fn paper() -> Self {
        Self {
            surface: PAPER_SURFACE_TOLERANCE,
            mass: 0.1,
            spring: 0.1,
            friction: 0.5,
            resistance: 0.2,
        }
    }

    /// Checks every tolerance is finite and within `[0, 1)`.
    ///
    /// # Errors
    /// The first bad tolerance, by name.
    pub fn validate(&self) -> Result<(), Error> {
        let below_one = 1.0 - f32::EPSILON;
        config::within("plant.tolerance.surface", self.surface, 0.0, below_one)?;
        config::within("plant.tolerance.mass", self.mass, 0.0, below_one)?;
        config::within("plant.tolerance.spring", self.spring, 0.0, below_one)?;
        config::within("plant.tolerance.friction", self.friction, 0.0, below_one)?;
        config::within(
            "plant.tolerance.resistance",
            self.resistance,
            0.0,
            below_one,
        )?;
        Ok(())
    }
}

impl Default for Tolerance {
    fn default() -> Self {
        Self::paper()
    }
}

/// The dynamics a controller evaluates at run time: mechanics and the force map.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Dynamics {
    /// Moving mass \[kg\].
    pub mass_kg: f32,
    /// Spring constant \[N/m\].
    pub spring_n_per_m: f32,
    /// Spring force at `x1 = 0` \[N\] (the spring pulls toward `-x1` with `K x1 + F0`).
    pub preload_n: f32,
    /// Viscous friction \[N s/m\].
    pub friction_n_s_per_m: f32,
    /// Reluctance network for the force `mu(g) x3^2 / 2`.
    pub circuit: Nominal,
    /// Position convention.
    pub convention: Convention,
}

impl Dynamics {
    /// The spring's pull toward `-x1` at `x_m`, `K x + F0` \[N\].
    #[inline]
    #[must_use]
    pub fn spring_force_n(&self, x_m: f32) -> f32 {
        self.spring_n_per_m * x_m + self.preload_n
    }

    /// The magnet's pull `mu(g) i^2 / 2` at airgap `g_m` with coil current `i_a` \[N\].
    #[inline]
    #[must_use]
    pub fn magnet_force_n(&self, g_m: f32, i_a: f32) -> f32 {
        0.5 * self.circuit.force_coefficient_h_per_m(g_m) * i_a * i_a
    }

    /// Acceleration \[m/s^2\] at `(x, v)` with coil current `i`.
    #[inline]
    #[must_use]
    pub fn acceleration_mps2(&self, x_m: f32, v_mps: f32, i_a: f32) -> f32 {
        let mu = self
            .circuit
            .force_coefficient_h_per_m(self.convention.gap_m(x_m));
        (0.5 * mu * i_a * i_a - self.spring_force_n(x_m) - self.friction_n_s_per_m * v_mps)
            / self.mass_kg
    }
}

/// The nominal actuator as the controller knows it: mechanics, coil, magnetic circuit,
/// uncertainty bounds, position convention and stroke.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Plant {
    /// Moving mass `m` \[kg\].
    pub mass_kg: f32,
    /// Spring constant `K` \[N/m\].
    pub spring_n_per_m: f32,
    /// Spring preload `F0`: the spring's force at `x1 = 0` \[N\]; the spring pulls toward
    /// `-x1` with `K x1 + F0` (0 in the paper).
    #[cfg_attr(feature = "serde", serde(default))]
    pub preload_n: f32,
    /// Viscous friction `lambda` \[N s/m\].
    pub friction_n_s_per_m: f32,
    /// Coil resistance `R` \[ohm\].
    pub resistance_ohm: f32,
    /// Magnetic circuit (nominal).
    pub magnetics: Magnetics,
    /// Uncertainty bounds on the airgap surface.
    pub bounds: Bounds,
    /// What the position coordinate means.
    pub convention: Convention,
    /// Mechanical stroke: positions run over `0..=stroke_m` \[m\].
    pub stroke_m: f32,
    /// Relative uncertainty of mass, spring, friction and resistance.
    #[cfg_attr(feature = "serde", serde(default))]
    pub tolerance: Tolerance,
}

/// Stroke of the default actuator \[m\].
pub const PAPER_STROKE_M: f32 = 4.0e-3;

/// Default relative uncertainty of the airgap surface (+-20 %).
pub const PAPER_SURFACE_TOLERANCE: f32 = 0.2;

impl Plant {
    /// The paper's actuator (Table I) with the default geometry ([`Magnetics::paper`]),
    /// surface bounds of +-20 %, the paper's convention and a 4 mm stroke.
    #[must_use]
    pub fn paper() -> Self {
        let magnetics = Magnetics::paper();
        let convention = Convention::Paper;
        let bounds = Bounds::around(
            &magnetics.fringing,
            convention.gap_range_m(PAPER_STROKE_M),
            PAPER_SURFACE_TOLERANCE,
            PAPER_SURFACE_TOLERANCE,
        );
        Self {
            mass_kg: 0.1,
            spring_n_per_m: 120.0,
            preload_n: 0.0,
            friction_n_s_per_m: 5.0,
            resistance_ohm: 0.4,
            magnetics,
            bounds,
            convention,
            stroke_m: PAPER_STROKE_M,
            tolerance: Tolerance::paper(),
        }
    }

    /// The nominal dynamics: nominal mechanics, surface at the centre of its bounds.
    ///
    /// # Errors
    /// As [`Plant::validate`].
    pub fn nominal_dynamics(&self) -> Result<Dynamics, Error> {
        let envelope = self.envelope()?;
        Ok(Dynamics {
            mass_kg: self.mass_kg,
            spring_n_per_m: self.spring_n_per_m,
            preload_n: self.preload_n,
            friction_n_s_per_m: self.friction_n_s_per_m,
            circuit: envelope.nominal(),
            convention: self.convention,
        })
    }

    /// The robust design dynamics: every uncertain parameter at the bound that makes the
    /// actuator slowest to follow a force command: the weakest magnet (`rho_x_hi`, so
    /// `mu = mu_lo` wherever `g > rho_0 / rho_x_lo`), the heaviest armature, the softest
    /// spring and the most friction. A law built on it never meets a plant weaker than its
    /// model; this is the paper's choice of `mu_lo` for `x3d`, applied to every parameter.
    ///
    /// # Errors
    /// As [`Plant::validate`].
    pub fn robust_dynamics(&self) -> Result<Dynamics, Error> {
        let envelope = self.envelope()?;
        let t = &self.tolerance;
        Ok(Dynamics {
            mass_kg: self.mass_kg * (1.0 + t.mass),
            spring_n_per_m: self.spring_n_per_m * (1.0 - t.spring),
            preload_n: self.preload_n * (1.0 - t.spring),
            friction_n_s_per_m: self.friction_n_s_per_m * (1.0 + t.friction),
            circuit: envelope.weakest(),
            convention: self.convention,
        })
    }

    /// The airgap \[m\] at position `x_m`.
    #[inline]
    #[must_use]
    pub fn gap_m(&self, x_m: f32) -> f32 {
        self.convention.gap_m(x_m)
    }

    /// The surfaces real actuators of this design have: the nominal fringing model over
    /// the stroke, `+-` [`Tolerance::surface`]. The controller's [`Plant::bounds`] contain
    /// them and may be wider.
    #[must_use]
    pub fn physical_bounds(&self) -> Bounds {
        let s = self.tolerance.surface;
        Bounds::around(
            &self.magnetics.fringing,
            self.convention.gap_range_m(self.stroke_m),
            s,
            s,
        )
    }

    /// The bounds envelope of this plant.
    ///
    /// # Errors
    /// As [`Plant::validate`].
    #[inline(never)]
    pub fn envelope(&self) -> Result<Envelope, Error> {
        self.validate()?;
        Envelope::new(&self.magnetics, &self.bounds)
    }

    /// Checks every parameter: finite, physical, bounds ordered, convention consistent with
    /// the stroke.
    ///
    /// # Errors
    /// The first bad parameter, by name, with its value and the reason.
    pub fn validate(&self) -> Result<(), Error> {
        config::positive("plant.mass_kg", self.mass_kg)?;
        config::at_least("plant.spring_n_per_m", self.spring_n_per_m, 0.0)?;
        config::at_least("plant.preload_n", self.preload_n, 0.0)?;
        config::at_least("plant.friction_n_s_per_m", self.friction_n_s_per_m, 0.0)?;
        config::positive("plant.resistance_ohm", self.resistance_ohm)?;
        config::positive("plant.stroke_m", self.stroke_m)?;
        self.magnetics.validate()?;
        self.bounds.validate()?;
        self.tolerance.validate()?;
        if let Convention::Physical { gap_at_zero_m } = self.convention {
            config::finite("plant.convention.gap_at_zero_m", gap_at_zero_m)?;
            if gap_at_zero_m <= self.stroke_m {
                return Err(Error {
                    param: "plant.convention.gap_at_zero_m",
                    value: gap_at_zero_m,
                    reason: Reason::NotAbove {
                        other: "plant.stroke_m",
                        limit: self.stroke_m,
                    },
                });
            }
        }
        Ok(())
    }

    /// The spring's pull toward `-x1` at `x_m`, `K x + F0` \[N\].
    #[inline]
    #[must_use]
    pub fn spring_force_n(&self, x_m: f32) -> f32 {
        self.spring_n_per_m * x_m + self.preload_n
    }

    /// Static current \[A\] that holds position `x_m` against the spring with the nominal
    /// magnetics: `sqrt(2 (K x + F0) / mu(g))` (0 where the spring needs no force).
    #[must_use]
    pub fn holding_current_a(&self, x_m: f32) -> f32 {
        let force = self.spring_force_n(x_m);
        if force <= 0.0 {
            return 0.0;
        }
        let mu = self.magnetics.force_coefficient_h_per_m(self.gap_m(x_m));
        crate::control::math::sqrt(2.0 * force / mu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32, rel: f32) -> bool {
        ((a - b) / b).abs() <= rel
    }

    #[test]
    fn default_geometry_reproduces_table_one() {
        let m = Magnetics::paper();
        let rho_x = m.rho_x_per_h_m(0.0);
        assert!(close(rho_x, 2.8e10, 3e-5), "rho_x = {rho_x}");
        assert_eq!(m.rho0_per_h, 630.0);
    }

    #[test]
    fn inductance_and_force_coefficient_hand_values() {
        let m = Magnetics::paper();
        // L = 4900 / (2.8e10 g + 630); mu = 4900 * 2.8e10 / (2.8e10 g + 630)^2.
        assert!(close(m.inductance_h(1e-3), 175.0e-6, 1e-4));
        assert!(close(m.inductance_h(3e-3), 58.33e-6, 1e-4));
        assert!(close(m.force_coefficient_h_per_m(1e-3), 0.1750, 1e-4));
        assert!(close(m.force_coefficient_h_per_m(3e-3), 0.019_44, 2e-4));
    }

    #[test]
    fn rectangular_fringing_grows_with_the_gap() {
        let f = Magnetics::paper_rectangular().fringing;
        assert!(close(f.surface_m2(0.0), 49e-6, 1e-6));
        assert!(close(f.surface_m2(3e-3), 100e-6, 1e-6));
    }

    fn assert_bounds_ordered(plant: &Plant) {
        let env = plant.envelope().unwrap();
        let (g_lo, g_hi) = plant.convention.gap_range_m(plant.stroke_m);
        for k in 0..=400 {
            let g = g_lo + (g_hi - g_lo) * k as f32 / 400.0;
            let nominal_rho = plant.magnetics.reluctance_per_h(g);
            let nominal_l = plant.magnetics.inductance_h(g);
            let nominal_mu = plant.magnetics.force_coefficient_h_per_m(g);
            assert!(
                0.0 < env.rho_lo(g) && env.rho_lo(g) <= nominal_rho,
                "rho at {g}"
            );
            assert!(nominal_rho <= env.rho_hi(g), "rho at {g}");
            assert!(0.0 < env.l_lo(g) && env.l_lo(g) <= nominal_l, "L at {g}");
            assert!(nominal_l <= env.l_hi(g), "L at {g}");
            assert!(0.0 < env.mu_lo(g), "mu_lo at {g}");
            assert!(
                env.mu_lo(g) <= nominal_mu && nominal_mu <= env.mu_hi(g),
                "mu at {g}"
            );
        }
    }

    #[test]
    fn bounds_are_ordered_over_the_stroke_for_both_fringing_models() {
        let coefficient = Plant::paper();
        assert_bounds_ordered(&coefficient);

        let magnetics = Magnetics::paper_rectangular();
        let gaps = coefficient.convention.gap_range_m(PAPER_STROKE_M);
        let rectangular = Plant {
            magnetics,
            bounds: Bounds::around(&magnetics.fringing, gaps, 0.2, 0.2),
            ..coefficient
        };
        assert_bounds_ordered(&rectangular);

        let physical = Plant {
            convention: Convention::Physical {
                gap_at_zero_m: 4.5e-3,
            },
            ..rectangular
        };
        assert_bounds_ordered(&physical);
    }

    #[test]
    fn default_bounds_are_twenty_percent_of_the_surface() {
        let p = Plant::paper();
        let s = p.magnetics.fringing.surface_m2(0.0);
        assert!(close(p.bounds.s_lo_m2, 0.8 * s, 1e-6));
        assert!(close(p.bounds.s_hi_m2, 1.2 * s, 1e-6));
        let env = p.envelope().unwrap();
        // mu_lo/mu at 3 mm is S_lo/S = 0.8 (rho_0 is negligible there).
        let g = 3e-3;
        let ratio = env.mu_lo(g) / p.magnetics.force_coefficient_h_per_m(g);
        assert!(close(ratio, 0.8, 1e-3), "{ratio}");
    }

    #[test]
    fn mu_bounds_stay_correct_at_nanometre_gaps() {
        // Below rho0/rho_x the force coefficient rises with rho_x; the extremes must follow.
        let env = Plant::paper().envelope().unwrap();
        let (lo, hi) = env.rho_x_range();
        for g in [0.0_f32, 1e-9, 2e-8, 2.5e-8, 3e-8, 1e-7] {
            let mut min = f32::INFINITY;
            let mut max = 0.0_f32;
            for k in 0..=1000 {
                let r = lo + (hi - lo) * k as f32 / 1000.0;
                let mu = force_coefficient(4900.0, r, 630.0, g);
                min = min.min(mu);
                max = max.max(mu);
            }
            assert!(env.mu_lo(g) <= min * (1.0 + 1e-5), "mu_lo at {g}");
            assert!(env.mu_hi(g) >= max * (1.0 - 1e-5), "mu_hi at {g}");
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut p = Plant::paper();
        p.mass_kg = -0.1;
        assert_eq!(p.validate().unwrap_err().param, "plant.mass_kg");
        let mut p = Plant::paper();
        p.resistance_ohm = f32::NAN;
        let e = p.validate().unwrap_err();
        assert_eq!(
            (e.param, e.reason),
            ("plant.resistance_ohm", Reason::NotFinite)
        );
        let mut p = Plant::paper();
        core::mem::swap(&mut p.bounds.s_lo_m2, &mut p.bounds.s_hi_m2);
        assert_eq!(p.validate().unwrap_err().param, "bounds.s_lo_m2");
        let mut p = Plant::paper();
        p.convention = Convention::Physical {
            gap_at_zero_m: 3e-3,
        };
        assert_eq!(
            p.validate().unwrap_err().param,
            "plant.convention.gap_at_zero_m"
        );
    }

    #[test]
    fn robust_dynamics_sit_at_the_unfavourable_bounds() {
        let p = Plant::paper();
        let d = p.robust_dynamics().unwrap();
        assert!(close(d.mass_kg, 0.11, 1e-6));
        assert!(close(d.spring_n_per_m, 108.0, 1e-6));
        assert!(close(d.friction_n_s_per_m, 7.5, 1e-6));
        let env = p.envelope().unwrap();
        for g in [1e-4_f32, 1e-3, 3e-3] {
            let mu = d.circuit.force_coefficient_h_per_m(g);
            assert!(close(mu, env.mu_lo(g), 1e-6), "{g}");
        }
        let n = p.nominal_dynamics().unwrap();
        assert!(close(n.mass_kg, 0.1, 1e-7));
        let mu = n.circuit.force_coefficient_h_per_m(3e-3);
        assert!(close(mu, p.magnetics.force_coefficient_h_per_m(3e-3), 1e-5));
        let mut bad = p;
        bad.tolerance.friction = 1.0;
        assert_eq!(
            bad.validate().unwrap_err().param,
            "plant.tolerance.friction"
        );
    }

    #[test]
    fn conventions_map_position_to_gap() {
        assert_eq!(Convention::Paper.gap_m(2e-3), 2e-3);
        assert_eq!(Convention::Paper.gap_m(-1e-4), 0.0);
        let phys = Convention::Physical {
            gap_at_zero_m: 4.5e-3,
        };
        assert!((phys.gap_m(3e-3) - 1.5e-3).abs() < 1e-9);
        assert_eq!(phys.emf_sign(), -1.0);
        assert_eq!(Convention::Paper.emf_sign(), 1.0);
    }
}
