//! A flow sensor for a flight controller: camera frames in, MAVLink out.
//!
//! The whole program of a flow-sensor board on the library's pipeline
//! ([`kestrel::sensor::FlowSensor`]): each frame is tracked from the one before and the
//! camera's motion read out as OPTICAL_FLOW_RAD (for PX4) and OPTICAL_FLOW (for ArduPilot) on
//! the autopilot's UART, with a HEARTBEAT every second; a frame that cannot be used reads out
//! with quality 0, which the autopilot ignores.
//!
//! `cargo run --release --example flow_sensor` runs it in QEMU on the frames `build.rs` renders
//! into flash, played back and forth for 2 s with one transfer cut short;
//! `bench/mavlink_link.sh --example flow_sensor` decodes its USART2 with pymavlink. On a board, change:
//!
//! - [`Camera`]: start the DCMI's DMA into `static` frame buffers and return each completed
//!   one with its capture time. Keep three, so the DMA fills one while the sensor reads the
//!   last two; a transfer error or a short transfer is a frame of fewer bytes.
//! - [`Autopilot`]: the UART, pins, clock and baud rate wired to the autopilot; better, hand
//!   each message to the UART's TX DMA than wait on it.
//! - [`WIDTH`], [`HEIGHT`], [`FOV_DEGREES`]: the camera's frame and lens; the buffers are
//!   sized from them at compile time.
//! - The gyro, if the board has one: give `process` its integral over each frame interval.
//! - Semihosting (the end of the run, the panic handler): without a debugger it faults.
#![no_std]
#![no_main]

use core::ptr::{read_volatile, write_volatile};

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use kestrel::detect::Corner;
use kestrel::ego::mavlink::{
    encode_heartbeat, encode_optical_flow, encode_optical_flow_rad, EncodeError, MavlinkHeader,
    MAX_FRAME_LEN,
};
use kestrel::ego::CameraParams;
use kestrel::lk::scratch_len;
use kestrel::sensor::{FlowSensor, FlowSensorConfig};
use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig};
use kestrel::ImageView;
use kestrel::Point;

/// The camera's frames: 8-bit grey, packed rows.
const WIDTH: usize = 160;
const HEIGHT: usize = 120;
/// The lens's horizontal field of view, degrees.
const FOV_DEGREES: f32 = 60.0;
/// The vehicle's MAVLink system id; the component is a flow sensor's (100).
const SYSTEM_ID: u8 = 1;

/// The flow-sensor preset: 25 tracks, 7x7 windows on two pyramid levels, FAST corners.
const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
const TRACKS: usize = PRESET.max_tracks;
const STORAGE_LEN: usize = tracker_storage_len(WIDTH, HEIGHT, PRESET.pyramid_levels());
const LK_SCRATCH_LEN: usize = scratch_len(PRESET.lk.window);
/// Corner candidates of one detection: three per track.
const CANDIDATES: usize = 3 * TRACKS;
const NO_CORNER: Corner = Corner {
    position: Point::from_bits(0, 0),
    score: 0,
};

