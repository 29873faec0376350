//! A minimal closed-loop actuator, `no_std` and `f32`: the tests on the Cortex-M4F (cycle
//! counts, the guard, SysTick, the bench session) drive the tick with it. It is not the simulator
//! (`hil-sim`, f64, uncertain plant, ADC model, scenarios); it only has to give the tick
//! the inputs a real loop gives it, physically consistent enough for the supervisor's
//! monitors (the electrical residual compares the measured current with the applied
//! voltage).
//!
//! Model (`ema::control::model`, with the settings' nominal magnetics and convention):
//! `L(g) i' = u - R i + s v i mu(g)`, `m x'' = i^2 mu(g) / 2 - lambda v - K x`, end stops
//! at 0 and the stroke; explicit Euler, [`SUBSTEPS`] steps per tick. The bridge applies the
//! average voltage of its drive; in coast the current returns to the bus through the
//! freewheeling diodes (`u = -Vbus sign(i)`) until it is zero. As on the firmware, a drive
//! computed at tick `k` takes effect from the next period (the compare register is
//! preloaded), so each period runs with the previous tick's drive. Converter codes are the
//! ideal ones plus +-1 code of deterministic noise.
#![allow(dead_code)]

use ema::control::bridge::{Drive, Mode};
use ema::control::model;
use ema::control::sense::{Calibration, Frame, Measurement};
use ema::control::Settings;

/// Integration steps per tick.
pub const SUBSTEPS: u32 = 20;

/// The actuator.
pub struct Plant {
    plant: model::Plant,
    cal: Calibration,
    ts_s: f32,
    /// Position \[m\].
    pub x_m: f32,
    /// Velocity \[m/s\].
    pub v_mps: f32,
    /// Coil current \[A\].
    pub i_a: f32,
    /// Bus voltage \[V\].
    pub vbus_v: f32,
    pending: Drive,
    noise: u32,
}

impl Plant {
    /// At rest at `x_m`, no current, bridge coasting, on a `vbus_v` bus.
    pub fn new(settings: &Settings, x_m: f32, vbus_v: f32) -> Self {
        Self {
            plant: settings.plant,
            cal: settings.sense,
            ts_s: 1.0 / settings.rate_hz,
            x_m,
            v_mps: 0.0,
            i_a: 0.0,
            vbus_v,
            pending: Drive::default(),
            noise: 0x2545_f491,
        }
    }

    fn jitter(&mut self) -> i32 {
        // xorshift32, +-1 code.
        self.noise ^= self.noise << 13;
        self.noise ^= self.noise >> 17;
        self.noise ^= self.noise << 5;
        (self.noise % 3) as i32 - 1
    }

    /// The converter codes now.
    pub fn frame(&mut self) -> Frame {
        let ideal = self.cal.frame(&Measurement {
            x_m: self.x_m,
            i_a: self.i_a,
            vbus_v: self.vbus_v,
        });
        let (a, b, c) = (self.jitter(), self.jitter(), self.jitter());
        let noisy = |code: u16, j: i32| (i32::from(code) + j).clamp(0, 4095) as u16;
        Frame {
            position: noisy(ideal.position, a),
            current: noisy(ideal.current, b),
            vbus: noisy(ideal.vbus, c),
        }
    }

    /// One period with the previous drive; `drive` (this tick's) applies from the next.
    pub fn advance(&mut self, drive: &Drive) {
        let applied = core::mem::replace(&mut self.pending, *drive);
        let p = &self.plant;
        let h = self.ts_s / SUBSTEPS as f32;
        for _ in 0..SUBSTEPS {
            let g = p.gap_m(self.x_m).max(1e-6);
            let l = p.magnetics.inductance_h(g);
            let mu = p.magnetics.force_coefficient_h_per_m(g);
            let u = match applied.mode {
                Mode::Coast => {
                    if self.i_a.abs() * l < self.vbus_v * h {
                        self.i_a = 0.0;
                        0.0
                    } else if self.i_a > 0.0 {
                        -self.vbus_v
                    } else {
                        self.vbus_v
                    }
                }
                _ => applied.u_v,
            };
            let di = (u - p.resistance_ohm * self.i_a
                + p.convention.emf_sign() * self.v_mps * self.i_a * mu)
                / l;
            let a = (0.5 * self.i_a * self.i_a * mu
                - p.friction_n_s_per_m * self.v_mps
                - p.spring_force_n(self.x_m))
                / p.mass_kg;
            self.i_a += h * di;
            self.v_mps += h * a;
            self.x_m += h * self.v_mps;
            if self.x_m < 0.0 {
                self.x_m = 0.0;
                self.v_mps = self.v_mps.max(0.0);
            } else if self.x_m > p.stroke_m {
                self.x_m = p.stroke_m;
                self.v_mps = self.v_mps.min(0.0);
            }
        }
    }
}
