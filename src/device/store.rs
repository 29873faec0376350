//! Parameters in flash: [`sequential-storage`](sequential_storage)'s map over any
//! `embedded-storage` NOR flash (the chip's through its HAL, a simulated one in `hil-sim`
//! and in the tests).
//!
//! **Power cuts.** sequential-storage appends: a save writes a new item after the old one
//! (item header with its own CRC, then the data with a CRC), and the old item is only
//! dropped once a newer one reads back whole; a page is erased only after what it still
//! holds has been copied on. A power cut at any point therefore leaves the old set or the
//! new one readable, never a mix; a half-written item is ignored and the store repairs
//! itself on the next operation. `hil-sim`'s test cuts the power at every single write
//! and erase of a save and reads back after each.
//!
//! **The record.** On top, the set is stored as one record
//! `FORMAT (u16 LE) | postcard(Params) | CRC-32C (u32 LE)`: a set whose bytes changed is
//! refused by its CRC; a set of an earlier format is migrated (each format's layout is
//! kept here, and what a later format added takes its default); a set of a format this
//! firmware does not know (a later one) is refused by version; a set that decodes is
//! still validated as a build validates an actuator file before it is used
//! ([`crate::device::params::Params::build`], by the caller). A refused set stays in the
//! flash until a save replaces it, and the board runs its built-in defaults and says why
//! ([`LoadError`]); the host tool backs a set up and restores it across a firmware that
//! cannot read it (`bench backup`, `bench restore`).
//!
//! | format | layout | read as |
//! |---|---|---|
//! | 1 | the actuator, the set point's source and filter | format 2 with the link's default timeout |
//! | 2 | format 1, then the link's timeout and what it does on expiry ([`crate::device::liveness::Settings`]) | format 3 with no position correction |
//! | 3 ([`FORMAT`]) | format 2, then the position sensor's correction from the end stops ([`crate::control::sense::PositionCorrection`]) | itself |
//!
//! A change of [`Params`]' encoding without a new format fails a test that pins the
//! defaults' encoded bytes to the format number.
//!
//! **Blocking.** sequential-storage's operations are futures; with a flash whose
//! operations complete at once (the chip's, which stalls the CPU while it programs) they
//! are ready at the first poll, and [`block_on`] runs them without an executor.
//!
//! ```
//! use ema::control::actuator::Actuator;
//! use ema::device::params::Params;
//! use ema::device::protocol::LoadError;
//! use ema::device::store::{RamFlash, Store};
//!
//! let mut store = Store::new(RamFlash::<4096, 2>::new(), 0..8192).unwrap();
//! assert_eq!(store.load(), Err(LoadError::Empty));
//! let mut p = Params::new(Actuator::PRODUCT);
//! p.actuator.board.supply_v = 12.0;
//! store.save(&p).unwrap();
//! assert_eq!(store.load(), Ok(p));
//! ```

use core::future::Future;
use core::ops::Range;
use core::pin::pin;
use core::task::{Context, Poll, Waker};

use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

use crate::control::sense::PositionCorrection;
use crate::device::params::Params;
use crate::device::protocol::{LoadError, StoreError, CRC};

/// Version of the stored record this firmware writes (see the module documentation for
/// the earlier ones it reads).
pub const FORMAT: u16 = 3;

/// Format 1's layout: [`Params`] before the link's timeout.
#[derive(serde::Deserialize)]
struct Format1 {
    actuator: crate::control::actuator::Actuator,
    setpoint: crate::device::analog::Settings,
}

/// Format 2's layout: [`Params`] before the position sensor's correction.
#[derive(serde::Deserialize)]
struct Format2 {
    actuator: crate::control::actuator::Actuator,
    setpoint: crate::device::analog::Settings,
    link: crate::device::liveness::Settings,
}

/// The map key of the parameter set.
pub const KEY: u8 = 1;
/// Largest record \[bytes\].
pub const MAX_RECORD: usize = 200;
/// Bytes in each of the two flash sectors the board keeps its parameters in (the
/// STM32F405's sectors 1 and 2, 16 KiB each: the firmware's `board::STORE_RANGE`); the
/// virtual board's simulated flash has the same geometry.
pub const SECTOR_BYTES: usize = 16 * 1024;
/// Buffer the store works in: the record, its key, word alignment.
const BUFFER: usize = MAX_RECORD + 16;

