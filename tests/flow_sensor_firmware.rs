//! The firmware's flow sensor and the library's, bit for bit: the host runs
//! [`kestrel::sensor::FlowSensor`] on the frames the firmware keeps in flash (rendered by the
//! firmware's own `build.rs`), with the same bad input after frame 5, and encodes each readout as
//! the firmware does. Every OPTICAL_FLOW_RAD frame must equal the one the firmware printed on the
//! emulated STM32F405 (`tests/data/flow_sensor_firmware.txt`, which `bench/target.sh` checks
//! the firmware against on every run).

use kestrel::detect::Corner;
use kestrel::ego::mavlink::{encode_optical_flow_rad, MavlinkHeader, MAX_FRAME_LEN};
use kestrel::ego::CameraParams;
use kestrel::lk::scratch_len;
use kestrel::sensor::{FlowSensor, FlowSensorConfig, FlowSensorError};
use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig, TrackerError};
use kestrel::{ImageError, ImageView};

#[allow(dead_code)]
#[path = "../firmware/build.rs"]
mod firmware_build;

use firmware_build::scene::{
    FIELD_OF_VIEW_DEGREES, FRAMES, FRAME_INTERVAL_US, FRAME_LEN, HEIGHT, WIDTH,
};

const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
const TRACKS: usize = PRESET.max_tracks;

/// The firmware's readouts: one per frame pair, stamped a frame interval apart, from sequence 0
/// of system 1, component 100.
struct Readouts {
    header: MavlinkHeader,
    time_usec: u64,
    frames: Vec<String>,
}

impl Readouts {
    fn take(&mut self, sensor: &mut FlowSensor<'_, TRACKS>) {
        self.time_usec += u64::from(FRAME_INTERVAL_US);
        let reading = sensor.readout(self.time_usec);
        let mut frame = [0u8; MAX_FRAME_LEN];
        let len = encode_optical_flow_rad(&reading, self.header.advance(), &mut frame).unwrap();
        self.frames
            .push(frame[..len].iter().map(|b| format!("{b:02x}")).collect());
    }
}

#[test]
fn the_host_sends_the_firmwares_flow_sensor_frames_bit_for_bit() {
    let pixels = firmware_build::render_frames();
    let frame = |k: usize| &pixels[k * FRAME_LEN..(k + 1) * FRAME_LEN];
    let view = |k: usize| ImageView::packed(frame(k), WIDTH, HEIGHT).unwrap();

    let fov = FIELD_OF_VIEW_DEGREES.to_radians();
    let camera = CameraParams::from_horizontal_fov(WIDTH as u16, HEIGHT as u16, fov);
    let mut storage = vec![0u8; tracker_storage_len(WIDTH, HEIGHT, PRESET.pyramid_levels())];
    let mut lk_scratch = vec![0i16; scratch_len(PRESET.lk.window)];
    let mut candidates = vec![Corner::default(); 3 * TRACKS];
    let buffers = TrackerBuffers {
        storage: &mut storage,
        lk_scratch: &mut lk_scratch,
        detect_scratch: &mut [],
        candidates: &mut candidates,
    };
    let mut sensor =
        FlowSensor::<TRACKS>::new(FlowSensorConfig::new(camera), WIDTH, HEIGHT, buffers).unwrap();
    let mut readouts = Readouts {
        header: MavlinkHeader {
            system_id: 1,
            component_id: 100,
            sequence: 0,
        },
        time_usec: 0,
        frames: Vec::new(),
    };

    sensor.start(view(0)).unwrap();
    for k in 1..FRAMES {
        let step = sensor.process(view(k - 1), view(k), FRAME_INTERVAL_US, None);
        assert!(step.unwrap().motion.is_ok(), "frame {k}");
        readouts.take(&mut sensor);
        if k == 5 {
            // The firmware's bad input, cut from frame 6: a buffer a byte short and a zero-size
            // frame are not frames (refused before the sensor), one of another size the
            // sensor refuses.
            let short = ImageView::packed(&frame(6)[..FRAME_LEN - 1], WIDTH, HEIGHT);
            assert_eq!(short.unwrap_err(), ImageError::BufferTooSmall);
            sensor.refuse(FRAME_INTERVAL_US);
            readouts.take(&mut sensor);
            assert_eq!(
                ImageView::packed(&[], 0, 0).unwrap_err(),
                ImageError::ZeroSize
            );
            sensor.refuse(FRAME_INTERVAL_US);
            readouts.take(&mut sensor);
            let small = &frame(6)[..(WIDTH / 2) * (HEIGHT / 2)];
            let small = ImageView::packed(small, WIDTH / 2, HEIGHT / 2).unwrap();
            let refused = sensor.process(view(5), small, FRAME_INTERVAL_US, None);
            let mismatch = FlowSensorError::Tracker(TrackerError::FrameSizeMismatch);
            assert_eq!(refused.unwrap_err(), mismatch);
            readouts.take(&mut sensor);
        }
    }

    let firmware = include_str!("data/flow_sensor_firmware.txt");
    let firmware: Vec<&str> = firmware.lines().collect();
    assert_eq!(readouts.frames.len(), firmware.len());
    for (i, (host, target)) in readouts.frames.iter().zip(&firmware).enumerate() {
        assert_eq!(host, target, "readout {i} differs from the firmware's");
    }
}
