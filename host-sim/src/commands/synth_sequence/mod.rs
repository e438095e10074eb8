//! `host-sim synth-sequence`: a seeded synthetic flight with exact ground truth, for
//! `egomotion` and `stabilize` and the scripts that check them.
//!
//! DIR receives `frames/frame_NNNNN.png`, `truth.csv` (the exact homography of every frame
//! pair, in ego.csv's layout) and, for paths that turn at a constant rate, `gyro.csv` (the exact
//! body rates, sampled every millisecond from frame 0 to the last frame, in the layout
//! `egomotion --gyro` reads) and, with moving objects, `objects.csv` (every object's box in
//! every frame from 1, as `motion` numbers its boxes, to score them), and with
//! `--auto-exposure`, `exposure.csv` (each frame's gain and bias).
//!
//! The camera flags ([`camera_flags`]) film the flight with a real camera's defects; without
//! them the frames are those of the ideal camera, unchanged.

mod camera_flags;
mod mover_flags;

use std::path::PathBuf;

use super::egomotion::fps;
use super::synth::{noise, seed, size};
use super::CommandError;
use crate::cli::values::{self, path};
use crate::egomotion::FrameClock;
use crate::egomotion::GYRO_COLUMNS;
use crate::io::atomic::write_atomically;
use crate::io::csv::CsvWriter;
use crate::io::images::write_png;
use crate::io::{create_output_dir, Progress};
use crate::synth::{
    AutoExposure, Camera, FlightPath, FlightSequence, GliderSize, SceneSpec, OBJECT_SHARE,
};
use camera_flags::CameraOptions;
use mover_flags::MoverOptions;

/// `host-sim synth-sequence`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "write a seeded synthetic flight with exact homographies and gyro",
    before_help = "host-sim synth-sequence: write a seeded synthetic flight over textured ground, with the exact
homography of every frame pair and, when the camera turns at a constant rate, its gyro log.