/// Runs a future that needs no waking to completion (see the module documentation).
pub fn block_on<F: Future>(f: F) -> F::Output {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

/// A blocking `embedded-storage` flash seen through the asynchronous traits
/// sequential-storage takes: every operation completes before its future is polled.
#[derive(Debug)]
pub struct Blocking<F>(pub F);

impl<F: ErrorType> embedded_storage_async::nor_flash::ErrorType for Blocking<F> {
    type Error = F::Error;
}

impl<F: ReadNorFlash> embedded_storage_async::nor_flash::ReadNorFlash for Blocking<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl<F: NorFlash> embedded_storage_async::nor_flash::NorFlash for Blocking<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.0.erase(from, to)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write(offset, bytes)
    }
}

impl<F: MultiwriteNorFlash> embedded_storage_async::nor_flash::MultiwriteNorFlash for Blocking<F> {}

/// The parameter store.
pub struct Store<F: NorFlash> {
    map: MapStorage<u8, Blocking<F>, NoCache>,
}

/// No RAM cache: every operation reads the flash (a few hundred bytes per save).
type NoCache = Cache<Uncached, Uncached, Uncached, u8>;

/// Encodes `params` as a record into `buf`; returns its length.
///
/// # Errors
/// [`StoreError::TooBig`] when it does not fit.
pub fn encode(params: &Params, buf: &mut [u8; MAX_RECORD]) -> Result<usize, StoreError> {
    let (head, rest) = buf.split_at_mut(2);
    head.copy_from_slice(&FORMAT.to_le_bytes());
    let body = postcard::to_slice(params, rest)
        .map_err(|_| StoreError::TooBig)?
        .len();
    let len = body.checked_add(2).ok_or(StoreError::TooBig)?;
    let (covered, tail) = buf.split_at_mut(len);
    let crc = CRC.checksum(covered).to_le_bytes();
    tail.get_mut(..4)
        .ok_or(StoreError::TooBig)?
        .copy_from_slice(&crc);
    len.checked_add(4).ok_or(StoreError::TooBig)
}

/// Decodes a record, of this format or an earlier one (migrated).
///
/// # Errors
/// A CRC mismatch, a format this firmware does not read, bytes that do not decode.
pub fn decode(record: &[u8]) -> Result<Params, LoadError<'static>> {
    let n = record.len();
    let body_end = n
        .checked_sub(4)
        .filter(|&e| e >= 2)
        .ok_or(LoadError::Decode)?;
    let (covered, crc) = record.split_at(body_end);
    let mut got = [0u8; 4];
    got.copy_from_slice(crc);
    if CRC.checksum(covered) != u32::from_le_bytes(got) {
        return Err(LoadError::Crc);
    }
    let mut version = [0u8; 2];
    version.copy_from_slice(covered.get(..2).ok_or(LoadError::Decode)?);
    let body = covered.get(2..).ok_or(LoadError::Decode)?;
    match u16::from_le_bytes(version) {
        FORMAT => match postcard::take_from_bytes::<Params>(body) {
            Ok((p, [])) => Ok(p),
            _ => Err(LoadError::Decode),
        },
        2 => match postcard::take_from_bytes::<Format2>(body) {
            Ok((old, [])) => Ok(Params {
                actuator: old.actuator,
                setpoint: old.setpoint,
                link: old.link,
                sensor: PositionCorrection::NONE,
            }),
            _ => Err(LoadError::Decode),
        },
        1 => match postcard::take_from_bytes::<Format1>(body) {
            Ok((old, [])) => Ok(Params {
                actuator: old.actuator,
                setpoint: old.setpoint,
                link: crate::device::liveness::Settings::default(),
                sensor: PositionCorrection::NONE,
            }),
            _ => Err(LoadError::Decode),
        },
        found => Err(LoadError::Version {
            found,
            expected: FORMAT,
        }),
    }
}

