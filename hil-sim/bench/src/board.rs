//! The virtual board: the firmware's own application ([`ema::device`]: the same
//! [`Controller`] in the "interrupt", the same [`Dispatcher`] in the "main loop", the same
//! queues, the same [`device::boot`] and store on a simulated flash) on the simulated
//! plant, converter and bridge of [`hil_sim::simulation::sim`], one period at a time.
//!
//! What the firmware does with hardware, the virtual board does here:
//!
//! | firmware | virtual board |
//! |---|---|
//! | TIM1 + ADC1 interrupt, 20 kHz | [`VirtualBoard::tick`]: sample the plant, tick, advance the plant one period |
//! | UART with DMA | bytes in and out ([`VirtualBoard::input`], [`VirtualBoard::output`]) at the link's rate ([`ema::device::protocol::BAUD`], 10 bits a byte), a receive ring of the firmware's size that drops what overflows it; [`VirtualBoard::serve`] moves them over a pseudo-terminal and drops what the host does not read, as a UART does, counting both ([`VirtualBoard::dropped`]) |
//! | the watchdogs | a run of ticks that do not feed them longer than the window watchdog waits ([`ema::device::guard::WATCHDOG_QUIET_PERIODS`]) restarts the application with the fault the firmware's next start latches (`main_loop_stalled` after a stalled main loop, `overrun` otherwise) |
//! | flash sectors 1 and 2 | [`Flash`], which can lose its power at any write |
//! | a save restarts the chip, which writes the flash before it starts the control | [`VirtualBoard::restart`] with the set to save, the same [`device::boot`] |
//! | the measured current-sensor zero | the nominal zero |
//!
//! The plant, the sensors and the supply are the actuator's judging scenario
//! ([`hil_sim::simulation::actuator::scenario`]: nominal plant, supply resistance `R/8`,
//! averaged bridge) with a deterministic converter by default (12 bits, one sample of
//! delay, no noise): a capture then equals, bit for bit, the simulator's run of the same
//! scenario ([`super::prediction`]), which the end-to-end tests check. `noise` adds the
//! typical converter noise.
//!
//! The armature starts at rest at the open end stop; injected faults
//! ([`VirtualBoard::inject`]) act on the plant as `hil-sim faults` injects them.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ema::control::actuator::Actuator;
use ema::control::bridge::HBridge;
use ema::control::supervisor::Fault;
use ema::device::guard::{End, Start};
use ema::device::params::{Board, Params};
use ema::device::protocol::{self, Build, LoadError, Mode, Sample, StoreError};
use ema::device::store::{ReadOnly, Store};
use ema::device::{
    self, Action, Boot, Controller, Dispatcher, Inputs, Queues, Storage, Ticked, CAPTURE_CAPACITY,
};
use hil_sim::simulation::board::scenario;
use hil_sim::simulation::hal::{self, Adc, Converter, Lines, Pin, Pwm};
use hil_sim::simulation::scenario::{BridgeMode, Scenario, Sensors};
use hil_sim::simulation::sim::Stepper;
use hil_sim::Error;

use super::flash::{Flash, PAGE, PAGES};

/// How the virtual board is made.
#[derive(Clone, Debug)]
pub struct Options {
    /// The actuator the "firmware" is built for (its built-in parameters) and the plant.
    pub actuator: Actuator,
    /// Typical converter noise (1.5 codes RMS, seed 1) instead of none.
    pub noise: bool,
    /// The built-in `link.*` parameters. A board served faster than real time
    /// ([`VirtualBoard::serve`] without a speed) runs its ticks faster than a host's
    /// heartbeat, paced in real time, can follow: its timeout must be off (0).
    pub link: ema::device::liveness::Settings,
    /// The link at the UART's rate, through a receive ring of the firmware's size (the
    /// default); off, bytes reach the board and leave it at once (a decoder fed at volume).
    pub uart: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            actuator: Actuator::PRODUCT,
            noise: false,
            link: ema::device::liveness::Settings::default(),
            uart: true,
        }
    }
}