The camera looks down at a plane with a 60 degree horizontal field of view. Paths:
  pan          translation parallel to the ground (the image shifts)
  yaw          turning about the optical axis while drifting (the image turns)
  climb        moving towards or away from the ground while drifting (the image zooms)
  perspective  a tilted ground, turning and moving along every axis (a full homography)
  rotation     turning about every axis without moving (a gyro predicts it all)
  shake        hovering with a slow drift and a random tremor in every frame
  still        not moving at all (a camera on a mast or a tripod)",
    after_help = "Files in DIR:
  frames/frame_NNNNN.png   the frames (8-bit grey), for 'host-sim egomotion DIR/frames'
  truth.csv                frame,h11,...,h33: the exact homography from frame-1 to frame
  gyro.csv                 t_us,gx,gy,gz: the exact body rates every millisecond, for
                           'egomotion --gyro' (all paths but shake)
  exposure.csv             frame,gain,bias (with --auto-exposure): each frame's gain and
                           bias, I' = gain x I + bias
  objects.csv              frame,id,x,y,w,h,dx,dy (with --objects): every object's box in
                           every frame from 1, as 'host-sim motion' numbers its boxes.csv;
                           id 0 to K-1; x,y the box's left and top pixel edges and w,h its
                           size, px (pixel column c spans c to c+1, so a box of boxes.csv
                           compares as it is); dx,dy the object's own motion since the frame
                           before, px: its shift less the ground's under its centre;
                           the box encloses every part (a walker's swinging limbs,
                           a blob's stretch), not its shadow

Moving objects glide on their own paths in the image, whatever the camera does. Example: 10
to 12 px targets at 160x120 (--object-size 20-24 at 320x240) for 'host-sim motion':
  host-sim synth-sequence --out f --path pan --width 160 --height 120 --objects 3 \\
      --object-size 10-12 --noise 1.5
  host-sim motion f/frames --out boxes.csv     (then match boxes.csv to f/objects.csv)
Movers as real footage has them: small distant walkers (8 to 20 px tall) that stop and start
and cast shadows, seen from a mast through a real camera:
  host-sim synth-sequence --out f --path still --objects 4 --object-kind walker \\
      --object-size 8-20 --object-speed 0.15 --stop-go --shadows --exposure 15 \\
      --jpeg 70 --noise 2

The camera: time is counted in frame intervals (1 / --fps). Frame k's reference instant, at
which truth.csv, gyro.csv and objects.csv hold exactly, is the middle of its first row's
exposure. With --exposure each row integrates the scene over the exposure centred on its own
instant (sampled at most half a pixel of motion apart); with --rolling-shutter row r of R is
read r / R of the readout time after the first. Each sensor pixel then goes through, in order:
vignetting, the auto-exposure gain and bias, shot and read noise, --noise; then binning
(--downscale), rounding to 8 bits, JPEG (--jpeg).

The light model (--light): a pixel of ideal grey level g collects on average
  g / 255 x 10000 electrons x (lux / 1000) x (exposure / 10 ms),
Poisson-distributed, plus Gaussian read noise (--read-noise); the gain that follows keeps the
mean at g, so the noise grows with g and with less light: at mid grey and 10 ms its standard
deviation is about 1.8 grey levels at 1000 lux, 7.5 at 60 lux and 30 at 5 lux.

Exit status: 0 success; 1 an unreadable --scene image or an output that cannot be written;
2 bad command line."
)]
pub struct SynthSequenceOptions {
    /// output directory, created if missing
    #[arg(long, value_name = "DIR", value_parser = path)]
    pub out: PathBuf,
    /// one of the paths above
    #[arg(long, value_name = "P", default_value = "pan", value_parser = flight_path)]
    pub path: FlightPath,
    /// number of frames, 2 to 10000
    #[arg(long, value_name = "N", default_value_t = 30, value_parser = frames)]
    pub frames: usize,
    /// frame width, 16 to 4096 px
    #[arg(long, value_name = "W", default_value_t = 320, value_parser = size)]
    pub width: usize,
    /// frame height, 16 to 4096 px
    #[arg(long, value_name = "H", default_value_t = 240, value_parser = size)]
    pub height: usize,
    /// seed of the scene, the path and the objects, >= 0
    #[arg(long, value_name = "S", default_value_t = 1, value_parser = seed)]
    pub seed: u64,
    /// independently moving textured rectangles, each covering 12% of the frame unless
    /// --object-size is given, 0 to 8 (2 make 20-30% of the tracks outliers)
    #[arg(long, value_name = "K", default_value_t = 0, value_parser = objects)]
    pub objects: usize,
    /// each object's width and height instead: PX, or MIN-MAX px to draw each side between
    /// (10-12), 1 to 4096; such objects are textured all over, on the same paths
    #[arg(long, value_name = "PX", value_parser = object_size)]
    pub object_size: Option<(f64, f64)>,
    /// additive Gaussian sensor noise, 0 to 50 grey levels [default: 1; 0 with --light]
    #[arg(long, value_name = "SIGMA", value_parser = noise)]
    pub noise: Option<f64>,
    /// frame rate, 1 to 10000: the gyro log's clock, and the camera's for --exposure and
    /// --rolling-shutter
    #[arg(long, value_name = "F", default_value_t = 30.0, value_parser = fps)]
    pub fps: f64,
    #[command(flatten)]
    pub camera: CameraOptions,
    #[command(flatten)]
    pub movers: MoverOptions,
}

impl SynthSequenceOptions {
    /// The additive noise: as given, else 1 grey level, or none when --light models it.
    fn noise(&self) -> f64 {
        let default = if self.camera.light.is_some() {
            0.0
        } else {
            1.0
        };
        self.noise.unwrap_or(default)
    }
}

fn frames(text: &str) -> Result<usize, String> {
    let range = |n| (2..=10_000).contains(&n);
    values::whole(text, range, "must be between 2 and 10000").map(|n| n as usize)
}

fn objects(text: &str) -> Result<usize, String> {
    let range = |n| (0..=8).contains(&n);
    values::whole(text, range, "must be between 0 and 8").map(|n| n as usize)
}