#[inline(never)]
fn store_error<E>(e: &sequential_storage::Error<E>) -> StoreError {
    match e {
        sequential_storage::Error::Storage { .. } => StoreError::Flash,
        sequential_storage::Error::FullStorage => StoreError::Full,
        sequential_storage::Error::Corrupted { .. } => StoreError::Corrupted,
        sequential_storage::Error::BufferTooBig
        | sequential_storage::Error::BufferTooSmall(_)
        | sequential_storage::Error::ItemTooBig
        | sequential_storage::Error::SerializationError(_) => StoreError::TooBig,
        _ => StoreError::Internal,
    }
}

/// A word-aligned work buffer (some flashes need aligned writes from RAM).
#[repr(align(4))]
struct Buffer([u8; BUFFER]);

impl<F: NorFlash> Store<F> {
    /// A store on `flash` within `range` (whole erase pages, at least two).
    ///
    /// # Errors
    /// A range that is not whole pages or is shorter than two.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, StoreError> {
        let config = MapConfig::try_new(range).map_err(|_| StoreError::Internal)?;
        Ok(Self {
            map: MapStorage::new(Blocking(flash), config, Cache::new_uncached()),
        })
    }

    /// The stored set, decoded (validate it before use).
    ///
    /// # Errors
    /// Nothing stored, another format, a CRC mismatch, bytes that do not decode, or the
    /// flash failing.
    pub fn load(&mut self) -> Result<Params, LoadError<'static>> {
        let mut buf = Buffer([0; BUFFER]);
        let item = block_on(self.map.fetch_item::<&[u8]>(&mut buf.0, &KEY))
            .map_err(|e| LoadError::Store(store_error(&e)))?;
        match item {
            None => Err(LoadError::Empty),
            Some(record) => decode(record),
        }
    }

    /// Stores `params` (replacing the stored set, power-fail safe).
    ///
    /// # Errors
    /// The flash failing, no room, or a set too big for a record.
    #[inline(never)]
    pub fn save(&mut self, params: &Params) -> Result<(), StoreError> {
        let mut record = [0u8; MAX_RECORD];
        let n = encode(params, &mut record)?;
        let record = record.get(..n).ok_or(StoreError::TooBig)?;
        let mut buf = Buffer([0; BUFFER]);
        block_on(self.map.store_item(&mut buf.0, &KEY, &record)).map_err(|e| store_error(&e))
    }

    /// The flash, to read it through another view (see [`ReadOnly`]).
    pub fn flash(&mut self) -> &mut F {
        &mut self.map.flash().0
    }

    /// The flash back.
    pub fn release(self) -> F {
        self.map.destroy().0 .0
    }
}

/// A flash error of [`RamFlash`] and [`ReadOnly`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the flash, or not aligned.
    OutOfBounds,
    /// A write or erase on a read-only flash.
    ReadOnly,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::ReadOnly => NorFlashErrorKind::Other,
        }
    }
}

/// A flash in RAM: `PAGES` pages of `PAGE` bytes, erased to `0xFF`, writes clear bits as
/// NOR flash does (for tests and the on-target check).
#[derive(Clone, Debug)]
pub struct RamFlash<const PAGE: usize, const PAGES: usize> {
    pages: [[u8; PAGE]; PAGES],
}

impl<const PAGE: usize, const PAGES: usize> Default for RamFlash<PAGE, PAGES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const PAGE: usize, const PAGES: usize> RamFlash<PAGE, PAGES> {
    /// Erased.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            pages: [[0xFF; PAGE]; PAGES],
        }
    }

    fn byte(&mut self, at: usize) -> Option<&mut u8> {
        self.pages
            .get_mut(at.checked_div(PAGE)?)?
            .get_mut(at.checked_rem(PAGE)?)
    }
}

impl<const PAGE: usize, const PAGES: usize> ErrorType for RamFlash<PAGE, PAGES> {
    type Error = FlashError;
}

impl<const PAGE: usize, const PAGES: usize> ReadNorFlash for RamFlash<PAGE, PAGES> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let start = usize::try_from(offset).map_err(|_| FlashError::OutOfBounds)?;
        for (k, b) in bytes.iter_mut().enumerate() {
            let at = start.checked_add(k).ok_or(FlashError::OutOfBounds)?;
            *b = *self.byte(at).ok_or(FlashError::OutOfBounds)?;
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        PAGE.saturating_mul(PAGES)
    }
}

