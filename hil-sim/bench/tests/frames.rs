//! A million random and mutated frames into the board's decoder and dispatcher (the
//! virtual board runs the firmware's own [`ema::device`]): none panics, every frame the
//! board cannot read is counted, the rejections it sends (at most
//! [`ema::device::REJECTIONS_PER_S`]) name the error the decoder gives for that frame, in
//! order, every valid request is answered, and a rejected frame never arms the board,
//! moves its set point or changes a parameter. A flood of noise with requests among it:
//! every request answered, and the rejections within their rate.
//!
//! Three kinds of input, drawn from a fixed seed (printed):
//! * noise: random bytes of random length;
//! * wire mutations of valid requests: bits flipped, bytes replaced (zeros included, which
//!   split a frame), inserted, deleted, truncated, repeated: nearly all fail the CRC;
//! * message mutations: the same operators on the postcard message of a valid request,
//!   then sealed with a correct CRC (and now and then another version), so the decoder's
//!   later checks and the dispatcher's validation see them; some of these are valid
//!   requests, which the board may carry out.
//!
//! The expected outcome of every frame comes from the core's own [`Framer`] and
//! [`protocol::decode`] run on the host over the same bytes; the board's answers must be
//! those, in order, with only rejections left out.

use bench::board::{Options, VirtualBoard};
use ema::control::actuator::Actuator;
use ema::device::protocol::{
    self, Command, FrameError, Framer, Message, Request, Trigger, Value, CRC, CRC_LEN, MAX_FRAME,
    VERSION,
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

const SEED: u64 = 0x00E3_A5EE_D000_0001;
const FRAMES: u64 = 1_000_000;
/// Rejected frames per batch: their answers (about 10 bytes each) fit the board's
/// transmit buffer.
const BATCH: usize = 48;

fn corpus() -> Vec<Command<'static>> {
    vec![
        Command::Status,
        Command::Arm,
        Command::Disarm,
        Command::Move {
            position_m: 3e-3,
            time_s: Some(0.05),
        },
        Command::Move {
            position_m: 1e-3,
            time_s: None,
        },
        Command::Clear,
        Command::Get {
            name: "tuning.margin",
        },
        Command::Set {
            name: "tuning.margin",
            value: Value::Number(0.6),
        },
        Command::Set {
            name: "setpoint.source",
            value: Value::Choice(1),
        },
        Command::Save,
        Command::Load,
        Command::Defaults,
        Command::Restart,
        Command::Stream {
            signals: 0b11,
            decimation: 20,
        },
        Command::Capture {
            samples: 16,
            decimation: 2,
            trigger: Trigger::Now,
        },
        Command::ReadCapture { offset: 0 },
        Command::Capture {
            samples: 64,
            decimation: 1,
            trigger: Trigger::Probe,
        },
        Command::Probe {
            amplitude_a: 0.3,
            half_ticks: 16,
            cycles: 2,
        },
    ]
}