#[entry]
fn main() -> ! {
    // The tracker's memory, in `.bss`: the RAM the sensor needs is known when it links.
    static mut STORAGE: [u8; STORAGE_LEN] = [0; STORAGE_LEN];
    static mut LK_SCRATCH: [i16; LK_SCRATCH_LEN] = [0; LK_SCRATCH_LEN];
    static mut CORNERS: [Corner; CANDIDATES] = [NO_CORNER; CANDIDATES];

    let lens =
        CameraParams::from_horizontal_fov(WIDTH as u16, HEIGHT as u16, FOV_DEGREES.to_radians());
    let buffers = TrackerBuffers {
        storage: STORAGE,
        lk_scratch: LK_SCRATCH,
        detect_scratch: &mut [], // FAST needs none
        candidates: CORNERS,
    };
    let config = FlowSensorConfig::new(lens);
    let Ok(mut sensor) = FlowSensor::<TRACKS>::new(config, WIDTH, HEIGHT, buffers) else {
        panic!("the flow sensor refused its settings");
    };
    let mut camera = Camera { tick: 0 };
    let mut autopilot = Autopilot::connect(SYSTEM_ID);
    let (mut next_heartbeat_us, mut last_us) = (0, 0);
    let mut previous: Option<(ImageView<'static>, u64)> = None;

    while let Some(frame) = camera.next_frame() {
        let since_last = (frame.time_us - last_us) as u32;
        last_us = frame.time_us;
        match (ImageView::packed(frame.pixels, WIDTH, HEIGHT), previous) {
            // The first frame: the tracks start on it; nothing to read out yet.
            (Ok(next), None) => {
                previous = sensor.start(next).ok().map(|_| (next, frame.time_us));
                continue;
            }
            (Ok(next), Some((prev, prev_us))) => {
                let interval = (frame.time_us - prev_us) as u32;
                // No gyro here; with one, Some([x, y, z]): rad integrated over the interval.
                previous = match sensor.process(prev, next, interval, None) {
                    Ok(_) => Some((next, frame.time_us)),
                    // Refused (quality 0): start again on this frame.
                    Err(_) => sensor.start(next).ok().map(|_| (next, frame.time_us)),
                };
            }
            // Not a whole frame: quality 0; the tracks wait on `prev` for the next one.
            (Err(_), _) => sensor.refuse(since_last),
        }

        let rad = sensor.readout(frame.time_us);
        let flow = sensor.optical_flow(&rad);
        if frame.time_us >= next_heartbeat_us {
            next_heartbeat_us = (frame.time_us / 1_000_000 + 1) * 1_000_000;
            autopilot.send(encode_heartbeat);
        }
        autopilot.send(|h, buf| encode_optical_flow_rad(&rad, h, buf));
        autopilot.send(|h, buf| encode_optical_flow(&flow, h, buf));
    }

    // Only the recording ends: a camera on a board never does.
    hprintln!("link bytes={} frame_clock_us={}", autopilot.bytes, last_us);
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

/// A frame from the camera: its pixels and when it was taken, microseconds.
struct Frame {
    pixels: &'static [u8],
    time_us: u64,
}

/// The frames `build.rs` renders into flash, packed one after the other, played at 100
/// frames/s until the heartbeats at 0, 1 and 2 s have gone out; frame 150 is cut short.
static RECORDING: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/frames.bin"));
const FRAME_LEN: usize = WIDTH * HEIGHT;
const FRAME_INTERVAL_US: u64 = 10_000;
const PLAYBACK: core::ops::RangeInclusive<u64> = 0..=205;
const CUT_SHORT: u64 = 150;

/// The camera. Here: the recording, forwards and backwards (0, 1, ..., 11, 10, ..., 0, 1, ...)
/// so the motion reverses at each end. On a board: wait for the DCMI's DMA to complete a
/// buffer and return it, stamped by a timer.
struct Camera {
    tick: u64,
}

impl Camera {
    /// The next frame, or `None` when the recording is over.
    fn next_frame(&mut self) -> Option<Frame> {
        let tick = self.tick;
        self.tick += 1;
        let period = (2 * (RECORDING.len() / FRAME_LEN)).saturating_sub(2).max(1);
        let phase = tick as usize % period;
        let start = phase.min(period - phase) * FRAME_LEN;
        let frame = RECORDING.get(start..start + FRAME_LEN).unwrap_or(&[]);
        let pixels = match tick {
            CUT_SHORT => frame.get(..FRAME_LEN / 2).unwrap_or(&[]),
            _ => frame,
        };
        let time_us = tick * FRAME_INTERVAL_US;
        PLAYBACK
            .contains(&tick)
            .then_some(Frame { pixels, time_us })
    }
}

/// The autopilot at the other end of USART2 (TX PA2, RX PA3, AF7; 921600 baud 8N1): MAVLink 2
/// messages in one sequence. QEMU connects USART2 to its second `-serial` backend.
struct Autopilot {
    header: MavlinkHeader,
    bytes: u32,
}

const USART2: usize = 0x4000_4400;

impl Autopilot {
    /// Sets USART2 up by its registers, for the vehicle `system_id`.
    fn connect(system_id: u8) -> Self {
        let reg = |address: usize| address as *mut u32;
        // SAFETY: the STM32F405's registers (RCC, GPIOA, USART2), set up once before anything
        // else uses GPIOA or USART2; read-modify-write keeps the other bits.
        unsafe {
            let modify = |r: *mut u32, clear: u32, set: u32| {
                write_volatile(r, read_volatile(r) & !clear | set)
            };
            modify(reg(0x4002_3830), 0, 1); // RCC_AHB1ENR: GPIOA
            modify(reg(0x4002_3840), 0, 1 << 17); // RCC_APB1ENR: USART2
            modify(reg(0x4002_0000), 0b1111 << 4, 0b1010 << 4); // GPIOA_MODER: PA2, PA3 AF
            modify(reg(0x4002_0020), 0xFF << 8, 0x77 << 8); // GPIOA_AFRL: AF7
            write_volatile(reg(USART2 + 0x08), (42_000_000 + 460_800) / 921_600); // BRR, 42 MHz
            write_volatile(reg(USART2 + 0x0C), 1 << 13 | 1 << 3); // CR1: UE, TE
        }
        let header = MavlinkHeader::flow_sensor(system_id);
        Self { header, bytes: 0 }
    }

    /// Encodes one message with the next sequence number and writes it, waiting for the
    /// transmit register to empty (TXE) before each byte.
    fn send(
        &mut self,
        encode: impl FnOnce(MavlinkHeader, &mut [u8]) -> Result<usize, EncodeError>,
    ) {
        let mut buf = [0u8; MAX_FRAME_LEN];
        // Every message fits in MAX_FRAME_LEN bytes: encoding cannot fail.
        let len = encode(self.header.advance(), &mut buf).unwrap_or(0);
        for &byte in buf.iter().take(len) {
            // SAFETY: USART2's status and data registers; `Autopilot` is their only user.
            unsafe {
                while read_volatile(USART2 as *const u32) & 1 << 7 == 0 {}
                write_volatile((USART2 + 0x04) as *mut u32, u32::from(byte));
            }
        }
        self.bytes += len as u32;
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