impl<const PAGE: usize, const PAGES: usize> NorFlash for RamFlash<PAGE, PAGES> {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = PAGE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let from = usize::try_from(from).map_err(|_| FlashError::OutOfBounds)?;
        let to = usize::try_from(to).map_err(|_| FlashError::OutOfBounds)?;
        let whole = |x: usize| x.checked_rem(PAGE) == Some(0);
        if !whole(from) || !whole(to) || to > self.capacity() {
            return Err(FlashError::OutOfBounds);
        }
        let (first, last) = (from.checked_div(PAGE), to.checked_div(PAGE));
        let (Some(first), Some(last)) = (first, last) else {
            return Err(FlashError::OutOfBounds);
        };
        for page in self.pages.iter_mut().take(last).skip(first) {
            page.fill(0xFF);
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let start = usize::try_from(offset).map_err(|_| FlashError::OutOfBounds)?;
        for (k, b) in bytes.iter().enumerate() {
            let at = start.checked_add(k).ok_or(FlashError::OutOfBounds)?;
            let cell = self.byte(at).ok_or(FlashError::OutOfBounds)?;
            *cell &= *b;
        }
        Ok(())
    }
}

impl<const PAGE: usize, const PAGES: usize> MultiwriteNorFlash for RamFlash<PAGE, PAGES> {}

/// A flash that can be read but not written: the chip's flash while the control interrupt
/// runs (a write or erase would stall it, see the firmware's `store` notes). A load that
/// would need to repair the store fails instead of writing.
#[derive(Debug)]
pub struct ReadOnly<F>(pub F);

impl<F: ReadNorFlash> ErrorType for ReadOnly<F> {
    type Error = FlashError;
}