/// What the test rig does to the virtual board: a fault in the plant or its sensors, the
/// supply, the analog set point, a power cut (the scenario's timed fault is
/// [`hil_sim::simulation::scenario::Injection`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stimulus {
    /// The supply's source voltage \[V\].
    Supply(f64),
    /// The position sensor's output at 0 V (open) or back to normal.
    PositionOpen(bool),
    /// The analog set-point input: a voltage \[V\] or a loop current \[A\] (as the source
    /// chosen reads it: the code is computed with that scale).
    Analog {
        /// The value.
        value: f64,
        /// A loop current (else a voltage).
        current: bool,
    },
    /// The power goes at this step of the next save (see [`Flash::cut_after`]).
    CutSave(u64),
    /// The coil's resistance \[ohm\] (a winding off its datasheet, or warm).
    Resistance(f64),
    /// The coil's circuit open (a broken wire), or closed again.
    CoilOpen(bool),
    /// The armature jammed where it is, or free again.
    Jammed(bool),
    /// The airgaps' surfaces this many times the file's (flux fringing off the model).
    Surfaces(f64),
    /// The bridge driver's fault output (over-temperature, under-voltage), wired to the
    /// timer's break input with the current comparator: active or gone.
    DriverFault(bool),
    /// The armature off its datasheet: mass \[kg\], spring rate \[N/m\], preload \[N\],
    /// friction \[N s/m\] (a broken spring: zero rate and preload).
    Mechanics {
        /// Moving mass \[kg\].
        mass_kg: f64,
        /// Spring rate \[N/m\].
        spring_n_per_m: f64,
        /// Spring preload \[N\].
        preload_n: f64,
        /// Viscous friction \[N s/m\].
        friction_n_s_per_m: f64,
    },
    /// The position sensor's gain error (relative) and offset \[code\]; its noise kept.
    PositionSensor {
        /// Relative gain error (`-2` reads backwards about the calibration's offset).
        gain_error: f64,
        /// Offset \[code\].
        offset_code: f64,
    },
    /// The main loop hangs (it no longer serves the link nor checks in), or runs again.
    HangMainLoop(bool),
}

/// Bytes the firmware's receive ring holds (its `link::RX_RING`): what arrives while it
/// is full is lost, as when the DMA overwrites bytes the main loop has not read.
pub const RX_RING: usize = 256;

/// Bytes lost on the way, as a UART loses them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dropped {
    /// Received while the receive ring was full.
    pub received: u64,
    /// Sent while the host did not read.
    pub sent: u64,
}

/// The plant side: what the firmware's timer, converter and bridge see.
struct Plant {
    stepper: Stepper,
    converter: Converter,
    bridge: HBridge<Pwm, Pin>,
    lines: Lines,
    mode: BridgeMode,
    position_open: bool,
    analog_code: u16,
    driver_fault: bool,
}

/// The application side, rebuilt at every start.
struct Running {
    controller: Controller<Vec<Sample>>,
    dispatcher: Dispatcher,
    queues: Queues,
    store: Store<Flash>,
}

/// A virtual board.
pub struct VirtualBoard {
    options: Options,
    scenario: Scenario,
    defaults: Params,
    board: Board,
    period_ns: u32,
    plant: Plant,
    running: Option<Running>,
    flash: Option<Flash>,
    save_cut: Option<u64>,
    /// Bytes from the host not yet on the line.
    line: std::collections::VecDeque<u8>,
    /// The receive ring: bytes on the line, not yet taken by the main loop.
    rx: Vec<u8>,
    tx: Vec<u8>,
    /// Bytes the line may still carry this tick, each way (a byte every 10 bits).
    credit: [f64; 2],
    dropped: Dropped,
    /// The main loop hangs.
    main_hung: bool,
    /// Ticks in a row that did not feed the watchdogs.
    unfed: u32,
    ticks: u64,
    starts: u32,
    last_boot: Option<Boot>,
    cut_saves: u32,
    /// Largest coil current magnitude since the last [`VirtualBoard::take_peak_current_a`].
    peak_current_a: f64,
}

/// The store's flash range (the chip's two sectors, [`PAGE`] bytes each).
fn store_range() -> std::ops::Range<u32> {
    0..u32::try_from(PAGE * PAGES).unwrap_or(u32::MAX)
}

impl VirtualBoard {
    /// Powers a new board on: an erased flash, so the built-in parameters.
    ///
    /// # Errors
    /// An actuator whose settings do not derive.
    pub fn new(options: Options) -> Result<Self, Error> {
        Self::with_flash(options, Flash::default())
    }

