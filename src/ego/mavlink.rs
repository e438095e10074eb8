//! MAVLink 2 frames of OPTICAL_FLOW_RAD (feature `mavlink`), serialised by the `mavlink` crate.
//!
//! Only the OPTICAL_FLOW_RAD serialiser and the frame's CRC are linked in. The frame is built
//! in a 280-byte buffer on the stack (the `mavlink` crate's largest frame) and copied into the
//! caller's buffer; [`MAX_FRAME_LEN`] bytes always suffice.
//!
//! ```
//! use kestrel::ego::mavlink::{encode_optical_flow_rad, MavlinkHeader, MAX_FRAME_LEN};
//! use kestrel::ego::OpticalFlowRad;
//! let flow = OpticalFlowRad { time_usec: 1_000, quality: 200, ..Default::default() };
//! let header = MavlinkHeader { system_id: 1, component_id: 100, sequence: 0 };
//! let mut buf = [0u8; MAX_FRAME_LEN];
//! let len = encode_optical_flow_rad(&flow, header, &mut buf).unwrap();
//! assert_eq!(buf[0], 0xFD); // MAVLink 2
//! assert_eq!(&buf[7..10], &[106, 0, 0]); // message id
//! assert!(len <= MAX_FRAME_LEN);
//! ```

use super::flow_rad::OpticalFlowRad;
use mavlink::dialects::common::OPTICAL_FLOW_RAD_DATA;
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MessageData};

/// OPTICAL_FLOW_RAD's message id.
///
/// ```
/// use kestrel::ego::mavlink::OPTICAL_FLOW_RAD_ID;
/// assert_eq!(OPTICAL_FLOW_RAD_ID, 106);
/// ```
pub const OPTICAL_FLOW_RAD_ID: u32 = 106;

/// The longest OPTICAL_FLOW_RAD frame: 10 header bytes, a 44-byte payload, 2 CRC bytes
/// (unsigned; MAVLink 2 trims trailing zero bytes of the payload, so frames are often shorter).
///
/// ```
/// use kestrel::ego::mavlink::MAX_FRAME_LEN;
/// static mut TX: [u8; MAX_FRAME_LEN] = [0; MAX_FRAME_LEN];
/// assert_eq!(MAX_FRAME_LEN, 10 + 44 + 2);
/// ```
pub const MAX_FRAME_LEN: usize = 56;

/// The sender fields of a MAVLink frame header.
///
/// ```
/// use kestrel::ego::mavlink::MavlinkHeader;
/// let header = MavlinkHeader { system_id: 1, component_id: 100, sequence: 7 };
/// assert_eq!(header.sequence, 7);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MavlinkHeader {
    /// The sending system (the vehicle), usually 1.
    pub system_id: u8,
    /// The sending component; MAV_COMP_ID_CAMERA is 100.
    pub component_id: u8,
    /// Frame sequence number, incremented by the sender per frame.
    pub sequence: u8,
}

/// Why a frame could not be encoded.
///
/// ```
/// use kestrel::ego::mavlink::{encode_optical_flow_rad, EncodeError, MavlinkHeader};
/// use kestrel::ego::OpticalFlowRad;
/// let header = MavlinkHeader { system_id: 1, component_id: 100, sequence: 0 };
/// let result = encode_optical_flow_rad(&OpticalFlowRad::default(), header, &mut [0u8; 8]);
/// assert_eq!(result, Err(EncodeError::BufferTooSmall));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The buffer is shorter than the frame.
    BufferTooSmall,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("buffer too small for the MAVLink frame")
    }
}

