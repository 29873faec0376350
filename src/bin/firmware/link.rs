//! The bench link on USART2 with DMA, at register level: received bytes land in a circular
//! buffer by DMA (DMA1 stream 5, channel 4), which the main loop reads where the DMA has
//! written up to; frames go out by DMA (DMA1 stream 6, channel 4) from a buffer the main
//! loop fills when the last transfer has ended. No interrupt: the main loop, woken by every
//! control interrupt (20 kHz), polls both streams, so nothing of the link can delay the
//! tick or reach it.
//!
//! **Why a UART and not USB (CDC-ACM through the OTG FS port).** With DMA and polling the
//! link needs no interrupt, so nothing of it competes with the control interrupt, while a
//! USB device must answer the host within its protocol's deadlines and so needs an
//! interrupt of its own and a device stack (`usb-device`, `usbd-serial`, the OTG driver).
//! A UART also goes through any USB-serial
//! adapter, isolated ones included: on a bench with a 24-48 V bridge that keeps the PC's
//! ground off the power stage's, which a USB cable straight to the board would not. The
//! price is the adapter and the rate below.
//!
//! At [`ema::device::protocol::BAUD`] (460 800 baud, 46 bytes per millisecond), the receive
//! ring ([`RX_RING`] bytes) holds more than 5 ms of input; the main loop reads it every 50
//! us except while it writes the flash, which only happens before the link starts (see
//! `app`). A host that sends more than the ring holds while the dispatcher waits for an
//! answer (one tick) would lose bytes: the CRC of the frame then refuses it by name.

use stm32f4xx_hal::pac;
use stm32f4xx_hal::rcc::{Enable, Rcc, Reset};

use crate::board;

/// Receive ring \[bytes\].
pub const RX_RING: usize = 256;
/// Transmit buffer \[bytes\]: the dispatcher's whole transmit buffer fits.
pub const TX_BUFFER: usize = ema::device::TX_CAPACITY;

/// DMA1 stream of USART2_RX (channel 4).
const RX_STREAM: usize = 5;
/// DMA1 stream of USART2_TX (channel 4).
const TX_STREAM: usize = 6;
/// DMA_SxCR: channel 4 (CHSEL), byte sizes, memory increment.
const DMA_CHSEL4: u32 = 4 << 25;
const DMA_MINC: u32 = 1 << 10;
const DMA_CIRC: u32 = 1 << 8;
const DMA_DIR_M2P: u32 = 0b01 << 6;
const DMA_EN: u32 = 1;
/// DMA_HIFCR: every flag of stream 5 (bits 6, 8-11) and of stream 6 (bits 16, 18-21).
const HIFCR_STREAM5: u32 = 0x0000_0F40;
const HIFCR_STREAM6: u32 = 0x003D_0000;
/// USART_CR1: enable, transmitter, receiver.
const CR1_UE: u16 = 1 << 13;
const CR1_TE: u16 = 1 << 3;
const CR1_RE: u16 = 1 << 2;
/// USART_CR3: DMA for transmission and reception.
const CR3_DMAT: u16 = 1 << 7;
const CR3_DMAR: u16 = 1 << 6;
/// USART_SR: transmission complete.
const SR_TC: u16 = 1 << 6;

/// USART_BRR at 16x oversampling: PCLK1 / baud, rounded (42 MHz / 460 800 = 91.1: 91,
/// 0.16 % fast).
pub const USART_BRR: u16 = {
    let brr = (board::PCLK1_HZ + ema::device::protocol::BAUD / 2) / ema::device::protocol::BAUD;
    assert!(brr >= 16 && brr < 1 << 16);
    brr as u16
};

/// The link: the two DMA buffers and the receive position.
pub struct Link {
    rx: &'static mut [u8; RX_RING],
    tx: &'static mut [u8; TX_BUFFER],
    /// Next byte of the ring to read.
    tail: usize,
}

fn dma1() -> &'static pac::dma2::RegisterBlock {
    // SAFETY: DMA1's streams 5 and 6 belong to the link, which only the main loop uses.
    unsafe { &*pac::DMA1::ptr() }
}

fn usart2() -> &'static pac::usart1::RegisterBlock {
    // SAFETY: USART2 belongs to the link, which only the main loop uses.
    unsafe { &*pac::USART2::ptr() }
}

