//! An independent reading of a MAVLink 2 OPTICAL_FLOW_RAD frame: header, CRC and payload
//! written out from the MAVLink specification, so the encoder is not checked against itself.

use kestrel::ego::mavlink::{encode_optical_flow_rad, EncodeError, MavlinkHeader, MAX_FRAME_LEN};
use kestrel::ego::OpticalFlowRad;

/// OPTICAL_FLOW_RAD's CRC_EXTRA byte in the common dialect.
const CRC_EXTRA: u8 = 138;
/// The untrimmed payload length.
const PAYLOAD_LEN: usize = 44;

/// Encodes `reading` into a buffer of 0..=63 bytes and checks the frame, or the refusal.
pub fn check(reading: &OpticalFlowRad, sequence: u8, [system_id, component_id, len]: [u8; 3]) {
    let header = MavlinkHeader {
        system_id,
        component_id,
        sequence,
    };
    let mut buf = vec![0u8; usize::from(len % 64)];
    let mut full = [0u8; MAX_FRAME_LEN];
    let frame_len = encode_optical_flow_rad(reading, header, &mut full).expect("a full buffer");
    let frame = &full[..frame_len];
    match encode_optical_flow_rad(reading, header, &mut buf) {
        Ok(n) => assert_eq!(&buf[..n], frame),
        Err(EncodeError::BufferTooSmall) => assert!(buf.len() < frame_len),
    }
    assert_eq!(
        &frame[..10],
        &[
            0xFD,
            frame[1],
            0,
            0,
            sequence,
            system_id,
            component_id,
            106,
            0,
            0
        ]
    );
    let payload_len = usize::from(frame[1]);
    assert_eq!(frame_len, 10 + payload_len + 2);
    let crc = crc_mcrf4xx(&frame[1..10 + payload_len]);
    assert_eq!(&frame[frame_len - 2..], &crc.to_le_bytes(), "CRC");
    // MAVLink 2 trims trailing zeros; put them back.
    let mut payload = [0u8; PAYLOAD_LEN];
    payload[..payload_len].copy_from_slice(&frame[10..10 + payload_len]);
    assert!(payload_len == 0 || payload[payload_len - 1] != 0 || payload_len == 1);
    assert_eq!(decode(&payload), wire(reading));
}

/// The wire fields, as bit patterns (NaN compares equal to itself this way).
type Wire = (u64, u32, [u32; 5], u32, u32, i16, u8, u8);

fn wire(r: &OpticalFlowRad) -> Wire {
    let [gx, gy, gz] = r.wire_gyro();
    (
        r.time_usec,
        r.integration_time_us,
        [r.integrated_x, r.integrated_y, gx, gy, gz].map(f32::to_bits),
        r.time_delta_distance_us,
        r.wire_distance().to_bits(),
        r.temperature,
        r.sensor_id,
        r.quality,
    )
}

/// The payload in MAVLink's wire order (fields sorted by size, little-endian).
fn decode(p: &[u8; PAYLOAD_LEN]) -> Wire {
    let u32_at = |i: usize| u32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]]);
    let mut time = [0u8; 8];
    time.copy_from_slice(&p[..8]);
    (
        u64::from_le_bytes(time),
        u32_at(8),
        [12, 16, 20, 24, 28].map(u32_at),
        u32_at(32),
        u32_at(36),
        i16::from_le_bytes([p[40], p[41]]),
        p[42],
        p[43],
    )
}

/// CRC-16/MCRF4XX (X.25) over `bytes` and the message's CRC_EXTRA, as MAVLink specifies it.
fn crc_mcrf4xx(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &byte in bytes.iter().chain(&[CRC_EXTRA]) {
        let mut t = byte ^ (crc & 0xFF) as u8;
        t ^= t << 4;
        let t = u16::from(t);
        crc = (crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4);
    }
    crc
}
