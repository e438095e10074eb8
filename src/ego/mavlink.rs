//! MAVLink 2 frames of a flow sensor (feature `mavlink`): OPTICAL_FLOW_RAD, OPTICAL_FLOW and
//! HEARTBEAT, serialised by the `mavlink` crate.
//!
//! Only these serialisers and the frame's CRC are linked in. A frame is built in a 280-byte
//! buffer on the stack (the `mavlink` crate's largest frame) and copied into the caller's
//! buffer; [`MAX_FRAME_LEN`] bytes always suffice.
//!
//! # What the autopilots read
//!
//! Send both flow messages of each readout, made from the same integration
//! ([`FlowRadAccumulator::readout`] then [`FlowRadAccumulator::optical_flow`]):
//!
//! - **PX4** reads OPTICAL_FLOW_RAD only. It stamps each message on arrival and takes
//!   `integration_time_us` as the integration span, so readouts must be sent as soon as they are
//!   made: `EKF2_OF_DELAY` is the delay from the end of the integration to the message's arrival
//!   (PX4 itself moves the sample back to the middle of the integration); `time_usec` is not
//!   used to align them. In the air EKF2 fuses a reading only when `quality` reaches
//!   `EKF2_OF_QMIN` (on the ground `EKF2_OF_QMIN_GND`, 0 by default, so there quality 0 passes)
//!   and the flow rate stays within `SENS_FLOW_MAXR` (8 rad/s by default); it subtracts the
//!   integrated gyro itself, or its own gyro when the fields are NaN.
//! - **ArduPilot** (`FLOW_TYPE` 5) reads OPTICAL_FLOW and has no OPTICAL_FLOW_RAD handler. From
//!   4.7 it averages `flow_rate_x/y` (or, from sensors that never fill them, `flow_x/y`; 4.6
//!   and earlier read only `flow_x/y`) over the messages between its own updates, timed by
//!   their arrival, so the messages must come at a steady rate, less than 0.5 s apart. It
//!   uses its own gyro for the body rates. EKF3 drops a reading outright when its quality is
//!   0 or its flow rate (or the gyro's) reaches 4.2 rad/s in magnitude, and fuses only rates
//!   below `EK3_MAX_FLOW` per axis (2.5 rad/s by default, settable up to 4.0).
//!
//! The library does not clamp rates to those limits: a rate beyond them is a true measurement
//! that the autopilot should reject, not a smaller one it would trust. What never reaches the
//! wire is a NaN or infinite flow: such a reading is sent with zero flow and quality 0.
//!
//! # Who is sending
//!
//! MAVLink's common set has no component type for a flow sensor. The HEARTBEAT says
//! [`MAV_TYPE_CAMERA`] (the sensor is a camera; the field is meant for "camera, gimbal, etc."
//! components) with [`MAV_AUTOPILOT_INVALID`] (not a flight controller), and the frames come from
//! [`FLOW_SENSOR_COMPONENT_ID`], MAV_COMP_ID_CAMERA (100), the id PX4FLOW-style sensors use.
//! Neither autopilot filters flow by component id (ArduPilot follows the first sender it hears),
//! so a vehicle that already has a camera at 100 can pick any free id in [`MavlinkHeader`].
//! The system id is the vehicle's (usually 1).
//!
//! [`FlowRadAccumulator::readout`]: super::FlowRadAccumulator::readout
//! [`FlowRadAccumulator::optical_flow`]: super::FlowRadAccumulator::optical_flow
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

use super::flow_rad::{OpticalFlow, OpticalFlowRad};
use mavlink::dialects::common::{
    MavAutopilot, MavModeFlag, MavState, MavType, HEARTBEAT_DATA, OPTICAL_FLOW_DATA,
    OPTICAL_FLOW_RAD_DATA,
};
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MessageData};