    /// Powers a board on with `flash` (as another board left it).
    ///
    /// # Errors
    /// An actuator whose settings do not derive.
    pub fn with_flash(options: Options, flash: Flash) -> Result<Self, Error> {
        let scenario = scenario(&options.actuator, options.noise)?;
        let defaults = Params {
            link: options.link,
            ..Params::new(options.actuator)
        };
        let board = Board {
            rate_hz: options.actuator.board.rate_hz,
            current_zero_code: None,
        };
        let plant = Plant::new(&scenario)?;
        let period_ns = (1e9 / scenario.rate_hz()).round() as u32;
        let mut b = Self {
            options,
            scenario,
            defaults,
            board,
            period_ns,
            plant,
            running: None,
            flash: Some(flash),
            save_cut: None,
            line: std::collections::VecDeque::new(),
            rx: Vec::new(),
            tx: Vec::new(),
            credit: [0.0; 2],
            dropped: Dropped::default(),
            main_hung: false,
            unfed: 0,
            ticks: 0,
            starts: 0,
            last_boot: None,
            cut_saves: 0,
            peak_current_a: 0.0,
        };
        b.start(None)?;
        Ok(b)
    }

    /// The scenario the plant runs.
    #[must_use]
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The options it was made with.
    #[must_use]
    pub fn options(&self) -> &Options {
        &self.options
    }

    /// Starts (after a power-on or a restart): stores `save` first when given, then loads;
    /// with `latched`, the fault a watchdog reset leaves latched.
    fn start(&mut self, save: Option<Params>) -> Result<(), Error> {
        self.start_with(save, None)
    }

    fn start_with(&mut self, save: Option<Params>, latched: Option<Fault>) -> Result<(), Error> {
        let mut flash = match self.running.take() {
            Some(r) => r.store.release(),
            None => self.flash.take().unwrap_or_default(),
        };
        flash.power_on();
        if save.is_some() {
            if let Some(step) = self.save_cut.take() {
                flash.cut_after(step);
            }
        }
        let mut store = Store::new(flash, store_range())
            .map_err(|e| Error::param("store", f64::NAN, format!("{e:?}")))?;
        let mut boot = device::boot(&mut store, &self.defaults, &self.board, save.as_ref())
            .map_err(Error::Actuator)?;
        let mut flash = store.release();
        if flash.is_dead() {
            // The power went during the save: the board is off. It comes back on with
            // whatever the flash holds.
            self.cut_saves += 1;
            flash.power_on();
            let mut store = Store::new(flash, store_range())
                .map_err(|e| Error::param("store", f64::NAN, format!("{e:?}")))?;
            boot = device::boot(&mut store, &self.defaults, &self.board, None)
                .map_err(Error::Actuator)?;
            flash = store.release();
        }
        let store = Store::new(flash, store_range())
            .map_err(|e| Error::param("store", f64::NAN, format!("{e:?}")))?;
        let mut controller = Controller::new(
            boot.install,
            self.period_ns,
            vec![Sample::default(); CAPTURE_CAPACITY],
        );
        if let Some(fault) = latched {
            controller.trip(&mut self.plant.bridge, fault);
        }
        let capacity = u16::try_from(CAPTURE_CAPACITY).unwrap_or(u16::MAX);
        let dispatcher = Dispatcher::new(self.board, Build::THIS, self.defaults, &boot, capacity);
        self.running = Some(Running {
            controller,
            dispatcher,
            queues: Queues::new(),
            store,
        });
        self.rx.clear();
        self.main_hung = false;
        self.unfed = 0;
        self.starts += 1;
        self.last_boot = Some(boot);
        Ok(())
    }

    /// A power cycle (or a reset): the application starts again from the flash; the plant
    /// keeps its state.
    ///
    /// # Errors
    /// As [`VirtualBoard::new`].
    pub fn restart(&mut self) -> Result<(), Error> {
        self.start(None)
    }