/// `PX` or `MIN-MAX`: the range each side of an object is drawn from.
fn object_size(text: &str) -> Result<(f64, f64), String> {
    let side = |part: &str| {
        let fits = |v: f64| (1.0..=4096.0).contains(&v);
        values::number(part, fits, "each side must be between 1 and 4096 px")
    };
    match text.split_once('-') {
        None => side(text).map(|v| (v, v)),
        Some((low, high)) => {
            let (low, high) = (side(low)?, side(high)?);
            match low <= high {
                true => Ok((low, high)),
                false => Err(format!("MIN must not exceed MAX (got \"{text}\")")),
            }
        }
    }
}

fn flight_path(text: &str) -> Result<FlightPath, String> {
    FlightPath::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = FlightPath::ALL.iter().map(|p| p.name()).collect();
        format!("must be one of {} (got \"{text}\")", names.join(", "))
    })
}

/// Gyro samples per second in gyro.csv.
const GYRO_RATE_HZ: u64 = 1000;

/// Runs `synth-sequence`.
pub fn run(options: &SynthSequenceOptions) -> Result<(), CommandError> {
    let camera = options.camera.camera(options.fps, options.seed)?;
    let sequence = flight_sequence(options, camera)?;
    let frames_dir = options.out.join("frames");
    create_output_dir(&frames_dir)?;
    let mut progress = Progress::new("synth-sequence", Some(options.frames));
    for k in 0..options.frames {
        write_png(&frames_dir.join(frame_name(k)), &sequence.frame(k))?;
        progress.update(k + 1);
    }
    progress.finish();
    write_atomically(
        &options.out.join("truth.csv"),
        truth_csv(&sequence, options.frames).as_bytes(),
    )?;
    if options.objects > 0 {
        write_atomically(
            &options.out.join("objects.csv"),
            objects_csv(&sequence, options.frames).as_bytes(),
        )?;
    }
    if let Some(steps) = camera.auto_exposure {
        write_atomically(
            &options.out.join("exposure.csv"),
            exposure_csv(steps, options.frames).as_bytes(),
        )?;
    }
    let clock = FrameClock::new(options.fps);
    if let Some(rates) = sequence.flight().body_rates(options.fps) {
        let end_us = clock.time_us(options.frames - 1);
        write_atomically(
            &options.out.join("gyro.csv"),
            gyro_csv(rates, end_us).as_bytes(),
        )?;
    }
    Ok(())
}

/// The flight the options describe, filmed by `camera`, over the --scene photograph if given.
fn flight_sequence(
    options: &SynthSequenceOptions,
    camera: Camera,
) -> Result<FlightSequence, CommandError> {
    let spec =
        SceneSpec::new(options.width, options.height, options.seed).with_noise(options.noise());
    let size = match options.object_size {
        Some((low, high)) => GliderSize::Sides(low, high),
        None => GliderSize::Share(OBJECT_SHARE),
    };
    let mover = options.movers.mover(options.objects)?;
    let sequence = FlightSequence::with_movers(spec, options.path, options.objects, size, mover)
        .with_camera(camera);
    Ok(match options.camera.photo()? {
        Some(photo) => sequence.with_photo(&photo, options.frames),
        None => sequence,
    })
}

/// `frame,gain,bias`: the auto-exposure loop's gain and bias in every frame.
fn exposure_csv(steps: AutoExposure, frames: usize) -> String {
    let mut csv = CsvWriter::new(Vec::new(), &EXPOSURE_COLUMNS).expect("CSV into memory");
    for k in 0..frames {
        let lighting = steps.lighting(k);
        let values = [lighting.gain, lighting.bias].map(|v| format!("{v:.6}"));
        csv.record((k, values)).expect("CSV into memory");
    }
    String::from_utf8(csv.finish().expect("CSV into memory")).expect("ASCII")
}

/// Columns of exposure.csv.
const EXPOSURE_COLUMNS: [&str; 3] = ["frame", "gain", "bias"];

/// The file name of frame `k`: zero-padded, so file-name order is frame order.
pub fn frame_name(k: usize) -> String {
    format!("frame_{k:05}.png")
}

/// `frame,h11,...,h33`: the homography from frame-1 to frame for every pair, exact to f64.
fn truth_csv(sequence: &FlightSequence, frames: usize) -> String {
    let mut csv = CsvWriter::new(Vec::new(), &TRUTH_COLUMNS).expect("CSV into memory");
    for k in 1..frames {
        let m = sequence.flight().pair_homography(k).m;
        let entries: Vec<String> = m.iter().flatten().map(|v| format!("{v:e}")).collect();
        csv.record((k, entries)).expect("CSV into memory");
    }
    String::from_utf8(csv.finish().expect("CSV into memory")).expect("ASCII")
}