/// OPTICAL_FLOW_RAD's message id.
///
/// ```
/// use kestrel::ego::mavlink::OPTICAL_FLOW_RAD_ID;
/// assert_eq!(OPTICAL_FLOW_RAD_ID, 106);
/// ```
pub const OPTICAL_FLOW_RAD_ID: u32 = 106;

/// OPTICAL_FLOW's message id.
///
/// ```
/// use kestrel::ego::mavlink::OPTICAL_FLOW_ID;
/// assert_eq!(OPTICAL_FLOW_ID, 100);
/// ```
pub const OPTICAL_FLOW_ID: u32 = 100;

/// HEARTBEAT's message id.
///
/// ```
/// use kestrel::ego::mavlink::HEARTBEAT_ID;
/// assert_eq!(HEARTBEAT_ID, 0);
/// ```
pub const HEARTBEAT_ID: u32 = 0;

/// The byte OPTICAL_FLOW_RAD's CRC ends with (CRC_EXTRA, from the message's definition).
///
/// ```
/// use kestrel::ego::mavlink::OPTICAL_FLOW_RAD_CRC_EXTRA;
/// assert_eq!(OPTICAL_FLOW_RAD_CRC_EXTRA, 138);
/// ```
pub const OPTICAL_FLOW_RAD_CRC_EXTRA: u8 = 138;

/// The byte OPTICAL_FLOW's CRC ends with (CRC_EXTRA; extension fields do not change it).
///
/// ```
/// use kestrel::ego::mavlink::OPTICAL_FLOW_CRC_EXTRA;
/// assert_eq!(OPTICAL_FLOW_CRC_EXTRA, 175);
/// ```
pub const OPTICAL_FLOW_CRC_EXTRA: u8 = 175;

/// The byte HEARTBEAT's CRC ends with (CRC_EXTRA).
///
/// ```
/// use kestrel::ego::mavlink::HEARTBEAT_CRC_EXTRA;
/// assert_eq!(HEARTBEAT_CRC_EXTRA, 50);
/// ```
pub const HEARTBEAT_CRC_EXTRA: u8 = 50;

/// The longest frame of the three: OPTICAL_FLOW_RAD's, 10 header bytes, a 44-byte payload and
/// 2 CRC bytes (unsigned; MAVLink 2 trims trailing zero bytes of the payload, so frames are
/// often shorter). OPTICAL_FLOW takes at most 46 bytes, HEARTBEAT 21.
///
/// ```
/// use kestrel::ego::mavlink::MAX_FRAME_LEN;
/// static mut TX: [u8; MAX_FRAME_LEN] = [0; MAX_FRAME_LEN];
/// assert_eq!(MAX_FRAME_LEN, 10 + 44 + 2);
/// ```
pub const MAX_FRAME_LEN: usize = 56;

/// The component id a flow sensor sends from: MAV_COMP_ID_CAMERA (see the module page).
///
/// ```
/// use kestrel::ego::mavlink::FLOW_SENSOR_COMPONENT_ID;
/// assert_eq!(FLOW_SENSOR_COMPONENT_ID, 100);
/// ```
pub const FLOW_SENSOR_COMPONENT_ID: u8 = 100;

/// The HEARTBEAT's `type`: MAV_TYPE_CAMERA.
///
/// ```
/// use kestrel::ego::mavlink::MAV_TYPE_CAMERA;
/// assert_eq!(MAV_TYPE_CAMERA, 30);
/// ```
pub const MAV_TYPE_CAMERA: u8 = 30;

/// The HEARTBEAT's `autopilot`: MAV_AUTOPILOT_INVALID, a component that is not a flight
/// controller.
///
/// ```
/// use kestrel::ego::mavlink::MAV_AUTOPILOT_INVALID;
/// assert_eq!(MAV_AUTOPILOT_INVALID, 8);
/// ```
pub const MAV_AUTOPILOT_INVALID: u8 = 8;

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
    /// The sending component; [`FLOW_SENSOR_COMPONENT_ID`] for a flow sensor.
    pub component_id: u8,
    /// Frame sequence number, incremented by the sender per frame.
    pub sequence: u8,
}