    /// Applies a stimulus: a fault into the plant, the supply, the analog input, or a power
    /// cut armed for the next save.
    pub fn inject(&mut self, stimulus: Stimulus) {
        match stimulus {
            Stimulus::Supply(v) => self.plant.stepper.set_supply_v(v),
            Stimulus::PositionOpen(open) => self.plant.position_open = open,
            Stimulus::Analog { value, current } => {
                let per_code = if current {
                    f64::from(ema::device::analog::CURRENT_A_PER_CODE)
                } else {
                    f64::from(ema::device::analog::VOLTAGE_V_PER_CODE)
                };
                self.plant.analog_code = (value / per_code).round().clamp(0.0, 4095.0) as u16;
            }
            Stimulus::CutSave(step) => self.save_cut = Some(step),
            Stimulus::Resistance(r) => self.plant.stepper.set_resistance_ohm(r),
            Stimulus::CoilOpen(open) => self.plant.stepper.set_coil_open(open),
            Stimulus::Jammed(jammed) => self.plant.stepper.set_jammed(jammed),
            Stimulus::Surfaces(scale) => {
                let mut p = self.file_plant();
                p.scale_surfaces(scale);
                self.plant.stepper.plant_mut().gaps = p.gaps;
            }
            Stimulus::DriverFault(active) => self.plant.driver_fault = active,
            Stimulus::Mechanics {
                mass_kg,
                spring_n_per_m,
                preload_n,
                friction_n_s_per_m,
            } => {
                let p = self.plant.stepper.plant_mut();
                p.mass_kg = mass_kg;
                p.spring_n_per_m = spring_n_per_m;
                p.preload_n = preload_n;
                p.friction_n_s_per_m = friction_n_s_per_m;
            }
            Stimulus::PositionSensor {
                gain_error,
                offset_code,
            } => self
                .plant
                .converter
                .set_position_error(gain_error, offset_code),
            Stimulus::HangMainLoop(hung) => self.main_hung = hung,
        }
    }

    /// Bytes from the host: they reach the board at the link's rate.
    pub fn input(&mut self, bytes: &[u8]) {
        self.line.extend(bytes);
    }

    /// Bytes from the host not yet delivered to the board.
    #[must_use]
    pub fn input_pending(&self) -> usize {
        self.line.len()
    }

    /// Bytes lost so far.
    #[must_use]
    pub const fn dropped(&self) -> Dropped {
        self.dropped
    }

