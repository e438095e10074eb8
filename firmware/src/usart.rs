//! USART2 as a transmit-only serial port for the MAVLink stream, by its registers.
//!
//! USART2 (TX on PA2, RX on PA3, alternate function 7) is the port the autopilot is wired to.
//! QEMU's netduinoplus2 connects it to its second `-serial` backend; without one (the plain
//! `cargo run`) its bytes go nowhere, so the semihosting report on the console stays clean.
//!
//! Writing never waits: [`Usart::try_write`] puts a byte in the data register only when the
//! transmitter has room (TXE) and says whether it did.

use core::ptr::{read_volatile, write_volatile};

/// RCC: AHB1 and APB1 peripheral clock enables.
const RCC_AHB1ENR: *mut u32 = 0x4002_3830 as *mut u32;
const RCC_APB1ENR: *mut u32 = 0x4002_3840 as *mut u32;
const RCC_AHB1ENR_GPIOAEN: u32 = 1 << 0;
const RCC_APB1ENR_USART2EN: u32 = 1 << 17;
/// GPIOA: mode and alternate function (pins 0 to 7) registers.
const GPIOA_MODER: *mut u32 = 0x4002_0000 as *mut u32;
const GPIOA_AFRL: *mut u32 = 0x4002_0020 as *mut u32;
/// USART2's registers.
const USART2: usize = 0x4000_4400;
const SR: *mut u32 = USART2 as *mut u32;
const DR: *mut u32 = (USART2 + 0x04) as *mut u32;
const BRR: *mut u32 = (USART2 + 0x08) as *mut u32;
const CR1: *mut u32 = (USART2 + 0x0C) as *mut u32;
const SR_TXE: u32 = 1 << 7;
const CR1_UE: u32 = 1 << 13;
const CR1_TE: u32 = 1 << 3;
const CR1_RE: u32 = 1 << 2;
/// APB1 runs at 42 MHz with the 168 MHz system clock.
const APB1_HZ: u32 = 42_000_000;
/// The line rate: 921600 baud, 8N1, the usual rate of a MAVLink flow sensor's port.
pub const BAUD: u32 = 921_600;

/// The transmitter, once set up.
pub struct Usart {
    _private: (),
}

impl Usart {
    /// Clocks GPIOA and USART2, puts PA2/PA3 on the USART and enables it at [`BAUD`], 8N1.
    pub fn new() -> Self {
        // SAFETY: fixed register addresses of the STM32F405, written once at start-up before
        // anything else uses GPIOA or USART2; read-modify-write keeps the other bits.
        unsafe {
            modify(RCC_AHB1ENR, |r| r | RCC_AHB1ENR_GPIOAEN);
            modify(RCC_APB1ENR, |r| r | RCC_APB1ENR_USART2EN);
            // PA2 and PA3: alternate function mode (0b10), AF7.
            modify(GPIOA_MODER, |r| (r & !(0b1111 << 4)) | (0b1010 << 4));
            modify(GPIOA_AFRL, |r| (r & !(0xFF << 8)) | (0x77 << 8));
            // 16x oversampling: BRR is the clock over the rate, rounded.
            write_volatile(BRR, (APB1_HZ + BAUD / 2) / BAUD);
            write_volatile(CR1, CR1_UE | CR1_TE | CR1_RE);
        }
        Self { _private: () }
    }

    /// Writes `byte` if the transmit register is empty; false (nothing written) otherwise.
    pub fn try_write(&mut self, byte: u8) -> bool {
        // SAFETY: USART2's status and data registers; `Usart` is the only writer.
        unsafe {
            if read_volatile(SR) & SR_TXE == 0 {
                return false;
            }
            write_volatile(DR, u32::from(byte));
        }
        true
    }
}

/// Read-modify-write of a peripheral register.
///
/// # Safety
/// `register` must be a valid, aligned peripheral register.
unsafe fn modify(register: *mut u32, f: impl FnOnce(u32) -> u32) {
    write_volatile(register, f(read_volatile(register)));
}