impl MavlinkHeader {
    /// A flow sensor's header on system `system_id`, sequence 0.
    ///
    /// ```
    /// use kestrel::ego::mavlink::MavlinkHeader;
    /// let header = MavlinkHeader::flow_sensor(1);
    /// assert_eq!((header.system_id, header.component_id, header.sequence), (1, 100, 0));
    /// ```
    pub const fn flow_sensor(system_id: u8) -> Self {
        Self {
            system_id,
            component_id: FLOW_SENSOR_COMPONENT_ID,
            sequence: 0,
        }
    }

    /// The header of the next frame: this one, after which the sequence counts up (wrapping).
    /// One counter per link: every frame sent on it takes the next number, whatever its type.
    ///
    /// ```
    /// use kestrel::ego::mavlink::MavlinkHeader;
    /// let mut link = MavlinkHeader { system_id: 1, component_id: 100, sequence: 255 };
    /// assert_eq!(link.advance().sequence, 255);
    /// assert_eq!(link.advance().sequence, 0);
    /// ```
    pub fn advance(&mut self) -> Self {
        let current = *self;
        self.sequence = self.sequence.wrapping_add(1);
        current
    }
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
/// returns its length. A missing gyro is sent as NaN (MAVLink's "no gyro", which PX4 reads as
/// "use mine"), an unknown distance as -1.
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
    encode(header, &data, buf)
}

/// Writes `flow` as an unsigned MAVLink 2 OPTICAL_FLOW frame, with its extension fields
/// `flow_rate_x/y`, at the start of `buf` and returns its length. An unknown ground distance
/// is sent as -1.
///
/// ```
/// use kestrel::ego::mavlink::{encode_optical_flow, MavlinkHeader, MAX_FRAME_LEN};
/// use kestrel::ego::OpticalFlow;
/// let flow = OpticalFlow { flow_x: 7, flow_rate_x: 0.5, flow_rate_y: -0.25, quality: 150,
///     ..Default::default() };
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let len = encode_optical_flow(&flow, MavlinkHeader::flow_sensor(1), &mut buf).unwrap();
/// assert_eq!((len, buf[1], buf[7]), (46, 34, 100)); // length, payload, message id
/// ```
pub fn encode_optical_flow(
    flow: &OpticalFlow,
    header: MavlinkHeader,
    buf: &mut [u8],
) -> Result<usize, EncodeError> {
    let data = OPTICAL_FLOW_DATA {
        time_usec: flow.time_usec,
        flow_comp_m_x: flow.flow_comp_m_x,
        flow_comp_m_y: flow.flow_comp_m_y,
        ground_distance: flow.wire_ground_distance(),
        flow_x: flow.flow_x,
        flow_y: flow.flow_y,
        sensor_id: flow.sensor_id,
        quality: flow.quality,
        flow_rate_x: flow.flow_rate_x,
        flow_rate_y: flow.flow_rate_y,
    };
    debug_assert_eq!(OPTICAL_FLOW_DATA::ID, OPTICAL_FLOW_ID);
    encode(header, &data, buf)
}

/// Writes a flow sensor's unsigned MAVLink 2 HEARTBEAT frame at the start of `buf` and returns
/// its length: type [`MAV_TYPE_CAMERA`], autopilot [`MAV_AUTOPILOT_INVALID`], no mode flags,
/// state MAV_STATE_ACTIVE. Send it once a second: ground stations and routers list a component
/// only while its heartbeats keep coming.
///
/// ```
/// use kestrel::ego::mavlink::{encode_heartbeat, MavlinkHeader, MAX_FRAME_LEN};
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let len = encode_heartbeat(MavlinkHeader::flow_sensor(1), &mut buf).unwrap();
/// assert_eq!((len, buf[7]), (21, 0)); // 9-byte payload, message id 0
/// assert_eq!(&buf[14..19], &[30, 8, 0, 4, 3]); // type, autopilot, mode, state, version
/// ```
pub fn encode_heartbeat(header: MavlinkHeader, buf: &mut [u8]) -> Result<usize, EncodeError> {
    let data = HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_CAMERA,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: mavlink::dialects::common::MINOR_MAVLINK_VERSION,
    };
    debug_assert_eq!(HEARTBEAT_DATA::ID, HEARTBEAT_ID);
    encode(header, &data, buf)
}