/// COBS, as the core frames (`protocol::encode`), delimiter appended.
fn cobs(raw: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_at = 0;
    let mut code = 1u8;
    for &b in raw {
        if b == 0 {
            out[code_at] = code;
            code_at = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_at] = code;
    out.push(0);
    out
}

/// The inverse of [`cobs`] (without the delimiter), for valid frames.
fn uncobs(frame: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < frame.len() {
        let code = usize::from(frame[k]);
        out.extend_from_slice(&frame[k + 1..k + code]);
        k += code;
        if code < 0xFF && k < frame.len() {
            out.push(0);
        }
    }
    out
}

fn mutate(rng: &mut Pcg64Mcg, bytes: &mut Vec<u8>) {
    for _ in 0..rng.random_range(1..=4) {
        let n = bytes.len();
        match rng.random_range(0..7) {
            0 if n > 0 => {
                let k = rng.random_range(0..n);
                bytes[k] ^= 1 << rng.random_range(0..8);
            }
            1 if n > 0 => {
                let k = rng.random_range(0..n);
                bytes[k] = rng.random();
            }
            2 => {
                let k = rng.random_range(0..=n);
                bytes.insert(k, rng.random());
            }
            3 if n > 0 => {
                bytes.remove(rng.random_range(0..n));
            }
            4 if n > 0 => bytes.truncate(rng.random_range(0..n)),
            5 if n > 0 => {
                let from = rng.random_range(0..n);
                let to = rng.random_range(from..=n.min(from + 40));
                let chunk = bytes[from..to].to_vec();
                let at = rng.random_range(0..=bytes.len());
                bytes.splice(at..at, chunk);
            }
            _ => {
                let extra = rng.random_range(1..300);
                bytes.extend((0..extra).map(|_| rng.random::<u8>()));
            }
        }
    }
}

/// One input: bytes ending with a delimiter.
fn input(rng: &mut Pcg64Mcg, corpus: &[Command<'static>]) -> Vec<u8> {
    let command = corpus[rng.random_range(0..corpus.len())];
    let request = Request {
        seq: rng.random(),
        command,
    };
    let mut out = match rng.random_range(0..10) {
        0..=2 => {
            let len = rng.random_range(0..400);
            (0..len).map(|_| rng.random::<u8>()).collect()
        }
        3..=6 => {
            let mut frame = [0u8; MAX_FRAME];
            let n = protocol::encode(&request, &mut frame).unwrap();
            let mut bytes = frame[..n - 1].to_vec();
            mutate(rng, &mut bytes);
            bytes
        }
        _ => {
            let mut frame = [0u8; MAX_FRAME];
            let n = protocol::encode(&request, &mut frame).unwrap();
            let raw = uncobs(&frame[..n - 1]);
            let mut body = raw[1..raw.len() - CRC_LEN].to_vec();
            mutate(rng, &mut body);
            let version = if rng.random_range(0..50) == 0 {
                rng.random()
            } else {
                VERSION
            };
            let mut raw = vec![version];
            raw.extend_from_slice(&body);
            let crc = CRC.checksum(&raw).to_le_bytes();
            raw.extend_from_slice(&crc);
            let mut framed = cobs(&raw);
            framed.pop();
            framed
        }
    };
    out.push(0);
    out
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    Rejected(FrameError),
    Reply { seq: u16, command: Kind },
}

/// What an accepted command was, for the checks (strings do not outlive the frame).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Arm,
    Restarts,
    Other,
}

/// The outcomes the core's framer and decoder give for `bytes`, and where each frame
/// ends in them.
fn expected(framer: &mut Framer, bytes: &[u8]) -> Vec<(usize, Expect)> {
    let mut out = Vec::new();
    for (at, &b) in bytes.iter().enumerate() {
        let e = match framer.push(b) {
            None => continue,
            Some(Err(e)) => Expect::Rejected(e),
            Some(Ok(raw)) => match protocol::decode::<Request>(raw) {
                Err(e) => Expect::Rejected(e),
                Ok(r) => Expect::Reply {
                    seq: r.seq,
                    command: match r.command {
                        Command::Arm => Kind::Arm,
                        Command::Save | Command::Restart => Kind::Restarts,
                        _ => Kind::Other,
                    },
                },
            },
        };
        framer.clear();
        out.push((at, e));
    }
    out
}

/// The board's answers in `bytes` (telemetry and start announcements left out).
fn answers(framer: &mut Framer, bytes: &[u8], out: &mut Vec<Expect>) {
    for &b in bytes {
        let Some(raw) = framer.push(b) else { continue };
        let raw = raw.expect("the board sent a frame that does not fit");
        match protocol::decode::<Message>(raw).expect("the board sent a bad frame") {
            Message::Rejected(e) => out.push(Expect::Rejected(e)),
            Message::Reply { seq, .. } => out.push(Expect::Reply {
                seq,
                command: Kind::Other,
            }),
            Message::Telemetry(_) | Message::Started(_) => {}
        }
        framer.clear();
    }
}

fn same(got: &Expect, want: &Expect) -> bool {
    match (got, want) {
        (Expect::Reply { seq: a, .. }, Expect::Reply { seq: b, .. }) => a == b,
        _ => got == want,
    }
}

struct Fuzz {
    board: VirtualBoard,
    rx: Framer,
    got: Vec<Expect>,
    /// Rejections answered, by kind.
    answered: std::collections::BTreeMap<String, u64>,
}

/// A rejection's kind (its variant's name).
fn kind(e: &FrameError) -> String {
    format!("{e:?}")
        .split([' ', '{'])
        .next()
        .unwrap()
        .to_owned()
}

impl Fuzz {
    /// Feeds `bytes` and ticks until the replies in `want` are out and the board has
    /// counted every rejection in it (plus one tick, for a rejection still to leave);
    /// checks that the answers are `want` with only rejections left out; counts the
    /// rejections answered, by kind.
    fn exchange(&mut self, bytes: &[u8], want: &[Expect]) {
        let rejected = self.board.counts().rejected;
        let starts = self.board.starts();
        let wanted_rejections = want
            .iter()
            .filter(|e| matches!(e, Expect::Rejected(_)))
            .count() as u32;
        let replies = want.len() - wanted_rejections as usize;
        self.board.input(bytes);
        self.got.clear();
        let mut settled = false;
        for _ in 0..5_000 {
            self.board.tick().unwrap();
            let out = self.board.output();
            answers(&mut self.rx, &out, &mut self.got);
            let got_replies = self
                .got
                .iter()
                .filter(|e| matches!(e, Expect::Reply { .. }))
                .count();
            // A restart starts the counts again.
            let counted = self.board.starts() != starts
                || self.board.counts().rejected - rejected == wanted_rejections;
            if settled {
                break;
            }
            settled = got_replies >= replies && counted && self.board.input_pending() == 0;
        }
        // The answers: `want` with some rejections left out, nothing else.
        let mut next = self.got.iter().peekable();
        for w in want {
            match next.peek() {
                Some(g) if same(g, w) => {
                    next.next();
                }
                _ => assert!(
                    matches!(w, Expect::Rejected(_)),
                    "the reply {w:?} is missing: answers {:?}, wanted {want:?}",
                    self.got
                ),
            }
        }
        assert!(
            next.next().is_none(),
            "answers {:?} are not those wanted, in order: {want:?}",
            self.got
        );
        for g in &self.got {
            if let Expect::Rejected(r) = g {
                *self.answered.entry(kind(r)).or_default() += 1;
            }
        }
    }
}

#[test]
fn a_million_random_and_mutated_frames_are_answered_by_name_and_change_nothing() {
    println!("seed {SEED:#x}");
    let mut rng = Pcg64Mcg::seed_from_u64(SEED);
    let corpus = corpus();
    let mut fuzz = Fuzz {
        board: VirtualBoard::new(Options {
            uart: false,
            ..Options::default()
        })
        .unwrap(),
        rx: Framer::new(),
        got: Vec::new(),
        answered: std::collections::BTreeMap::new(),
    };
    // The start announcement.
    fuzz.exchange(&[], &[]);
    let mut host = Framer::new();
    let (mut frames, mut rejected, mut accepted, mut inputs) = (0u64, 0u64, 0u64, 0u64);
    let mut by_error = std::collections::BTreeMap::<String, u64>::new();
    let mut batch: Vec<u8> = Vec::new();
    let mut batch_want: Vec<Expect> = Vec::new();
    let mut arms = 0u64;

    let flush = |fuzz: &mut Fuzz, batch: &mut Vec<u8>, want: &mut Vec<Expect>| {
        if want.is_empty() {
            return;
        }
        let (mode, params, setpoint) = (
            fuzz.board.mode(),
            fuzz.board.params(),
            fuzz.board.setpoint_m(),
        );
        let refused = fuzz.board.counts().rejected;
        fuzz.exchange(batch, want);
        // Rejected frames only: nothing armed, moved or changed; each one counted.
        assert!(
            mode.armed() || !fuzz.board.mode().armed(),
            "a rejected frame armed the board"
        );
        assert_eq!(
            fuzz.board.params(),
            params,
            "a rejected frame changed a parameter"
        );
        assert_eq!(fuzz.board.setpoint_m().to_bits(), setpoint.to_bits());
        assert_eq!(fuzz.board.counts().rejected - refused, want.len() as u32);
        batch.clear();
        want.clear();
    };

    while frames < FRAMES {
        let mut bytes = input(&mut rng, &corpus);
        inputs += 1;
        let mut want = expected(&mut host, &bytes);
        // A save or restart starts the board again (a new framer, received bytes
        // dropped): the input ends with it.
        if let Some(k) = want.iter().position(|(_, e)| {
            matches!(
                e,
                Expect::Reply {
                    command: Kind::Restarts,
                    ..
                }
            )
        }) {
            bytes.truncate(want[k].0 + 1);
            want.truncate(k + 1);
        }
        frames += want.len() as u64;
        for (_, e) in &want {
            if let Expect::Rejected(r) = e {
                rejected += 1;
                *by_error.entry(kind(r)).or_default() += 1;
            } else {
                accepted += 1;
            }
        }
        let want: Vec<Expect> = want.into_iter().map(|(_, e)| e).collect();
        if want.iter().all(|e| matches!(e, Expect::Rejected(_))) {
            batch.extend_from_slice(&bytes);
            batch_want.extend_from_slice(&want);
            if batch_want.len() >= BATCH {
                flush(&mut fuzz, &mut batch, &mut batch_want);
            }
        } else {
            flush(&mut fuzz, &mut batch, &mut batch_want);
            let armed = fuzz.board.mode().armed();
            fuzz.exchange(&bytes, &want);
            if !armed && fuzz.board.mode().armed() {
                // Only an accepted arm command arms.
                assert!(
                    want.iter().any(|e| matches!(
                        e,
                        Expect::Reply {
                            command: Kind::Arm,
                            ..
                        }
                    )),
                    "armed without an arm command: {want:?}"
                );
                arms += 1;
            }
        }
    }
    flush(&mut fuzz, &mut batch, &mut batch_want);

    println!(
        "{inputs} inputs, {frames} frames: {rejected} rejected ({by_error:?}), answered by name {:?}, {accepted} valid requests carried out (the board armed {arms} times by an arm command); {} starts",
        fuzz.answered,
        fuzz.board.starts()
    );
    assert!(frames >= FRAMES);
    // Every kind of damage is met, and valid requests too (the dispatcher's own refusals).
    for kind in [
        "Cobs",
        "Short",
        "Crc",
        "Version",
        "Truncated",
        "Malformed",
        "Trailing",
        "TooLong",
    ] {
        assert!(
            by_error.get(kind).copied().unwrap_or(0) > 100,
            "{kind}: {by_error:?}"
        );
        // Answered (within the rate) and named as the decoder names it: some of each.
        assert!(
            fuzz.answered.get(kind).copied().unwrap_or(0) > 0,
            "{kind} never answered: {:?}",
            fuzz.answered
        );
    }
    assert!(accepted > 10_000, "{accepted}");
}

/// Noise at the link's full rate (a zero in every four bytes: a damaged frame in every
/// four), with a valid request after every 900 bytes of it, into
/// a board whose link runs at the UART's rate: every request is answered, and the board
/// sends no more rejections than [`ema::device::REJECTIONS_PER_S`] allows over the time
/// the line took.
#[test]
fn a_noisy_line_gets_every_reply_and_its_rejections_within_their_rate() {
    println!("seed {SEED:#x}");
    let mut rng = Pcg64Mcg::seed_from_u64(SEED ^ 0x5a);
    let mut board = VirtualBoard::new(Options::default()).unwrap();
    let mut bytes = Vec::new();
    let requests = 50u16;
    for seq in 0..requests {
        bytes.extend((0..900).map(|_| {
            if rng.random_range(0..4) == 0 {
                0
            } else {
                rng.random::<u8>()
            }
        }));
        bytes.push(0);
        let mut frame = [0u8; MAX_FRAME];
        let command = if seq % 2 == 0 {
            Command::Status
        } else {
            Command::Get {
                name: "tuning.margin",
            }
        };
        let n = protocol::encode(&Request { seq, command }, &mut frame).unwrap();
        bytes.extend_from_slice(&frame[..n]);
    }
    board.input(&bytes);
    let (mut rx, mut got) = (Framer::new(), Vec::new());
    let t0 = board.ticks();
    while board.input_pending() > 0 {
        board.tick().unwrap();
        answers(&mut rx, &board.output(), &mut got);
    }
    for _ in 0..2_000 {
        board.tick().unwrap();
        answers(&mut rx, &board.output(), &mut got);
    }
    let seconds = (board.ticks() - t0) as f64 / f64::from(Actuator::PRODUCT.board.rate_hz);
    let replies: Vec<u16> = got
        .iter()
        .filter_map(|e| match e {
            Expect::Reply { seq, .. } => Some(*seq),
            Expect::Rejected(_) => None,
        })
        .collect();
    let sent = got.len() - replies.len();
    let counted = board.counts().rejected;
    let allowed = (f64::from(ema::device::REJECTIONS_PER_S) * seconds).ceil() as usize + 1;
    println!(
        "{} bytes in {seconds:.3} s of line: {} replies, {counted} frames rejected, {sent} rejections sent ({allowed} allowed)",
        bytes.len(),
        replies.len()
    );
    assert_eq!(replies, (0..requests).collect::<Vec<_>>());
    assert!(sent <= allowed, "{sent} rejections sent, {allowed} allowed");
    assert!(counted as usize > sent, "{counted} rejected, {sent} sent");
    assert_eq!(board.dropped(), Default::default());
}
