//! `host-sim demo`: the README's first command. Renders a built-in sequence with exact ground
//! truth, runs each section of the demo on it, and writes pictures and a summary.
//!
//! The demo is a list of [`Section`]s; each gets the same [`Scenario`] and a folder of its own
//! and returns its lines of the summary. A new mode of the library becomes a new entry in
//! [`SECTIONS`].

mod motion;
mod tracks;

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::CommandError;
use crate::io::atomic::write_atomically;
use crate::io::create_output_dir;
use crate::synth::{CameraPath, MovingObject, Scene, SceneSpec, Sequence, Surface};
use crate::Frame;

/// `host-sim demo [--out DIR]`: its flags and usage text.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "run the library on a built-in sequence and write pictures (start here)",
    before_help = "host-sim demo: run the library on a built-in sequence and write pictures and a summary.

Renders 60 frames of a seeded synthetic scene (320x240: the camera pans, turns and zooms
while a textured box crosses the view) with exact ground truth, runs each part of the demo on
it and prints a summary. Needs no input file.",
    after_help = "Files in DIR:
  summary.txt                   the summary printed on stdout
  tracks/contact_sheet.png      every 5th frame with the KLT tracks' trails
  tracks/trails/NNNNNN.png      every frame with the trails
  tracks/tracks.csv             the tracks, as 'host-sim track' writes them
  motion/flow.png               the grid flow of a frame pair (colour wheel)
  motion/boxes/NNNNNN.png       every 5th frame with the moving boxes

Exit status: 0 success; 1 an output that cannot be written; 2 bad command line."
)]
pub struct DemoOptions {
    /// output directory, created if missing
    #[arg(long, value_name = "DIR", default_value = "demo-out", value_parser = crate::cli::values::path)]
    pub out: PathBuf,
}

/// The built-in sequence, rendered, with its ground truth.
#[derive(Debug)]
pub struct Scenario {
    /// The sequence: its camera path, its objects, the truth of every point.
    pub sequence: Sequence,
    /// Its frames.
    pub frames: Vec<Frame>,
}

/// One part of the demo.
#[derive(Debug, Clone, Copy)]
pub struct Section {
    /// Its folder in the output directory.
    pub name: &'static str,
    /// What it shows, for the summary.
    pub title: &'static str,
    /// Writes its pictures into the folder it is given and returns its summary lines.
    pub run: fn(&Scenario, &Path) -> Result<Vec<String>, CommandError>,
}

/// The sections, in the order they run.
pub const SECTIONS: &[Section] = &[
    Section {
        name: "tracks",
        title: "KLT tracks (up to 100)",
        run: tracks::run,
    },
    Section {
        name: "motion",
        title: "Dense grid flow and moving-object boxes (8 px cells)",
        run: motion::run,
    },
];

/// Frame size of the built-in sequence.
const WIDTH: usize = 320;
const HEIGHT: usize = 240;
/// Frames of the built-in sequence: two seconds at 30 Hz.
const FRAMES: usize = 60;

/// What the built-in sequence shows, for the summary.
const SCENE: &str = "the camera pans right and down, turns 10 degrees and zooms in 20%, \
                     while a textured box (outlined in white) crosses the view";

impl Scenario {
    /// The built-in sequence: a seeded scene along a steady camera path, with a box moving
    /// across it on its own.
    pub fn built_in() -> Self {
        let spec = SceneSpec::new(WIDTH, HEIGHT, 2024).with_noise(1.0);
        let half_size = (30.0, 22.0);
        let boxed = MovingObject {
            half_size,
            start: (-40.0, 150.0),
            velocity: (4.5, -1.2),
            surface: Surface::textured(7, half_size),
        };
        let scene = Scene::new(spec).with_objects(vec![boxed]);
        let path = CameraPath {
            pan: (1.5, 0.6),
            rotation: 10f64.to_radians() / FRAMES as f64,
            zoom: 1.2f64.powf(1.0 / FRAMES as f64),
            ..CameraPath::still(((WIDTH - 1) as f64 / 2.0, (HEIGHT - 1) as f64 / 2.0))
        };
        let sequence = Sequence::new(scene, path, FRAMES);
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let frames = sequence.render_all(threads);
        Self { sequence, frames }
    }
}

/// Runs `demo`.
pub fn run(options: &DemoOptions) -> Result<(), CommandError> {
    let clock = Instant::now();
    create_output_dir(&options.out)?;
    let scenario = Scenario::built_in();
    let mut summary = format!(
        "Kestrel demo: {FRAMES} frames of {WIDTH}x{HEIGHT} px of a built-in scene: {SCENE}.\n\
         Rendered in {:.1} s; output in {}\n",
        clock.elapsed().as_secs_f64(),
        options.out.display()
    );
    for section in SECTIONS {
        let dir = options.out.join(section.name);
        create_output_dir(&dir)?;
        let lines = (section.run)(&scenario, &dir)?;
        let _ = writeln!(summary, "\n{}: {}/", section.title, dir.display());
        for line in lines {
            let _ = writeln!(summary, "  {line}");
        }
    }
    let _ = writeln!(summary, "\nDone in {:.1} s.", clock.elapsed().as_secs_f64());
    write_atomically(&options.out.join("summary.txt"), summary.as_bytes())?;
    // A closed stdout (`host-sim demo | head`) is not an error: the summary is in the file.
    let _ = std::io::stdout().lock().write_all(summary.as_bytes());
    Ok(())
}