    /// Bytes for the host (taken).
    pub fn output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.tx)
    }

    /// Ticks since the board was made.
    #[must_use]
    pub const fn ticks(&self) -> u64 {
        self.ticks
    }

    /// The plant as the file describes it, before any stimulus.
    #[must_use]
    pub fn file_plant(&self) -> hil_sim::simulation::plant::Params {
        self.scenario.plant.resolve(&self.scenario.controller.plant)
    }

    /// The largest coil current magnitude (the plant's, not the converter's) since the
    /// last call \[A\].
    pub fn take_peak_current_a(&mut self) -> f64 {
        std::mem::take(&mut self.peak_current_a)
    }

    /// How often the application started (power-on, restarts, saves).
    #[must_use]
    pub const fn starts(&self) -> u32 {
        self.starts
    }

    /// Saves the power cut short (the board then came back on).
    #[must_use]
    pub const fn cut_saves(&self) -> u32 {
        self.cut_saves
    }

    /// How the last start found its parameters.
    #[must_use]
    pub fn last_boot(&self) -> Option<&Boot> {
        self.last_boot.as_ref()
    }

    /// The operating state.
    #[must_use]
    pub fn mode(&self) -> Mode {
        self.running
            .as_ref()
            .map_or(Mode::Disarmed, |r| r.controller.mode())
    }

    /// The set point \[m\].
    #[must_use]
    pub fn setpoint_m(&self) -> f32 {
        self.running
            .as_ref()
            .map_or(0.0, |r| r.controller.setpoint_m())
    }

    /// The parameters in use.
    #[must_use]
    pub fn params(&self) -> Params {
        self.running
            .as_ref()
            .map_or(self.defaults, |r| *r.dispatcher.params())
    }

    /// Frames refused and telemetry dropped.
    #[must_use]
    pub fn counts(&self) -> device::Counts {
        self.running
            .as_ref()
            .map(|r| r.dispatcher.counts())
            .unwrap_or_default()
    }

    /// The true position \[m\].
    #[must_use]
    pub fn position_m(&self) -> f64 {
        self.plant.stepper.sample().x_m
    }

    /// One control period: the dispatcher takes the bytes it can, the controller ticks on
    /// the plant's conversions, the plant advances one period, the dispatcher completes
    /// answers and telemetry; a save or restart the dispatcher asked for happens once its
    /// answer is out.
    ///
    /// # Errors
    /// A restart that fails (an actuator whose settings do not derive).
    pub fn tick(&mut self) -> Result<Ticked, Error> {
        let Some(run) = self.running.as_mut() else {
            return Ok(Ticked::default());
        };
        let (mut main, mut isr) = run.queues.split();
        // The line: at most its rate's bytes this tick, into the ring while it has room.
        let per_tick = if self.options.uart {
            f64::from(protocol::BAUD) / 10.0 / self.scenario.rate_hz()
        } else {
            f64::INFINITY
        };
        self.credit = self.credit.map(|c| (c + per_tick).min(per_tick.max(1.0)));
        while self.credit[0] >= 1.0 {
            let Some(b) = self.line.pop_front() else {
                break;
            };
            self.credit[0] -= 1.0;
            if self.rx.len() < RX_RING || !self.options.uart {
                self.rx.push(b);
            } else {
                self.dropped.received += 1;
            }
        }
        if !self.main_hung {
            let taken = {
                let mut ro = ReadOnlyStore(&mut run.store);
                run.dispatcher.receive(&self.rx, &mut main, &mut ro)
            };
            self.rx.drain(..taken);
        }

        if self.plant.driver_fault {
            // The break input is held low: the outputs stay off, whatever software does.
            self.plant.stepper.trip_break();
        }
        let truth = self.plant.stepper.sample();
        self.peak_current_a = self.peak_current_a.max(truth.i_a.abs());
        let x = if self.plant.position_open {
            -1.0
        } else {
            truth.x_m
        };
        let frame = self.plant.converter.sample(x, truth.i_a, truth.vbus_v);
        let now = (self.ticks.wrapping_mul(u64::from(self.period_ns))) as u32;
        let inputs = Inputs {
            frame,
            analog: self.plant.analog_code,
            start: Start {
                now,
                hardware_trip: self.plant.stepper.broken(),
            },
            break_active: self.plant.driver_fault || self.plant.stepper.break_input_active(),
        };
        let ticked = run
            .controller
            .tick(&mut self.plant.bridge, &inputs, &mut isr, End::default);
        if ticked.restore_outputs {
            // The firmware sets the timer's main output again.
            self.plant.stepper.release_break();
        }
        self.plant
            .stepper
            .advance(self.plant.lines.switches(), self.plant.mode);
        self.ticks += 1;

        if !self.main_hung {
            run.dispatcher.poll(&mut main);
            let out = if self.credit[1] >= run.dispatcher.tx().len() as f64 {
                run.dispatcher.tx().len()
            } else {
                self.credit[1].floor() as usize
            };
            self.credit[1] -= out as f64;
            self.tx.extend_from_slice(&run.dispatcher.tx()[..out]);
            run.dispatcher.sent(out);
        }
        let latched = run.controller.state().supervisor.latched();
        let action = if self.main_hung {
            None
        } else {
            run.dispatcher.take_action()
        };
        match action {
            Some(Action::Save(p)) => self.start(Some(p))?,
            Some(Action::Restart) => self.start(None)?,
            None => {}
        }
        // The window watchdog: a few periods without a feed reset the chip.
        self.unfed = if ticked.feed { 0 } else { self.unfed + 1 };
        if self.unfed > ema::device::guard::WATCHDOG_QUIET_PERIODS {
            let fault = if latched == Some(Fault::MainLoopStalled) {
                Fault::MainLoopStalled
            } else {
                Fault::Overrun
            };
            self.start_with(None, Some(fault))?;
        }
        Ok(ticked)
    }

    /// Runs `n` ticks.
    ///
    /// # Errors
    /// As [`VirtualBoard::tick`].
    pub fn run(&mut self, n: u64) -> Result<(), Error> {
        for _ in 0..n {
            self.tick()?;
        }
        Ok(())
    }

    /// Serves a host on `port` until `stop` is set: ticks in batches of a millisecond,
    /// `speed` times real time (`None`: as fast as it can), moving bytes between the port
    /// and the board, and calling `between` (stimuli), between batches.
    ///
    /// # Errors
    /// The port failing, or a restart that fails.
    pub fn serve<P: Read + Write>(
        &mut self,
        port: &mut P,
        speed: Option<f64>,
        stop: &AtomicBool,
        mut between: impl FnMut(&mut Self),
    ) -> anyhow::Result<()> {
        let batch = ((self.scenario.rate_hz() / 1000.0).round() as u64).max(1);
        let start = Instant::now();
        let t0 = self.ticks;
        let mut buf = [0u8; 1024];
        let busy = |e: &std::io::Error| {
            matches!(
                e.kind(),
                std::io::ErrorKind::TimedOut
                    | std::io::ErrorKind::WouldBlock
                    | std::io::ErrorKind::Interrupted
            )
        };
        while !stop.load(Ordering::Relaxed) {
            // Only as much as the line carries: the rest waits in the port, as it would
            // in a USB-serial adapter.
            if self.input_pending() < buf.len() {
                match port.read(&mut buf) {
                    Ok(n) => self.input(&buf[..n]),
                    Err(e) if busy(&e) => {}
                    Err(e) => return Err(e.into()),
                }
            }
            between(self);
            self.run(batch)?;
            let out = self.output();
            // What the host does not take is lost, as a UART's bytes are when nobody
            // listens: the board never waits for its host.
            let mut at = 0;
            while at < out.len() {
                match port.write(&out[at..]) {
                    Ok(0) => break,
                    Ok(n) => at += n,
                    Err(e) if busy(&e) => break,
                    Err(e) => return Err(e.into()),
                }
            }
            self.dropped.sent += (out.len() - at) as u64;
            if let Some(speed) = speed {
                let board_s = (self.ticks - t0) as f64 / self.scenario.rate_hz();
                let ahead = board_s / speed - start.elapsed().as_secs_f64();
                if ahead > 0.0 {
                    std::thread::sleep(Duration::from_secs_f64(ahead));
                }
            }
        }
        Ok(())
    }

    /// The flash, for a test that inspects it or moves it to another board.
    #[must_use]
    pub fn into_flash(mut self) -> Flash {
        match self.running.take() {
            Some(r) => r.store.release(),
            None => self.flash.take().unwrap_or_default(),
        }
    }
}

