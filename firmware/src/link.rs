//! The autopilot link: the flow sensor's MAVLink 2 stream on USART2.
//!
//! Per readout the link queues OPTICAL_FLOW_RAD (PX4 reads it) and OPTICAL_FLOW (ArduPilot
//! reads it), after a HEARTBEAT whenever a new second of the frame clock begins, then moves as
//! many queued bytes to the USART as it takes without waiting. A frame that does not fit in the
//! queue is dropped whole and counted: the frame loop never blocks on a busy port, and the
//! stream never carries half a frame. Sequence numbers count every frame put on the wire.
//!
//! QEMU 7.2's USART model transmits synchronously and raises no transmit interrupt, so here the
//! queue is drained from the frame loop ([`Link::pump`]) and its cost is measured per frame; on
//! the board the same pump belongs in USART2's TXE interrupt.

use heapless::Deque;
use kestrel::ego::mavlink::{
    encode_heartbeat, encode_optical_flow, encode_optical_flow_rad, EncodeError, MavlinkHeader,
    MAX_FRAME_LEN,
};
use kestrel::ego::{OpticalFlow, OpticalFlowRad};

use crate::usart::Usart;

/// Where the link's bytes go: a byte at a time, refused while the port is busy.
pub trait Port {
    /// Writes `byte` when the port has room; false (nothing written) when it is busy.
    fn try_write(&mut self, byte: u8) -> bool;
}

impl Port for Usart {
    fn try_write(&mut self, byte: u8) -> bool {
        Usart::try_write(self, byte)
    }
}

/// The vehicle's MAVLink system id.
const SYSTEM_ID: u8 = 1;
/// Microseconds between heartbeats on the frame clock.
const HEARTBEAT_PERIOD_US: u64 = 1_000_000;
/// Bytes the transmit queue holds: a readout's frames several times over (at most 21 + 56 + 46
/// bytes), so a port that falls behind for a few frames loses nothing.
const QUEUE_LEN: usize = 512;

/// What the link has done so far.
#[derive(Debug, Clone, Copy, Default)]
pub struct LinkCounts {
    pub heartbeats: u32,
    pub flow_rad: u32,
    pub flow: u32,
    /// OPTICAL_FLOW_RAD frames of quality 0 (refused or unusable frames).
    pub invalid: u32,
    /// Frames dropped because the queue was full.
    pub dropped: u32,
    /// Bytes handed to the USART.
    pub bytes: u32,
}

/// The MAVLink stream over a port, USART2 on the board.
pub struct Link<P: Port = Usart> {
    port: P,
    outbox: Outbox,
}

impl Link {
    /// The link on a freshly set-up USART2, sequence from 0.
    pub fn new() -> Self {
        Self::on(Usart::new())
    }
}

impl<P: Port> Link<P> {
    /// The link on `port`, sequence from 0.
    pub fn on(port: P) -> Self {
        Self {
            port,
            outbox: Outbox {
                queue: Deque::new(),
                header: MavlinkHeader::flow_sensor(SYSTEM_ID),
                next_heartbeat_us: 0,
                counts: LinkCounts::default(),
            },
        }
    }

    /// Queues one readout (with a HEARTBEAT when one is due) and pumps the queue.
    pub fn send(&mut self, rad: &OpticalFlowRad, flow: &OpticalFlow) {
        self.outbox.queue_readout(rad, flow);
        self.pump();
    }

    /// Moves queued bytes to the port while it has room; never waits.
    pub fn pump(&mut self) {
        let outbox = &mut self.outbox;
        while let Some(&byte) = outbox.queue.front() {
            if !self.port.try_write(byte) {
                break;
            }
            outbox.queue.pop_front();
            outbox.counts.bytes += 1;
        }
    }

    /// Bytes still queued.
    pub fn pending(&self) -> usize {
        self.outbox.queue.len()
    }

    /// The counts so far.
    pub fn counts(&self) -> LinkCounts {
        self.outbox.counts
    }

    /// The port, to inspect or change it.
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }
}

/// The frames waiting for the port, and what went into them: the same for every port, so built
/// once.
struct Outbox {
    queue: Deque<u8, QUEUE_LEN>,
    header: MavlinkHeader,
    next_heartbeat_us: u64,
    counts: LinkCounts,
}

impl Outbox {
    /// Queues one readout's frames, a HEARTBEAT first when one is due.
    #[inline(never)]
    fn queue_readout(&mut self, rad: &OpticalFlowRad, flow: &OpticalFlow) {
        if rad.time_usec >= self.next_heartbeat_us {
            self.next_heartbeat_us =
                (rad.time_usec / HEARTBEAT_PERIOD_US + 1) * HEARTBEAT_PERIOD_US;
            if self.queue_frame(encode_heartbeat) {
                self.counts.heartbeats += 1;
            }
        }
        if self.queue_frame(|h, buf| encode_optical_flow_rad(rad, h, buf)) {
            self.counts.flow_rad += 1;
            self.counts.invalid += u32::from(rad.quality == 0);
        }
        if self.queue_frame(|h, buf| encode_optical_flow(flow, h, buf)) {
            self.counts.flow += 1;
        }
    }

    /// Encodes a frame with the next sequence number and queues it whole; false (and counted
    /// as dropped, its number not used) when it does not fit.
    fn queue_frame(
        &mut self,
        encode: impl FnOnce(MavlinkHeader, &mut [u8]) -> Result<usize, EncodeError>,
    ) -> bool {
        let mut frame = [0u8; MAX_FRAME_LEN];
        let Ok(len) = encode(self.header, &mut frame) else {
            self.counts.dropped += 1;
            return false;
        };
        let bytes = frame.get(..len).unwrap_or(&[]);
        if QUEUE_LEN - self.queue.len() < bytes.len() {
            self.counts.dropped += 1;
            return false;
        }
        for &byte in bytes {
            // Room was checked above: the push cannot fail.
            let _ = self.queue.push_back(byte);
        }
        self.header.advance();
        true
    }
}

/// The cost of sending, per readout: encoding, queueing and pumping.
#[derive(Debug, Clone, Copy, Default)]
pub struct SendCost {
    pub readouts: u64,
    pub total: u64,
    pub worst: u64,
}

impl SendCost {
    /// Adds one readout's instructions.
    pub fn add(&mut self, instructions: u64) {
        self.readouts += 1;
        self.total += instructions;
        self.worst = self.worst.max(instructions);
    }

    /// Instructions per readout on average.
    pub fn mean(&self) -> u64 {
        self.total / self.readouts.max(1)
    }
}