/// Serialises `data` as a MAVLink 2 frame and copies it into `buf`.
fn encode<D: MessageData>(
    header: MavlinkHeader,
    data: &D,
    buf: &mut [u8],
) -> Result<usize, EncodeError> {
    let mut raw = MAVLinkV2MessageRaw::new();
    let header = MavHeader {
        system_id: header.system_id,
        component_id: header.component_id,
        sequence: header.sequence,
    };
    raw.serialize_message_data(header, data);
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

    /// Checks a frame's CRC against the given CRC_EXTRA, then parses it with the `mavlink`
    /// crate (which checks the CRC with its own table).
    fn decode(frame: &[u8], crc_extra: u8) -> MavMessage {
        let len = frame.len();
        let crc = crc_mcrf4xx(&frame[1..len - 2], crc_extra);
        assert_eq!(crc.to_le_bytes(), [frame[len - 2], frame[len - 1]]);
        let mut bytes = [0u8; 280];
        bytes[..len].copy_from_slice(frame);
        let raw = MAVLinkV2MessageRaw::from_bytes_unparsed(bytes);
        assert!(raw.has_valid_crc::<MavMessage>());
        MavMessage::parse(MavlinkVersion::V2, raw.message_id(), raw.payload()).unwrap()
    }

    fn decode_rad(frame: &[u8]) -> OPTICAL_FLOW_RAD_DATA {
        match decode(frame, OPTICAL_FLOW_RAD_CRC_EXTRA) {
            MavMessage::OPTICAL_FLOW_RAD(data) => data,
            other => panic!("decoded {}", other.message_name()),
        }
    }

    fn decode_flow(frame: &[u8]) -> OPTICAL_FLOW_DATA {
        match decode(frame, OPTICAL_FLOW_CRC_EXTRA) {
            MavMessage::OPTICAL_FLOW(data) => data,
            other => panic!("decoded {}", other.message_name()),
        }
    }

    const HEADER: MavlinkHeader = MavlinkHeader {
        system_id: 1,
        component_id: 100,
        sequence: 42,
    };

    #[test]
    fn the_crate_agrees_on_ids_and_crc_extras() {
        assert_eq!(
            (OPTICAL_FLOW_RAD_DATA::ID, OPTICAL_FLOW_RAD_DATA::EXTRA_CRC),
            (OPTICAL_FLOW_RAD_ID, OPTICAL_FLOW_RAD_CRC_EXTRA)
        );
        assert_eq!(
            (OPTICAL_FLOW_DATA::ID, OPTICAL_FLOW_DATA::EXTRA_CRC),
            (OPTICAL_FLOW_ID, OPTICAL_FLOW_CRC_EXTRA)
        );
        assert_eq!(
            (HEARTBEAT_DATA::ID, HEARTBEAT_DATA::EXTRA_CRC),
            (HEARTBEAT_ID, HEARTBEAT_CRC_EXTRA)
        );
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
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow_rad(&flow, HEADER, &mut buf).unwrap();
        assert_eq!(len, MAX_FRAME_LEN);
        // Magic, payload length, flags, sequence, system, component, message id.
        assert_eq!(buf[..10], [0xFD, 44, 0, 0, 42, 1, 100, 106, 0, 0]);

        let data = decode_rad(&buf[..len]);
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
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow_rad(&flow, HEADER, &mut buf).unwrap();
        // Temperature, sensor id and quality are zero: MAVLink 2 trims them off the payload.
        assert_eq!((len, buf[1]), (MAX_FRAME_LEN - 4, 40));
        let data = decode_rad(&buf[..len]);
        assert!(data.integrated_xgyro.is_nan() && data.integrated_zgyro.is_nan());
        assert_eq!((data.distance, data.quality), (-1.0, 0));
    }

    #[test]
    fn optical_flow_round_trips_with_its_extension_fields() {
        let flow = OpticalFlow {
            time_usec: 987_654_321,
            sensor_id: 2,
            flow_x: -123,
            flow_y: 456,
            flow_comp_m_x: 0.75,
            flow_comp_m_y: -1.5,
            quality: 77,
            ground_distance: Some(3.5),
            flow_rate_x: -1.25,
            flow_rate_y: 2.5,
        };
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow(&flow, HEADER, &mut buf).unwrap();
        assert_eq!(buf[..10], [0xFD, 34, 0, 0, 42, 1, 100, 100, 0, 0]);
        assert_eq!(len, 10 + 34 + 2);
        // The wire order: time, comp x/y, distance, flow x/y, sensor, quality, rates.
        assert_eq!(buf[10..18], 987_654_321u64.to_le_bytes());
        assert_eq!(buf[30..32], (-123i16).to_le_bytes());
        assert_eq!(buf[36..40], (-1.25f32).to_le_bytes());
        let data = decode_flow(&buf[..len]);
        assert_eq!(
            (data.time_usec, data.sensor_id, data.quality),
            (987_654_321, 2, 77)
        );
        assert_eq!((data.flow_x, data.flow_y), (-123, 456));
        assert_eq!((data.flow_comp_m_x, data.flow_comp_m_y), (0.75, -1.5));
        assert_eq!(data.ground_distance, 3.5);
        assert_eq!((data.flow_rate_x, data.flow_rate_y), (-1.25, 2.5));
    }

    #[test]
    fn an_empty_optical_flow_is_trimmed_and_says_distance_unknown() {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow(&OpticalFlow::default(), HEADER, &mut buf).unwrap();
        // Everything after the distance is zero: trimmed to time, comp x/y and distance.
        assert_eq!((len, buf[1]), (10 + 20 + 2, 20));
        let data = decode_flow(&buf[..len]);
        assert_eq!(
            (data.ground_distance, data.quality, data.flow_rate_x),
            (-1.0, 0, 0.0)
        );
    }

    #[test]
    fn heartbeat_names_a_camera_that_is_not_an_autopilot() {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode_heartbeat(HEADER, &mut buf).unwrap();
        assert_eq!(buf[..10], [0xFD, 9, 0, 0, 42, 1, 100, 0, 0, 0]);
        match decode(&buf[..len], HEARTBEAT_CRC_EXTRA) {
            MavMessage::HEARTBEAT(data) => {
                assert_eq!(data.mavtype as u8, MAV_TYPE_CAMERA);
                assert_eq!(data.autopilot as u8, MAV_AUTOPILOT_INVALID);
                assert_eq!(data.system_status, MavState::MAV_STATE_ACTIVE);
                assert_eq!((data.custom_mode, data.mavlink_version), (0, 3));
            }
            other => panic!("decoded {}", other.message_name()),
        }
    }

    #[test]
    fn every_encoder_refuses_a_short_buffer() {
        let mut short = [0u8; 20];
        assert_eq!(
            encode_heartbeat(HEADER, &mut short),
            Err(EncodeError::BufferTooSmall)
        );
        let flow = OpticalFlow {
            quality: 1,
            ..Default::default()
        };
        assert_eq!(
            encode_optical_flow(&flow, HEADER, &mut short),
            Err(EncodeError::BufferTooSmall)
        );
    }
}