/// The store as the main loop sees it: read-only (on the chip a write would stall the
/// control interrupt; see the firmware's notes).
struct ReadOnlyStore<'a>(&'a mut Store<Flash>);

impl Storage for ReadOnlyStore<'_> {
    fn load(&mut self) -> Result<Params, LoadError<'static>> {
        // The same flash, through a wrapper that refuses writes: a load that would need a
        // repair fails as on the chip.
        let mut copy =
            Store::new(ReadOnly(self.0.flash()), store_range()).map_err(LoadError::Store)?;
        copy.load()
    }
}

impl Plant {
    fn new(sc: &Scenario) -> Result<Self, Error> {
        let plant = sc.plant.resolve(&sc.controller.plant);
        let stepper = Stepper::for_scenario(sc, plant, sc.integration.substeps)?;
        let converter = match &sc.sensors {
            Sensors::Adc(adc) => adc.start(&sc.controller.sense),
            Sensors::Ideal => Adc::default().start(&sc.controller.sense),
        };
        let (pwm, dir, en, lines) = hal::bridge_io(sc.bridge.max_duty);
        let bridge = match HBridge::new(pwm, dir, en) {
            Ok(b) => b,
            Err(e) => match e {},
        };
        Ok(Self {
            stepper,
            converter,
            bridge,
            lines,
            mode: sc.bridge.mode,
            position_open: false,
            analog_code: 0,
            driver_fault: false,
        })
    }
}

/// A store error as text.
#[must_use]
pub fn store_error(e: StoreError) -> &'static str {
    match e {
        StoreError::Flash => "the flash refused an operation",
        StoreError::Full => "no room left",
        StoreError::Corrupted => "corruption the store could not repair",
        StoreError::Internal => "the store's own check failed",
        StoreError::TooBig => "the set does not fit a record",
    }
}
