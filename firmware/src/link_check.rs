//! A boot-time check of the link's full-queue path, which QEMU's always-ready USART never
//! takes: readouts sent to a port that stays busy must fill the queue with whole frames and
//! then be dropped and counted, never block, and the frames kept must come out whole with
//! their sequence numbers gap-free once the port drains.
//!
//! Prints `link_check queued=N dropped=N drained=N whole=N gaps=N` (`whole=-1` when the bytes do
//! not split into whole frames) and returns whether every condition held.

use cortex_m_semihosting::hprintln;
use kestrel::ego::{OpticalFlow, OpticalFlowRad};

use crate::link::{Link, Port};

/// Readouts sent while the port is busy: several times what the queue holds.
const READOUTS: u64 = 12;
/// MAVLink 2's start byte and the bytes around a frame's payload (header 10, CRC 2).
const MAGIC: u8 = 0xFD;
const OVERHEAD: u16 = 12;

/// A port that refuses every byte while busy, and once it is not, follows the bytes it takes
/// frame by frame.
#[derive(Default)]
struct TestPort {
    busy: bool,
    /// Bytes taken.
    drained: usize,
    /// Frames ended whole, and the gaps between their sequence numbers.
    whole: u32,
    gaps: u32,
    /// A byte that should have started a frame and did not.
    broken: bool,
    /// The frame being read: its bytes so far and its length once known.
    at: u16,
    len: u16,
    last_seq: Option<u8>,
}

impl TestPort {
    fn take(&mut self, byte: u8) {
        self.drained += 1;
        match self.at {
            0 if byte != MAGIC => self.broken = true,
            1 => self.len = OVERHEAD + u16::from(byte),
            4 => {
                if self.last_seq.is_some_and(|l| l.wrapping_add(1) != byte) {
                    self.gaps += 1;
                }
                self.last_seq = Some(byte);
            }
            _ => {}
        }
        self.at += 1;
        if self.at > 1 && self.at == self.len {
            (self.at, self.whole) = (0, self.whole + 1);
        }
    }
}

impl Port for TestPort {
    fn try_write(&mut self, byte: u8) -> bool {
        if !self.busy {
            self.take(byte);
        }
        !self.busy
    }
}

/// Runs the check; true when it passed.
pub fn run() -> bool {
    let busy = TestPort {
        busy: true,
        ..TestPort::default()
    };
    let mut link = Link::on(busy);
    for frame in 0..READOUTS {
        let rad = OpticalFlowRad {
            time_usec: frame * 10_000,
            integration_time_us: 10_000,
            integrated_x: 0.001,
            quality: 200,
            ..OpticalFlowRad::default()
        };
        link.send(&rad, &OpticalFlow::from_rad(&rad, (140.0, 140.0)));
    }
    let counts = link.counts();
    let queued = link.pending();
    link.port_mut().busy = false;
    link.pump();
    let port = link.port_mut();
    let whole = port.at == 0 && !port.broken;
    let (drained, frames, gaps) = (port.drained, port.whole, port.gaps);
    hprintln!(
        "link_check queued={} dropped={} drained={} whole={} gaps={}",
        queued,
        counts.dropped,
        drained,
        if whole { i64::from(frames) } else { -1 },
        gaps
    );
    let sent = counts.heartbeats + counts.flow_rad + counts.flow;
    // Nothing reached the busy port; then everything queued did, whole.
    counts.dropped > 0
        && counts.bytes == 0
        && link.counts().bytes as usize == drained
        && drained == queued
        && whole
        && frames == sent
        && gaps == 0
        && link.pending() == 0
}