/// Writes `flow` as an unsigned MAVLink 2 OPTICAL_FLOW_RAD frame at the start of `buf` and
/// returns its length. A missing gyro is sent as NaN, an unknown distance as -1.
///
/// ```
/// use kestrel::ego::mavlink::{encode_optical_flow_rad, MavlinkHeader, MAX_FRAME_LEN};
/// use kestrel::ego::OpticalFlowRad;
/// let flow = OpticalFlowRad { integrated_x: 0.01, quality: 150, ..Default::default() };
/// let header = MavlinkHeader { system_id: 1, component_id: 100, sequence: 9 };
/// let mut buf = [0u8; 64];
/// let len = encode_optical_flow_rad(&flow, header, &mut buf).unwrap();
/// assert_eq!((len, buf[1], buf[4]), (MAX_FRAME_LEN, 44, 9)); // length, payload, sequence
/// ```
pub fn encode_optical_flow_rad(
    flow: &OpticalFlowRad,
    header: MavlinkHeader,
    buf: &mut [u8],
) -> Result<usize, EncodeError> {
    let [xgyro, ygyro, zgyro] = flow.wire_gyro();
    let data = OPTICAL_FLOW_RAD_DATA {
        time_usec: flow.time_usec,
        integration_time_us: flow.integration_time_us,
        integrated_x: flow.integrated_x,
        integrated_y: flow.integrated_y,
        integrated_xgyro: xgyro,
        integrated_ygyro: ygyro,
        integrated_zgyro: zgyro,
        time_delta_distance_us: flow.time_delta_distance_us,
        distance: flow.wire_distance(),
        temperature: flow.temperature,
        sensor_id: flow.sensor_id,
        quality: flow.quality,
    };
    debug_assert_eq!(OPTICAL_FLOW_RAD_DATA::ID, OPTICAL_FLOW_RAD_ID);
    let mut raw = MAVLinkV2MessageRaw::new();
    let header = MavHeader {
        system_id: header.system_id,
        component_id: header.component_id,
        sequence: header.sequence,
    };
    raw.serialize_message_data(header, &data);
    let frame = raw.raw_bytes();
    let out = buf
        .get_mut(..frame.len())
        .ok_or(EncodeError::BufferTooSmall)?;
    out.copy_from_slice(frame);
    Ok(frame.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::MavMessage;
    use mavlink::{MavlinkVersion, Message};

    /// CRC-16/MCRF4XX as MAVLink specifies it, written out independently of the crate.
    fn crc_mcrf4xx(bytes: &[u8], crc_extra: u8) -> u16 {
        let mut crc: u16 = 0xFFFF;
        for &byte in bytes.iter().chain([crc_extra].iter()) {
            let mut t = byte ^ (crc & 0xFF) as u8;
            t ^= t << 4;
            let t = u16::from(t);
            crc = (crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4);
        }
        crc
    }

    /// Parses a frame with the `mavlink` crate, after checking its CRC.
    fn decode(frame: &[u8]) -> OPTICAL_FLOW_RAD_DATA {
        let mut bytes = [0u8; 280];
        bytes[..frame.len()].copy_from_slice(frame);
        let raw = MAVLinkV2MessageRaw::from_bytes_unparsed(bytes);
        assert!(raw.has_valid_crc::<MavMessage>());
        assert_eq!(raw.message_id(), OPTICAL_FLOW_RAD_ID);
        match MavMessage::parse(MavlinkVersion::V2, raw.message_id(), raw.payload()).unwrap() {
            MavMessage::OPTICAL_FLOW_RAD(data) => data,
            other => panic!("decoded {}", other.message_name()),
        }
    }

    #[test]
    fn frames_decode_with_the_right_id_crc_and_fields() {
        let flow = OpticalFlowRad {
            time_usec: 123_456_789,
            sensor_id: 3,
            integration_time_us: 20_000,
            integrated_x: 0.0125,
            integrated_y: -0.5,
            integrated_xgyro: Some(0.01),
            integrated_ygyro: Some(-0.02),
            integrated_zgyro: Some(0.03),
            temperature: 2_150,
            quality: 201,
            time_delta_distance_us: 1_500,
            distance: Some(2.25),
        };
        let header = MavlinkHeader {
            system_id: 1,
            component_id: 100,
            sequence: 42,
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow_rad(&flow, header, &mut buf).unwrap();
        assert_eq!(len, MAX_FRAME_LEN);
        // Magic, payload length, flags, sequence, system, component, message id.
        assert_eq!(buf[..10], [0xFD, 44, 0, 0, 42, 1, 100, 106, 0, 0]);
        let crc = crc_mcrf4xx(&buf[1..len - 2], 138);
        assert_eq!(crc.to_le_bytes(), [buf[len - 2], buf[len - 1]]);

        let data = decode(&buf[..len]);
        assert_eq!(data.time_usec, 123_456_789);
        assert_eq!(
            (data.sensor_id, data.quality, data.temperature),
            (3, 201, 2_150)
        );
        assert_eq!(data.integration_time_us, 20_000);
        assert_eq!((data.integrated_x, data.integrated_y), (0.0125, -0.5));
        let gyro = (
            data.integrated_xgyro,
            data.integrated_ygyro,
            data.integrated_zgyro,
        );
        assert_eq!(gyro, (0.01, -0.02, 0.03));
        assert_eq!((data.time_delta_distance_us, data.distance), (1_500, 2.25));
    }

    #[test]
    fn missing_values_use_the_wire_conventions() {
        let flow = OpticalFlowRad {
            time_usec: 7,
            ..Default::default()
        };
        let header = MavlinkHeader {
            system_id: 1,
            component_id: 100,
            sequence: 0,
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow_rad(&flow, header, &mut buf).unwrap();
        // Temperature, sensor id and quality are zero: MAVLink 2 trims them off the payload.
        assert_eq!((len, buf[1]), (MAX_FRAME_LEN - 4, 40));
        let data = decode(&buf[..len]);
        assert!(data.integrated_xgyro.is_nan() && data.integrated_zgyro.is_nan());
        assert_eq!((data.distance, data.quality), (-1.0, 0));
    }
}