impl<F: ReadNorFlash> ReadNorFlash for ReadOnly<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        self.0
            .read(offset, bytes)
            .map_err(|_| FlashError::OutOfBounds)
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl<F: NorFlash> NorFlash for ReadOnly<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, _: u32, _: u32) -> Result<(), FlashError> {
        Err(FlashError::ReadOnly)
    }

    fn write(&mut self, _: u32, _: &[u8]) -> Result<(), FlashError> {
        Err(FlashError::ReadOnly)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::control::actuator::Actuator;

    type Flash = RamFlash<1024, 2>;

    #[test]
    fn a_record_round_trips_and_every_damage_is_named() {
        let mut p = Params::new(Actuator::PRODUCT);
        p.actuator.coil.turns = 71.0;
        let mut rec = [0; MAX_RECORD];
        let n = encode(&p, &mut rec).unwrap();
        assert!(n < MAX_RECORD, "{n}");
        assert_eq!(decode(&rec[..n]), Ok(p));
        // Any flipped bit of the body: the CRC.
        for byte in 2..n - 4 {
            let mut bad = rec;
            bad[byte] ^= 0x04;
            assert_eq!(decode(&bad[..n]), Err(LoadError::Crc), "{byte}");
        }
        // A later format, sealed with its own CRC: refused by version.
        let mut other = rec;
        other[0] = 4;
        let crc = CRC.checksum(&other[..n - 4]).to_le_bytes();
        other[n - 4..n].copy_from_slice(&crc);
        assert_eq!(
            decode(&other[..n]),
            Err(LoadError::Version {
                found: 4,
                expected: FORMAT
            })
        );
        assert_eq!(decode(&rec[..3]), Err(LoadError::Decode));
    }

    /// A record sealed as the store seals one: `format`, `body`, the CRC.
    fn sealed(format: u16, body: &[u8]) -> std::vec::Vec<u8> {
        let mut rec = format.to_le_bytes().to_vec();
        rec.extend_from_slice(body);
        let crc = CRC.checksum(&rec).to_le_bytes();
        rec.extend_from_slice(&crc);
        rec
    }

    #[test]
    fn a_format_1_set_is_migrated_with_the_links_default() {
        #[derive(serde::Serialize)]
        struct Written {
            actuator: Actuator,
            setpoint: crate::device::analog::Settings,
        }
        let mut a = Actuator::PRODUCT;
        a.coil.turns = 72.0;
        let setpoint = crate::device::analog::Settings {
            source: crate::device::analog::Source::Current,
            filter_s: 0.01,
        };
        let mut body = [0u8; MAX_RECORD];
        let body = postcard::to_slice(
            &Written {
                actuator: a,
                setpoint,
            },
            &mut body,
        )
        .unwrap();
        let p = decode(&sealed(1, body)).unwrap();
        assert_eq!((p.actuator, p.setpoint), (a, setpoint));
        assert_eq!(p.link, crate::device::liveness::Settings::default());
        assert_eq!(p.sensor, PositionCorrection::NONE);
        // Format 1's bytes under a later number do not decode (they are shorter).
        assert_eq!(decode(&sealed(2, body)), Err(LoadError::Decode));
        assert_eq!(decode(&sealed(FORMAT, body)), Err(LoadError::Decode));
    }

    #[test]
    fn a_format_2_set_is_migrated_without_a_position_correction() {
        #[derive(serde::Serialize)]
        struct Written {
            actuator: Actuator,
            setpoint: crate::device::analog::Settings,
            link: crate::device::liveness::Settings,
        }
        let mut a = Actuator::PRODUCT;
        a.board.supply_v = 30.0;
        let link = crate::device::liveness::Settings {
            timeout_s: 0.25,
            ..crate::device::liveness::Settings::default()
        };
        let mut body = [0u8; MAX_RECORD];
        let body = postcard::to_slice(
            &Written {
                actuator: a,
                setpoint: crate::device::analog::Settings::default(),
                link,
            },
            &mut body,
        )
        .unwrap();
        let p = decode(&sealed(2, body)).unwrap();
        assert_eq!((p.actuator, p.link), (a, link));
        assert_eq!(p.sensor, PositionCorrection::NONE);
        // Format 2's bytes under format 3's number do not decode (they are shorter).
        assert_eq!(decode(&sealed(FORMAT, body)), Err(LoadError::Decode));
    }

    /// The encoded defaults, pinned to the format: a change of the parameters' encoding
    /// (a field added, removed, moved or retyped) fails here until [`FORMAT`] is raised
    /// and the old layout is read as a migration. (A change of the product's default
    /// values fails it too: then only the pinned figures change.)
    #[test]
    fn the_defaults_encoding_is_pinned_to_the_format() {
        let mut rec = [0; MAX_RECORD];
        let n = encode(&Params::new(Actuator::PRODUCT), &mut rec).unwrap();
        let crc = u32::from_le_bytes(rec[n - 4..n].try_into().unwrap());
        assert_eq!(
            (FORMAT, n, crc),
            (3, 147, 0xc664_4e8b),
            "the parameters' encoding changed: raise store::FORMAT and migrate the old one \
             (got {n} bytes, CRC {crc:#010x})"
        );
    }

    #[test]
    fn the_latest_save_is_loaded_across_page_changes() {
        let mut store = Store::new(Flash::new(), 0..2048).unwrap();
        let mut p = Params::new(Actuator::PRODUCT);
        // 1 KiB pages hold a handful of records: 40 saves wrap the pages many times.
        for k in 0..40 {
            p.actuator.board.supply_v = 12.0 + k as f32;
            store.save(&p).unwrap();
            assert_eq!(
                store.load().unwrap().actuator.board.supply_v,
                12.0 + k as f32
            );
        }
        // A fresh store on the same flash (a restart) reads the last one.
        let flash = store.release();
        let mut again = Store::new(flash, 0..2048).unwrap();
        assert_eq!(again.load().unwrap(), p);
    }

    #[test]
    fn a_read_only_flash_loads_and_refuses_to_save() {
        let mut store = Store::new(Flash::new(), 0..2048).unwrap();
        let p = Params::new(Actuator::PRODUCT);
        store.save(&p).unwrap();
        let mut ro = Store::new(ReadOnly(store.release()), 0..2048).unwrap();
        assert_eq!(ro.load(), Ok(p));
        assert_eq!(ro.save(&p), Err(StoreError::Flash));
        assert!(Store::new(Flash::new(), 0..1024).is_err());
    }
}
