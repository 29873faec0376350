//! A virtual board on a pseudo-terminal, served as fast as it can, and the host tool's
//! link to it opened by the terminal's path, as `bench --port` does: the rig of the tests
//! that drive the board through the real serial path.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::thread;
use std::time::Duration;

use bench::board::{Dropped, Options, Stimulus, VirtualBoard};
use bench::cli;
use bench::link::Link;
use ema::device::protocol::{Command, Message, Reply};

pub struct Rig {
    pub link: Link<serialport::TTYPort>,
    pub inject: mpsc::Sender<Stimulus>,
    /// The board's ticks and the bytes it dropped, sent and received, as of its last
    /// batch.
    seen: Arc<Mutex<(u64, Dropped)>>,
    /// The largest coil current since the last [`Rig::take_peak_current_a`] (the bits of a
    /// non-negative `f64`, which order as the values do).
    peak: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    /// The board's thread; it ends with the board's starts and cut saves.
    board: Option<thread::JoinHandle<(u32, u32)>>,
    _slave: serialport::TTYPort,
}

impl Rig {
    /// A board made with `options`, served as fast as it can, started and announced; its
    /// link timeout is off (a host's heartbeat, paced in real time, cannot keep up with a
    /// board that runs faster: [`Options::link`]).
    pub fn new(options: Options) -> Self {
        let link = ema::device::liveness::Settings {
            timeout_s: 0.0,
            ..options.link
        };
        Self::with_speed(Options { link, ..options }, None)
    }

    /// A board made with `options`, served at `speed` times real time (`None`: as fast as
    /// it can), started and announced.
    pub fn with_speed(options: Options, speed: Option<f64>) -> Self {
        let (master, slave) = serialport::TTYPort::pair().unwrap();
        let path = serialport::SerialPort::name(&slave).unwrap();
        // Opened (and its input flushed) before the board runs, so that its start
        // announcement is read.
        let mut link = cli::open(path.as_ref(), Duration::from_secs(5)).unwrap();
        let (tx, rx) = mpsc::channel::<Stimulus>();
        let stop = Arc::new(AtomicBool::new(false));
        let stop2 = stop.clone();
        let peak = Arc::new(AtomicU64::new(0));
        let peak2 = peak.clone();
        let seen = Arc::new(Mutex::new((0, Dropped::default())));
        let seen2 = seen.clone();
        let board = thread::spawn(move || {
            let mut master = master;
            serialport::SerialPort::set_timeout(&mut master, Duration::from_millis(1)).unwrap();
            let mut b = VirtualBoard::new(options).unwrap();
            b.serve(&mut master, speed, &stop2, |b| {
                while let Ok(i) = rx.try_recv() {
                    b.inject(i);
                }
                peak2.fetch_max(b.take_peak_current_a().to_bits(), Ordering::Relaxed);
                *seen2.lock().unwrap() = (b.ticks(), b.dropped());
            })
            .unwrap();
            (b.starts(), b.cut_saves())
        });
        link.wait_started(Duration::from_secs(5)).unwrap();
        Self {
            link,
            inject: tx,
            seen,
            peak,
            stop,
            board: Some(board),
            _slave: slave,
        }
    }

    /// The board's ticks so far.
    #[allow(dead_code)]
    pub fn ticks(&self) -> u64 {
        self.seen.lock().unwrap().0
    }

    /// The bytes the board dropped so far.
    #[allow(dead_code)]
    pub fn dropped(&self) -> Dropped {
        self.seen.lock().unwrap().1
    }

    /// Waits, without a word on the link, until the board has run `ticks` more ticks.
    #[allow(dead_code)]
    pub fn wait_ticks(&self, ticks: u64) {
        let until = self.ticks() + ticks;
        while self.ticks() < until {
            thread::sleep(Duration::from_millis(1));
        }
    }

    /// The host falls silent (its process hung: the port still open, no heartbeat) until
    /// `back` returns; then it talks again.
    #[allow(dead_code)]
    pub fn host_away(&mut self, back: impl FnOnce(&Self)) {
        self.link.stop_heartbeat();
        back(self);
        self.link.start_heartbeat();
    }

    pub fn status(&mut self) -> ema::device::protocol::Status<'static> {
        cli::status(&mut self.link).unwrap()
    }

    /// The refusal `command` meets, as text; panics when it is not refused.
    pub fn refusal(&mut self, command: Command<'_>) -> String {
        let f = self.link.request(command).unwrap();
        let mut scratch = Vec::new();
        match f.message(&mut scratch).unwrap() {
            Message::Reply {
                reply: Reply::Refused(r),
                ..
            } => format!("{r:?}"),
            other => panic!("not refused: {other:?}"),
        }
    }

    /// The largest coil current since the last call (or the start) \[A\].
    #[allow(dead_code)]
    pub fn take_peak_current_a(&self) -> f64 {
        f64::from_bits(self.peak.swap(0, Ordering::Relaxed))
    }

    /// Stops the board; its starts and cut saves.
    pub fn finish(mut self) -> (u32, u32) {
        self.stop.store(true, Ordering::Relaxed);
        self.board.take().unwrap().join().unwrap()
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(b) = self.board.take() {
            let _ = b.join();
        }
    }
}
