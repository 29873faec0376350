//! A simulated NOR flash with the STM32F405's geometry for the parameter store, that can
//! lose its power at any single write or erase.
//!
//! The store's two pages are the chip's two 16 KiB sectors the firmware keeps its
//! parameters in ([`ema::device::store::SECTOR_BYTES`]); byte writes, as the HAL programs
//! them. A write can only clear bits; an erase sets a whole page to `0xFF`.
//!
//! **Power cuts.** [`Flash::cut_after`] arms a cut: the flash counts every byte it
//! programs and every page it erases as one step, and at the chosen step the power goes:
//! the byte being programmed ends up with only some of its bits cleared (the first half
//! of them, as a program pulse cut short leaves it), the page being erased ends up half
//! erased, and every operation after that fails ([`Cut`]) until the board restarts
//! ([`Flash::power_on`]). [`Flash::steps`] counts the steps of an operation, so a test
//! can cut at each of them in turn.

use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Bytes per erase page (the STM32F405 sector the store uses).
pub const PAGE: usize = ema::device::store::SECTOR_BYTES;
/// Pages of the store.
pub const PAGES: usize = 2;

/// The error after a power cut (or outside the flash).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// The power went.
    PowerLost,
    /// Outside the flash or not page-aligned.
    OutOfBounds,
}

impl NorFlashError for Cut {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Cut::PowerLost => NorFlashErrorKind::Other,
            Cut::OutOfBounds => NorFlashErrorKind::OutOfBounds,
        }
    }
}

/// The flash, with erase pages of `P` bytes.
#[derive(Clone, Debug)]
pub struct Flash<const P: usize = PAGE> {
    bytes: Vec<u8>,
    steps: u64,
    erases: u64,
    cut_at: Option<u64>,
    dead: bool,
}

impl Default for Flash {
    /// The chip's: two sectors of [`PAGE`] bytes.
    fn default() -> Self {
        Self::new(PAGES)
    }
}

impl<const P: usize> Flash<P> {
    /// Erased, `pages` pages.
    #[must_use]
    pub fn new(pages: usize) -> Self {
        Self {
            bytes: vec![0xFF; P * pages],
            steps: 0,
            erases: 0,
            cut_at: None,
            dead: false,
        }
    }

    /// The power goes at step `step` from now (0: the next byte or page).
    pub fn cut_after(&mut self, step: u64) {
        self.cut_at = Some(self.steps + step);
    }

    /// Steps (bytes programmed, pages erased) since the flash was made.
    #[must_use]
    pub const fn steps(&self) -> u64 {
        self.steps
    }

    /// Pages erased (or begun) since the flash was made.
    #[must_use]
    pub const fn erases(&self) -> u64 {
        self.erases
    }

    /// Whether the power was cut.
    #[must_use]
    pub const fn is_dead(&self) -> bool {
        self.dead
    }

    /// The board restarts: operations work again, no cut is armed.
    pub fn power_on(&mut self) {
        self.dead = false;
        self.cut_at = None;
    }

    /// The contents.
    #[must_use]
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// One step; `true` when the power goes at it.
    fn step(&mut self) -> bool {
        let now = self.steps;
        self.steps += 1;
        if self.cut_at == Some(now) {
            self.dead = true;
            self.cut_at = None;
            return true;
        }
        false
    }

    fn alive(&self) -> Result<(), Cut> {
        if self.dead {
            Err(Cut::PowerLost)
        } else {
            Ok(())
        }
    }
}

impl<const P: usize> ErrorType for Flash<P> {
    type Error = Cut;
}

impl<const P: usize> ReadNorFlash for Flash<P> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Cut> {
        self.alive()?;
        let at = offset as usize;
        let src = self
            .bytes
            .get(at..at + bytes.len())
            .ok_or(Cut::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.bytes.len()
    }
}

impl<const P: usize> NorFlash for Flash<P> {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = P;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Cut> {
        self.alive()?;
        let (from, to) = (from as usize, to as usize);
        if from % P != 0 || to % P != 0 || to > self.bytes.len() {
            return Err(Cut::OutOfBounds);
        }
        for start in (from..to).step_by(P) {
            self.erases += 1;
            let cut = self.cut_at == Some(self.steps);
            let page = &mut self.bytes[start..start + P];
            if cut {
                // Half erased: the first half of the page reads 0xFF, the rest as before.
                page[..P / 2].fill(0xFF);
                self.step();
                return Err(Cut::PowerLost);
            }
            page.fill(0xFF);
            self.step();
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Cut> {
        self.alive()?;
        let at = offset as usize;
        if at + bytes.len() > self.bytes.len() {
            return Err(Cut::OutOfBounds);
        }
        for (k, &b) in bytes.iter().enumerate() {
            let cut = self.step();
            let cell = &mut self.bytes[at + k];
            if cut {
                // The program pulse cut short: only the lower half of the bits it was to
                // clear are cleared.
                *cell &= b | 0xF0;
                return Err(Cut::PowerLost);
            }
            *cell &= b;
        }
        Ok(())
    }
}

impl<const P: usize> MultiwriteNorFlash for Flash<P> {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_clear_bits_and_a_cut_leaves_a_partial_byte() {
        let mut f = Flash::<256>::new(2);
        f.write(0, &[0x0F, 0xAA]).unwrap();
        let mut b = [0; 2];
        f.read(0, &mut b).unwrap();
        assert_eq!(b, [0x0F, 0xAA]);
        f.cut_after(1);
        assert_eq!(f.write(2, &[0x00, 0x00, 0x00]), Err(Cut::PowerLost));
        assert!(f.is_dead());
        assert_eq!(f.read(0, &mut b), Err(Cut::PowerLost));
        f.power_on();
        let mut c = [0; 3];
        f.read(2, &mut c).unwrap();
        // Byte 2 written, byte 3 half programmed, byte 4 untouched.
        assert_eq!(c, [0x00, 0xF0, 0xFF]);
        f.cut_after(0);
        assert_eq!(f.erase(0, 512), Err(Cut::PowerLost));
        f.power_on();
        let mut d = [0; 256];
        f.read(0, &mut d).unwrap();
        assert!(d[..128].iter().all(|&x| x == 0xFF));
        assert_eq!(d[128..131], [0xFF; 3]);
        f.read(2, &mut c).unwrap();
        assert_eq!(c, [0xFF; 3]);
    }
}