/// `frame,id,x,y,w,h,dx,dy`: every object's box in every frame from 1, and its own motion
/// since the frame before.
fn objects_csv(sequence: &FlightSequence, frames: usize) -> String {
    let mut csv = CsvWriter::new(Vec::new(), &OBJECT_COLUMNS).expect("CSV into memory");
    for k in 1..frames {
        let ground = sequence.flight().pair_homography(k);
        for (id, object) in sequence.objects().iter().enumerate() {
            let (x, y, w, h) = object.box_at(k);
            let (before, now) = (object.position(k - 1), object.position(k));
            let carried = ground.apply(before.0, before.1);
            let own = (now.0 - carried.0, now.1 - carried.1);
            let values = [x, y, w, h, own.0, own.1].map(|v| format!("{v:.3}"));
            csv.record((k, id, values)).expect("CSV into memory");
        }
    }
    String::from_utf8(csv.finish().expect("CSV into memory")).expect("ASCII")
}

/// Columns of objects.csv.
const OBJECT_COLUMNS: [&str; 8] = ["frame", "id", "x", "y", "w", "h", "dx", "dy"];

/// Columns of truth.csv: ego.csv's first ten.
const TRUTH_COLUMNS: [&str; 10] = [
    "frame", "h11", "h12", "h13", "h21", "h22", "h23", "h31", "h32", "h33",
];

/// `t_us,gx,gy,gz` every millisecond from 0 to `end_us` (and at `end_us`), constant `rates`.
fn gyro_csv(rates: [f64; 3], end_us: u64) -> String {
    let step = 1_000_000 / GYRO_RATE_HZ;
    let mut csv = CsvWriter::new(Vec::new(), &GYRO_COLUMNS).expect("CSV into memory");
    let mut times: Vec<u64> = (0..=end_us).step_by(step as usize).collect();
    if times.last() != Some(&end_us) {
        times.push(end_us);
    }
    let rates = rates.map(|r| format!("{r:e}"));
    for t in times {
        csv.record((t, &rates)).expect("CSV into memory");
    }
    String::from_utf8(csv.finish().expect("CSV into memory")).expect("ASCII")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gyro_log_covers_every_frame() {
        let text = gyro_csv([1.0, -0.5, 0.0], 2_500);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t_us,gx,gy,gz");
        assert_eq!(lines[1], "0,1e0,-5e-1,0e0");
        assert_eq!(lines.last().unwrap().split(',').next(), Some("2500"));
        assert_eq!(lines.len(), 1 + 4);
    }

    #[test]
    fn object_sizes_are_one_side_or_a_range() {
        assert_eq!(object_size("11"), Ok((11.0, 11.0)));
        assert_eq!(object_size("10-12.5"), Ok((10.0, 12.5)));
        assert!(object_size("12-10")
            .unwrap_err()
            .contains("MIN must not exceed MAX"));
        assert!(object_size("0").unwrap_err().contains("between 1 and 4096"));
        assert!(object_size("ten").is_err());
    }

    #[test]
    fn objects_csv_has_a_row_per_object_and_frame_from_one() {
        let spec = SceneSpec::new(160, 120, 3);
        let sides = GliderSize::Sides(10.0, 12.0);
        let sequence = FlightSequence::with_object_size(spec, FlightPath::Pan, 2, sides);
        let text = objects_csv(&sequence, 4);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "frame,id,x,y,w,h,dx,dy");
        assert_eq!(lines.len(), 1 + 3 * 2);
        assert!(lines[1].starts_with("1,0,") && lines[6].starts_with("3,1,"));
        let w: f64 = lines[1].split(',').nth(4).unwrap().parse().unwrap();
        assert!((10.0..=12.0).contains(&w));
    }

    #[test]
    fn frame_names_sort_in_frame_order() {
        assert!(frame_name(9) < frame_name(10));
        assert_eq!(frame_name(3), "frame_00003.png");
    }
}