impl Link {
    /// USART2 at [`ema::device::protocol::BAUD`], 8N1, its pins ([`board::LINK_TX_PIN`],
    /// [`board::LINK_RX_PIN`]) already in their alternate function; reception running.
    pub fn start(
        _usart: pac::USART2,
        _dma: pac::DMA1,
        rx: &'static mut [u8; RX_RING],
        tx: &'static mut [u8; TX_BUFFER],
        rcc: &mut Rcc,
    ) -> Self {
        pac::USART2::enable(rcc);
        pac::USART2::reset(rcc);
        pac::DMA1::enable(rcc);
        pac::DMA1::reset(rcc);
        let u = usart2();
        let d = dma1();
        // SAFETY: register values from RM0090 (USART and DMA chapters); the buffers are
        // 'static and only the DMA writes the ring.
        unsafe {
            u.brr().write(|w| w.bits(USART_BRR));
            u.cr3().write(|w| w.bits(CR3_DMAT | CR3_DMAR));
            let s = d.st(RX_STREAM);
            s.par().write(|w| w.bits(u.dr().as_ptr() as u32));
            s.m0ar().write(|w| w.bits(rx.as_mut_ptr() as u32));
            s.ndtr().write(|w| w.bits(RX_RING as u32));
            d.hifcr().write(|w| w.bits(HIFCR_STREAM5 | HIFCR_STREAM6));
            s.cr()
                .write(|w| w.bits(DMA_CHSEL4 | DMA_MINC | DMA_CIRC | DMA_EN));
            let s = d.st(TX_STREAM);
            s.par().write(|w| w.bits(u.dr().as_ptr() as u32));
            s.cr()
                .write(|w| w.bits(DMA_CHSEL4 | DMA_MINC | DMA_DIR_M2P));
            u.cr1().write(|w| w.bits(CR1_UE | CR1_TE | CR1_RE));
        }
        Self { rx, tx, tail: 0 }
    }

    /// Where the DMA writes next.
    fn head(&self) -> usize {
        let left = dma1().st(RX_STREAM).ndtr().read().bits() as usize;
        // NDTR counts down from RX_RING to 1 and reloads: 0 is never read, but be safe.
        RX_RING.saturating_sub(left) % RX_RING
    }

    /// The received bytes not yet consumed, as one contiguous run (the rest of a wrapped
    /// run comes at the next call).
    pub fn received(&self) -> &[u8] {
        let head = self.head();
        let end = if head >= self.tail { head } else { RX_RING };
        self.rx.get(self.tail..end).unwrap_or(&[])
    }

    /// The first `n` bytes of [`Link::received`] were taken.
    pub fn consume(&mut self, n: usize) {
        self.tail = (self.tail + n) % RX_RING;
    }

    /// The last transmission has ended (the DMA stream has stopped).
    pub fn tx_idle(&self) -> bool {
        dma1().st(TX_STREAM).cr().read().bits() & DMA_EN == 0
    }

    /// Starts sending the first bytes of `bytes` (as many as the buffer holds) if the
    /// last transmission has ended; returns how many.
    pub fn send(&mut self, bytes: &[u8]) -> usize {
        if bytes.is_empty() || !self.tx_idle() {
            return 0;
        }
        let n = bytes.len().min(TX_BUFFER);
        let (Some(dst), Some(src)) = (self.tx.get_mut(..n), bytes.get(..n)) else {
            return 0;
        };
        dst.copy_from_slice(src);
        let d = dma1();
        let s = d.st(TX_STREAM);
        // SAFETY: the stream is stopped; the buffer is 'static and not written again
        // until the stream has stopped.
        unsafe {
            d.hifcr().write(|w| w.bits(HIFCR_STREAM6));
            s.m0ar().write(|w| w.bits(self.tx.as_ptr() as u32));
            s.ndtr().write(|w| w.bits(n as u32));
            s.cr()
                .write(|w| w.bits(DMA_CHSEL4 | DMA_MINC | DMA_DIR_M2P | DMA_EN));
        }
        n
    }

    /// Waits until the last byte has left the line (before a reset).
    pub fn flush(&self) {
        while !self.tx_idle() {}
        while usart2().sr().read().bits() & SR_TC == 0 {}
    }
}
